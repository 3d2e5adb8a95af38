"""
One scalar/array dispatch across the kinematics core (vessel_kinematics.core.dispatch).

For every public function of rotation, quaternion, geodesy, flow and frames: each scalar input
kind (float, int, np.float16/32/64 scalars, 0-d arrays) gives the same type and the same value
as the same number passed as a Python float; 1-d and 2-d batches give float64 arrays equal
element by element to the one-point results. Plus the three inconsistencies of issue 9 as
named regression tests.
"""

from __future__ import annotations

import math
import types
from typing import Any, Callable

import numpy as np
import pytest

from vessel_kinematics.core import dispatch, flow, frames, geodesy, quaternion, rotation

Q = (0.8, 0.2, -0.3, 0.4)                 # not unit on purpose where a function allows it
QU = tuple((np.array(Q) / np.linalg.norm(Q)).tolist())
V3 = (1.5, -2.0, 0.5)
P_ECEF = (3.9e6, 0.8e6, 4.9e6)
R3 = tuple(map(tuple, rotation.rzyx(0.1, -0.2, 0.3).tolist()))
M6 = tuple(map(tuple, (np.arange(36.0).reshape(6, 6) / 7.0).tolist()))
C3 = ((2.0, 0.1, 0.0), (0.1, 3.0, 0.2), (0.0, 0.2, 4.0))

