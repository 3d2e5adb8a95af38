"""
Real sensor timing through the pipeline: late, early and offset stamps, and time jumps.

Each message is handed to :class:`~vessel_kinematics.ros.pipeline.Pipeline` with an arrival
time, as the node hands its clock's time and the replay its bag's log time: fixes delivered
late, one fix very late, messages stamped far ahead, a GNSS clock in GPS time, a frozen IMU
clock, a looped bag and a clock that goes back.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from test_pipeline import decoded, fix_msg, imu_msg, make, T0, vel_msg, Vessel
from vessel_kinematics.ros.params import NavigatorParams
from vessel_kinematics.ros.pipeline import Pipeline
from vessel_kinematics.ros.timing import CLOCK_CONFIRM_NS, OFFSET_WINDOW


def stamp_ns(msg) -> int:
    return msg.header.stamp.sec * 10 ** 9 + msg.header.stamp.nanosec


def arrivals(messages, fix_delay: float = 0.0, delay: dict | None = None):
    """Return (name, msg, arrival ns) in arrival order: fixes ``fix_delay`` s after their stamp."""
    out = []
    for i, (name, msg) in enumerate(messages):
        late = (delay or {}).get(i, fix_delay if name == 'fix' else 0.0)
        out.append((name, msg, stamp_ns(msg) + int(round(late * 1e9))))
    out.sort(key=lambda a: a[2])
    return out


def run(pipe: Pipeline, items) -> tuple[list, list]:
    """Feed ``items``; return the emissions' decoded outputs, and the refusals."""
    outs, refused = [], []
    for name, msg, arrival in items:
        result = pipe.handle(name, msg, arrival)
        if result.rejected:
            refused.append((name, result.rejected))
        refused += [(n, r) for n, r, _ in result.later]
        if result.emissions:
            outs.append(decoded(result.emissions))
    last = pipe.flush()
    if last.emissions:
        outs.append(decoded(last.emissions))
    return outs, refused


def odometry(outs, topic='odometry'):
    """Return (stamp s, x, y) of each ``topic`` output."""
    rows = [(o[topic].header.stamp.sec + o[topic].header.stamp.nanosec * 1e-9,
             o[topic].pose.pose.position.x, o[topic].pose.pose.position.y)
            for o in outs if topic in o]
    return np.array(rows)


VESSEL = Vessel(2.0, 0.2, 0.05)


def messages(t_end: float = 20.0):
    return list(VESSEL.messages(t_end, fix_hz=5.0))


def test_fixes_0_3_s_late_are_all_fused_and_the_outputs_keep_their_rate():
    on_time, _ = run(make(publish_rate=30.0), arrivals(messages()))
    pipe = make(publish_rate=30.0)
    late, refused = run(pipe, arrivals(messages(), fix_delay=0.3))
    assert refused == [] and pipe.counts['fix'] == 101 and pipe.counts['resets'] == 0
    # The same outputs, at the same stamps; the last one the same state to the bit.
    a, b = odometry(on_time), odometry(late)
    assert len(b) >= 0.95 * len(a) and len(a) == pytest.approx(30 * 20, abs=3)
    in_order = make(publish_rate=30.0)
    run(in_order, arrivals(messages()))
    np.testing.assert_array_equal(pipe.estimator.x, in_order.estimator.x)
    np.testing.assert_array_equal(pipe.estimator.P, in_order.estimator.P)
    # At the same stamps (the late run starts 0.3 s later: its first fix), the pose is within
    # what a fix's correction can move it before the fix arrives.
    common = np.intersect1d(a[:, 0], b[:, 0])
    assert len(common) >= len(a) - 12
    np.testing.assert_allclose(a[np.isin(a[:, 0], common), 1:],
                               b[np.isin(b[:, 0], common), 1:], atol=0.05)
    # odometry/local never jumps: 2 m/s at 30 Hz is 0.07 m a step.
    local = odometry(late, 'odometry/local')
    assert np.max(np.linalg.norm(np.diff(local[:, 1:], axis=0), axis=1)) < 0.1


