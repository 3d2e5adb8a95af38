"""
Nothing a peer sends stops the node: the attacks of issue 25's first item, over real DDS.

Each test starts the installed navigator, sends what a hostile or buggy peer on a vessel's graph
would (a ``/clock`` rclpy cannot take, a ``use_sim_time`` switched on from outside, a velocity
source switched while messages of the old type are queued, a storm of parameter sets of every
type, rejections and errors from one place in turn), and asserts that the node is alive, still
publishing, and counted what it refused.
The logger's double-severity trap is also shown with rclpy's own logger, in process.
"""

from __future__ import annotations

import math
import random
import struct
import time
from typing import Any

from dds_harness import diagnostic_values, LATCHED, make_twist, RELIABLE, seconds
from geometry_msgs.msg import TransformStamped
from nav_msgs.msg import Odometry
import pytest
from rcl_interfaces.srv import ListParameters
import rclpy
from rclpy.logging import get_logger
from rosgraph_msgs.msg import Clock
from test_navigator_node import Scenario, T0, Voyage
from tf2_msgs.msg import TFMessage
from vessel_kinematics.ros.node.log import NodeLog
from vessel_kinematics.ros.node.subscriptions import INPUT_SILENCE


def _clock(seconds: float, sec: int | None = None, nanosec: int | None = None) -> Clock:
    msg = Clock()
    msg.clock.sec = int(seconds) if sec is None else sec
    msg.clock.nanosec = round(seconds % 1 * 1e9) % 10 ** 9 if nanosec is None else nanosec
    return msg


def _started(dds: Any, run_navigator: Any) -> tuple[Voyage, Scenario]:
    """Start the navigator and play the first second of a voyage at 2 m/s."""
    voyage = Voyage(speed=2.0)
    scenario = Scenario(dds, run_navigator)
    scenario.play(voyage.events(1.0))
    return voyage, scenario


def _on_sim_time(dds: Any, run_navigator: Any) -> tuple[Voyage, Scenario, Any]:
    """Start the navigator on /clock and play a second of a voyage; return its /clock publisher."""
    voyage = Voyage(speed=2.0)
    scenario = Scenario(dds, run_navigator, use_sim_time=True)
    clock = dds.publisher('/clock', Clock)
    assert dds.spin_until(lambda: clock.get_subscription_count() > 0, 10.0)
    # The clock leads the inputs (none is stamped ahead of it: future_tolerance).
    clock.publish(_clock(T0 + 1.0))
    dds.spin_for(0.1)
    scenario.play(voyage.events(1.0))
    return voyage, scenario, clock


def _publishing(scenario: Scenario, voyage: Voyage, start: float) -> None:
    """Play one more second of the voyage and check its odometry comes out."""
    cut = len(scenario.out['odometry'])
    scenario.play(voyage.events(1.0, start=start))
    assert len(scenario.out['odometry']) > cut, 'the node stopped publishing'
    assert scenario.process.alive(), scenario.process.output()


@pytest.mark.dds
@pytest.mark.parametrize('executor', ['events', 'single'])
def test_a_negative_clock_is_counted_and_ignored(dds, run_navigator, navigator_env,
                                                 monkeypatch, executor) -> None:
    monkeypatch.setitem(navigator_env, 'VK_NAVIGATOR_EXECUTOR', executor)
    voyage, scenario, clock = _on_sim_time(dds, run_navigator)
    for _ in range(5):
        clock.publish(_clock(0.0, sec=-5))               # rclpy's TimeSource refuses it
        dds.spin_for(0.05)
    clock.publish(_clock(T0 + 2.0))
    dds.spin_for(0.1)
    _publishing(scenario, voyage, 1.0)
    values = scenario.counts()
    assert int(values.get('rejected clock/bad_stamp', '0')) >= 1, values
    assert values['internal_errors'] == '0', values
    assert 'Traceback' not in scenario.process.output()


@pytest.mark.dds
def test_one_clock_message_far_off_never_resets(dds, run_navigator) -> None:
    """
    /clock once 1e9 s ahead, once 900 s behind, once with nanosec 4e9, inputs arriving meanwhile.

    The node's clock shows each until the next good /clock, and the inputs that arrive in
    between arrive then (900 s behind, they are ahead of it: refused as ``future_stamp``). No
    reset, so ``odometry/local`` never jumps; the nanoseconds are counted as a bad clock.
    """
    voyage, scenario, clock = _on_sim_time(dds, run_navigator)
    start = 1.0
    for bad in (_clock(T0 + 1e9), _clock(T0 - 900.0), _clock(T0 + start, nanosec=4 * 10 ** 9)):
        clock.publish(bad)
        dds.spin_for(0.1)
        dds.play(voyage.events(0.2, start=start), pace=0.005)     # arriving at the bad clock
        start += 0.2
        clock.publish(_clock(T0 + start + 1.0))
        dds.spin_for(0.1)
        scenario.play(voyage.events(0.5, start=start))
        start += 0.5
    values = scenario.counts()
    assert values['resets'] == '0', values
    assert int(values.get('rejected clock/bad_stamp', '0')) == 1, values
    local = [m.pose.pose.position for m in scenario.out['odometry/local']]
    steps = [math.hypot(b.x - a.x, b.y - a.y) for a, b in zip(local, local[1:])]
    assert max(steps) < 0.5, max(steps)                  # 2 m/s: 0.4 m over 0.2 s refused
    assert values['internal_errors'] == '0', values


