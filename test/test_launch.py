"""
The launch file: it names the installed executable and parameters file; it loads with launch_ros.

The static checks parse ``launch/navigator.launch.py`` with :mod:`ast` and always run; the
check that builds the LaunchDescription needs ``launch_ros`` and skips only where it is absent.
"""

from __future__ import annotations

import ast
import importlib.util
import os
from pathlib import Path
from typing import Any

import pytest

REPO = Path(__file__).resolve().parents[1]
LAUNCH_FILE = REPO / 'launch' / 'navigator.launch.py'


def _constants(tree: ast.Module) -> dict[str, Any]:
    """Return the module-level NAME = <literal or os.path.join of literals> assignments."""
    found: dict[str, Any] = {}
    for statement in tree.body:
        if isinstance(statement, ast.Assign) and len(statement.targets) == 1:
            target = statement.targets[0]
            if isinstance(target, ast.Name):
                try:
                    found[target.id] = _evaluate(statement.value, found)
                except ValueError:
                    pass
    return found


def _evaluate(node: ast.AST, constants: dict[str, Any]) -> Any:
    """Evaluate a literal, a known constant name or os.path.join(...) of those."""
    if isinstance(node, ast.Constant):
        return node.value
    if isinstance(node, ast.Name) and node.id in constants:
        return constants[node.id]
    if (isinstance(node, ast.Call) and ast.unparse(node.func) == 'os.path.join'
            and not node.keywords):
        return os.path.join(*(_evaluate(arg, constants) for arg in node.args))
    raise ValueError(f'not a constant: {ast.unparse(node)}')


def _calls(tree: ast.AST, name: str) -> list[ast.Call]:
    return [node for node in ast.walk(tree)
            if isinstance(node, ast.Call) and ast.unparse(node.func).split('.')[-1] == name]


def _keyword(call: ast.Call, name: str) -> ast.AST | None:
    return next((k.value for k in call.keywords if k.arg == name), None)


@pytest.fixture(scope='module')
def launch_tree() -> ast.Module:
    """Return the parsed launch file."""
    return ast.parse(LAUNCH_FILE.read_text(), filename=str(LAUNCH_FILE))


def test_launch_file_names_the_navigator_executable(launch_tree: ast.Module) -> None:
    constants = _constants(launch_tree)
    nodes = _calls(launch_tree, 'Node')
    assert len(nodes) == 1, 'the launch file starts exactly one Node'
    node = nodes[0]
    assert _evaluate(_keyword(node, 'package'), constants) == 'vessel_kinematics'
    assert _evaluate(_keyword(node, 'executable'), constants) == 'navigator'
    name = _keyword(node, 'name')
    assert name is None or _evaluate(name, constants) == 'navigator'


def test_launch_file_takes_params_file_and_use_sim_time(launch_tree: ast.Module) -> None:
    constants = _constants(launch_tree)
    arguments = {_evaluate(call.args[0], constants): call
                 for call in _calls(launch_tree, 'DeclareLaunchArgument')}
    assert {'params_file', 'use_sim_time'} <= set(arguments)
    assert _evaluate(_keyword(arguments['use_sim_time'], 'default_value'), constants) == 'false'
    # The default parameters file is the installed share/vessel_kinematics/config/navigator.yaml.
    source = ast.unparse(launch_tree)
    shares = _calls(launch_tree, 'get_package_share_directory')
    assert shares and all(_evaluate(c.args[0], constants) == 'vessel_kinematics' for c in shares)
    config = [v for v in constants.values()
              if isinstance(v, str) and v.replace(os.sep, '/') == 'config/navigator.yaml']
    assert config or "'navigator.yaml'" in source, 'the default params file is navigator.yaml'
    # The node's parameters are the params_file argument and use_sim_time.
    parameters = ast.unparse(_keyword(_calls(launch_tree, 'Node')[0], 'parameters'))
    assert 'params_file' in parameters and 'use_sim_time' in parameters
    for config_call in _calls(launch_tree, 'LaunchConfiguration'):
        assert _evaluate(config_call.args[0], constants) in arguments


def test_launch_file_and_what_it_names_are_installed(colcon_install: Path) -> None:
    share = colcon_install / 'vessel_kinematics' / 'share' / 'vessel_kinematics'
    assert (share / 'launch' / 'navigator.launch.py').is_file()
    assert (share / 'config' / 'navigator.yaml').is_file()
    executable = colcon_install / 'vessel_kinematics' / 'lib' / 'vessel_kinematics' / 'navigator'
    assert executable.is_file() and os.access(executable, os.X_OK)


def test_launch_description_with_launch_ros(colcon_install: Path,
                                            monkeypatch: pytest.MonkeyPatch) -> None:
    pytest.importorskip('launch_ros')
    from launch import LaunchContext
    from launch.actions import DeclareLaunchArgument
    from launch_ros.actions import Node

    prefix = colcon_install / 'vessel_kinematics'
    monkeypatch.setenv('AMENT_PREFIX_PATH',
                       os.pathsep.join([str(prefix), os.environ.get('AMENT_PREFIX_PATH', '')]))
    spec = importlib.util.spec_from_file_location('navigator_launch', LAUNCH_FILE)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    description = module.generate_launch_description()
    arguments = {a.name: a for a in description.entities if isinstance(a, DeclareLaunchArgument)}
    context = LaunchContext()
    default = ''.join(s.perform(context) for s in arguments['params_file'].default_value)
    assert Path(default) == prefix / 'share' / 'vessel_kinematics' / 'config' / 'navigator.yaml'
    nodes = [e for e in description.entities if isinstance(e, Node)]
    assert len(nodes) == 1
    assert nodes[0].node_package == 'vessel_kinematics'
    assert nodes[0].node_executable == 'navigator'