def test_parameters_set_at_run_time_keep_the_history():
    """
    course.min_speed set ten times a second with every fix 0.3 s late: every fix fused.

    The history's copies hold the state, not the parameters, so they survive a set that does
    not change what the state is; the final state is the one of a run with no set, to the bit.
    """
    items = arrivals(messages(10.0), fix_delay=0.3)
    still = make(publish_rate=30.0)
    run(still, items)
    pipe = make(publish_rate=30.0)
    refused = []
    for k, (name, msg, arrival) in enumerate(items):
        if k % 6 == 0:                   # 60 inputs a second: a set every 0.1 s
            flat = pipe.params.to_flat()
            flat['course.min_speed'] = 0.3 + 0.01 * (k % 12 == 0)
            pipe.set_params(NavigatorParams.from_flat(flat))
        result = pipe.handle(name, msg, arrival)
        refused += [result.rejected] if result.rejected else []
    assert refused == [] and pipe.counts['fix'] == still.counts['fix'] == 51
    np.testing.assert_array_equal(pipe.estimator.x, still.estimator.x)
    np.testing.assert_array_equal(pipe.estimator.P, still.estimator.P)


def test_a_parameter_that_changes_the_state_starts_the_history_anew():
    """velocity.reference water: the state changes kind; what waits for the IMU is kept."""
    pipe = make()
    run(pipe, arrivals(messages(5.0)))
    waiting = pipe.handle('velocity', vel_msg(5.5, 2.0, 0.0), int((T0 + 5.5) * 1e9))
    assert waiting.rejected is None and pipe.timeline.waiting == 1
    flat = pipe.params.to_flat()
    flat['velocity.reference'] = 'water'
    pipe.set_params(NavigatorParams.from_flat(flat))
    assert pipe.timeline.waiting == 1 and pipe.timeline.newest_ns is None
    late = pipe.handle('fix', fix_msg(4.9, VESSEL.position(4.9)), int((T0 + 5.5) * 1e9))
    assert late.rejected == 'too_late'


def test_one_fix_1_5_s_late_is_fused_without_a_reset():
    msgs = messages()
    index = next(i for i, (n, m) in enumerate(msgs)
                 if n == 'fix' and stamp_ns(m) > (T0 + 10) * 1e9)
    pipe = make()
    _, refused = run(pipe, arrivals(msgs, delay={index: 1.5}))
    assert refused == [] and pipe.counts['resets'] == 0 and pipe.timeline.late >= 1
    in_order = make()
    run(in_order, arrivals(msgs))
    np.testing.assert_array_equal(pipe.estimator.x, in_order.estimator.x)


@pytest.mark.parametrize('name', ['fix', 'imu', 'velocity'])
def test_a_message_stamped_1e6_s_ahead_is_refused_and_moves_nothing(name):
    msgs = messages(10.0)
    index = next(i for i, (n, m) in enumerate(msgs)
                 if n == name and stamp_ns(m) > (T0 + 5) * 1e9)
    msgs[index][1].header.stamp.sec += 1_000_000
    items = arrivals(msgs)
    arrival = stamp_ns(msgs[index - 1][1])
    items = [(n, m, arrival if m is msgs[index][1] else a) for n, m, a in items]
    items.sort(key=lambda a: a[2])
    pipe = make(publish_rate=30.0)
    outs, refused = run(pipe, items)
    assert refused == [(name, 'future_stamp')] and pipe.counts['resets'] == 0
    assert pipe.estimator.t == int(round((T0 + 10.0) * 1e9))
    stamps = odometry(outs)[:, 0]
    assert stamps.max() <= T0 + 10.0 + 1e-9 and np.all(np.diff(stamps) > 0)
    assert len(stamps) == pytest.approx(300, abs=3)


