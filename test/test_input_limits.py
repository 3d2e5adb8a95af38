"""
Plausibility limits at the edge: each just inside (accepted) and just outside (rejected, counted).

Through :meth:`Pipeline.handle` with rclpy messages (and rosbags' dataclasses where rclpy's
field checks cannot hold the value, e.g. a uint32 ROS 1 ``sec``), so the counts in
``/diagnostics`` are checked too. A hypothesis test throws random finite garbage at a running
pipeline: it never raises, and every output stays finite with non-negative variances.
"""

from __future__ import annotations

import math
from typing import Any, Callable, Iterable

from hypothesis import given, HealthCheck, settings, strategies as st
import numpy as np
import pytest
from rosbags.typesys import get_typestore, Stores
from sensor_msgs.msg import NavSatFix
from test_pipeline import (all_finite, decoded, fix_msg, handle, imu_msg, make, T0, vel_msg,
                           Vessel)
from vessel_kinematics.estimation import Reason
from vessel_kinematics.ros import inputs, outputs
from vessel_kinematics.ros.pipeline import Emission, Pipeline

UP = math.inf
T = 1.0  # seconds after T0 of the message under test


def _next(x: float) -> float:
    """Return the next float above x (just outside an upper limit)."""
    return math.nextafter(x, UP)


def _fix(**fields: Any) -> NavSatFix:
    msg = fix_msg(T, (0.0, 0.0, 0.0))
    for name, value in fields.items():
        if name == 'cov':
            msg.position_covariance = np.asarray(value, dtype=float).reshape(9)
        else:
            setattr(msg, name, value)
    return msg


def _imu(rate=(0.0, 0.0, 0.0), o_cov=None, w_cov=None) -> Any:
    msg = imu_msg(T, 0.3, 0.0)
    msg.angular_velocity.x, msg.angular_velocity.y, msg.angular_velocity.z = rate
    if o_cov is not None:
        msg.orientation_covariance = np.asarray(o_cov, dtype=float).reshape(9)
    if w_cov is not None:
        msg.angular_velocity_covariance = np.asarray(w_cov, dtype=float).reshape(9)
    return msg


def _vel(linear=(2.0, 0.0, 0.0), angular=(0.0, 0.0, 0.0), cov=None) -> Any:
    msg = vel_msg(T, 0.0, 0.0)
    lin, ang = msg.twist.twist.linear, msg.twist.twist.angular
    lin.x, lin.y, lin.z = linear
    ang.x, ang.y, ang.z = angular
    if cov is not None:
        msg.twist.covariance = np.asarray(cov, dtype=float).reshape(36)
    return msg


def _stamped(msg: Any, sec: int, nanosec: int) -> Any:
    msg.header.stamp.sec, msg.header.stamp.nanosec = sec, nanosec
    return msg


def _diag(*values: float) -> list[float]:
    return np.diag(values).reshape(-1).tolist()


def _cov6(lin: list[float], ang: list[float]) -> np.ndarray:
    c = np.zeros((6, 6))
    c[0:3, 0:3] = np.asarray(lin).reshape(3, 3)
    c[3:6, 3:6] = np.asarray(ang).reshape(3, 3)
    return c


V = inputs.MAX_VARIANCE
MAX_SEC = inputs.MAX_STAMP_SEC
NS = 10 ** 9
GOOD9 = _diag(0.09, 0.09, 0.25)
# Pairwise bounded (|c_ij| <= sqrt(c_ii c_jj)) yet indefinite: only the determinant says so.
INDEFINITE = [1.0, 0.9, -0.9, 0.9, 1.0, 0.9, -0.9, 0.9, 1.0]
SINGULAR = [0.09, 0.09, 0.0, 0.09, 0.09, 0.0, 0.0, 0.0, 0.25]  # PSD, rank 2: accepted
TOO_CORRELATED = [0.09, 0.09 * 1.001, 0.0, 0.09 * 1.001, 0.09, 0.0, 0.0, 0.0, 0.25]
ASYMMETRIC = [0.09, 0.01, 0.0, 0.0, 0.09, 0.0, 0.0, 0.0, 0.25]

