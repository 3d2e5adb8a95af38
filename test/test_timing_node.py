"""
Real sensor timing over DDS: the installed navigator under ``use_sim_time`` and a ``/clock``.

Each input is published when the clock reaches its stamp plus its delivery latency, as a
vessel's drivers deliver them: fixes 0.3 s late (one of them 1.5 s), one message per input
stamped 1e6 s ahead, and a GNSS clock in GPS time (18 s ahead). Every late fix is fused,
nothing resets, the outputs keep their rate, and the pose stays on the truth.
"""

from __future__ import annotations

import copy
import math
from typing import Any

from dds_harness import diagnostic_values, seconds
from diagnostic_msgs.msg import DiagnosticArray
from nav_msgs.msg import Odometry
import pytest
from rosgraph_msgs.msg import Clock
from test_navigator_node import ORIGIN, Scenario, T0, Voyage
from vessel_kinematics.ros.timing import OFFSET_WINDOW

pytestmark = pytest.mark.dds

VOYAGE = Voyage(speed=2.0)
DURATION = 8.0


def play(dds: Any, events: list[tuple[float, str, Any]], end: float) -> None:
    """Publish /clock in 10 ms steps and each (arrival s, topic, msg) once the clock reaches it."""
    clock = dds.publisher('/clock', Clock)
    events = sorted(events, key=lambda e: e[0])
    index = 0
    for step in range(int(end * 100) + 1):
        t = T0 + step * 0.01
        msg = Clock()
        msg.clock.sec, msg.clock.nanosec = int(t), round(t % 1 * 1e9) % 10 ** 9
        clock.publish(msg)
        while index < len(events) and events[index][0] <= t + 1e-9:
            dds.publish(events[index][1], events[index][2])
            index += 1
        dds.spin_for(0.004)
    dds.spin_for(0.5)


def timed(delays: dict[int, float] | None = None, fix_delay: float = 0.3,
          fix_shift: float = 0.0) -> list[tuple[float, str, Any]]:
    """Return the voyage's inputs with their arrival times (s), fixes ``fix_delay`` late."""
    out = []
    fixes = 0
    for topic, msg in VOYAGE.events(DURATION, imu_hz=50.0, fix_hz=5.0):
        t = seconds(msg.header.stamp)
        late = 0.0
        if topic == 'fix':
            late = (delays or {}).get(fixes, fix_delay)
            fixes += 1
            if fix_shift:
                msg.header.stamp.sec += int(fix_shift)
        out.append((t + late, topic, msg))
    return out


def rate(odometry: list[Odometry], start: float, end: float) -> float:
    stamps = [seconds(m.header.stamp) for m in odometry]
    return sum(T0 + start <= s < T0 + end for s in stamps) / (end - start)


def error(msg: Odometry) -> float:
    n, e, _ = VOYAGE.ned(seconds(msg.header.stamp) - T0)
    p = msg.pose.pose.position
    return math.hypot(p.x - e, p.y - n)


def test_late_fixes_and_stamps_1e6_s_ahead(dds, run_navigator) -> None:
    scenario = Scenario(dds, run_navigator, use_sim_time=True, publish_rate=20.0)
    events = timed(delays={20: 1.5})
    # One message of each input stamped 1e6 s ahead, at 4 s.
    for topic in ('imu', 'velocity', 'fix'):
        arrival, _, msg = next(e for e in events if e[1] == topic and e[0] >= T0 + 4.0)
        glitch = copy.deepcopy(msg)
        glitch.header.stamp.sec += 1_000_000
        events.append((arrival + 0.001, topic, glitch))
    diagnostics = scenario.diagnostics
    play(dds, events, DURATION + 2.0)
    assert scenario.process.alive(), scenario.process.output()
    values = scenario.counts()
    fixes = sum(1 for e in events if e[1] == 'fix')
    assert values['accepted fix'] == str(fixes - 1), values          # all but the glitch
    assert values['resets'] == '0', values
    for topic in ('fix', 'imu', 'velocity'):
        assert values[f'rejected {topic}/future_stamp'] == '1', values
    assert not any(k.startswith('rejected fix/') and k != 'rejected fix/future_stamp'
                   for k in values), values
    odometry = scenario.out['odometry']
    stamps = [seconds(m.header.stamp) for m in odometry]
    assert max(stamps) <= T0 + DURATION and stamps == sorted(stamps)
    before, after = rate(odometry, 1.0, 4.0), rate(odometry, 4.0, DURATION - 0.5)
    assert after >= 0.8 * before and before > 15.0, (before, after)
    assert max(error(m) for m in odometry if seconds(m.header.stamp) > T0 + 1.0) < 1.5
    assert isinstance(diagnostics[-1], DiagnosticArray)


def test_a_fix_clock_18_s_ahead_is_named_and_taken_off(dds, run_navigator) -> None:
    scenario = Scenario(dds, run_navigator, use_sim_time=True, publish_rate=20.0,
                        origin=list(ORIGIN))
    play(dds, timed(fix_delay=0.1, fix_shift=18.0), DURATION + 2.0)
    assert scenario.process.alive(), scenario.process.output()
    values = scenario.counts()
    # Refused until a window of fixes shows the offset steady, then 18 s is taken off.
    assert values['resets'] == '0', values
    assert values['rejected fix/future_stamp'] == str(OFFSET_WINDOW - 1), values
    assert int(values['accepted fix']) >= 10, values
    status = {s.name: s for s in scenario.diagnostics[-1].status}['navigator: fix']
    assert status.level == b'\x02', status
    assert 'fix stamps 17.9 s ahead of the clock: GPS time instead of UTC?' in status.message
    odometry = scenario.out['odometry']
    assert odometry and max(error(m) for m in odometry) < 1.5
    assert diagnostic_values(scenario.diagnostics[-1])['resets'] == '0'