def test_a_gps_time_fix_clock_is_named_in_diagnostics_taken_off_and_set_by_time_offset():
    msgs = messages(10.0)
    for name, msg in msgs:
        if name == 'fix':
            msg.header.stamp.sec += 18           # GPS time stamped as UTC
    items = [(n, m, stamp_ns(m) - (18 * 10 ** 9 if n == 'fix' else 0)) for n, m in msgs]
    pipe = make()
    run(pipe, items)
    # Refused until a full window shows the offset steady; then taken off, exactly 18 s.
    assert pipe.counts['fix/future_stamp'] == OFFSET_WINDOW - 1 and pipe.counts['resets'] == 0
    assert pipe.counts['fix'] == 51 - (OFFSET_WINDOW - 1)
    assert pipe.timing.corrections['fix'] == 18 * 10 ** 9
    status = {s.name: s for s in decoded([pipe.diagnostics(int((T0 + 10) * 1e9))])
              ['/diagnostics'].status}['navigator: fix']
    assert status.level == b'\x02', status
    expected = 'fix stamps 18.0 s ahead of the clock: GPS time instead of UTC?'
    assert status.message.startswith(expected), status.message
    assert 'set fix.time_offset' in status.message
    in_order = make()
    run(in_order, [(n, m, a) for n, m, a in items if n != 'fix'] + [
        (n, m, a) for n, m, a in arrivals(messages(10.0)) if n == 'fix'])
    np.testing.assert_allclose(pipe.estimator.x[0:2], in_order.estimator.x[0:2], atol=0.05)
    corrected = make(fix__time_offset=-18.0)
    run(corrected, items)
    assert corrected.counts['fix'] == 51 and 'fix/future_stamp' not in corrected.counts
    status = {s.name: s for s in decoded([corrected.diagnostics(int((T0 + 10) * 1e9))])
              ['/diagnostics'].status}['navigator: fix']
    assert status.level == b'\x00', status


def test_one_glitch_is_never_taken_for_a_clock_offset():
    items = arrivals(messages(10.0))
    for k, (name, msg, _) in enumerate(items):
        if name == 'fix' and k % 7 == 0:
            msg.header.stamp.sec += 10 ** 6 + k  # scattered glitches: no steady offset
    pipe = make()
    _, refused = run(pipe, items)
    assert {r for _, r in refused} == {'future_stamp'} and pipe.counts['resets'] == 0
    assert pipe.timing.corrections['fix'] == 0


def test_a_fix_clock_slightly_behind_warns_then_errors():
    for delay, level in ((1.2, b'\x01'), (2.5, b'\x02')):
        pipe = make()
        run(pipe, arrivals(messages(10.0), fix_delay=delay))
        status = {s.name: s for s in decoded([pipe.diagnostics(int((T0 + 12) * 1e9))])
                  ['/diagnostics'].status}['navigator: fix']
        assert status.level == level and f'{delay:.1f} s behind the clock' in status.message
        assert pipe.counts['resets'] == 0


def test_a_frozen_imu_clock_is_refused_as_repeated_without_resets():
    pipe = make()
    msgs = messages(5.0)
    run(pipe, arrivals(msgs))
    frozen = imu_msg(5.0, 0.0, 0.05)
    arrival = int((T0 + 5.0) * 1e9)
    for k in range(200):                       # 2 kHz whose clock froze at 5.0 s
        frozen.angular_velocity.z = 0.05 + 1e-4 * k
        result = pipe.handle('imu', frozen, arrival + k * 500_000)
    assert pipe.counts['imu/repeated_stamp'] == 200 and pipe.counts['resets'] == 0
    assert result.rejected == 'repeated_stamp'


def test_one_imu_1000_s_in_the_past_is_too_late_not_a_reset():
    pipe = make()
    run(pipe, arrivals(messages(5.0)))
    result = pipe.handle('imu', imu_msg(-995.0, 0.0, 0.05), int((T0 + 5.0) * 1e9))
    assert result.rejected == 'too_late' and pipe.counts['resets'] == 0


def test_one_early_fix_makes_nothing_else_stale():
    msgs = messages(10.0)
    index = next(i for i, (n, m) in enumerate(msgs)
                 if n == 'fix' and stamp_ns(m) > (T0 + 5) * 1e9)
    pipe = make()
    _, refused = run(pipe, arrivals(msgs, delay={index: -0.45}))   # 0.45 s before its stamp
    assert refused == [] and pipe.counts['resets'] == 0


