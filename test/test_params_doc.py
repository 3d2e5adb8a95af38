"""docs/parameters.md is generated from the one parameter table, and is in step with it."""

from __future__ import annotations

from pathlib import Path
import subprocess
import sys

from vessel_kinematics.ros.params import markdown, PARAMETERS

REPO = Path(__file__).resolve().parents[1]


def test_docs_parameters_md_is_the_generated_table() -> None:
    text = (REPO / 'docs' / 'parameters.md').read_text()
    assert text == markdown(), ('docs/parameters.md is not the table: regenerate it with '
                                '`python -m vessel_kinematics.ros.params --markdown '
                                '> docs/parameters.md`')
    for parameter in PARAMETERS:
        assert f'| `{parameter.name}` |' in text, parameter.name


def test_the_generator_is_a_command() -> None:
    done = subprocess.run([sys.executable, '-m', 'vessel_kinematics.ros.params', '--markdown'],
                          cwd=REPO, capture_output=True, text=True, timeout=60, check=True)
    assert done.stdout == markdown()
