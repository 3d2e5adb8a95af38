"""
One parameter reader: the node (a real process) and the replay accept and refuse the same files.

Each case is a ROS 2 parameters file and the namespace the node runs in. The node reads it
with rcl (``--params-file``), after the one reader of :mod:`vessel_kinematics.ros.params_file`
has checked it; the replay with :func:`vessel_kinematics.tools.replay.load_params` (the same
reader). Both must accept it, with the same ``max_gap`` and ``origin``, or both refuse it. The
hostile files (too deep, too big, too many keys, too long a list) are refused by both in one
line with exit status 2, a file of unknown names gets one warning line.
"""

from __future__ import annotations

import math
from pathlib import Path
import subprocess
import sys

import dds_harness
import pytest
from vessel_kinematics.ros.params import NavigatorParams, ParameterError
from vessel_kinematics.ros.params_file import MAX_BYTES, MAX_KEYS, node_pattern_matches
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
    ('yaml_1_2_exponent', '', 'navigator:\n  ros__parameters:\n    max_gap: 2e0\n', 2.0),
    ('leading_dot', '', 'navigator:\n  ros__parameters:\n    max_gap: .5\n', 0.5),
    ('removed_at_its_neutral_value', '',
     'navigator:\n  ros__parameters:\n    two_d: false\n    max_gap: 3.0\n', 3.0),
    ('removed_with_a_meaning', '', 'navigator:\n  ros__parameters:\n    two_d: true\n', 1.0),
]


def _hostile(tmp_path: Path) -> dict[str, tuple[Path, str | None]]:
    """Return {case: (file, the refusal's words, None for a warning)} of the hostile files."""
    cases: dict[str, tuple[str, str | None]] = {
        'deep_flow': ('navigator: ' + '[' * 5000 + ']' * 5000 + '\n', 'nested deeper than'),
        'five_megabytes': ('navigator:\n  ros__parameters:\n    map_frame: '
                           + 'x' * 5_000_000 + '\n', 'larger than'),
        'long_list': ('navigator:\n  ros__parameters:\n    tf.publish: ['
                      + ', '.join(['x'] * 100_000) + ']\n', 'a list longer than'),
        'unknown_keys': ('navigator:\n  ros__parameters:\n'
                         + ''.join(f'    u{k}: 0\n' for k in range(MAX_KEYS - 10)), None),
        'too_many_keys': ('navigator:\n  ros__parameters:\n'
                          + ''.join(f'    u{k}: 0\n' for k in range(50_000)), 'keys'),
        'many_lists': ('navigator:\n  ros__parameters:\n'
                       + ''.join(f'    u{k}: [{", ".join(["1"] * 1000)}]\n'
                                 for k in range(200)), 'YAML values'),
        'long_value': ('navigator:\n  ros__parameters:\n    max_gap: "'
                       + 'x' * 500_000 + '"\n', "'max_gap'"),
    }
    out = {}
    for case, (text, words) in cases.items():
        path = tmp_path / f'{case}.yaml'
        path.write_text(text)
        out[case] = (path, words)
    return out


def test_the_replay_refuses_hostile_files_in_one_short_line(tmp_path, voyage_bag) -> None:
    for case, (path, words) in _hostile(tmp_path).items():
        done = subprocess.run([sys.executable, '-m', 'vessel_kinematics.tools.replay',
                               str(voyage_bag), str(tmp_path / f'out_{case}'), '--params-file',
                               str(path), '--no-progress', '--no-copy-inputs'],
                              capture_output=True, text=True, timeout=120)
        lines = done.stderr.strip().splitlines()
        assert 'Traceback' not in done.stderr and len(lines) == 1, (case, done.stderr[:500])
        assert len(lines[0]) < 300, (case, lines[0][:400])        # a short excerpt at most
        if words is None:
            assert done.returncode == 0 and 'warning' in lines[0] and str(MAX_KEYS - 10) \
                in lines[0]
        else:
            assert done.returncode == 2 and words in lines[0], (case, lines[0])


def test_a_yaml_1_2_number_on_the_replays_command_line(tmp_path, voyage_bag) -> None:
    assert replay.parse_param('max_gap:=2e0') == ('max_gap', 2.0)
    assert replay.parse_param('max_gap:=.5') == ('max_gap', 0.5)
    assert replay.load_params(None, {'max_gap': 2.0}).max_gap == 2.0
    with pytest.raises(ParameterError, match="'two_d': was removed: use motion: ground"):
        NavigatorParams.from_flat({'two_d': True})


def test_a_removed_name_is_ignored_in_one_line_saying_what_replaces_it(capsys) -> None:
    from vessel_kinematics.ros.navigator import check_arguments
    assert replay.load_params(None, {'two_d': True}).motion == 'surface'
    line = capsys.readouterr().err.strip()
    assert line == ("replay: warning: -p: parameter 'two_d' was removed and is ignored (use "
                    'motion: ground; two_d: True is NOT applied)'), line
    said: list[str] = []
    assert check_arguments(['navigator', '--ros-args', '-p', 'publish_tf:=true'],
                           said.append) is None
    assert said == ["-p: parameter 'publish_tf' was removed and is ignored (use tf.publish: "
                    '[none])']
    assert MAX_BYTES == 1 << 20


@pytest.fixture(scope='module')
def voyage_bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    from test_replay import write_voyage
    return write_voyage(tmp_path_factory.mktemp('voyage') / 'in', duration=2.0)


@pytest.mark.dds
def test_the_node_refuses_hostile_files_in_one_short_line(navigator_env, tmp_path) -> None:
    executable = dds_harness.resolve_executable(navigator_env, 'navigator')
    for case, (path, words) in _hostile(tmp_path).items():
        if words is None:           # a warning: the node starts (test_the_node_accepts...)
            continue
        done = subprocess.run([str(executable), '--ros-args', '--params-file', str(path)],
                              env=navigator_env, capture_output=True, text=True, timeout=60,
                              check=False)
        lines = done.stderr.strip().splitlines()
        assert done.returncode == 2 and len(lines) == 1 and words in lines[0], (case, lines)
        assert len(lines[0]) < 300 and not done.stdout, case
    done = subprocess.run([str(executable), '--ros-args', '-p', 'max_gap:=1e9'],
                          env=navigator_env, capture_output=True, text=True, timeout=60)
    assert done.returncode == 2 and "'max_gap': must be in" in done.stderr, done.stderr


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