# (case, input, message just inside the limit, message just outside, reason)
LIMITS: list[tuple[str, str, Callable[[], Any], Callable[[], Any], str]] = [
    ('speed', 'velocity', lambda: _vel((60.0, -80.0, 0.0)),
     lambda: _vel((60.0, -80.0, 1e-3)), Reason.IMPLAUSIBLE_SPEED),
    ('speed surge', 'velocity', lambda: _vel((inputs.MAX_SPEED, 0.0, 0.0)),
     lambda: _vel((_next(inputs.MAX_SPEED), 0.0, 0.0)), Reason.IMPLAUSIBLE_SPEED),
    ('velocity rate', 'velocity', lambda: _vel(angular=(0.0, 12.0, 16.0)),
     lambda: _vel(angular=(0.0, 12.0, 16.001)), Reason.IMPLAUSIBLE_RATE),
    ('imu rate', 'imu', lambda: _imu((0.0, 0.0, -inputs.MAX_BODY_RATE)),
     lambda: _imu((0.0, 0.0, -_next(inputs.MAX_BODY_RATE))), Reason.IMPLAUSIBLE_RATE),
    ('height high', 'fix', lambda: _fix(altitude=inputs.MAX_HEIGHT),
     lambda: _fix(altitude=_next(inputs.MAX_HEIGHT)), Reason.IMPLAUSIBLE_HEIGHT),
    ('height low', 'fix', lambda: _fix(altitude=inputs.MIN_HEIGHT),
     lambda: _fix(altitude=math.nextafter(inputs.MIN_HEIGHT, -UP)),
     Reason.IMPLAUSIBLE_HEIGHT),
    ('nanosec fix', 'fix', lambda: _stamped(_fix(), int(T0) + 1, NS - 1),
     lambda: _stamped(_fix(), int(T0), NS), Reason.BAD_STAMP),
    ('nanosec imu', 'imu', lambda: _stamped(_imu(), int(T0) + 1, NS - 1),
     lambda: _stamped(_imu(), int(T0), 2 * NS), Reason.BAD_STAMP),
    ('negative sec', 'velocity', lambda: _stamped(_vel(), 1, 0),
     lambda: _stamped(_vel(), -1, 0), Reason.BAD_STAMP),
    ('int32 sec', 'imu', lambda: _stamped(_imu(), MAX_SEC, NS - 1),
     lambda: _stamped(_imu(), -2 ** 31, 0), Reason.BAD_STAMP),
    ('fix variance', 'fix', lambda: _fix(cov=_diag(V, V, V)),
     lambda: _fix(cov=_diag(V, _next(V), V)), Reason.BAD_COVARIANCE),
    ('fix negative variance', 'fix', lambda: _fix(cov=_diag(0.09, 0.0, 0.25)),
     lambda: _fix(cov=_diag(0.09, -1e-12, 0.25)), Reason.BAD_COVARIANCE),
    ('fix correlation', 'fix', lambda: _fix(cov=SINGULAR),
     lambda: _fix(cov=TOO_CORRELATED), Reason.BAD_COVARIANCE),
    ('fix symmetry', 'fix', lambda: _fix(cov=[0.09, 0.01, 0, 0.01, 0.09, 0, 0, 0, 0.25]),
     lambda: _fix(cov=ASYMMETRIC), Reason.BAD_COVARIANCE),
    ('fix determinant', 'fix', lambda: _fix(cov=np.eye(3).reshape(9)),
     lambda: _fix(cov=INDEFINITE), Reason.BAD_COVARIANCE),
    ('imu orientation variance', 'imu', lambda: _imu(o_cov=_diag(-1.0, 0.0, 0.0)),
     lambda: _imu(o_cov=_diag(0.01, -0.01, 0.01)), Reason.BAD_COVARIANCE),
    ('imu orientation symmetry', 'imu', lambda: _imu(o_cov=GOOD9),
     lambda: _imu(o_cov=ASYMMETRIC), Reason.BAD_COVARIANCE),
    ('imu rate variance', 'imu', lambda: _imu(w_cov=_diag(V, V, V)),
     lambda: _imu(w_cov=_diag(-1e-9, 0.0, 0.0)), Reason.BAD_COVARIANCE),
    ('velocity linear covariance', 'velocity', lambda: _vel(cov=_cov6(SINGULAR, GOOD9)),
     lambda: _vel(cov=_cov6(INDEFINITE, GOOD9)), Reason.BAD_COVARIANCE),
    ('velocity angular covariance', 'velocity', lambda: _vel(cov=_cov6(GOOD9, SINGULAR)),
     lambda: _vel(cov=_cov6(GOOD9, ASYMMETRIC)), Reason.BAD_COVARIANCE),
]


