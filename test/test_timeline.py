"""
The state history (``estimation/timeline.py``): late measurements fused at their own stamps.

Without ROS: the estimator and its timeline fed records. What the timeline promises is checked
against the estimator fed the same records in stamp order, bit for bit: a late fix, any
permutation of arrival within ``history_length`` (hypothesis), a measurement that waits for
the IMU, one too late, and one whose stamp repeats.
"""

from __future__ import annotations

import math
import random

from hypothesis import given, settings, strategies as st
import numpy as np
from reference import ConstantTurn
from test_estimator import fix_at, imu_at, make_config, ns, T0, vel_at
from vessel_kinematics.estimation import Estimator
from vessel_kinematics.estimation.timeline import PACE_SILENT, Timeline

RANK = ('fix', 'imu', 'velocity')


def stream(t_end: float, fix_hz: float = 5.0, seed: int = 3) -> list[tuple[str, object]]:
    """Return (input, record) of a vessel turning at 2 m/s, in stamp order (the key's)."""
    truth = ConstantTurn(2.0, 0.3, 0.05)
    rng = np.random.default_rng(seed)
    events = []
    for rate, name in ((50.0, 'imu'), (10.0, 'velocity'), (fix_hz, 'fix')):
        events += [(k / rate, name) for k in range(int(t_end * rate) + 1)]
    events.sort(key=lambda e: (ns(T0 + e[0]), RANK.index(e[1])))
    out = []
    for t, name in events:
        if name == 'imu':
            out.append((name, imu_at(T0 + t, truth.psi(t), truth.r)))
        elif name == 'velocity':
            out.append((name, vel_at(T0 + t, (truth.u, truth.v, 0.0))))
        else:
            out.append((name, fix_at(T0 + t, truth.position(t) + rng.normal(0.0, 0.5, 3),
                                     sigma=0.5)))
    return out


def make(history: float = 2.0) -> tuple[Estimator, Timeline]:
    est = Estimator(make_config(velocity__reference='water'))
    updates = {'fix': est.fix, 'imu': est.imu, 'velocity': est.velocity}
    return est, Timeline(est, updates, history)


def in_order(records) -> Estimator:
    """Return the estimator fed ``records`` in the given (stamp) order, without a timeline."""
    est = Estimator(make_config(velocity__reference='water'))
    for name, m in records:
        assert getattr(est, name)(m) is None
    return est


def feed(timeline: Timeline, arrivals) -> list:
    """Hand (input, record, arrival s) to the timeline in that order; return every refusal."""
    refused = []
    for name, m, arrival in arrivals:
        refused += [o for o in timeline.apply(name, m) if o.rejection]
    return refused + [o for o in timeline.flush() if o.rejection]


def same_state(a: Estimator, b: Estimator) -> None:
    np.testing.assert_array_equal(a.x, b.x)
    np.testing.assert_array_equal(a.P, b.P)
    assert a.t == b.t and a.attitude.r9 == b.attitude.r9


def test_fixes_delivered_late_give_the_in_order_state_bit_for_bit():
    records = stream(20.0)
    arrivals = sorted(((name, m, (m.stamp_ns - ns(T0)) * 1e-9 + (0.3 if name == 'fix' else 0.0))
                       for name, m in records), key=lambda a: a[2])
    est, timeline = make()
    assert feed(timeline, arrivals) == []
    same_state(est, in_order(records))
    # Every fix came after IMU samples newer than it: each was re-applied at its stamp.
    assert timeline.late == 101 and timeline.reapplied > 101 * 15


@settings(max_examples=15, deadline=None, derandomize=True)
@given(st.integers(0, 2 ** 32 - 1))
def test_any_arrival_order_within_history_length_gives_the_same_state(seed):
    records = stream(6.0)
    rng = random.Random(seed)
    # Each message delayed by up to 1.5 s (history_length 2 s), arriving in that order.
    arrivals = sorted(((name, m, (m.stamp_ns - ns(T0)) * 1e-9 + rng.uniform(0.0, 1.5))
                       for name, m in records), key=lambda a: a[2])
    est, timeline = make()
    assert feed(timeline, arrivals) == []
    same_state(est, in_order(records))


