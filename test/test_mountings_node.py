"""
The IMU mounting from /tf_static in the live navigator over DDS.

A static-transform broadcaster (the test node: tf2_msgs/TFMessage on /tf_static, reliable,
transient-local, published before the navigator starts, as a URDF's robot_state_publisher
would) gives ``base_link -> imu_link`` rotated; the IMU publishes in ``imu_link``. The
navigator's odometry attitude equals the same voyage through the pipeline with the mounting
as ``imu.mounting_rpy``, and its log and /diagnostics say the source.
"""

from __future__ import annotations

import math
from typing import Any

from dds_harness import LATCHED, seconds
from geometry_msgs.msg import TransformStamped
import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from test_navigator_node import ORIGIN, Scenario, T0, Voyage
from test_pipeline import decoded, handle
from tf2_msgs.msg import TFMessage
from vessel_kinematics.ros.params import NavigatorParams
from vessel_kinematics.ros.pipeline import Pipeline

pytestmark = pytest.mark.dds

IMU_RPY = (0.2, -0.1, 1.1)       # imu_link in base_link, rad (R = Rz Ry Rx)


def _mounted(events: list[tuple[str, Any]], mounting: Rotation) -> list[tuple[str, Any]]:
    """Turn the IMU messages of a base_link voyage into those of an IMU in imu_link."""
    for topic, msg in events:
        if topic != 'imu':
            continue
        o = msg.orientation
        base = Rotation.from_quat([o.x, o.y, o.z, o.w])
        o.x, o.y, o.z, o.w = (float(c) for c in (base * mounting).as_quat())
        w = msg.angular_velocity
        w.x, w.y, w.z = (float(c) for c in mounting.inv().apply([w.x, w.y, w.z]))
        msg.header.frame_id = 'imu_link'        # isotropic covariances: unchanged
    return events


def test_imu_mounting_from_tf_static_equals_the_parameters(dds, run_navigator) -> None:
    mounting = Rotation.from_euler('ZYX', [IMU_RPY[2], IMU_RPY[1], IMU_RPY[0]])
    transform = TransformStamped()
    transform.header.frame_id, transform.child_frame_id = 'base_link', 'imu_link'
    transform.transform.translation.x, transform.transform.translation.z = 0.3, 0.5
    q = transform.transform.rotation
    q.x, q.y, q.z, q.w = (float(c) for c in mounting.as_quat())
    # Latched before the navigator exists: only a transient-local subscription receives it.
    dds.publisher('/tf_static', TFMessage, LATCHED).publish(TFMessage(transforms=[transform]))

    scenario = Scenario(dds, run_navigator)
    dds.spin_for(0.5)
    voyage = Voyage(speed=2.0, yaw_rate=0.05)
    events = _mounted(voyage.events(4.0), mounting)
    scenario.play(events)

    # The parameter case: the same messages through the pipeline, imu.mounting_rpy set.
    reference = Pipeline(NavigatorParams.from_flat(
        {'origin': list(ORIGIN), 'sensor_qos': 'reliable', 'imu.mounting_rpy': list(IMU_RPY),
         'publish_rate': 0.0}))
    expected = {}
    for topic, msg in events:
        odometry = decoded(handle(reference, topic, msg).emissions).get('odometry')
        if odometry is not None:
            expected[seconds(odometry.header.stamp)] = odometry.pose.pose.orientation
    judged = [m for m in scenario.out['odometry'] if seconds(m.header.stamp) >= T0 + 0.5]
    assert len(judged) > 100
    for msg in judged:
        o, e = msg.pose.pose.orientation, expected[seconds(msg.header.stamp)]
        np.testing.assert_allclose([o.x, o.y, o.z, o.w], [e.x, e.y, e.z, e.w], atol=1e-9)
    # ... which is the vessel's attitude (the mounting undone), not the IMU's.
    last = judged[-1]
    yaw = Rotation.from_quat([getattr(last.pose.pose.orientation, c) for c in 'xyzw'])
    t = seconds(last.header.stamp) - T0
    assert abs(math.remainder(yaw.as_euler('ZYX')[0] - (math.pi / 2 - voyage.heading(t)),
                              2 * math.pi)) < 1e-6
    assert scenario.counts()['imu mounting'] == 'tf_static imu_link'
    log = scenario.process.output()
    assert ('imu mounting from /tf_static: frame imu_link (rpy (0.2, -0.1, 1.1) rad, '
            'xyz (0.3, 0, 0.5) m)') in log, log
    assert 'gnss antenna from parameters (gnss.antenna_position [0.0, 0.0, 0.0]) ' \
           '(frame gnss not in /tf_static)' in log, log
