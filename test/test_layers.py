"""
The architecture, checked: four layers, each importing only those below, and no import cycle.

Every import of every module counts, function-level ones included (an import hidden in a
function is still a dependency). The layers (``vessel_kinematics/__init__.py``):
core -> estimation -> ros -> tools.
"""

from __future__ import annotations

import ast
from pathlib import Path
import sys

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / 'vessel_kinematics'
LAYERS = ('core', 'estimation', 'ros', 'tools')
STDLIB = set(sys.stdlib_module_names)
#: What no module below the ROS edge may import.
ROS_EDGE_ONLY = ('rclpy', 'rosbags', 'yaml', 'matplotlib', 'rosidl_runtime_py')


def _modules() -> dict[str, Path]:
    out = {}
    for path in sorted(PACKAGE.rglob('*.py')):
        parts = path.relative_to(PACKAGE.parent).with_suffix('').parts
        name = '.'.join(parts[:-1] if parts[-1] == '__init__' else parts)
        out[name] = path
    return out


MODULES = _modules()


def _imports(path: Path) -> set[str]:
    """Return every module ``path`` imports, at any depth, as absolute dotted names."""
    found = set()
    package = '.'.join(path.relative_to(PACKAGE.parent).with_suffix('').parts[:-1])
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ''
            if node.level:
                base = '.'.join(package.split('.')[:len(package.split('.')) - node.level + 1]
                                + ([base] if base else []))
            found.add(base)
            for alias in node.names:             # from pkg import module
                if f'{base}.{alias.name}' in MODULES:
                    found.add(f'{base}.{alias.name}')
    return found


def _layer(module: str) -> str | None:
    parts = module.split('.')
    return parts[1] if len(parts) > 1 and parts[1] in LAYERS else None


@pytest.mark.parametrize('module', sorted(MODULES))
def test_each_module_imports_only_its_layer_and_below(module: str) -> None:
    layer = _layer(module)
    imports = _imports(MODULES[module])
    ours = {i for i in imports if i.startswith('vessel_kinematics')}
    if layer is None:                # the package's __init__ and the replay shim
        return
    rank = LAYERS.index(layer)
    for target in ours:
        target_layer = _layer(target)
        if target_layer is not None:
            assert LAYERS.index(target_layer) <= rank, f'{module} imports {target} (above it)'
    third_party = {i.split('.')[0] for i in imports - ours} - STDLIB - {'__future__'}
    if layer == 'core':
        assert third_party <= {'numpy'}, f'{module}: the core imports numpy only: {third_party}'
    if layer in ('core', 'estimation'):
        banned = {t for t in third_party
                  if t in ROS_EDGE_ONLY or t.endswith('_msgs') or t.endswith('_interfaces')}
        assert not banned, f'{module} imports {banned}: only the ROS edge may'


def test_no_import_cycle() -> None:
    graph = {m: {i for i in _imports(p) if i in MODULES and i != m} for m, p in MODULES.items()}
    # A package's __init__ importing its own modules is no cycle of dependencies.
    for m in graph:
        graph[m] = {i for i in graph[m] if not m.startswith(i + '.') and not i == m}
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(m: str) -> None:
        state[m] = 1
        stack.append(m)
        for n in sorted(graph[m]):
            if state.get(n) == 1:
                cycle = stack[stack.index(n):] + [n]
                raise AssertionError('import cycle: ' + ' -> '.join(cycle))
            if n not in state:
                visit(n)
        stack.pop()
        state[m] = 2

    for m in sorted(graph):
        if m not in state:
            visit(m)


def test_the_layers_are_what_the_package_says() -> None:
    assert {_layer(m) for m in MODULES} == set(LAYERS) | {None}
    assert (PACKAGE / 'replay.py').is_file()      # python -m vessel_kinematics.replay


@pytest.mark.parametrize('module', sorted(m for m in MODULES if _layer(m) is not None
                                          and not m.endswith('__init__')
                                          and MODULES[m].name != '__init__.py'))
def test_each_module_declares_its_public_surface(module: str) -> None:
    """``__all__`` in every module, naming only what the module defines or imports."""
    import importlib
    mod = importlib.import_module(module)
    assert hasattr(mod, '__all__'), f'{module} has no __all__'
    missing = [name for name in mod.__all__ if not hasattr(mod, name)]
    assert not missing, f'{module}.__all__ names what it does not have: {missing}'


def test_bag_io_lives_in_tools_bags_only() -> None:
    """Only ``tools/bags.py`` imports rosbags: bag I/O is written once."""
    users = sorted(m for m, p in MODULES.items()
                   if any(i.split('.')[0] == 'rosbags' for i in _imports(p)))
    assert users == ['vessel_kinematics.tools.bags']


def test_matplotlib_lives_in_tools_plot_only() -> None:
    """Only ``tools/plot.py`` imports matplotlib: plotting is apart from the scores."""
    users = sorted(m for m, p in MODULES.items()
                   if any(i.split('.')[0] == 'matplotlib' for i in _imports(p)))
    assert users == ['vessel_kinematics.tools.plot']


def test_the_scores_are_numbers_only() -> None:
    """``tools/evaluate.py`` takes data and returns numbers: no matplotlib, no driver."""
    imports = _imports(MODULES['vessel_kinematics.tools.evaluate'])
    assert not {i for i in imports if i.split('.')[0] in ('matplotlib', 'rosbags', 'rclpy')}
    ours = {i for i in imports if i.startswith('vessel_kinematics.tools')}
    assert ours <= {'vessel_kinematics.tools.bags'}, ours   # bags are read through tools/bags


@pytest.mark.parametrize('module', ['sim_model', 'sim_sensors'])
def test_the_simulated_vessel_is_numbers_only(module: str) -> None:
    """``tools/sim_model.py`` (the vessel), ``sim_sensors.py`` (its sensors): numpy, the core."""
    imports = _imports(MODULES[f'vessel_kinematics.tools.{module}'])
    ours = {i for i in imports if i.startswith('vessel_kinematics')}
    assert all(_layer(i) == 'core' for i in ours - {'vessel_kinematics.tools.sim_model'}), ours
    third_party = {i.split('.')[0] for i in imports - ours} - STDLIB - {'__future__'}
    assert third_party == {'numpy'}