def test_a_fix_ahead_of_the_imu_waits_for_it_and_is_then_applied_in_order():
    records = stream(2.0)
    est, timeline = make()
    fix = next(m for name, m in records if name == 'fix' and m.stamp_ns > ns(T0 + 1.0))
    early = [(n, m, (m.stamp_ns - ns(T0)) * 1e-9) for n, m in records if m is not fix]
    cut = next(i for i, (_, m, _) in enumerate(early) if m.stamp_ns > fix.stamp_ns - ns(0.3))
    # The fix comes 0.3 s before its stamp, ahead of every IMU sample so far.
    early.insert(cut, ('fix', fix, (fix.stamp_ns - ns(T0)) * 1e-9 - 0.3))
    for name, m, _ in early[:cut + 1]:
        timeline.apply(name, m)
    assert timeline.waiting >= 1 and est.last_fix_ns < fix.stamp_ns
    for name, m, _ in early[cut + 1:]:
        timeline.apply(name, m)
    assert all(o.rejection is None for o in timeline.flush())   # the last velocity
    assert timeline.waiting == 0 and timeline.late == 0      # applied in order: no re-work
    same_state(est, in_order(records))


def test_a_waiting_fix_goes_in_when_the_imu_stops():
    records = [(n, m) for n, m in stream(1.0) if m.stamp_ns <= ns(T0 + 0.5)]
    est, timeline = make()
    for name, m in records:
        timeline.apply(name, m)
    late_fix = fix_at(T0 + 0.7, (1.4, 0.0, 0.0))
    assert timeline.apply('fix', late_fix) == []            # waits for the IMU
    # No IMU sample stamped within PACE_SILENT of the newest: the IMU is silent.
    out = timeline.apply('velocity', vel_at(T0 + 0.5 + PACE_SILENT + 0.01, (2.0, 0.0, 0.0)))
    assert [o.name for o in out][-2:] == ['fix', 'velocity'] and timeline.waiting == 0
    assert est.last_fix_ns == late_fix.stamp_ns


def test_two_waiting_fixes_with_one_stamp_leave_in_arrival_order():
    """
    A receiver sending its fix twice with one stamp, ahead of the IMU: both wait.

    The first is applied when the IMU reaches its stamp, the second is refused as
    ``repeated_stamp``, whatever their values (the waiting list never compares two
    measurements: a canboat capture of a Furuno receiver did this and stopped the replay).
    """
    records = [(n, m) for n, m in stream(1.0) if m.stamp_ns <= ns(T0 + 0.5)]
    est, timeline = make()
    for name, m in records:
        timeline.apply(name, m)
    first, second = fix_at(T0 + 0.6, (1.2, 0.0, 0.0)), fix_at(T0 + 0.6, (1.3, 0.1, 0.0))
    assert timeline.apply('fix', first) == [] and timeline.apply('fix', second) == []
    assert timeline.waiting_by_input() == {'fix': 2}
    out = timeline.apply('imu', imu_at(T0 + 0.62, 0.0, 0.0))
    got = [(o.name, o.measurement, o.rejection and o.rejection.reason) for o in out]
    assert got[:2] == [('fix', first, None), ('fix', second, 'repeated_stamp')]
    assert [(name, reason) for name, _, reason in got[2:]] == [('imu', None)]
    assert est.last_fix_ns == first.stamp_ns and timeline.waiting == 0


def test_too_late_and_repeated_stamps_are_refused_and_change_nothing():
    records = stream(5.0)
    est, timeline = make(history=1.0)
    for name, m in records:
        assert all(o.rejection is None for o in timeline.apply(name, m))
    timeline.flush()
    x, p, t = est.x.copy(), est.P.copy(), est.t
    old_fix = fix_at(T0 + 3.5, (0.0, 0.0, 0.0))                 # 1.5 s behind the newest
    (out,) = timeline.apply('fix', old_fix)
    assert out.rejection.reason == 'too_late' and 'history_length 1 s' in out.rejection.detail
    imu_again = next(m for name, m in reversed(records) if name == 'imu'
                     and m.stamp_ns < ns(T0 + 4.9))
    (out,) = timeline.apply('imu', imu_again)                 # a sensor whose clock froze
    assert out.rejection.reason == 'repeated_stamp'
    np.testing.assert_array_equal(est.x, x)
    np.testing.assert_array_equal(est.P, p)
    assert est.t == t and est.resets == 0 and timeline.late == 0


def test_the_history_is_bounded_by_history_length():
    est, timeline = make(history=1.0)
    for name, m in stream(30.0):
        timeline.apply(name, m)
    span = (timeline._keys[-1][0] - timeline._keys[0][0]) * 1e-9
    assert span <= 1.0 + 0.1 + 1e-9 and len(timeline._snapshots) <= 12
    assert math.isclose(timeline.newest_ns * 1e-9, T0 + 30.0)