@pytest.mark.parametrize('case, name, inside, outside, reason', LIMITS,
                         ids=[case[0] for case in LIMITS])
def test_limit_just_inside_and_just_outside(case: str, name: str, inside: Callable[[], Any],
                                            outside: Callable[[], Any], reason: Reason) -> None:
    accepted = make()
    result = handle(accepted, name, inside())
    assert result.rejected is None, (case, result.rejected, result.detail)
    assert accepted.counts[name] == 1
    _check_outputs(result.emissions)
    refused = make()
    result = handle(refused, name, outside())
    assert (result.rejected, result.emissions) == (reason, ()), (case, result)
    assert result.detail
    assert refused.counts[f'{name}/{reason.value}'] == 1 and refused.counts[name] == 0
    diagnostics = decoded([refused.diagnostics(int(T0 * 1e9))])['/diagnostics']
    values = {kv.key: kv.value for kv in diagnostics.status[0].values}
    assert values[f'rejected {name}/{reason.value}'] == '1'


def test_limit_constants_are_the_documented_ones() -> None:
    assert inputs.MAX_SPEED == 100.0 and inputs.MAX_BODY_RATE == 20.0
    assert (inputs.MIN_HEIGHT, inputs.MAX_HEIGHT) == (-12_000.0, 50_000.0)
    assert inputs.MAX_STAMP_SEC == np.iinfo(np.int32).max
    assert inputs.MAX_VARIANCE == 1e12


def test_sec_beyond_int32_from_a_bag_is_rejected() -> None:
    """ROS 1 stamps are uint32 seconds: rosbags' dataclasses carry them, the outputs cannot."""
    types = get_typestore(Stores.ROS2_JAZZY).types

    def header(sec: int) -> Any:
        return types['std_msgs/msg/Header'](
            stamp=types['builtin_interfaces/msg/Time'](sec=sec, nanosec=0), frame_id='imu')

    def imu(sec: int) -> Any:
        cov = np.zeros(9)
        return types['sensor_msgs/msg/Imu'](
            header=header(sec), orientation=types['geometry_msgs/msg/Quaternion'](
                x=0.0, y=0.0, z=0.0, w=1.0), orientation_covariance=cov,
            angular_velocity=types['geometry_msgs/msg/Vector3'](x=0.0, y=0.0, z=0.0),
            angular_velocity_covariance=cov,
            linear_acceleration=types['geometry_msgs/msg/Vector3'](x=0.0, y=0.0, z=9.8),
            linear_acceleration_covariance=cov)

    pipe = make()
    assert handle(pipe, 'imu', imu(MAX_SEC)).rejected is None
    result = handle(pipe, 'imu', imu(MAX_SEC + 1))
    assert result.rejected == Reason.BAD_STAMP and 'int32' in result.detail
    assert inputs.stamp_problem(2 ** 32 - 1, 0) is not None
    assert inputs.stamp_problem(MAX_SEC, NS - 1) is None


def test_latest_stamp_comes_out_unwrapped() -> None:
    pipe = make()
    fix = _stamped(fix_msg(0.0, (0.0, 0.0, 0.0)), MAX_SEC, NS - 3)
    log = _stamped(vel_msg(0.0, 2.0, 0.0), MAX_SEC, NS - 2)
    imu = _stamped(imu_msg(0.0, 0.0, 0.0), MAX_SEC, NS - 1)
    assert handle(pipe, 'fix', fix).rejected is None
    assert handle(pipe, 'velocity', log).rejected is None
    result = handle(pipe, 'imu', imu)
    assert result.rejected is None and result.emissions
    for topic, msg in decoded(result.emissions).items():
        for stamped in getattr(msg, 'transforms', [msg]):
            stamp = stamped.header.stamp
            assert (stamp.sec, stamp.nanosec) == (MAX_SEC, NS - 1), topic


# --------------------------------------------------------------------- random garbage

finite = st.floats(allow_nan=False, allow_infinity=False)
plausible = st.floats(-50.0, 50.0)
variance = st.one_of(st.floats(0.0, 2e12), finite)
vector9 = st.one_of(st.lists(finite, min_size=9, max_size=9),
                    st.tuples(variance, variance, variance).map(lambda d: _diag(*d)),
                    st.just([-1.0] + [0.0] * 8), st.just([0.0] * 9))
