"""
/diagnostics as diagnostic_updater builds them: a status per task named after the node.

Pipeline-level: the statuses and their names, an input going late (WARN) then gone (ERROR) by
the configured thresholds, the clock going back (never a negative age), ``fix/filtered``'s
NO_FIX while dead reckoning. Over DDS with the real node: a stopped input is flagged WARN
then ERROR, under the node's real name.
"""

from __future__ import annotations

import time
from typing import Any

from dds_harness import make_fix, make_imu, make_twist
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
import pytest
from sensor_msgs.msg import NavSatStatus
from test_navigator_node import ORIGIN, Scenario, Voyage
from test_pipeline import decoded, fix_msg, handle, imu_msg, make, T0, vel_msg
from vessel_kinematics.ros import outputs
from vessel_kinematics.ros.diagnostics import CLOCK_WENT_BACK
from vessel_kinematics.ros.pipeline import Emission

NS = 1_000_000_000
OK, WARN, ERROR = DiagnosticStatus.OK, DiagnosticStatus.WARN, DiagnosticStatus.ERROR


def _statuses(array: Emission | DiagnosticArray) -> dict[str, DiagnosticStatus]:
    """Return the statuses by name of a pipeline's emission or of a received array."""
    if isinstance(array, Emission):
        array = decoded([array])['/diagnostics']
    return {status.name: status for status in array.status}


def _values(status: DiagnosticStatus) -> dict[str, str]:
    return {kv.key: kv.value for kv in status.values}


def _run(pipe: Any, t_end: float, fix: bool = True) -> None:
    """Feed 10 Hz IMU and velocity (and 1 Hz fixes) from T0 to T0 + t_end."""
    for k in range(int(t_end * 10)):
        t = k / 10
        handle(pipe, 'imu', imu_msg(t, 0.0, 0.0))
        handle(pipe, 'velocity', vel_msg(t + 0.001, 1.0, 0.0))
        if fix and k % 10 == 0:
            handle(pipe, 'fix', fix_msg(t + 0.002, (t, 0.0, 0.0)))


def test_statuses_named_after_the_node_with_rates() -> None:
    pipe = make()
    pipe.diagnostics(int(T0 * NS), 'nav')
    _run(pipe, 4.0)
    statuses = _statuses(pipe.diagnostics(int((T0 + 4.0) * NS), 'nav'))
    assert set(statuses) == {'nav: estimate', 'nav: fix', 'nav: imu', 'nav: velocity',
                             'nav: heading', 'nav: log'}
    assert statuses['nav: heading'].level == OK and statuses['nav: log'].level == OK
    assert 'acceleration level (m/s^2)' in _values(statuses['nav: estimate'])
    assert statuses['nav: estimate'].level == OK
    assert _values(statuses['nav: estimate'])['mode'] == 'fused'
    imu = statuses['nav: imu']
    assert imu.level == OK and float(_values(imu)['rate (Hz)']) == pytest.approx(10.0)
    assert float(_values(statuses['nav: fix'])['rate (Hz)']) == pytest.approx(1.0)


def test_stopped_input_is_late_then_gone() -> None:
    pipe = make(**{'diagnostics.stale_warn': 1.0, 'diagnostics.stale_error': 3.0})
    _run(pipe, 2.0)
    last_fix = 1.0 + 0.002
    # Velocity and IMU go on, the fixes stopped at T0 + 1.002.
    for t, level in ((last_fix + 0.5, OK), (last_fix + 2.0, WARN), (last_fix + 4.0, ERROR)):
        for k in range(int((t - 2.0) * 10)):
            handle(pipe, 'imu', imu_msg(2.0 + k / 10, 0.0, 0.0))
        status = _statuses(pipe.diagnostics(int((T0 + t) * NS)))['navigator: fix']
        assert status.level == level, (t, status.message)
    assert 'stale' in status.message
    assert _statuses(pipe.diagnostics(int((T0 + t) * NS)))['navigator: imu'].level == OK


def test_the_estimate_is_not_fused_once_every_input_fell_silent() -> None:
    """The mode follows the stamps, which stand still when nothing arrives: the clock tells."""
    pipe = make()
    _run(pipe, 4.0)
    for t, level in ((3.5, OK), (7.0, WARN), (24.0, WARN)):
        status = _statuses(pipe.diagnostics(int((T0 + t) * NS)))['navigator: estimate']
        assert status.level == level, (t, status.message)
    assert status.message == 'fused until 21 s ago: no fix has arrived since'


def test_never_received_input_is_an_error_after_stale_error() -> None:
    pipe = make(**{'diagnostics.stale_error': 2.0})
    assert _statuses(pipe.diagnostics(int(T0 * NS)))['navigator: velocity'].level == WARN
    assert _statuses(pipe.diagnostics(int((T0 + 3) * NS)))['navigator: velocity'].level == ERROR


def test_clock_going_back_never_gives_a_negative_age() -> None:
    pipe = make()
    _run(pipe, 2.0)
    pipe.diagnostics(int((T0 + 2.0) * NS))
    array = _statuses(pipe.diagnostics(int((T0 - 100.0) * NS)))   # /clock jumped back 102 s
    for status in array.values():
        for key, value in _values(status).items():
            if 'age' in key or 'rate' in key or 'since' in key:
                assert value == CLOCK_WENT_BACK or value == 'n/a' or float(value) >= 0.0, key
    fix = array['navigator: fix']
    assert fix.level == WARN and fix.message == CLOCK_WENT_BACK
    assert _values(array['navigator: estimate'])['age fix (s)'] == CLOCK_WENT_BACK