@pytest.mark.dds
def test_an_input_topic_the_node_could_not_subscribe_to_is_refused(dds, run_navigator) -> None:
    """imu.topics or fix.topics set to a name rcl refuses, or to one of the node's outputs."""
    voyage, scenario = _started(dds, run_navigator)
    for name, value, reason in (('imu.topics', ['~abc'], 'topic names'),
                                ('fix.topics', ['a' * 300], 'length'),
                                ('imu.topics', ['odometry'], "node's nav_msgs/msg/Odometry")):
        (result,) = dds.set_parameters('/navigator', {name: value})
        assert not result.successful and reason in result.reason, (name, result.reason)
    assert dds.get_parameters('/navigator', ['imu.topics'])['imu.topics'] == ['imu']
    _publishing(scenario, voyage, 1.0)
    values = scenario.counts()
    assert int(values['accepted imu']) > 50 and int(values['accepted fix']) > 2, values
    assert values['internal_errors'] == '0', values


@pytest.mark.dds
def test_bytes_that_are_no_tf_message_on_tf_static_are_counted(dds, run_navigator) -> None:
    """Garbage on /tf_static: ``cdr_error`` once a message, no traceback, no absurd count."""
    voyage, scenario = _started(dds, run_navigator)
    tf_static = dds.publisher('/tf_static', TFMessage, LATCHED)
    assert dds.spin_until(lambda: tf_static.get_subscription_count() > 0, 10.0)
    header = b'\x00\x01\x00\x00'
    for payload in (header + struct.pack('<I', 200) + bytes(range(64)),   # 200 in 64 bytes
                    header + struct.pack('<I', 0xFFFFFFFF),               # 4e9 in 8 bytes
                    header + bytes(range(256)) * 8):                      # a count of 50462976
        tf_static.publish(payload)
        dds.spin_for(0.2)
    _publishing(scenario, voyage, 1.0)
    values = scenario.counts()
    assert values.get('rejected tf_static/cdr_error') == '3', values
    assert 'rejected tf_static/too_large' not in values, values
    assert values['internal_errors'] == '0', values
    assert 'Traceback' not in scenario.process.output()


#: What a hostile or buggy peer sets a parameter to: every type, and no sense.
STORM_VALUES: tuple[Any, ...] = (
    True, 0, -1, 2 ** 63 - 1, -0.0, 1e308, math.nan, math.inf, -math.inf, '', 'x' * 10000,
    'none', 'water', [1.0, 2.0, 3.0], [math.nan] * 3, [1, 2, 3], ['a', 'b'], [True, False])


@pytest.mark.dds
def test_a_storm_of_parameter_sets_never_stops_the_node(dds, run_navigator) -> None:
    """
    Every parameter set to values of every type and no sense, alone and in batches, as inputs flow.

    Each set is answered (a refusal with its reason); the node stays alive with no internal
    error and no traceback; once the values it started with are set back, it is on the voyage
    again. A fixed seed: the same storm in every run.
    """
    voyage, scenario = _started(dds, run_navigator)
    names = sorted(dds._call(ListParameters, '/navigator/list_parameters',
                             ListParameters.Request(), 10.0).result.names)
    assert len(names) > 40, names
    before = dds.get_parameters('/navigator', names)
    rng = random.Random(25)
    start, accepted = 1.0, 0
    for _ in range(150):
        count = rng.choice((1, 1, 2, 8))
        batch = {name: rng.choice(STORM_VALUES) for name in rng.sample(names, count)}
        results = dds.set_parameters('/navigator', batch)
        assert len(results) == len(batch), batch
        assert all(r.successful or r.reason for r in results), (batch, results)
        accepted += sum(r.successful for r in results)
        dds.play(voyage.events(0.05, start=start), pace=0.001)
        start += 0.05
        assert scenario.process.alive(), scenario.process.output()
    assert accepted > 0                  # some of it got through the checks, and changed things
    results = dds.set_parameters('/navigator', before)
    assert all(r.successful or 'read-only' in r.reason for r in results), results
    assert repr(dds.get_parameters('/navigator', names)) == repr(before)   # NaN equal to NaN
    scenario.play(voyage.events(3.0, start=start))
    last = scenario.out['odometry'][-1]
    n, e, _ = voyage.ned(seconds(last.header.stamp) - T0)
    p = last.pose.pose.position
    assert math.hypot(p.x - e, p.y - n) < 1.0, (p, (e, n))
    assert scenario.counts()['internal_errors'] == '0'
    assert 'Traceback' not in scenario.process.output()