# (name, function, arguments): a float argument is a scalar slot that takes every input kind,
# a tuple is a point (vector, quaternion or matrix) that batches take stacked.
SPECS: list[tuple[str, Callable[..., Any], tuple[Any, ...]]] = [
    ('rotation.skew', rotation.skew, (V3,)),
    ('rotation.vee', rotation.vee, (R3,)),
    ('rotation.rot_x', rotation.rot_x, (0.3,)),
    ('rotation.rot_y', rotation.rot_y, (0.3,)),
    ('rotation.rot_z', rotation.rot_z, (0.3,)),
    ('rotation.rzyx', rotation.rzyx, (0.1, -0.2, 0.3)),
    ('rotation.rzyx_small_angle', rotation.rzyx_small_angle, (0.01, -0.02, 0.03)),
    ('rotation.tzyx', rotation.tzyx, (0.1, -0.2)),
    ('rotation.eulerang', rotation.eulerang, (0.1, -0.2, 0.3)),
    ('rotation.rotation_axis_angle', rotation.rotation_axis_angle, (V3, 0.4)),
    ('rotation.rot2euler', rotation.rot2euler, (R3,)),
    ('rotation.rotation_rate', rotation.rotation_rate, (R3, V3)),
    ('rotation.euler_from_rows', rotation.euler_from_rows, (0.1, 0.2, 0.9, 0.1, -0.2, 0.3,
                                                            0.9)),
    ('quaternion.normalize', quaternion.normalize, (Q,)),
    ('quaternion.is_unit', quaternion.is_unit, (QU,)),
    ('quaternion.quat_conjugate', quaternion.quat_conjugate, (Q,)),
    ('quaternion.quat_multiply', quaternion.quat_multiply, (Q, QU)),
    ('quaternion.rquat', quaternion.rquat, (QU,)),
    ('quaternion.tquat', quaternion.tquat, (QU,)),
    ('quaternion.quatern', quaternion.quatern, (QU,)),
    ('quaternion.quat_rotate', quaternion.quat_rotate, (QU, V3)),
    ('quaternion.rot2q', quaternion.rot2q, (R3,)),
    ('quaternion.euler2q', quaternion.euler2q, (0.1, -0.2, 0.3)),
    ('quaternion.q2euler', quaternion.q2euler, (QU,)),
    ('quaternion.axis_angle2q', quaternion.axis_angle2q, (V3, 0.4)),
    ('quaternion.rotvec2q', quaternion.rotvec2q, (V3,)),
    ('quaternion.q2rotvec', quaternion.q2rotvec, (QU,)),
    ('quaternion.normalization_term', quaternion.normalization_term, (Q, 100.0)),
    ('quaternion.quat_derivative', quaternion.quat_derivative, (QU, V3)),
    ('quaternion.integrate_euler', quaternion.integrate_euler, (QU, V3, 0.01)),
    ('quaternion.integrate_exp', quaternion.integrate_exp, (QU, V3, 0.01)),
    ('geodesy.radius_prime_vertical', geodesy.radius_prime_vertical, (0.8,)),
    ('geodesy.radius_meridian', geodesy.radius_meridian, (0.8,)),
    ('geodesy.llh2ecef', geodesy.llh2ecef, (0.8, 0.2, 35.0)),
    ('geodesy.ecef2llh', geodesy.ecef2llh, (P_ECEF,)),
    ('geodesy.ecef2llh_fossen', geodesy.ecef2llh_fossen, (P_ECEF,)),
    ('geodesy.rll', geodesy.rll, (0.2, 0.8)),
    ('geodesy.ned2ecef_velocity', geodesy.ned2ecef_velocity, (V3, 0.8, 0.2)),
    ('geodesy.ecef2ned_velocity', geodesy.ecef2ned_velocity, (V3, 0.8, 0.2)),
    ('geodesy.rotate_ned', geodesy.rotate_ned, (V3, 0.8, 0.2, 0.7, 0.3)),
    ('geodesy.ecef2ned', geodesy.ecef2ned, (P_ECEF, 0.8, 0.2, 10.0)),
    ('geodesy.ned2ecef', geodesy.ned2ecef, ((10.0, 20.0, 1.0), 0.8, 0.2, 10.0)),
    ('geodesy.llh2ned', geodesy.llh2ned, (0.8, 0.2, 35.0, 0.8001, 0.2001, 1.0)),
    ('geodesy.ned2llh', geodesy.ned2llh, ((10.0, 20.0, 1.0), 0.8, 0.2, 10.0)),
    ('geodesy.llh2flat', geodesy.llh2flat, (0.8, 0.2, 35.0, 0.8001, 0.2001, 1.0)),
    ('geodesy.flat2llh', geodesy.flat2llh, ((10.0, 20.0, 1.0), 0.8, 0.2, 10.0)),
    ('flow.ssa', flow.ssa, (4.0,)),
    ('flow.speed', flow.speed, (V3,)),
    ('flow.course', flow.course, (V3, 0.3)),
    ('flow.sideslip', flow.sideslip, (V3,)),
    ('flow.angle_of_attack', flow.angle_of_attack, (V3,)),
    ('flow.heading(q)', flow.heading, (Q,)),
    ('flow.heading(R)', flow.heading, (R3,)),
    ('flow.current_ned', flow.current_ned, (0.5, 0.3)),
    ('flow.relative_velocity', flow.relative_velocity, (V3, QU, (0.3, -0.1, 0.0))),
    ('flow.relative_flow', flow.relative_flow, (V3, R3, (0.3, -0.1, 0.0))),
    ('flow.rotation_flow2body', flow.rotation_flow2body, (0.1, 0.2)),
    ('flow.flow_transform', flow.flow_transform, (0.1, 0.2)),
    ('flow.flow_matrix', flow.flow_matrix, (M6, 0.1, 0.2)),
    ('frames.ssa', frames.ssa, (-4.0,)),
    ('frames.ned_to_enu', frames.ned_to_enu, (V3,)),
    ('frames.enu_to_ned', frames.enu_to_ned, (V3,)),
    ('frames.frd_to_flu', frames.frd_to_flu, (V3,)),
    ('frames.flu_to_frd', frames.flu_to_frd, (V3,)),
    ('frames.quat_xyzw_to_wxyz', frames.quat_xyzw_to_wxyz, (Q,)),
    ('frames.quat_wxyz_to_xyzw', frames.quat_wxyz_to_xyzw, (Q,)),
    ('frames.q_nb_to_ros_wxyz', frames.q_nb_to_ros_wxyz, (Q,)),
    ('frames.q_nb_from_ros_wxyz', frames.q_nb_from_ros_wxyz, (Q,)),
    ('frames.q_nb_to_ros', frames.q_nb_to_ros, (Q,)),
    ('frames.q_nb_from_ros', frames.q_nb_from_ros, (Q,)),
    ('frames.yaw_ned_to_enu', frames.yaw_ned_to_enu, (-1.2,)),
    ('frames.yaw_enu_to_ned', frames.yaw_enu_to_ned, (2.5,)),
    ('frames.euler_ned_to_enu', frames.euler_ned_to_enu, (0.1, -0.2, 0.3)),
    ('frames.euler_enu_to_ned', frames.euler_enu_to_ned, (0.1, -0.2, 0.3)),
    ('frames.yaw_from_q', frames.yaw_from_q, (Q,)),
    ('frames.yaw_from_ros', frames.yaw_from_ros, (Q,)),
    ('frames.cov3_ned_to_enu', frames.cov3_ned_to_enu, (C3,)),
    ('frames.cov3_frd_to_flu', frames.cov3_frd_to_flu, (C3,)),
    ('frames.cov6_pose_to_ros', frames.cov6_pose_to_ros, (M6,)),
]