def test_the_time_since_each_input_arrived() -> None:
    """The arrival time (the driver's clock) is carried: how long since each input came in."""
    pipe = make()
    pipe.handle('imu', imu_msg(0.0, 0.0, 0.0), int((T0 + 5.0) * NS))     # arrived 5 s late
    status = _statuses(pipe.diagnostics(int((T0 + 6.5) * NS)))
    assert _values(status['navigator: imu'])['since received (s)'] == '1.500'
    assert _values(status['navigator: imu'])['age (s)'] == '6.500'
    assert _values(status['navigator: fix'])['since received (s)'] == 'never'


def test_warn_above_error_is_refused() -> None:
    from vessel_kinematics.ros.params import ParameterError
    with pytest.raises(ParameterError, match='stale_warn'):
        make(**{'diagnostics.stale_warn': 6.0, 'diagnostics.stale_error': 5.0})


def _fix_filtered(pipe: Any) -> Any:
    return decoded(Emission('/' + name, 0, data) for name, data in outputs.state_outputs(
        pipe.state(), pipe.params))['fix/filtered']


def test_fix_filtered_says_no_fix_while_dead_reckoning() -> None:
    pipe = make()
    _run(pipe, 2.0)
    fused = _fix_filtered(pipe)
    assert fused.status.status == NavSatStatus.STATUS_FIX
    for k in range(100):                      # 10 s more without a fix: dead reckoning
        handle(pipe, 'velocity', vel_msg(2.0 + k / 10, 1.0, 0.0))
    dead = _fix_filtered(pipe)
    assert dead.status.status == NavSatStatus.STATUS_NO_FIX
    assert dead.position_covariance[0] > fused.position_covariance[0]   # honest, growing


@pytest.mark.dds
def test_node_flags_a_stopped_input_warn_then_error(dds, run_navigator) -> None:
    # Inputs stamped with the wall clock (the node's clock); velocity stops, the IMU goes on.
    scenario = Scenario(dds, run_navigator, **{'diagnostics.stale_warn': 1.0,
                                               'diagnostics.stale_error': 2.5})
    q = Voyage(speed=1.0).quaternion_enu_flu(0.0)
    start = time.time()
    dds.publish('fix', make_fix(start, *ORIGIN))
    while time.time() - start < 1.5:
        now = time.time()
        dds.publish('imu', make_imu(now, q))
        dds.publish('velocity', make_twist(now, (1.0, 0.0, 0.0)))
        dds.spin_for(0.05)
    seen_before = len(scenario.diagnostics)
    levels: list[int] = []
    stop = time.time()
    while time.time() - stop < 15.0 and ERROR not in levels:
        dds.publish('imu', make_imu(time.time(), q))
        dds.spin_for(0.05)
        for array in scenario.diagnostics[seen_before:]:
            statuses = _statuses(array)
            levels.append(statuses['navigator: velocity'].level)
            last = statuses
        seen_before = len(scenario.diagnostics)
    # Late (WARN) first, then gone (ERROR); never back to OK while stopped.
    assert WARN in levels and ERROR in levels, levels
    assert levels.index(WARN) < levels.index(ERROR), levels
    assert levels == sorted(levels), levels
    assert last['navigator: imu'].level == OK, last['navigator: imu'].message
    assert 'stale' in last['navigator: velocity'].message


def test_faults_and_events_in_diagnostics_and_the_replay_summary(tmp_path: Any) -> None:
    """
    A compass frozen in a turn and a log silent for 40 s, replayed from a simulated bag.

    /diagnostics says each (``heading`` WARN frozen, ``log`` ERROR missing) while it lasts and
    OK after; the replay's summary lists the estimator's events (found, over, back) and its
    health at the end; the frozen samples are counted as ``imu/frozen_input``.
    """
    from vessel_kinematics.ros.params import NavigatorParams
    from vessel_kinematics.tools import replay, sim
    config = sim.VoyageConfig(duration=120.0, compass_freeze=(40.0, 30.0),
                              log_outage=(20.0, 40.0), outage=(0.0, 0.0))
    sim.generate(tmp_path / 'voyage', config)
    params = NavigatorParams.from_flat({'velocity.reference': 'water'})
    got, summary = replay.replay_in_memory(tmp_path / 'voyage', params,
                                           topics=['/diagnostics'])
    start = got['/diagnostics'][0][0]
    seen: dict[str, list[tuple[float, bytes, str]]] = {'heading': [], 'log': []}
    for stamp, array in got['/diagnostics']:
        for status in array.status:
            part = status.name.split(': ', 1)[1]
            if part in seen:
                level = bytes((status.level,))   # rosbags reads the byte as an int
                seen[part].append(((stamp - start) * 1e-9, level, status.message))
    heading_warn = [t for t, level, text in seen['heading']
                    if level == WARN and 'frozen' in text]
    assert heading_warn and 40.0 < heading_warn[0] <= 46.0 and heading_warn[-1] <= 71.0
    assert seen['heading'][-1][1] == OK
    log_error = [t for t, level, text in seen['log'] if level == ERROR and 'missing' in text]
    assert log_error and 28.5 <= log_error[0] <= 32.0 and log_error[-1] <= 61.0
    assert seen['log'][-1][1] == OK
    events = '\n'.join(summary.events)
    assert 'compass frozen' in events and 'compass live again' in events
    assert 'velocity sensor back after' in events
    assert summary.rejected['imu/frozen_input'] > 0
    text = summary.text()
    assert 'health     heading OK: ok' in text and 'health     log OK: ok' in text
    assert 'event      ' in text