def test_a_looped_bag_resets_once_and_the_outputs_resume():
    msgs = messages(10.0)
    pipe = make(publish_rate=30.0)
    outs, _ = run(pipe, arrivals(msgs))
    # The same stamps again from 7 s, arriving after the first pass (no /clock): 3 s back.
    again = [(n, m, stamp_ns(m) + 3 * 10 ** 9) for n, m in VESSEL.messages(10.0, fix_hz=5.0)
             if stamp_ns(m) >= (T0 + 7.0) * 1e9]
    outs2, refused = run(pipe, again)
    assert pipe.counts['resets'] == 1
    # Refused until every input has come too late JUMP_MESSAGES times (a fix: 0.6 s).
    assert {r for _, r in refused} <= {'too_late'} and len(refused) < 50
    assert len(odometry(outs2)) > 60                 # the output schedule restarted with it


def test_the_clock_going_back_resets_once():
    """/clock restarted: one reset, at most CLOCK_CONFIRM_NS of arrivals after it."""
    pipe = make()
    run(pipe, arrivals(messages(10.0)))
    results = [(stamp_ns(m), pipe.handle(n, m, stamp_ns(m))) for n, m in messages(2.0)]
    jumps = [t for t, r in results if any('time jump' in e.text for e in r.events)]
    assert pipe.counts['resets'] == 1 and len(jumps) == 1
    assert jumps[0] - int(T0 * 1e9) <= CLOCK_CONFIRM_NS       # or every input too late 3 times
    assert all(r.rejected is None for t, r in results if t > jumps[0])


def test_history_length_zero_refuses_every_late_fix():
    pipe = make(history_length=0.0)
    _, refused = run(pipe, arrivals(messages(10.0), fix_delay=0.3))
    assert refused and {r for _, r in refused} == {'too_late'}
    assert pipe.counts['resets'] == 0
    assert math.isfinite(pipe.estimator.x[0])


def test_a_glitch_ahead_of_every_other_input_is_refused_where_the_clock_says_nothing():
    """A node replaying old stamps without /clock: the clock is years ahead of every stamp."""
    items = [(n, m, a + 3 * 10 ** 18) for n, m, a in arrivals(messages(10.0))]
    index = next(i for i, (n, m, _) in enumerate(items)
                 if n == 'imu' and stamp_ns(m) > (T0 + 5) * 1e9)
    glitch = imu_msg(5.0 + 1e6, 0.0, 0.05)
    items.insert(index, ('imu', glitch, items[index][2]))
    pipe = make(publish_rate=30.0)
    outs, refused = run(pipe, items)
    assert refused == [('imu', 'future_stamp')] and pipe.counts['resets'] == 0
    assert odometry(outs)[:, 0].max() <= T0 + 10.0


@pytest.mark.parametrize('pause', [10.0, 14.0, 600.0])
@pytest.mark.parametrize('clockless', [False, True])
def test_a_pause_of_the_whole_recording(clockless, pause):
    """
    Nothing from 5 s on for ``pause`` s: refused nothing live; one message without a clock.

    A pause over 10 s had cost its first message (``future_stamp``, a fix in a yacht's log
    after each of its 14 s logger pauses).
    """
    later = [(n, m) for n, m in VESSEL.messages(5.0 + pause + 5.0, fix_hz=5.0)
             if stamp_ns(m) >= (T0 + 5.0 + pause) * 1e9]
    items = arrivals(messages(5.0)) + arrivals(later)
    if clockless:                      # arrivals one after the other, the clock years ahead
        items = [(n, m, 3 * 10 ** 18 + 10 ** 6 * i) for i, (n, m, _) in enumerate(items)]
    pipe = make()
    _, refused = run(pipe, items)
    assert refused == ([('fix', 'future_stamp')] if clockless else [])
    assert pipe.counts['resets'] == 0
