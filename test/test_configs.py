"""
The shipped parameter files (config/*.yaml) apply under any namespace and use current names.

Each has one section, ``/**/navigator`` (a bare ``navigator:`` would match only ``/navigator``
and silently stop applying under ``-r __ns:=/vessel``), and names only parameters of the
navigator's table that are not deprecated: a misspelt, removed or deprecated name fails here,
where the node would take it without complaint. ``navigator.yaml`` lists every parameter with
its default, as its header says.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import pytest
from vessel_kinematics.ros.params import PARAMETERS
from vessel_kinematics.ros.params_file import flatten
import yaml

REPO = Path(__file__).resolve().parents[1]
CONFIGS = sorted((REPO / 'config').glob('*.yaml'))
CURRENT = {p.name: p for p in PARAMETERS if not p.description.startswith('deprecated')}


def _parameters(path: Path) -> dict[str, Any]:
    document = yaml.safe_load(path.read_text())
    assert list(document) == ['/**/navigator'], path.name
    return flatten(document['/**/navigator']['ros__parameters'])


def _same(a: Any, b: Any) -> bool:
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(map(_same, a, b))
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a):
        return math.isnan(b)
    return bool(a == b)


def test_there_are_configs() -> None:
    assert {p.name for p in CONFIGS} >= {'navigator.yaml', 'demo.yaml'}


@pytest.mark.parametrize('path', CONFIGS, ids=[p.name for p in CONFIGS])
def test_a_config_names_only_current_parameters(path: Path) -> None:
    unknown = sorted(set(_parameters(path)) - set(CURRENT))
    assert unknown == []


def test_navigator_yaml_lists_every_parameter_with_its_default() -> None:
    values = _parameters(REPO / 'config' / 'navigator.yaml')
    assert sorted(values) == sorted(CURRENT)
    different = {name: (values[name], p.default) for name, p in CURRENT.items()
                 if not _same(values[name], p.default)}
    assert different == {}