SCALAR_KINDS: dict[str, Callable[[float], Any]] = {
    'float': float,
    'int': lambda x: int(round(x)),
    'np.float16': np.float16,
    'np.float32': np.float32,
    'np.float64': np.float64,
    'np.int64': lambda x: np.int64(round(x)),
    '0-d array': np.array,
    '0-d float32 array': lambda x: np.array(x, dtype=np.float32),
}

# Functions with a separate pure-Python body (the per-message kernels): its numbers must agree
# with the numpy body to round-off (libm and numpy may round sin/cos differently by an ulp).
# Everything else has one body, so a batch reproduces the one-point bits exactly.
TWO_BODIES = {'geodesy.llh2ned', 'geodesy.ned2llh', 'geodesy.llh2flat', 'geodesy.flat2llh',
              'flow.course', 'flow.sideslip', 'flow.angle_of_attack', 'flow.ssa',
              'frames.ssa', 'frames.yaw_ned_to_enu', 'frames.yaw_enu_to_ned',
              'frames.euler_ned_to_enu', 'frames.euler_enu_to_ned', 'frames.yaw_from_q',
              'frames.yaw_from_ros', 'flow.heading(q)', 'flow.relative_flow',
              'quaternion.integrate_euler', 'quaternion.integrate_exp'}


def _scalar_slots(args: tuple[Any, ...]) -> list[int]:
    return [i for i, a in enumerate(args) if isinstance(a, float)]


def _same(a: Any, b: Any) -> None:
    """Assert a and b have the same type (recursively) and the same bits (NaN equal)."""
    assert type(a) is type(b), (type(a), type(b))
    if isinstance(a, tuple):
        assert len(a) == len(b)
        for x, y in zip(a, b):
            _same(x, y)
    elif isinstance(a, np.ndarray):
        assert a.dtype == b.dtype and a.shape == b.shape
        np.testing.assert_array_equal(a, b)
    else:
        assert a == b or (a != a and b != b)


def _check_output_rule(name: str, out: Any, one: bool) -> None:
    """Assert the dispatch rule: Python floats (or bool) for one point, float64 arrays else."""
    if isinstance(out, tuple):
        for item in out:
            _check_output_rule(name, item, one)
        return
    if name == 'quaternion.is_unit':
        assert isinstance(out, bool) if one else out.dtype == np.bool_
    elif isinstance(out, np.ndarray):
        assert out.dtype == np.float64
        if one:
            assert out.ndim >= 1, f'{name}: a 0-d array where a float belongs'
    else:
        assert one and type(out) is float, f'{name}: {type(out)} for a batch'


SCALAR_SPECS = [s for s in SPECS if _scalar_slots(s[2])]


@pytest.mark.parametrize('kind', list(SCALAR_KINDS))
@pytest.mark.parametrize('name, func, args', SCALAR_SPECS, ids=[s[0] for s in SCALAR_SPECS])
def test_scalar_kinds_give_the_float_result(name, func, args, kind):
    slots = _scalar_slots(args)
    cast = SCALAR_KINDS[kind]
    given = list(args)
    as_float = list(args)
    for i in slots:
        given[i] = cast(args[i])
        as_float[i] = float(given[i])         # the exact float64 value of the input kind
    expected = func(*as_float)
    _check_output_rule(name, expected, one=True)
    _same(func(*given), expected)