vector3 = st.one_of(st.tuples(finite, finite, finite), st.tuples(plausible, plausible, plausible))
stamps = st.tuples(st.integers(-2 ** 31, 2 ** 31 - 1), st.integers(0, 2 ** 32 - 1))
offsets = st.floats(-3.0, 30.0)


def _stamp_of(msg: Any, offset: float, raw: tuple[int, int] | None) -> Any:
    if raw is None:
        msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(int((T0 + offset) * 1e9), NS)
    else:
        msg.header.stamp.sec, msg.header.stamp.nanosec = raw
    return msg


garbage_fix = st.builds(
    lambda offset, raw, lat, lon, alt, cov, cov_type, status: _stamp_of(
        _set(fix_msg(0.0, (0.0, 0.0, 0.0)), latitude=lat, longitude=lon, altitude=alt,
             position_covariance=np.asarray(cov, dtype=float), position_covariance_type=cov_type,
             status_status=status), offset, raw),
    offsets, st.one_of(st.none(), stamps), st.one_of(finite, st.floats(59.8, 60.0)),
    st.one_of(finite, st.floats(10.6, 10.8)), finite, vector9, st.integers(0, 3),
    st.integers(-1, 2)).map(lambda m: ('fix', m))
garbage_imu = st.builds(
    lambda offset, raw, q, w, o_cov, w_cov: _stamp_of(
        _set(imu_msg(0.0, 0.0, 0.0), orientation_xyzw=q, angular_velocity_xyz=w,
             orientation_covariance=np.asarray(o_cov, dtype=float),
             angular_velocity_covariance=np.asarray(w_cov, dtype=float)), offset, raw),
    offsets, st.one_of(st.none(), stamps),
    st.one_of(st.tuples(finite, finite, finite, finite),
              st.tuples(plausible, plausible, plausible, plausible)),
    vector3, vector9, vector9).map(lambda m: ('imu', m))
garbage_velocity = st.builds(
    lambda offset, raw, lin, ang, lin_cov, ang_cov: _stamp_of(
        _set(vel_msg(0.0, 0.0, 0.0), linear_xyz=lin, angular_xyz=ang,
             covariance=_cov6(lin_cov, ang_cov).reshape(36)), offset, raw),
    offsets, st.one_of(st.none(), stamps), vector3, vector3, vector9,
    vector9).map(lambda m: ('velocity', m))


def _set(msg: Any, **fields: Any) -> Any:
    """Set the fields of a test message, a few by shorthand."""
    for name, value in fields.items():
        if name == 'status_status':
            msg.status.status = value
        elif name == 'orientation_xyzw':
            o = msg.orientation
            o.x, o.y, o.z, o.w = value
        elif name == 'angular_velocity_xyz':
            v = msg.angular_velocity
            v.x, v.y, v.z = value
        elif name == 'linear_xyz':
            v = msg.twist.twist.linear
            v.x, v.y, v.z = value
        elif name == 'angular_xyz':
            v = msg.twist.twist.angular
            v.x, v.y, v.z = value
        elif name == 'covariance':
            msg.twist.covariance = value
        else:
            setattr(msg, name, value)
    return msg


def _check_outputs(emissions: Iterable[Emission]) -> None:
    """Every number finite, every variance (covariance diagonal) >= 0."""
    for emission in emissions:
        msg = decoded([emission])
        assert all_finite(msg), emission.topic
        (msg,) = msg.values()
        if hasattr(msg, 'pose') and hasattr(msg, 'twist'):
            for cov in (msg.pose.covariance, msg.twist.covariance):
                assert (np.diag(np.asarray(cov).reshape(6, 6)) >= 0.0).all(), emission.topic
        if hasattr(msg, 'position_covariance'):
            assert (np.asarray(msg.position_covariance)[[0, 4, 8]] >= 0.0).all()


def _state_emissions(pipe: Pipeline) -> list[Emission]:
    """Return the outputs of the pipeline's current state (none before it is ready)."""
    state = pipe.state()
    if state is None:
        return []
    return [Emission('/' + name, state.stamp_ns, data)
            for name, data in outputs.state_outputs(state, pipe.params)]