@pytest.mark.dds
def test_a_reader_wedged_by_an_empty_payload_is_subscribed_anew(dds, run_navigator) -> None:
    """
    One empty payload on ``fix`` from a reliable peer, then its fixes as before.

    The node's DDS reader for that peer wedges: nothing of it arrives again (another process's
    reader takes the later fixes, and so does a new reader of the node's). The node subscribes
    anew to an input silent for INPUT_SILENCE s while a publisher is matched, says so, counts
    it, and fuses that peer's fixes again.
    """
    voyage, scenario = _started(dds, run_navigator)
    before = scenario.counts()
    dds.publish('fix', b'')
    start, began = 1.0, time.monotonic()
    while time.monotonic() - began < INPUT_SILENCE + 3.0:
        scenario.play(voyage.events(0.5, start=start))
        dds.spin_for(0.2)
        start += 0.5
    after = scenario.counts()
    assert int(after.get('resubscribed fix', '0')) >= 1, after
    assert int(after['accepted fix']) > int(before['accepted fix']), (before, after)
    assert after['internal_errors'] == '0', after
    assert 'fix: nothing for 5 s while a publisher is matched' in scenario.process.output()


@pytest.mark.dds
def test_use_sim_time_is_read_only_at_run_time(dds, run_navigator) -> None:
    voyage, scenario = _started(dds, run_navigator)
    (result,) = dds.set_parameters('/navigator', {'use_sim_time': True})
    assert not result.successful and 'read-only' in result.reason, result.reason
    for name, value in (('motion', 'free'), ('base_frame', 'hull')):
        (result,) = dds.set_parameters('/navigator', {name: value})
        assert not result.successful and 'read-only' in result.reason, (name, result.reason)
    assert dds.get_parameters('/navigator', ['use_sim_time'])['use_sim_time'] is False
    _publishing(scenario, voyage, 1.0)
    # Diagnostics still come, on the steady clock, with wall-clock ages.
    assert scenario.counts()['mode'] in ('fused', 'dead_reckoning')


@pytest.mark.dds
def test_a_source_switch_with_the_old_type_queued_and_warnings_then_errors(
        dds, run_navigator) -> None:
    """
    velocity.source:=odometry while TwistWithCovarianceStamped messages keep coming.

    The old type still queued (or still sent by a peer) is refused as unused input, warned
    about at the same place that earlier warned about a rejected message: neither the log nor
    the callback may raise.
    """
    voyage, scenario = _started(dds, run_navigator)
    bad = make_twist(T0 + 1.0005, (math.nan, 0.0, 0.0))           # a rejection: a warning
    dds.publish('velocity', bad)
    dds.spin_for(0.2)
    for k in range(20):                                           # queued as the switch comes
        dds.publish('velocity', make_twist(T0 + 1.001 + 0.001 * k, (2.0, 0.0, 0.0)))
    results = dds.set_parameters('/navigator', {'velocity.source': 'odometry'})
    assert all(r.successful for r in results), [r.reason for r in results]
    for k in range(20):
        dds.publish('velocity', make_twist(T0 + 1.03 + 0.001 * k, (2.0, 0.0, 0.0)))
        dds.spin_for(0.01)
    # The IMU and the fixes go on: the node still publishes.
    events = [(topic, msg) for topic, msg in voyage.events(1.0, start=1.1)
              if topic != 'velocity']
    cut = len(scenario.out['odometry'])
    dds.play(events, sync=scenario.out['odometry'])
    assert len(scenario.out['odometry']) > cut
    assert scenario.process.alive(), scenario.process.output()
    values = scenario.counts()
    assert values['internal_errors'] == '0', values
    assert int(values.get('rejected velocity/nan_field', '0')) == 1, values
    assert 'Traceback' not in scenario.process.output()
    # An Odometry on velocity is taken now (the tester changes its publisher's type too: one
    # participant holds one type per topic).
    dds.node.destroy_publisher(dds._publishers.pop('velocity'))
    dds.publisher('velocity', Odometry, RELIABLE)
    odometry = Odometry()
    odometry.header = events[-1][1].header
    odometry.child_frame_id = 'base_link'
    odometry.twist.twist.linear.x = 2.0
    odometry.twist.covariance[0] = odometry.twist.covariance[7] = 0.01

    def taken(values: dict[str, str]) -> int:
        # Stamped after the last IMU sample, it waits for the next one (docs/timing.md).
        return int(values['accepted velocity']) + int(values.get('waiting velocity', '0'))

    before = taken(values)
    deadline = time.monotonic() + 15.0
    while taken(values) == before and time.monotonic() < deadline:
        odometry.header.stamp.nanosec = (odometry.header.stamp.nanosec + 1000) % 10 ** 9
        dds.publish('velocity', odometry)
        values = diagnostic_values(scenario.diagnostics[-1]) if scenario.diagnostics else values
        dds.spin_for(0.3)
    assert taken(values) > before, values


