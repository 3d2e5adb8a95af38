"""The type checker over the package: mypy must find nothing (the test command runs it)."""

from __future__ import annotations

from pathlib import Path
import subprocess
import sys

REPO = Path(__file__).resolve().parents[1]


def test_mypy_finds_no_error() -> None:
    result = subprocess.run(
        [sys.executable, '-m', 'mypy', '--ignore-missing-imports', '--no-error-summary',
         '--cache-dir', str(REPO / 'build' / 'mypy_cache'), 'vessel_kinematics'],
        cwd=REPO, capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, result.stdout + result.stderr
