"""
The attitude: taken from the IMU's orientation, predicted from its body rate in between.

Attitude q_nb is taken from the IMU orientation when it is given, and otherwise integrated
from the body rate ω with q̇ = T(q)ω (Fossen eq. 2.50/2.78) by the exact exponential step for
a constant rate or Fossen's Euler step with normalisation. It is not corrected by the fixes;
a constant heading offset is a filter state (:mod:`.estimator`), applied on top.

The attitude covariance is the IMU's (or a default), grown by the rate covariance times Σ dt²
while integrating. Everything here is pure Python on tuples of floats: it runs per IMU
message.
"""

from __future__ import annotations

import math
from typing import Any, Sequence

import numpy as np

from vessel_kinematics.core.frames import yaw_from_q
from vessel_kinematics.core.quaternion import integrate_euler4, integrate_exp4, rquat9
from vessel_kinematics.estimation.config import (DEFAULT_ATTITUDE_SIGMA, DEFAULT_RATE_SIGMA,
                                                 UNKNOWN_ATTITUDE_SIGMA)

__all__ = ['Attitude', 'floats', 'heading_of', 'tilt_of', 'yaw_only']

Quat = tuple[float, float, float, float]

# Shared read-only defaults (the attitude replaces, never mutates, these covariances).
_DEFAULT_ATT_COV = np.eye(3) * DEFAULT_ATTITUDE_SIGMA ** 2
_DEFAULT_RATE_COV = np.eye(3) * DEFAULT_RATE_SIGMA ** 2
_UNKNOWN_ATT_COV = np.eye(3) * UNKNOWN_ATTITUDE_SIGMA ** 2
for _a in (_DEFAULT_ATT_COV, _DEFAULT_RATE_COV, _UNKNOWN_ATT_COV):
    _a.flags.writeable = False


def floats(v: Any) -> tuple[float, ...]:
    """Return a vector (tuple, list or array) as a tuple of floats."""
    if type(v) is tuple:
        return v
    if isinstance(v, np.ndarray):
        return tuple(v.tolist())
    return tuple(float(c) for c in v)


def heading_of(r9: Sequence[float]) -> tuple[float, float]:
    """
    Return (cos ψ, sin ψ) of the heading of R(q) given row-major (Fossen zyx Euler angles).

    R₀₀ = cos ψ cos θ and R₁₀ = sin ψ cos θ; at θ = ±90° (no heading) ψ = 0 is returned.
    """
    c, s = r9[0], r9[3]
    n = math.hypot(c, s)
    if n == 0.0:
        return 1.0, 0.0
    return c / n, s / n


def tilt_of(r9: Sequence[float]) -> tuple[float, ...]:
    """
    Return R_tilt = Rz(ψ)ᵀ R(q) = Ry(θ) Rx(φ) row-major: the attitude without its heading.

    Fossen's zyx convention R = Rz(ψ) Ry(θ) Rx(φ); body vectors rotate into the level
    heading frame (x along the heading, horizontal) by R_tilt.
    """
    c, s = heading_of(r9)
    return (c * r9[0] + s * r9[3], c * r9[1] + s * r9[4], c * r9[2] + s * r9[5],
            -s * r9[0] + c * r9[3], -s * r9[1] + c * r9[4], -s * r9[2] + c * r9[5],
            r9[6], r9[7], r9[8])


def yaw_only(q: Sequence[float]) -> Quat:
    """Return the heading-only quaternion of ``q`` (roll and pitch set to zero)."""
    psi = yaw_from_q(q)                     # the one yaw of q (core.frames)
    return (math.cos(0.5 * psi), 0.0, 0.0, math.sin(0.5 * psi))