@settings(max_examples=150, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(st.lists(st.one_of(garbage_fix, garbage_imu, garbage_velocity), min_size=1,
                max_size=25))
def test_random_finite_garbage_never_crashes_or_poisons(messages: list[tuple[str, Any]]) -> None:
    pipe = make()
    vessel = Vessel(2.0)
    for name, msg in vessel.messages(1.0, imu_hz=10.0, vel_hz=5.0, fix_hz=2.0,
                                     t_start=-2.0):
        handle(pipe, name, msg)
    for name, msg in messages:
        result = handle(pipe, name, msg)
        _check_outputs(result.emissions)
    _check_outputs(_state_emissions(pipe))
    counts = pipe.counts
    assert all(n >= 0 for n in counts.values())


def test_the_issues_hostile_values_are_rejected() -> None:
    """The values of issue 8 that poisoned the filter are refused and counted."""
    pipe: Pipeline = make()
    vessel = Vessel(2.0)
    for name, msg in vessel.messages(2.0):
        assert handle(pipe, name, msg).rejected is None
    hostile = [('velocity', _stamped(_vel((1e150, 0.0, 0.0)), int(T0) + 2, 5_000_000),
                Reason.IMPLAUSIBLE_SPEED),
               ('velocity', _stamped(_vel((1e6, 0.0, 0.0)), int(T0) + 2, 6_000_000),
                Reason.IMPLAUSIBLE_SPEED),
               ('imu', _stamped(_imu((0.0, 0.0, 1e6)), int(T0) + 2, 7_000_000),
                Reason.IMPLAUSIBLE_RATE),
               ('imu', _stamped(_imu(o_cov=_diag(-4100.0, 0.01, 0.01)), int(T0) + 2,
                                8_000_000), Reason.BAD_COVARIANCE),
               ('fix', _stamped(_fix(cov=INDEFINITE), int(T0) + 2, 9_000_000),
                Reason.BAD_COVARIANCE),
               ('imu', _stamped(_imu(), int(T0) + 2, 1_500_000_000), Reason.BAD_STAMP)]
    for name, msg, reason in hostile:
        assert handle(pipe, name, msg).rejected == reason
    sent: list[Emission] = []
    for name, msg in vessel.messages(6.0, t_start=2.01):
        result = handle(pipe, name, msg)
        assert result.rejected is None
        sent.extend(result.emissions)
    _check_outputs(sent)
    last = [e for e in sent if e.topic == '/odometry/ned'][-1]
    pos = decoded([last])['odometry/ned'].pose.pose.position
    truth = vessel.position(6.0)
    assert math.hypot(pos.x - truth[0], pos.y - truth[1]) < 0.05
    assert pipe.counts['resets'] == 0


matrices = st.lists(st.floats(-10.0, 10.0), min_size=9, max_size=9).map(
    lambda v: np.asarray(v).reshape(3, 3))


@settings(max_examples=300, deadline=None)
@given(matrices, st.floats(1e-3, 10.0))
def test_covariance_check_against_eigenvalues(b: np.ndarray, shift: float) -> None:
    """cov3_problem agrees with numpy's eigenvalues away from the tolerance band."""
    psd = b @ b.T
    assert np.linalg.eigvalsh(psd).min() >= -1e-9 * max(1.0, np.abs(psd).max())
    assert inputs.cov3_problem(psd.reshape(9).tolist()) is None
    # Shifted down until the smallest eigenvalue is below -1e-5 trace (the tolerance is
    # 1e-6 trace): refused.
    low = np.linalg.eigvalsh(psd).min()
    depth = max(shift, 1e-5 * np.trace(psd))
    indefinite = psd - (low + depth) * np.eye(3)
    assert np.linalg.eigvalsh(indefinite).min() < -0.9 * depth
    assert inputs.cov3_problem(indefinite.reshape(9).tolist()) is not None
    # Slightly indefinite within the tolerance (rounding): accepted, while no variance is
    # negative (a negative variance is refused whatever its size).
    rounded = psd - (low + 1e-7 * np.trace(psd)) * np.eye(3)
    if (np.diag(rounded) >= 0.0).all():
        assert inputs.cov3_problem(rounded.reshape(9).tolist()) is None
    # Any asymmetry beyond the tolerance: refused.
    skew = psd + np.eye(3)
    skew[0, 1] += 1e-3 * math.sqrt(skew[0, 0] * skew[1, 1]) + 1e-9
    assert inputs.cov3_problem(skew.reshape(9).tolist()) == 'not symmetric'
