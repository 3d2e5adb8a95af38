"""
Benchmark the attitude integrators and the scalar rotation paths; prints, asserts nothing.

1. integrate_exp at a constant 1 rad/s about a fixed, non-axis-aligned BODY axis for one hour
   at 100 Hz (360 000 steps) against the closed form q(t) = q0 (x) exp(omega t / 2): the
   largest attitude error (rad) and the largest | |q| - 1 |. Issue 2's targets: <= 1e-11 rad
   and <= 1e-15. Fossen's Euler step q + h T(q) omega with normalisation on the same run, for
   contrast.
2. Per-call time of one-point calls against scipy's Rotation for one point (since issue 9 these
   functions have one numpy body; see vessel_kinematics.core.dispatch).
3. The per-message kernels kept beside the numpy bodies (quaternion mul4/normalize4/rquat9,
   frames swap_attitude4/yaw_from_q, flow ssa/course/sideslip/angle_of_attack): one call of
   the kernel (or of the function's scalar body) against the numpy body on a one-element
   batch, which is what the call would cost without it. ``--kernels`` runs only this part.

Run from the repository root: ``python bench/bench_quaternion.py``.
"""

from __future__ import annotations

import math
from pathlib import Path
import sys
import timeit

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from vessel_kinematics.core import flow as fl  # noqa: E402, I100
from vessel_kinematics.core import frames as fr  # noqa: E402
from vessel_kinematics.core import quaternion as qu  # noqa: E402
from vessel_kinematics.core import rotation as ro  # noqa: E402


RATE_HZ = 100.0
DURATION_S = 3600.0
AXIS = np.array([1.0, 2.0, 3.0]) / math.sqrt(14.0)
OMEGA = 1.0 * AXIS  # rad/s, |omega| = 1 (to round-off)
Q0 = qu.euler2q(0.3, -0.2, 1.1)


def closed_form(steps: np.ndarray, h: float) -> np.ndarray:
    """Return q0 (x) [cos(|w| t/2), sin(|w| t/2) w/|w|] at t = k h, in extended precision."""
    w = OMEGA.astype(np.longdouble)
    norm = np.sqrt(np.sum(w * w))
    half = steps.astype(np.longdouble) * np.longdouble(h) * norm / 2
    dq = np.concatenate([np.cos(half)[:, None], (np.sin(half) / norm)[:, None] * w[None, :]],
                        axis=1)
    return qu.quat_multiply(Q0, dq.astype(float))


def attitude_error(q: np.ndarray, q_ref: np.ndarray) -> np.ndarray:
    """Return the rotation angle (rad) of q_ref^* (x) q, for q and q_ref (..., 4)."""
    d = qu.quat_multiply(qu.quat_conjugate(q_ref), q)
    return 2.0 * np.arctan2(np.linalg.norm(d[:, 1:], axis=1), np.abs(d[:, 0]))


def run(step, h: float, n: int) -> np.ndarray:
    """Return the n + 1 attitudes from Q0 by ``step(q, OMEGA, h)``."""
    out = np.empty((n + 1, 4))
    out[0] = Q0
    q = Q0
    for k in range(1, n + 1):
        q = step(q, OMEGA, h)
        out[k] = q
    return out


def bench_integrators() -> None:
    """Print the one-hour integration errors of integrate_exp and of Fossen's Euler step."""
    h = 1.0 / RATE_HZ
    n = int(round(DURATION_S * RATE_HZ))
    ref = closed_form(np.arange(n + 1), h)
    print(f'constant |omega| = 1 rad/s about {np.round(AXIS, 4).tolist()}, h = {h} s, '
          f'{n} steps ({DURATION_S:.0f} s)')
    for name, step in (('integrate_exp', qu.integrate_exp),
                       ('integrate_euler (Fossen)', qu.integrate_euler)):
        t0 = timeit.default_timer()
        qs = run(step, h, n)
        elapsed = timeit.default_timer() - t0
        err = attitude_error(qs, ref)
        norm_err = np.abs(np.linalg.norm(qs, axis=1) - 1.0)
        print(f'  {name:26s} max angle error {err.max():.3e} rad (at end {err[-1]:.3e}), '
              f'max | |q|-1 | {norm_err.max():.3e}, {1e6 * elapsed / n:.2f} us/step')
    print('  targets (issue 2): integrate_exp <= 1e-11 rad and <= 1e-15')


def per_call(stmt, number: int = 5000) -> float:
    """Return the best per-call time (us) of ``stmt`` over five repeats."""
    return 1e6 * min(timeit.repeat(stmt, number=number, repeat=5)) / number


