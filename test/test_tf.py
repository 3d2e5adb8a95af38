"""
TF from the live navigator over DDS: /tf and /tf_static as tf2_msgs/TFMessage.

A real rclpy subscriber (tf2_msgs built from source by ``make build``) listens to what the
installed node publishes with tf2's QoS (/tf reliable volatile, /tf_static transient-local),
and checks the tree earth -> map -> odom -> base_link, map -> map_ned,
base_link -> base_link_frd, the stamps against the odometry's, one transform per child frame
and stamp (two inputs with one stamp), and ``tf.publish`` subsets.
"""

from __future__ import annotations

from collections import Counter
import math
from typing import Any

from dds_harness import LATCHED, make_imu, seconds
import pytest
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from test_navigator_node import Scenario, T0, Voyage
from tf2_msgs.msg import TFMessage

pytestmark = pytest.mark.dds

#: What tf2's TransformListener subscribes to /tf with.
TF_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=100,
                    reliability=ReliabilityPolicy.RELIABLE,
                    durability=DurabilityPolicy.VOLATILE)


def _with_shared_stamps(voyage: Voyage, events: list[tuple[str, Any]]) -> list[tuple[str, Any]]:
    """Add after every fix an IMU message with the fix's stamp: two poses with one stamp."""
    out = []
    for topic, msg in events:
        out.append((topic, msg))
        if topic == 'fix':
            t = seconds(msg.header.stamp)
            out.append(('imu', make_imu(t, voyage.quaternion_enu_flu(t - T0),
                                        (0.0, 0.0, -voyage.yaw_rate))))
    return out


def _run(dds: Any, run_navigator: Any, **params: Any) -> tuple[Scenario, list[Any], list[Any]]:
    scenario = Scenario(dds, run_navigator, **params)
    tf = dds.collect('/tf', TFMessage, TF_QOS)
    voyage = Voyage(speed=2.0, yaw_rate=0.05)
    scenario.play(_with_shared_stamps(voyage, voyage.events(3.0)))
    dds.spin_for(0.5)
    static = dds.collect('/tf_static', TFMessage, LATCHED)   # a late joiner: latched
    assert dds.spin_until(lambda: bool(static), 5.0), 'no latched /tf_static'
    return scenario, tf, static


def test_tree_stamps_and_one_transform_per_stamp(dds, run_navigator) -> None:
    scenario, tf, static = _run(dds, run_navigator)
    # /tf_static: one message with every static transform (tf2's StaticTransformBroadcaster).
    statics = {(t.header.frame_id, t.child_frame_id): t for t in static[-1].transforms}
    assert set(statics) == {('earth', 'map'), ('map', 'map_ned'), ('base_link', 'base_link_frd')}
    earth_map = statics[('earth', 'map')].transform.translation
    # The origin at 63.44 N lies ~6.4e6 m from the earth's centre (ECEF).
    assert 6.3e6 < math.sqrt(earth_map.x ** 2 + earth_map.y ** 2 + earth_map.z ** 2) < 6.4e6
    q = statics[('map', 'map_ned')].transform.rotation
    assert (q.x, q.y, q.z, q.w) == pytest.approx((math.sqrt(0.5), math.sqrt(0.5), 0.0, 0.0))
    q = statics[('base_link', 'base_link_frd')].transform.rotation
    assert (q.x, q.y, q.z, q.w) == pytest.approx((1.0, 0.0, 0.0, 0.0))
    # /tf: map -> odom and odom -> base_link only, never twice for one child and stamp.
    transforms = [t for msg in tf for t in msg.transforms]
    pairs = Counter((t.header.frame_id, t.child_frame_id) for t in transforms)
    assert set(pairs) == {('map', 'odom'), ('odom', 'base_link')}
    per_stamp = Counter((t.child_frame_id, t.header.stamp.sec, t.header.stamp.nanosec)
                        for t in transforms)
    assert max(per_stamp.values()) == 1
    # The outputs follow the IMU (docs/timing.md): at a stamp a fix shares with an IMU sample
    # the odometry goes out once, with both fused; TF once, at the same stamps.
    odometry = scenario.out['odometry/local']
    odometry_stamps = Counter((m.header.stamp.sec, m.header.stamp.nanosec) for m in odometry)
    assert max(odometry_stamps.values()) == 1
    base = {(t.header.stamp.sec, t.header.stamp.nanosec): t for t in transforms
            if t.child_frame_id == 'base_link'}
    assert set(base) == set(odometry_stamps)
    # odom -> base_link is the local pose (the last odometry of each stamp).
    by_stamp = {(m.header.stamp.sec, m.header.stamp.nanosec): m for m in odometry}
    stamp = max(by_stamp)
    p, tr = by_stamp[stamp].pose.pose.position, base[stamp].transform.translation
    assert (tr.x, tr.y, tr.z) == pytest.approx((p.x, p.y, p.z), abs=1e-9)


def test_tf_publish_subset_leaves_odom_base_to_another_node(dds, run_navigator) -> None:
    # A driver owns odom -> base_link: the navigator publishes earth -> map and map -> odom.
    scenario, tf, static = _run(dds, run_navigator, **{'tf.publish': ['earth_map', 'map_odom']})
    children = {t.child_frame_id for msg in tf for t in msg.transforms}
    assert children == {'odom'}
    assert [(t.header.frame_id, t.child_frame_id) for t in static[-1].transforms] == [
        ('earth', 'map')]
    assert scenario.process.alive()
