"""
The marine drivers' input forms at the edge, checked against scipy's rotations and by hand.

A heading as QuaternionStamped, a receiver's ENU velocity, and the failover between headings.
"""

from __future__ import annotations

import math

from dds_harness import stamp
from geometry_msgs.msg import QuaternionStamped, TwistStamped, TwistWithCovarianceStamped
import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from vessel_kinematics.estimation import GroundVelocity, ImuSample, Reason, Rejection
from vessel_kinematics.estimation.config import UNMEASURED_VARIANCE
from vessel_kinematics.ros.failover import HeadingFailover
from vessel_kinematics.ros.inputs import ground_velocity_from_msg, heading_from_msg
from vessel_kinematics.ros.params import NavigatorParams
from vessel_kinematics.ros.pipeline import Pipeline

PARAMS = NavigatorParams.from_flat({'imu.source': 'quaternion', 'gnss_velocity.source': 'twist'})


def _heading(yaw_enu: float, t: float = 10.0) -> QuaternionStamped:
    msg = QuaternionStamped()
    msg.header.stamp = stamp(t)
    x, y, z, w = Rotation.from_euler('z', yaw_enu).as_quat()
    msg.quaternion.x, msg.quaternion.y, msg.quaternion.z, msg.quaternion.w = x, y, z, w
    return msg


@pytest.mark.parametrize('yaw_enu_deg', [0.0, 37.0, 90.0, -120.0, 179.0])
def test_heading_is_fossens_psi_and_has_no_rate(yaw_enu_deg: float) -> None:
    sample = heading_from_msg(_heading(math.radians(yaw_enu_deg)), PARAMS)
    assert isinstance(sample, ImuSample) and sample.omega_b is None and sample.att_cov is None
    w, x, y, z = sample.q_nb
    psi = Rotation.from_quat([x, y, z, w]).as_euler('ZYX')[0]
    assert math.remainder(psi - (math.pi / 2 - math.radians(yaw_enu_deg)), 2 * math.pi) == \
        pytest.approx(0.0, abs=1e-12)


def test_heading_refusals() -> None:
    bad = _heading(0.0)
    bad.quaternion.w = math.nan
    assert heading_from_msg(bad, PARAMS).reason is Reason.NAN_FIELD
    zero = _heading(0.0)
    zero.quaternion.w = zero.quaternion.z = 0.0
    assert heading_from_msg(zero, PARAMS).reason is Reason.ZERO_QUATERNION


def test_receiver_velocity_enu_becomes_ned() -> None:
    msg = TwistStamped()
    msg.header.stamp = stamp(3.0)
    msg.twist.linear.x, msg.twist.linear.y = 1.5, -2.0       # east, north
    v = ground_velocity_from_msg(msg, PARAMS)
    assert isinstance(v, GroundVelocity)
    np.testing.assert_array_equal(v.v_ned[0:2], [-2.0, 1.5])
    # TwistStamped has no covariance: the default sigma horizontally, the vertical unmeasured.
    np.testing.assert_allclose(np.diag(v.cov), [0.04, 0.04, UNMEASURED_VARIANCE], rtol=1e-12)
    with_cov = TwistWithCovarianceStamped()
    with_cov.header.stamp = stamp(3.0)
    with_cov.twist.twist.linear.x, with_cov.twist.twist.linear.z = 1.0, 0.5
    covariance = [0.0] * 36
    covariance[0], covariance[7], covariance[14], covariance[1], covariance[6] = \
        0.01, 0.04, 0.09, 0.005, 0.005
    with_cov.twist.covariance = covariance
    v = ground_velocity_from_msg(with_cov, PARAMS)
    np.testing.assert_array_equal(v.v_ned, [0.0, 1.0, -0.5])
    np.testing.assert_allclose(v.cov, [[0.04, 0.005, 0.0], [0.005, 0.01, 0.0],
                                       [0.0, 0.0, 0.09]])
    msg.twist.linear.x = 150.0
    assert ground_velocity_from_msg(msg, PARAMS).reason is Reason.IMPLAUSIBLE_SPEED
    msg.twist.linear.x = math.inf
    assert ground_velocity_from_msg(msg, PARAMS).reason is Reason.NAN_FIELD


def test_a_receiver_velocity_is_never_a_body_velocity() -> None:
    """A TwistStamped on velocity (source none) is refused; on gnss_velocity it is fused."""
    pipe = Pipeline(PARAMS.__class__.from_flat({'velocity.source': 'none',
                                                'gnss_velocity.source': 'twist',
                                                'origin': [52.0, 5.0, 0.0]}))
    msg = TwistStamped()
    msg.header.stamp = stamp(3.0)
    msg.twist.linear.x = 2.0
    assert pipe.handle('velocity', msg, 3 * 10 ** 9).rejected == 'unused_input'
    assert pipe.handle('gnss_velocity', msg, 3 * 10 ** 9).rejected is None
    assert pipe.counts['gnss_velocity'] == 1 and pipe.counts['velocity'] == 0


def test_failover_by_priority_staleness_and_fault() -> None:
    s = 1_000_000_000
    failover = HeadingFailover(['a', 'b'], 1.0)
    assert failover.offer(1, 1 * s) and failover.in_use == 'b'     # only b so far
    assert failover.offer(0, 1 * s + 1) and failover.in_use == 'a'  # a has priority
    assert not failover.offer(1, 2 * s)                             # b stands by
    # a goes quiet: b takes over once a's last heading is older than the timeout.
    assert not failover.offer(1, 2 * s + 1)
    assert failover.offer(1, 2 * s + 2) and failover.in_use == 'b'
    assert failover.offer(0, 3 * s) and failover.in_use == 'a'      # a is back
    failover.refused(0, 3 * s, Reason.FROZEN_INPUT.value)          # ...and faulty
    assert failover.offer(1, 3 * s + 1) and failover.in_use == 'b'
    assert not failover.offer(0, 3 * s + 2)
    assert failover.offer(0, 4 * s + 1) and failover.in_use == 'a'  # the fault has timed out
    failover.refused(0, 5 * s, Reason.TOO_LATE.value)           # not a fault: a stays
    assert failover.offer(0, 5 * s + 1) and failover.switches == 5
    assert isinstance(Rejection(Reason.STANDBY, ''), Rejection)