def _batch(args: tuple[Any, ...], shape: tuple[int, ...]) -> tuple[list[Any], list[Any]]:
    """Return (batch arguments, per-element one-point arguments) with distinct values."""
    n = int(np.prod(shape))
    per_element: list[list[Any]] = [list(args) for _ in range(n)]
    batched: list[Any] = []
    for i, a in enumerate(args):
        base = np.asarray(a, dtype=float)
        stack = np.stack([base * (1.0 + 0.01 * k) if i else base + 0.01 * k
                          for k in range(n)])
        if base.shape == (3, 3) or base.shape == (6, 6):
            stack = np.stack([base] * n)          # keep rotation matrices rotations
        for k in range(n):
            per_element[k][i] = (float(stack[k]) if isinstance(a, float)
                                 else tuple(stack[k].tolist()) if stack[k].ndim == 1
                                 else stack[k])
        batched.append(stack.reshape(shape + base.shape))
    return batched, per_element


def _components(out: Any) -> list[np.ndarray]:
    return [np.asarray(c) for c in out] if isinstance(out, tuple) else [np.asarray(out)]


@pytest.mark.parametrize('shape', [(3,), (2, 2)], ids=['1-d', '2-d'])
@pytest.mark.parametrize('name, func, args', SPECS, ids=[s[0] for s in SPECS])
def test_batches_equal_the_one_point_results(name, func, args, shape):
    batched, per_element = _batch(args, shape)
    out = func(*batched)
    _check_output_rule(name, out, one=False)
    got = _components(out)
    for k, idx in enumerate(np.ndindex(*shape)):
        one = func(*per_element[k])
        _check_output_rule(name, one, one=True)
        want = _components(one) if not isinstance(one, tuple) or len(got) > 1 else [
            np.asarray(one)]
        assert len(want) == len(got)
        for g, w in zip(got, want):
            if name in TWO_BODIES:
                # Positions go through ECEF (6e6 m): round-off there is ~1e-9 m.
                atol = 1e-8 if name.startswith('geodesy') else 1e-15
                np.testing.assert_allclose(g[idx], w, rtol=2e-15, atol=atol)
            else:
                np.testing.assert_array_equal(g[idx], w)


# --- the three inconsistencies of issue 9, and the wrapping conventions ----------------------

def test_ssa_of_a_float32_scalar_is_a_float():
    got = flow.ssa(np.float32(4))
    assert type(got) is float
    assert got == flow.ssa(4.0) == float(np.asarray(flow.ssa(np.array([4.0])))[0])


def test_llh2ecef_float32_and_float16_give_the_same_type():
    ref = geodesy.llh2ecef(0.5, 0.25, 0.0)
    for kind in (np.float32, np.float16, np.float64):
        got = geodesy.llh2ecef(kind(0.5), kind(0.25), kind(0.0))
        assert type(got) is tuple and all(type(c) is float for c in got)
        assert got == ref                   # 0.5, 0.25 and 0 are exact in every width
    assert geodesy.llh2ecef(np.array([0.5]), 0.25, 0.0).dtype == np.float64


def test_yaw_ned_to_enu_west_is_plus_pi_for_scalars_and_arrays():
    assert frames.yaw_ned_to_enu(-math.pi / 2) == math.pi
    assert frames.yaw_ned_to_enu(np.array([-math.pi / 2]))[0] == math.pi
    assert frames.yaw_ned_to_enu(np.float32(-math.pi / 2)) == frames.yaw_ned_to_enu(
        float(np.float32(-math.pi / 2)))


@pytest.mark.parametrize('angle', [math.pi, -math.pi, 3 * math.pi, -3 * math.pi, 2 * math.pi,
                                   -0.0, 1e-300, 7.0, -7.0, 1e6, -1e6, math.nan, math.inf])
def test_ssa_scalar_and_array_bodies_agree_bit_for_bit(angle):
    scalar = flow.ssa(angle)
    array = flow.ssa(np.array([angle]))[0]
    assert (scalar == array and math.copysign(1, scalar) == math.copysign(1, array)) or (
        math.isnan(scalar) and math.isnan(array))
    assert math.isnan(scalar) or -math.pi < scalar <= math.pi


