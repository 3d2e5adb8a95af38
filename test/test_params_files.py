"""
One parameter reader: the node (a real process) and the replay accept and refuse the same files.

Each case is a ROS 2 parameters file and the namespace the node runs in. The node reads it
with rcl (``--params-file``); the replay with :func:`vessel_kinematics.tools.replay.load_params`
(rclpy's parser and rcl's wildcard keys). Both must accept it, with the same ``max_gap`` and
``origin``, or both refuse it.
"""

from __future__ import annotations

import math
from pathlib import Path
import subprocess

import dds_harness
import pytest
from vessel_kinematics.ros.params import node_pattern_matches, ParameterError
from vessel_kinematics.tools import replay

#: (case, namespace, params file text, expected max_gap or None when refused)
CASES = [
    ('wildcard', '', '/**:\n  ros__parameters:\n    max_gap: 2.5\n', 2.5),
    ('any_namespace', '/vessel',
     '/**/navigator:\n  ros__parameters:\n    max_gap: 2.5\n', 2.5),
    ('namespaced', '/vessel',
     '/vessel/navigator:\n  ros__parameters:\n    max_gap: 3.5\n', 3.5),
    ('bare_name', '', 'navigator:\n  ros__parameters:\n    max_gap: 1.5\n', 1.5),
    ('later_section_wins', '',
     '/**:\n  ros__parameters:\n    max_gap: 2.5\n'
     '/navigator:\n  ros__parameters:\n    max_gap: 4.5\n', 4.5),
    ('other_node_only', '', '/other:\n  ros__parameters:\n    max_gap: 2.5\n', 1.0),
    ('integer_as_double', '', 'navigator:\n  ros__parameters:\n    max_gap: 2\n', 2.0),
    ('list_of_ints', '',
     'navigator:\n  ros__parameters:\n    max_gap: 2.0\n    origin: [59, 10, 0]\n', 2.0),
    ('wrong_type', '', 'navigator:\n  ros__parameters:\n    max_gap: soon\n', None),
    ('out_of_range', '', 'navigator:\n  ros__parameters:\n    max_gap: -1.0\n', None),
    ('unknown_name', '',
     'navigator:\n  ros__parameters:\n    max_gapp: 2.0\n    max_gap: 2.0\n', 2.0),
    ('qos_overrides', '',
     'navigator:\n  ros__parameters:\n    max_gap: 2.0\n    qos_overrides:\n'
     '      /fix:\n        subscription:\n          reliability: reliable\n', 2.0),
]


def _replay_reads(path: Path, namespace: str) -> float | None:
    try:
        return replay.load_params(path, node_fqn=f'{namespace}/navigator').max_gap
    except ParameterError:
        return None


@pytest.mark.parametrize('case, namespace, text, expected', CASES, ids=[c[0] for c in CASES])
def test_replay_reads_params_files_as_the_node(case, namespace, text, expected,
                                               tmp_path) -> None:
    path = tmp_path / f'{case}.yaml'
    path.write_text(text)
    assert _replay_reads(path, namespace) == expected


@pytest.mark.dds
def test_the_node_accepts_and_refuses_the_same_files(dds, run_navigator, tmp_path) -> None:
    disagreements = []
    for case, namespace, text, expected in CASES:
        path = tmp_path / f'{case}.yaml'
        path.write_text(text)
        remaps = {'__ns': namespace} if namespace else None
        process = run_navigator(params_file=path, remaps=remaps)
        assert dds.spin_until(lambda: not process.alive() or 'navigator ready'
                              in process.output(), 30.0), process.output()
        if process.alive():
            values = dds.get_parameters(f'{namespace}/navigator', ['max_gap', 'origin'])
            node = values['max_gap']
            if case == 'list_of_ints':
                assert list(values['origin']) == [59.0, 10.0, 0.0]
            assert isinstance(node, float), (case, node)
            process.stop()
        else:
            node = None
            lines = [line for line in process.output().splitlines() if line.strip()]
            assert 'Traceback' not in process.output() and len(lines) <= 2, process.output()
        if node != _replay_reads(path, namespace) or node != expected:
            disagreements.append((case, node, _replay_reads(path, namespace), expected))
    assert not disagreements


@pytest.mark.parametrize('key, fqn, matches', [
    ('/**', '/navigator', True), ('/**', '/a/b/navigator', True),
    ('/**/navigator', '/navigator', True), ('/**/navigator', '/a/b/navigator', True),
    ('/*/navigator', '/a/navigator', True), ('/*/navigator', '/navigator', False),
    ('navigator', '/navigator', True), ('navigator', '/a/navigator', False),
    ('/a/navigator', '/a/navigator', True), ('/a/navigator', '/b/navigator', False),
    ('/**/nav', '/navigator', False),
])
def test_node_pattern_matches_as_rcl(key, fqn, matches) -> None:
    assert node_pattern_matches(key, fqn) is matches


def test_shipped_config_matches_under_a_namespace(repo) -> None:
    path = repo / 'config' / 'navigator.yaml'
    for fqn in ('/navigator', '/vessel/navigator'):
        values = replay.load_params(path, node_fqn=fqn)
        assert math.isnan(values.origin[0]) and values.max_gap == 1.0


@pytest.mark.dds
@pytest.mark.parametrize('args, code, first', [
    (['--help'], 0, 'usage: ros2 run vessel_kinematics navigator'),
    (['--ros-args', '--params-file', '/nonexistent/navigator.yaml'], 2,
     'navigator: error: cannot read --params-file /nonexistent/navigator.yaml'),
    (['--ros-args', '--params-file', '{bad}'], 2, 'navigator: error: --params-file'),
])
def test_help_and_a_bad_params_file_in_one_line(navigator_env, tmp_path, args, code,
                                                first) -> None:
    bad = tmp_path / 'bad.yaml'
    bad.write_text('navigator: [ros__parameters:\n')
    args = [str(bad) if a == '{bad}' else a for a in args]
    executable = dds_harness.resolve_executable(navigator_env, 'navigator')
    done = subprocess.run([str(executable), *args], env=navigator_env, capture_output=True,
                          text=True, timeout=60, check=False)
    assert done.returncode == code, done
    text = (done.stdout if code == 0 else done.stderr).strip()
    assert text.startswith(first), text
    if code:
        assert len(text.splitlines()) == 1 and not done.stdout, done