def bench_scalar_paths() -> None:
    """Print per-call times of the scalar paths and of scipy's Rotation for one point."""
    from scipy.spatial.transform import Rotation

    phi, theta, psi = 0.1, 0.2, 0.3
    q = qu.euler2q(phi, theta, psi)
    q_xyzw = q[[1, 2, 3, 0]]
    r = ro.rzyx(phi, theta, psi)
    v = np.array([1.0, -2.0, 0.5])
    w = np.array([0.01, -0.02, 0.03])
    rot = Rotation.from_quat(q_xyzw)
    cases = [
        ('rzyx', lambda: ro.rzyx(phi, theta, psi),
         lambda: Rotation.from_euler('ZYX', [psi, theta, phi]).as_matrix()),
        ('euler2q', lambda: qu.euler2q(phi, theta, psi),
         lambda: Rotation.from_euler('ZYX', [psi, theta, phi]).as_quat()),
        ('rquat', lambda: qu.rquat(q), lambda: Rotation.from_quat(q_xyzw).as_matrix()),
        ('rot2q', lambda: qu.rot2q(r), lambda: Rotation.from_matrix(r).as_quat()),
        ('q2euler', lambda: qu.q2euler(q),
         lambda: Rotation.from_quat(q_xyzw).as_euler('ZYX')),
        ('rot2euler', lambda: ro.rot2euler(r),
         lambda: Rotation.from_matrix(r).as_euler('ZYX')),
        ('quat_multiply', lambda: qu.quat_multiply(q, q), lambda: (rot * rot).as_quat()),
        ('quat_rotate', lambda: qu.quat_rotate(q, v), lambda: rot.apply(v)),
        ('integrate_exp', lambda: qu.integrate_exp(q, w, 0.01),
         lambda: (rot * Rotation.from_rotvec(0.01 * w)).as_quat()),
        ('rotation_axis_angle', lambda: ro.rotation_axis_angle(v, 0.4),
         lambda: Rotation.from_rotvec(0.4 * v / np.linalg.norm(v)).as_matrix()),
    ]
    print('one-point per-call time (one numpy body), vessel_kinematics vs scipy Rotation:')
    for name, ours, theirs in cases:
        t_ours, t_scipy = per_call(ours), per_call(theirs)
        print(f'  {name:20s} {t_ours:7.2f} us   scipy {t_scipy:7.2f} us   '
              f'ratio scipy/ours {t_scipy / t_ours:5.1f}x')


def bench_kernels() -> None:
    """Print per-call times of the per-message kernels against the numpy body (batch of 1)."""
    q = tuple(qu.euler2q(0.1, 0.2, 0.3).tolist())
    q1 = np.array([q])
    v = (1.0, -2.0, 0.5)
    v1 = np.array([v])
    a1 = np.array([4.0])
    cases = [
        ('quaternion.mul4 / quat_multiply', lambda: qu.mul4(q, q),
         lambda: qu.quat_multiply(q1, q1)),
        ('quaternion.normalize4 / normalize', lambda: qu.normalize4(*q),
         lambda: qu.normalize(q1)),
        ('quaternion.rquat9 / rquat', lambda: qu.rquat9(*q), lambda: qu.rquat(q1)),
        ('quaternion.integrate_exp4 / integrate_exp', lambda: qu.integrate_exp4(q, v, 0.01),
         lambda: qu.integrate_exp(q1, v1, 0.01)),
        ('frames.swap_attitude4 / q_nb_to_ros_wxyz', lambda: fr.swap_attitude4(*q),
         lambda: fr.q_nb_to_ros_wxyz(q1)),
        ('frames.yaw_from_q', lambda: fr.yaw_from_q(q), lambda: fr.yaw_from_q(q1)),
        ('flow.ssa', lambda: fl.ssa(4.0), lambda: fl.ssa(a1)),
        ('flow.course', lambda: fl.course(v, 0.3), lambda: fl.course(v1, 0.3)),
        ('flow.sideslip', lambda: fl.sideslip(v), lambda: fl.sideslip(v1)),
        ('flow.angle_of_attack', lambda: fl.angle_of_attack(v), lambda: fl.angle_of_attack(v1)),
    ]
    print('per-message kernels: scalar body vs the numpy body on a batch of one (us per call):')
    for name, kernel, numpy_body in cases:
        t_kernel, t_numpy = per_call(kernel), per_call(numpy_body)
        print(f'  {name:42s} {t_kernel:6.2f} us   numpy {t_numpy:6.2f} us   '
              f'{t_numpy / t_kernel:5.1f}x')


if __name__ == '__main__':
    if sys.argv[1:] != ['--kernels']:
        bench_integrators()
        bench_scalar_paths()
    bench_kernels()