def test_wrapped_angles_at_the_boundary_are_plus_pi_both_ways():
    # atan2(-0, x < 0) = -pi: every function returning an angle maps it to +pi, both bodies.
    v = (-1.0, -0.0, 0.0)
    assert flow.course(v) == math.pi == flow.course(np.array([v]))[0]
    assert flow.angle_of_attack((-1.0, 0.0, -0.0)) == math.pi
    assert flow.angle_of_attack(np.array([[-1.0, 0.0, -0.0]]))[0] == math.pi
    q_west = (0.0, 0.0, 0.0, -1.0)                 # yaw -pi by atan2 sign, +pi here
    assert frames.yaw_from_q(q_west) == math.pi == frames.yaw_from_q(np.array([q_west]))[0]


def test_dispatch_helpers():
    for value in (1, 1.0, np.float16(1), np.float32(1), np.int8(1), np.uint16(1),
                  np.array(1.0), np.array(1, dtype=np.int32)):
        assert dispatch.is_scalar(value)
    for value in (True, '1', None, np.array([1.0]), [1.0], (1.0,), np.array('a'),
                  np.array(1 + 0j), np.complex128(1)):
        assert not dispatch.is_scalar(value)
    assert dispatch.is_point((1, 2.0, np.float32(3)), 3)
    assert dispatch.is_point(np.zeros(3), 3) and not dispatch.is_point(np.zeros((1, 3)), 3)
    assert not dispatch.is_point((1.0, 2.0), 3) and not dispatch.is_point('abc', 3)
    assert dispatch.to_output(np.array(2.0), True) == 2.0
    assert dispatch.to_output(np.array([1.0, 2.0]), True) == (1.0, 2.0)
    assert isinstance(dispatch.to_output(np.array([1.0, 2.0]), False), np.ndarray)


def test_swap_kernel_is_the_array_body():
    q = np.array([[0.8, 0.2, -0.3, 0.4], [-0.1, 0.7, 0.5, -0.2]])
    for row, swapped in zip(q, frames.q_nb_to_ros_wxyz(q)):
        assert frames.swap_attitude4(*row.tolist()) == tuple(swapped.tolist())
        assert frames.swap_attitude4(*frames.swap_attitude4(*row.tolist())) == pytest.approx(
            tuple(row.tolist()), abs=1e-15)


def test_integrator_kernels_are_the_one_point_bodies():
    q, w = QU, V3
    assert quaternion.integrate_exp(q, w, 0.01).tolist() == list(
        quaternion.integrate_exp4(q, w, 0.01))
    assert quaternion.integrate_euler(np.array(q), np.array(w), np.float32(0.5)).tolist() == \
        list(quaternion.integrate_euler4(q, w, 0.5))
    assert quaternion.integrate_exp4(q, (0.0, 0.0, 0.0), 0.01) == quaternion.normalize4(*q)


def test_stamps_round_trip():
    assert frames.stamp_to_ns(1, 5) == 1_000_000_005
    assert frames.ns_to_stamp(1_000_000_005) == (1, 5)
    assert frames.ns_to_stamp(-1) == (-1, 999_999_999)
    for ns in (0, 1, 10**18 + 7, -10**9 - 3):
        assert frames.stamp_to_ns(*frames.ns_to_stamp(ns)) == ns


def test_every_public_core_function_is_covered():
    covered = {s[1] for s in SPECS}
    skip = {'cov_transform', 'cov3_enu_to_ned', 'cov3_flu_to_frd', 'cov6_ned_to_enu',
            'cov6_enu_to_ned', 'cov6_frd_to_flu', 'cov6_flu_to_frd', 'cov6_pose_from_ros',
            'rquat9', 'mul4', 'normalize4', 'half_sinc', 'stamp_to_ns', 'ns_to_stamp',
            'swap_attitude4', 'integrate_euler4', 'integrate_exp4', 'swap_world3', 'flip_body3',
            '_flat_error_table'}
    for module in (rotation, quaternion, geodesy, flow, frames):
        for name in module.__all__:
            obj = getattr(module, name)
            if isinstance(obj, types.FunctionType) and name not in skip:
                assert obj in covered, f'{module.__name__}.{name} has no dispatch case'