def test_the_nodes_log_takes_any_severity_from_one_place() -> None:
    """One call site of rclpy's logger refuses a second severity; NodeLog's does not."""
    rclpy.init()
    try:
        logger = get_logger('vk_test_log')

        def one_site(error: bool) -> None:
            (logger.error if error else logger.warning)('a line')

        one_site(False)
        with pytest.raises(ValueError):
            one_site(True)                       # what killed the node's except clause
        log = NodeLog(get_logger('vk_test_log_2'), period=0.0)
        for error in (False, True, False, True):
            log.throttled('one/key', 'a line', error=error)
        assert log.failures == 0
    finally:
        rclpy.try_shutdown()


def _tf_static(n: int, xyz: tuple[float, float, float] = (0.1, 0.0, 0.0), prefix: str = 'f',
               parent: str = 'base_link') -> TFMessage:
    transforms = []
    for i in range(n):
        t = TransformStamped()
        t.header.frame_id, t.child_frame_id = parent, f'{prefix}{i}' if n > 1 else prefix
        t.transform.translation.x, t.transform.translation.y, t.transform.translation.z = xyz
        t.transform.rotation.w = 1.0
        transforms.append(t)
    return TFMessage(transforms=transforms)


def _rss_kb(pid: int) -> int:
    for line in open(f'/proc/{pid}/status').read().splitlines():
        if line.startswith('VmRSS:'):
            return int(line.split()[1])
    return 0


def _sailing(dds, run_navigator) -> tuple[Scenario, Voyage, int, Any]:
    """Start the node, play a second, return it with its RSS (kB) and a /tf_static publisher."""
    voyage, scenario = _started(dds, run_navigator)
    return (scenario, voyage, _rss_kb(scenario.process.pid),
            dds.publisher('/tf_static', TFMessage, LATCHED))


@pytest.mark.dds
def test_tf_static_a_huge_message_and_a_1e9_m_lever_arm(dds, run_navigator) -> None:
    """50,000 frames in one message, then the antenna 1e9 m off: refused, the node unmoved."""
    scenario, voyage, rss, static = _sailing(dds, run_navigator)
    static.publish(_tf_static(50_000))
    # Latched depth 1: the next message would replace this one before it is delivered.
    assert dds.spin_until(lambda: scenario.diagnostics and int(scenario.counts().get(
        'rejected tf_static/too_large', '0')) == 50_000, 20.0), scenario.counts()
    static.publish(_tf_static(1, xyz=(1e9, 0.0, 0.0), prefix='gnss'))
    for k in range(3):
        _publishing(scenario, voyage, 1.0 + k)
    values = scenario.counts()
    assert int(values.get('rejected tf_static/too_large', '0')) == 50_000, values
    assert int(values.get('rejected tf_static/implausible_mounting', '0')) >= 1, values
    assert values['internal_errors'] == '0', values
    assert values['mode'] == 'fused', values
    assert values['gnss antenna'] == 'parameters', values
    last = scenario.out['odometry'][-1].pose.pose.position
    assert math.hypot(last.x, last.y) < 100.0, last
    assert _rss_kb(scenario.process.pid) - rss < 30_000
    log = scenario.process.output()
    assert log.count('/tf_static message refused: ') == 1, log
    assert 'Traceback' not in log


@pytest.mark.dds
def test_tf_static_many_messages_of_new_frames_stay_bounded(dds, run_navigator) -> None:
    """200 messages of new frames: the tree stops at its limit, with one line; memory bounded."""
    scenario, voyage, rss, static = _sailing(dds, run_navigator)
    for k in range(200):
        static.publish(_tf_static(1000 if k % 2 else 100, prefix=f'm{k}_'))
        dds.spin_for(0.02)
    _publishing(scenario, voyage, 1.0)
    _publishing(scenario, voyage, 2.0)
    values = scenario.counts()
    # Latched depth 1: a message may replace the last before it was delivered; most come.
    assert int(values['rejected tf_static/too_large']) >= 50 * 1000, values
    assert values['internal_errors'] == '0', values
    assert _rss_kb(scenario.process.pid) - rss < 30_000
    log = scenario.process.output()
    assert log.count('its limit; new frames are refused') == 1, log