class Attitude:
    """
    The IMU attitude q_nb with its covariance, and the body rate with its covariance.

    ``level``: roll and pitch forced to zero (motion ``ground``). ``integrator``:
    ``'exponential'`` or ``'euler'``.
    """

    def __init__(self, *, level: bool, integrator: str) -> None:
        self.level = level
        self.integrator = integrator
        self.set_q((1.0, 0.0, 0.0, 0.0))
        # Rate integration since the base was set: cov_att = base + cov_omega * Σ dt².
        self._base: np.ndarray = _UNKNOWN_ATT_COV
        self._dt2 = 0.0
        self.omega: tuple[float, float, float] | None = None
        self.cov_omega: np.ndarray = _DEFAULT_RATE_COV
        self.omega_from_imu = False
        #: The rate was derived from successive headings (a compass without a rate).
        self.derived = False
        self.last_attitude_ns: int | None = None
        self.last_rate_ns: int | None = None
        self.known = False

    def set_q(self, q: Sequence[float]) -> None:
        """Set q_nb (a unit quaternion, scalar first), its rotation matrix and heading."""
        self.q: Quat = floats(q)  # type: ignore[assignment]
        self.r9: tuple[float, ...] = rquat9(*self.q)
        #: (cos ψ, sin ψ) of R(q) (:func:`heading_of`), for the deferred time update.
        self.cs: tuple[float, float] = heading_of(self.r9)

    @property
    def cov(self) -> np.ndarray:
        """Return the attitude covariance (rad², small rotations about the BODY axes)."""
        if self._dt2 == 0.0:
            return self._base
        return self._base + self.cov_omega * self._dt2

    def measured(self, q: Sequence[float], cov: np.ndarray | None, stamp_ns: int) -> None:
        """Take a measured attitude with its covariance (None or all zero: the default)."""
        q = yaw_only(q) if self.level else q
        if q is not self.q:  # the time update to the message's stamp set this very q already
            self.set_q(q)
        self.last_attitude_ns = stamp_ns
        self._base = _DEFAULT_ATT_COV if cov is None else cov
        self._dt2 = 0.0
        self.known = True

    def assume(self, q: Sequence[float], yaw_variance: float) -> None:
        """
        Take an attitude no IMU measured (a heading from the course) with its heading variance.

        The covariance keeps its roll and pitch and takes ``yaw_variance`` (rad²) on the
        heading; the time of the last measured attitude is not moved: the compass stays silent.
        """
        self.set_q(q)
        cov = np.array(self.cov, dtype=float)
        cov[2, :] = 0.0
        cov[:, 2] = 0.0
        cov[2, 2] = yaw_variance
        self._base, self._dt2 = cov, 0.0

    def rate(self, stamp_ns: int, omega: Sequence[float], cov: np.ndarray | None) -> None:
        """Take a measured body rate ω (rad/s, FRD) and its covariance (None: the default)."""
        w = floats(omega)
        self.omega = (0.0, 0.0, w[2]) if self.level else (w[0], w[1], w[2])
        cov_omega = _DEFAULT_RATE_COV if cov is None else cov
        if cov_omega is not self.cov_omega:
            if self._dt2 != 0.0:                 # fold the integration so far in
                self._base, self._dt2 = self.cov, 0.0
            self.cov_omega = cov_omega
        self.last_rate_ns = stamp_ns if self.last_rate_ns is None else max(
            self.last_rate_ns, stamp_ns)

    def rates_fresh(self, t_ns: int, max_gap: float) -> bool:
        """Return True when a body rate no older than ``max_gap`` (s) is known."""
        return (self.omega is not None and self.last_rate_ns is not None
                and (t_ns - self.last_rate_ns) * 1e-9 <= max_gap)

    def integrate(self, dt: float) -> Quat:
        """
        Return q after ``dt`` s at the current body rate (q̇ = T(q)ω), and grow the covariance.

        Exponential: q ⊗ [cos(|ω|dt/2), sin(|ω|dt/2) ω/|ω|], exact for a constant rate;
        Euler: q + T(q)ω dt, normalised (Fossen eq. 2.84-2.85).
        """
        step = integrate_euler4 if self.integrator == 'euler' else integrate_exp4
        q1 = step(self.q, self.omega, dt)
        if self.level:
            q1 = yaw_only(q1)
        self._dt2 += dt * dt
        return q1

    def grow(self, dt: float) -> None:
        """Grow the covariance as integrating over ``dt`` would (a gap bridged unintegrated)."""
        self._dt2 += dt * dt
