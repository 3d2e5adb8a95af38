"""
The navigation state and its updates: pure Python and numpy, no ROS.

Measurements come in as small frozen records in Fossen's frames (NED world, BODY x forward,
y starboard, z down, scalar-first quaternions q_nb rotating BODY to NED, radians, metres,
seconds, stamps in integer nanoseconds); ``ros_io`` makes them from messages and turns the
:class:`NavState` back into messages.

The filter
----------
Attitude q_nb is taken from the IMU orientation when it is given, and otherwise integrated
from the body rate ω with q̇ = T(q)ω (Fossen eq. 2.50) by ``integrate_exp`` (exact for a
constant rate) or ``integrate_euler`` (Fossen's step + normalisation); between two IMU
orientations it is predicted from the rate too. It is not corrected by the fixes.

Position and velocity are a small linear Kalman filter whose transition depends on the known
attitude (a linear time-varying system)::

    x = [p_N, p_E, p_D, u, v, w]                (velocity.reference = ground, or no velocity)
    x = [p_N, p_E, p_D, u_r, v_r, w_r, c_N, c_E]  (velocity.reference = water)

p is the NED position of the base frame about the origin (m).

Ground reference: ν = [u, v, w] is the body velocity over ground (m/s, Fossen's ν₁), a random
walk in BODY driven by white body acceleration of density :data:`ACCEL_SIGMA`; between two
stamps ṗ = R(q)ν (Fossen eq. 2.18) with R averaged over the step (trapezoid).

Water reference (a speed log, a DVL water track): the state holds the velocity RELATIVE TO
THE WATER ν_r = ν − ν_c (Fossen ch. 2.4, eq. 2.108; ν_c = R(q)ᵀ[c_N, c_E, 0] the current in
BODY), which the hull's smooth dynamics make a random walk in BODY (density
:data:`ACCEL_SIGMA`), and the horizontal ocean current c in NED, a random walk in NED of
density :data:`CURRENT_SIGMA` (m/s per √s) that does not turn with the vessel. Then::

    ṗ = R(q) ν_r + [c_N, c_E, 0]ᵀ

The speed log measures ν_r directly, so it says nothing about c: the current is observable
only through the fixes, and while dead reckoning the position covariance grows with the
current's uncertainty (about σ_c·t), as the real error does. (With ν over ground in the state
and z = ν − Rᵀc instead, the random walk on ν in BODY makes every turn look like information
about c, and a dead-reckoning-only run claims a position σ several times smaller than its
real error.) The outputs keep their meaning: the body velocity over ground
ν = ν_r + R(q)ᵀ[c_N, c_E, 0] (the twist, with its covariance through the same sum), the
course from the velocity over ground R(q)ν_r + c, and ``current`` the estimate of c.

For both references the attitude error (given by the IMU's orientation covariance, or grown
by integrating rates) adds its share R S(ν) P_Θ S(ν)ᵀ Rᵀ · 2τ to the position process noise
(:meth:`Estimator._attitude_density`, ν the velocity that R rotates: over ground, or ν_r), so
a confident body velocity under an uncertain heading no longer gives an over-confident
position. Measurements:

- a body velocity (``velocity``): z = ν over ground (``ground``) or z = ν_r through water
  (``water``); components whose variance is at least :data:`UNMEASURED_VARIANCE` (e.g. a
  speed log's 1e6 on sway) are left out;
- a GNSS fix: z = p_antenna − R(q) r_b = p, r_b the antenna lever arm in BODY, with the fix's
  covariance plus the lever arm's share of the attitude covariance; a fix without height (or
  ``two_d``) updates the horizontal position only.

With no velocity input at all the same model gives speed and course from the fixes alone.
The local (``odom``) position integrates the same ṗ (with the current estimate in use, for
water) and is never corrected, so it never jumps; its covariance only grows. It is kept as a
consider (Schmidt-Kalman) state: with its cross-covariance to the filter state, so a
velocity or current error, constant over many steps, grows the local covariance as the error
it makes (∝ t, not √t), and a fix leaves the local covariance as it is while the filter
state's errors and the local's stop being treated as independent.

Time
----
A message newer than the state propagates it to the message's stamp (no integration across a
gap longer than ``max_gap``: time advances and the covariance is inflated instead). A message
older by at most ``reorder_window`` is used at the state's time without integrating backwards
(a fix is compared against the position predicted back to its stamp, p − ṗ·Δt); older by
up to ``max_gap`` it is rejected as ``stale_stamp``; further back (a bag looped) the state is
re-initialised, keeping the origin.

Deferred covariance propagation
-------------------------------
An IMU message only advances the attitude (pure Python on four floats) and accumulates
A = Σ R_mean dt over the steps; the position, the local position and the covariances are
propagated in one step when a velocity or fix update needs them, when the deferred interval
reaches :data:`LAZY_INTERVAL`, or (on copies) when the outputs are built. Since ν (and c) is
constant between updates the mean position is the same as stepping each message
(x ← x + A ν + Δt c, exact), and F = [[I, A, B], [0, I, 0], [0, 0, I]] (B = Δt on the
horizontal rows, water only) is the exact product of the per-message transitions; the process
noise is that of the continuous model over the whole interval with the mean rotation
R̄ = A/Δt, so the covariances differ from per-message propagation only by the variation of
R within the interval (a discretisation difference, ~|ω| Δt). The local covariance then
holds the velocity error over the interval rather than renewing it each message (it is
correlated in fact). Building outputs never changes the filter: the result does not depend on
``publish_rate`` or on when a driver calls :meth:`Estimator.state`.
"""

from __future__ import annotations

from dataclasses import dataclass
import math
from typing import Any, Sequence

import numpy as np

from vessel_kinematics import flow, geodesy
from vessel_kinematics.params import NavigatorParams
from vessel_kinematics.quaternion import _half_sinc, _mul4, _normalize4

#: Mode before the origin and the first position are known.
WAITING = 'waiting_for_origin'
#: Mode with a position but no fix used within :data:`FUSED_TIMEOUT` s (or GNSS disabled).
DEAD_RECKONING = 'dead_reckoning'
#: Mode with a fix used within :data:`FUSED_TIMEOUT` s.
FUSED = 'fused'

#: White body-acceleration density driving the velocity random walk (m/s² per √Hz).
ACCEL_SIGMA = 0.1
#: Correlation time τ of the attitude error (s), a first-order Gauss-Markov process: the
#: attitude's share of the position process noise is 2τ R S(ν) P_Θ S(ν)ᵀ Rᵀ per second.
#: An AHRS heading error (magnetic disturbance, declination, mounting) lasts seconds to
#: minutes; 5 s keeps the real Husky bag's estimate on its fixes (its magnetic heading is ~10
#: deg off) while costing the simulated voyage's white heading noise < 1 % of position RMS.
ATTITUDE_CORRELATION_TIME = 5.0
#: Attitude variance (rad²) above which the attitude share saturates (small-angle limit).
ATTITUDE_SHARE_MAX_VARIANCE = 1.0
#: Random-walk density of the ocean current (m/s per √s).
CURRENT_SIGMA = 0.005
#: Standard deviation of the velocity before any measurement (m/s).
INITIAL_VELOCITY_SIGMA = 3.0
#: Standard deviation of the current before any measurement (m/s).
INITIAL_CURRENT_SIGMA = 1.0
#: Attitude standard deviation (rad, each axis) when the IMU gives an unknown (zero) covariance.
DEFAULT_ATTITUDE_SIGMA = 0.02
#: Body-rate standard deviation (rad/s) when the IMU gives an unknown (zero) covariance.
DEFAULT_RATE_SIGMA = 0.01
#: Attitude standard deviation (rad) while nothing has told the attitude yet.
UNKNOWN_ATTITUDE_SIGMA = math.pi
#: A velocity component with a variance at least this ((m/s)²) is treated as unmeasured.
UNMEASURED_VARIANCE = 1e4
#: A fix older than this (s) no longer counts as fused.
FUSED_TIMEOUT = 3.0
#: Longest interval (s) over which the covariance propagation is deferred (see the module notes).
LAZY_INTERVAL = 0.1
#: Consecutive fixes refused by the innovation gate after which the position is re-initialised.
GATE_RESET_COUNT = 10

_TINY_VARIANCE = 1e-12
# Shared read-only defaults (the state replaces, never mutates, these covariances).
_DEFAULT_ATT_COV = np.eye(3) * DEFAULT_ATTITUDE_SIGMA ** 2
_DEFAULT_RATE_COV = np.eye(3) * DEFAULT_RATE_SIGMA ** 2
_DEFAULT_ATT_COV.flags.writeable = False
_DEFAULT_RATE_COV.flags.writeable = False


@dataclass(frozen=True, eq=False)
class GnssFix:
    """
    A GNSS fix of the antenna.

    ``lat``, ``lon`` in rad, ``height`` ellipsoidal in m (NaN: a horizontal-only fix),
    ``cov_ned`` the 3x3 position covariance in NED (m²).
    """

    stamp_ns: int
    lat: float
    lon: float
    height: float
    cov_ned: np.ndarray


@dataclass(frozen=True, eq=False)
class ImuSample:
    """
    An attitude and/or body rate of the base frame, already corrected for the IMU mounting.

    ``q_nb`` the unit quaternion BODY (FRD) to NED, scalar first (a tuple of floats from
    ``ros_io``, or any sequence or array), or None; ``att_cov`` its
    3x3 covariance (rad², small rotations about the BODY axes, i.e. of φ, θ, ψ near level,
    the order of an Odometry pose covariance) or None; ``omega_b`` the body
    rate [p, q, r] in FRD (rad/s, a tuple or array) or None, ``omega_cov`` its 3x3
    covariance ((rad/s)²).
    """

    stamp_ns: int
    q_nb: Sequence[float] | None
    att_cov: np.ndarray | None
    omega_b: Sequence[float] | None
    omega_cov: np.ndarray | None


@dataclass(frozen=True, eq=False)
class BodyVelocity:
    """
    A body velocity ν = [u, v, w] (m/s, FRD) of the base frame with its 3x3 covariance.

    Over ground or through water per ``velocity.reference``; ``omega_b`` an optional body rate
    (rad/s, FRD, e.g. a wheel odometry's yaw rate) used when the IMU gives none.
    """

    stamp_ns: int
    nu_b: np.ndarray
    cov: np.ndarray
    omega_b: np.ndarray | None = None
    omega_cov: np.ndarray | None = None


@dataclass(frozen=True)
class Rejection:
    """A refused measurement: a snake_case ``reason`` (counted) and a human ``detail``."""

    reason: str
    detail: str


@dataclass
class NavState:
    """
    The navigation state at ``stamp_ns``, in Fossen's frames, for building the outputs.

    ``p`` NED position of the base about the origin (m); ``q`` q_nb; ``nu`` body velocity
    over ground (m/s, FRD); ``omega`` body rate (rad/s, FRD, zero when unknown); ``v_n`` the
    velocity over ground in NED; ``current`` the NED current (m/s, water reference) or None;
    ``p_local`` the dead-reckoned position in the odom frame (NED axes, m); ``llh`` the base's
    latitude, longitude (rad) and ellipsoidal height (m); ``course`` χ, ``sideslip`` β and
    ``angle_of_attack`` α (rad); covariances 3x3 in the same frames; ``origin`` (rad, rad, m).
    """

    stamp_ns: int
    mode: str
    origin: tuple[float, float, float]
    p: np.ndarray
    q: np.ndarray
    nu: np.ndarray
    omega: np.ndarray
    v_n: np.ndarray
    current: np.ndarray | None
    p_local: np.ndarray
    llh: tuple[float, float, float]
    course: float
    sideslip: float
    angle_of_attack: float
    cov_p: np.ndarray
    cov_att: np.ndarray
    cov_nu: np.ndarray
    cov_omega: np.ndarray
    cov_current: np.ndarray | None
    cov_p_local: np.ndarray


def _flu_to_frd(v: tuple[float, float, float]) -> np.ndarray:
    return np.array([v[0], -v[1], -v[2]], dtype=float)


def _wrap_lon_deg(lon: float) -> float:
    """Return a longitude in degrees in [-180, 180] (params allow up to 360)."""
    return lon - 360.0 if lon > 180.0 else lon


def _yaw_only(q: Sequence[float]) -> tuple[float, float, float, float]:
    """Return the heading-only quaternion of ``q`` (roll and pitch set to zero)."""
    w, x, y, z = q
    psi = math.atan2(2.0 * (x * y + z * w), 1.0 - 2.0 * (y * y + z * z))
    return (math.cos(0.5 * psi), 0.0, 0.0, math.sin(0.5 * psi))


def _rquat9(q: Sequence[float]) -> tuple[float, ...]:
    """Return R(q) (Fossen eq. 2.72) row-major as nine floats: the scalar path of rquat."""
    w, x, y, z = q
    return (1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y - z * w), 2.0 * (x * z + y * w),
            2.0 * (x * y + z * w), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z - x * w),
            2.0 * (x * z - y * w), 2.0 * (y * z + x * w), 1.0 - 2.0 * (x * x + y * y))


def _floats(v: Any) -> tuple[float, ...]:
    """Return a vector (tuple, list or array) as a tuple of numbers (floats from an array)."""
    if type(v) is tuple:
        return v
    if isinstance(v, np.ndarray):
        return tuple(v.tolist())
    return tuple(float(c) for c in v)


def _skew(a: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])


def _finite(*arrays: Any) -> bool:
    """Return True when no array holds a NaN or an infinity (a sum is non-finite then)."""
    for a in arrays:
        if a is None:
            continue
        if isinstance(a, tuple):
            if not math.isfinite(sum(a)):
                return False
        elif not math.isfinite(sum(np.ravel(a).tolist())):
            return False
    return True


def _inverse_small(s: np.ndarray) -> np.ndarray | None:
    """
    Return the inverse of a 1x1..3x3 innovation covariance (cofactors), or None if singular.

    numpy's inv costs more in argument checks than the arithmetic for these sizes; larger
    matrices go to it.
    """
    n = s.shape[0]
    if n == 3:
        (a, b, c), (d, e, f), (g, h, i) = s.tolist()
        c00, c01, c02 = e * i - f * h, f * g - d * i, d * h - e * g
        det = a * c00 + b * c01 + c * c02
        if det == 0.0 or not math.isfinite(det):
            return None
        k = 1.0 / det
        return np.array([[c00 * k, (c * h - b * i) * k, (b * f - c * e) * k],
                         [c01 * k, (a * i - c * g) * k, (c * d - a * f) * k],
                         [c02 * k, (b * g - a * h) * k, (a * e - b * d) * k]])
    if n == 2:
        (a, b), (c, d) = s.tolist()
        det = a * d - b * c
        if det == 0.0 or not math.isfinite(det):
            return None
        k = 1.0 / det
        return np.array([[d * k, -b * k], [-c * k, a * k]])
    if n == 1:
        v = float(s[0, 0])
        return None if v == 0.0 or not math.isfinite(v) else np.array([[1.0 / v]])
    try:
        return np.linalg.inv(s)
    except np.linalg.LinAlgError:
        return None


class _CheckedCovariances:
    """
    Remember read-only covariance arrays already found finite (and whether all zero).

    ``ros_io`` hands out one shared read-only array per distinct covariance a driver sends, so
    the per-message checks reduce to an identity test. Writable arrays are always checked.
    """

    def __init__(self) -> None:
        self._known: list[tuple[np.ndarray, bool]] = []

    def check(self, cov: Any) -> bool | None:
        """Return None when not finite, else whether any entry is non-zero."""
        for known, nonzero in self._known:
            if known is cov:
                return nonzero
        if not _finite(cov):
            return None
        nonzero = bool(np.any(cov))
        if isinstance(cov, np.ndarray) and not cov.flags.writeable:
            if len(self._known) >= 8:
                self._known.pop(0)
            self._known.append((cov, nonzero))
        return nonzero


class Estimator:
    """The navigator's state and its time and measurement updates (see the module docstring)."""

    def __init__(self, params: NavigatorParams) -> None:
        self.params = params
        self.origin: tuple[float, float, float] | None = None
        self.resets = 0
        self._origin_event = False
        self._set_origin_from_params(params)
        self._init_state()

    # ------------------------------------------------------------------ state set-up

    @property
    def water(self) -> bool:
        """Return True for a through-water velocity input (the current is then estimated)."""
        return self.params.velocity_reference == 'water'

    def _init_state(self) -> None:
        """(Re-)initialise everything but the origin."""
        n = 8 if self.water else 6
        self.t: int | None = None
        self.x = np.zeros(n)
        self.P = np.zeros((n, n))
        self.P[3:6, 3:6] = np.eye(3) * INITIAL_VELOCITY_SIGMA ** 2
        if self.water:
            self.P[6:8, 6:8] = np.eye(2) * INITIAL_CURRENT_SIGMA ** 2
        self.position_ok = False
        self.q = (1.0, 0.0, 0.0, 0.0)   # also sets self._rot9 = R(q)
        # Deferred time update (see _propagate): elapsed s and the sum of R_mean dt, row-major.
        self._pending_dt = 0.0
        self._pending_a = (0.0,) * 9
        # Rate integration since cov_att was set: cov_att + cov_omega * sum(dt^2).
        self._att_base = np.eye(3) * UNKNOWN_ATTITUDE_SIGMA ** 2
        self._att_dt2 = 0.0
        self.omega: tuple[float, float, float] | None = None
        self.cov_omega = np.eye(3) * DEFAULT_RATE_SIGMA ** 2
        self.omega_from_imu = False
        self._checked = _CheckedCovariances()
        self._density_cache: tuple | None = None
        self.p_local = np.zeros(3)
        self.cov_p_local = np.zeros((3, 3))
        # Cov(local position error, filter state error), 3 x n (see the module notes).
        self._cross = np.zeros((3, n))
        self.last_fix_ns: int | None = None
        self.last_imu_ns: int | None = None
        self.last_velocity_ns: int | None = None
        self.last_attitude_ns: int | None = None
        self.last_rate_ns: int | None = None
        self._gate_rejections = 0
        if self.origin is not None and not self.params.gnss_enabled:
            self._init_position(np.zeros(3), np.zeros((3, 3)))

    def _init_position(self, p: np.ndarray, cov: np.ndarray) -> None:
        self.x[0:3] = p
        self.P[0:3, :] = 0.0
        self.P[:, 0:3] = 0.0
        self.P[0:3, 0:3] = cov
        self._cross[:, 0:3] = 0.0       # a new position: its error independent of the local
        self.position_ok = True
        self._gate_rejections = 0
        self._two_d()

    def _set_origin_from_params(self, params: NavigatorParams) -> bool:
        """Take a complete origin from the parameters; return True when it changed."""
        lat, lon, h = params.origin
        if math.isnan(lat) or math.isnan(h):
            return False
        origin = (math.radians(lat), math.radians(_wrap_lon_deg(lon)), float(h))
        if origin == self.origin:
            return False
        self.origin = origin
        self._origin_event = True
        return True

    @property
    def q(self) -> np.ndarray:
        """Return the attitude q_nb (unit, scalar first)."""
        return np.array(self._q4)

    @q.setter
    def q(self, value: Sequence[float]) -> None:
        self._q4 = _floats(value)
        self._rot9 = _rquat9(self._q4)

    @property
    def _rot(self) -> np.ndarray:
        """Return R(q) as a 3x3 array."""
        return np.array(self._rot9).reshape(3, 3)

    @property
    def cov_att(self) -> np.ndarray:
        """Return the attitude covariance (rad², small rotations about the BODY axes)."""
        if self._att_dt2 == 0.0:
            return self._att_base
        return self._att_base + self.cov_omega * self._att_dt2

    @cov_att.setter
    def cov_att(self, value: np.ndarray) -> None:
        self._att_base = value
        self._att_dt2 = 0.0

    # ------------------------------------------------------------------ projection

    def to_ned(self, lat: float, lon: float, h: float) -> np.ndarray:
        """Return the NED position (m) of a latitude, longitude (rad) and height (m)."""
        lat0, lon0, h0 = self.origin
        if self.params.projection == 'flat':
            return np.array(geodesy.llh2flat(lat, lon, h, lat0, lon0, h0), dtype=float)
        return np.array(geodesy.llh2ned(lat, lon, h, lat0, lon0, h0), dtype=float)

    def to_llh(self, p: np.ndarray) -> tuple[float, float, float]:
        """Return latitude, longitude (rad) and height (m) of a NED position about the origin."""
        lat0, lon0, h0 = self.origin
        ned = (float(p[0]), float(p[1]), float(p[2]))
        if self.params.projection == 'flat':
            lat, lon, h = geodesy.flat2llh(ned, lat0, lon0, h0)
        else:
            lat, lon, h = geodesy.ned2llh(ned, lat0, lon0, h0)
        return float(lat), float(lon), float(h)

    # ------------------------------------------------------------------ public queries

    @property
    def mode(self) -> str:
        """Return the mode: waiting_for_origin, dead_reckoning or fused."""
        if self.origin is None or not self.position_ok:
            return WAITING
        if (self.params.gnss_enabled and self.last_fix_ns is not None and self.t is not None
                and (self.t - self.last_fix_ns) * 1e-9 <= FUSED_TIMEOUT):
            return FUSED
        return DEAD_RECKONING

    @property
    def ready(self) -> bool:
        """Return True when there is a state to publish (origin and position known)."""
        return self.origin is not None and self.position_ok and self.t is not None

    def pop_origin_event(self) -> bool:
        """Return True once after the origin has been set or changed."""
        event, self._origin_event = self._origin_event, False
        return event

    def velocity_ned(self) -> np.ndarray:
        """Return the velocity over ground in NED (m/s): R(q)ν, or R(q)ν_r + c through water."""
        v_n = self._rot @ self.x[3:6]
        if self.water:
            v_n[0:2] += self.x[6:8]
        return v_n

    def _over_ground(self, x: np.ndarray, pm: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """
        Return the body velocity over ground and its covariance from a state and covariance.

        Ground reference: ν and P_νν as they are. Water: ν = ν_r + R(q)ᵀ[c_N, c_E, 0] (Fossen
        eq. 2.108), covariance J P Jᵀ with J = [I, R(q)ᵀ[:, 0:2]] over the [ν_r, c] block.
        """
        if not self.water:
            return x[3:6], pm[3:6, 3:6]
        r = self._rot9
        j = np.array([[1.0, 0.0, 0.0, r[0], r[3]],
                      [0.0, 1.0, 0.0, r[1], r[4]],
                      [0.0, 0.0, 1.0, r[2], r[5]]])
        return j @ x[3:8], j @ pm[3:8, 3:8] @ j.T

    def state(self) -> NavState:
        """
        Return the current state for the outputs (call only when :attr:`ready`).

        A deferred time update is applied to copies: building outputs never changes the
        filter, so its result does not depend on when (or whether) outputs are built.
        """
        if self._pending_dt > 0.0:
            x, pm, p_local, cov_p_local, _ = self._pending_applied()
        else:
            x, pm = self.x.copy(), self.P.copy()
            p_local, cov_p_local = self.p_local.copy(), self.cov_p_local.copy()
        r = self._rot9
        nu, cov_nu = self._over_ground(x, pm)
        u, v, w = nu_t = tuple(nu.tolist())
        v_n = (r[0] * u + r[1] * v + r[2] * w, r[3] * u + r[4] * v + r[5] * w,
               r[6] * u + r[7] * v + r[8] * w)
        course = float(flow.course(v_n, math.atan2(r[3], r[0])))
        sideslip = float(flow.sideslip(nu_t))
        alpha = float(flow.angle_of_attack(nu_t))
        current = cov_current = None
        if self.water:
            current = np.array([x[6], x[7], 0.0])
            cov_current = np.zeros((3, 3))
            cov_current[0:2, 0:2] = pm[6:8, 6:8]
        omega = np.zeros(3) if self.omega is None else np.array(self.omega)
        p = x[0:3]
        return NavState(
            stamp_ns=self.t, mode=self.mode, origin=self.origin, p=p, q=np.array(self._q4),
            nu=nu, omega=omega, v_n=np.array(v_n), current=current, p_local=p_local,
            llh=self.to_llh(p), course=course, sideslip=sideslip, angle_of_attack=alpha,
            cov_p=pm[0:3, 0:3], cov_att=np.array(self.cov_att), cov_nu=cov_nu,
            cov_omega=np.array(self.cov_omega), cov_current=cov_current,
            cov_p_local=cov_p_local)

    # ------------------------------------------------------------------ time update

    def _time(self, stamp_ns: int, q_end: np.ndarray | None = None) -> float | Rejection:
        """
        Bring the state to ``stamp_ns``; return how late the message is (s) or a rejection.

        0.0 for a message at or after the state's time (now propagated to it); the lateness
        in (0, reorder_window] for a message to use at the state's time; a reset for one more
        than ``max_gap`` back.
        """
        if stamp_ns <= 0:
            return Rejection('zero_stamp', 'header stamp is zero: the driver does not stamp')
        if self.t is None:
            self.t = stamp_ns
            if q_end is not None:
                self.q = q_end
            return 0.0
        if stamp_ns >= self.t:
            self._propagate(stamp_ns, q_end)
            return 0.0
        late = (self.t - stamp_ns) * 1e-9
        if late <= self.params.reorder_window:
            return late
        if late > self.params.max_gap:
            self.reset()
            self.t = stamp_ns
            if q_end is not None:
                self.q = q_end
            return 0.0
        return Rejection('stale_stamp', f'stamp {late:.3f} s older than the state, beyond '
                                        f'reorder_window {self.params.reorder_window} s')

    def reset(self) -> None:
        """Re-initialise the state (time went backwards: a bag looped); keep the origin."""
        self.resets += 1
        self._init_state()

    def _rates_fresh(self, t1: int) -> bool:
        return (self.omega is not None and self.last_rate_ns is not None
                and (t1 - self.last_rate_ns) * 1e-9 <= self.params.max_gap)

    def _propagate(self, t1: int, q_end: tuple | None) -> None:
        """
        Advance the attitude and the deferred time update from ``self.t`` to ``t1``.

        Per message only the attitude (pure Python on four floats) and the sum A = Σ R_mean dt
        of the trapezoid-mean rotations are updated; the position, the local position and the
        covariances follow in :meth:`_flush` (see the module notes).
        """
        dt = (t1 - self.t) * 1e-9
        self.t = t1
        if dt <= 0.0:
            if q_end is not None:
                self.q = q_end
            return
        integrating = self._rates_fresh(t1)
        if dt > self.params.max_gap:
            self._flush()
            self._inflate_gap(dt, integrating)
            if q_end is not None:
                self.q = q_end
            return
        q0 = self._q4
        r0 = self._rot9
        if q_end is not None:
            q1 = q_end
        elif integrating:
            a, b, c = self.omega
            if self.params.integrator == 'euler':
                hp, hq, hr = 0.5 * dt * a, 0.5 * dt * b, 0.5 * dt * c
                qw, qx, qy, qz = q0
                q1 = _normalize4(qw - qx * hp - qy * hq - qz * hr,
                                 qx + qw * hp - qz * hq + qy * hr,
                                 qy + qz * hp + qw * hq - qx * hr,
                                 qz - qy * hp + qx * hq + qw * hr)
            else:
                half = 0.5 * dt * math.hypot(a, b, c)
                k = 0.5 * dt * _half_sinc(half)
                q1 = _normalize4(*_mul4(q0, (math.cos(half), k * a, k * b, k * c)))
            if self.params.two_d:
                q1 = _yaw_only(q1)
            self._att_dt2 += dt * dt
        else:
            q1 = q0
        h = 0.5 * dt
        pa = self._pending_a
        if q1 is q0:
            self._pending_a = tuple([s + dt * r for s, r in zip(pa, r0)])
        else:
            r1 = _rquat9(q1)
            self._q4, self._rot9 = q1, r1
            self._pending_a = tuple([s + h * (r + t) for s, r, t in zip(pa, r0, r1)])
        self._pending_dt += dt
        if self._pending_dt >= LAZY_INTERVAL:
            self._flush()

    def _flush(self) -> None:
        """Apply the deferred time update to the state."""
        if self._pending_dt > 0.0:
            self.x, self.P, self.p_local, self.cov_p_local, self._cross = (
                self._pending_applied())
            self._pending_dt = 0.0
            self._pending_a = (0.0,) * 9

    def _pending_applied(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                                        np.ndarray]:
        """
        Return x, P, the local position, its covariance and cross-covariance after the update.

        Over Δt = ``_pending_dt``: x ← F x, P ← F P Fᵀ + Q with F = [[I, A, B], [0, I, 0],
        [0, 0, I]], A = Σ R_mean dt (the product of the per-message transitions, exact), B the
        current's Δt on the horizontal position (water only), and Q the continuous-time process
        noise over Δt with the mean rotation R̄ = A / Δt: white body acceleration (q_pp =
        σ_a² Δt³/3, q_pv = R̄ σ_a² Δt²/2, q_vv = σ_a² Δt), the current's random walk in NED
        (horizontal q_pp += σ_c² Δt³/3, q_pc = σ_c² Δt²/2, q_cc = σ_c² Δt), and the attitude
        share of :meth:`_attitude_density`. The local position l ← l + G v (G = [A, B], v the
        velocity part of x) shares the position's process noise: L ← L + G Xᵥᵀ + Xᵥ Gᵀ +
        G P_vv Gᵀ + Q_pp and X ← (X + G P_v·) Fᵀ + Q_p·, X = Cov(l, x). New arrays: the
        state's are not modified.
        """
        dt = self._pending_dt
        a9 = self._pending_a
        n = self.x.size
        xl = self.x.tolist()
        u, v, w = xl[3:6]
        s0 = a9[0] * u + a9[1] * v + a9[2] * w
        s1 = a9[3] * u + a9[4] * v + a9[5] * w
        s2 = a9[6] * u + a9[7] * v + a9[8] * w
        water = n == 8
        if water:                        # ṗ = R ν_r + c
            s0 += xl[6] * dt
            s1 += xl[7] * dt
        x = np.array([xl[0] + s0, xl[1] + s1, xl[2] + s2] + xl[3:])
        l0, l1, l2 = self.p_local.tolist()
        p_local = np.array([l0 + s0, l1 + s1, l2 + s2])
        qa = ACCEL_SIGMA ** 2
        q_pp = qa * dt ** 3 / 3.0
        q_vv = qa * dt
        k_cross = qa * dt / 2.0          # R̄ σ_a² Δt²/2 = A σ_a² Δt/2
        # The attitude share R̄ S(ν) P_Θ S(ν)ᵀ R̄ᵀ 2τ Δt = A M Aᵀ, M = S(ν) P_Θ S(ν)ᵀ 2τ/Δt.
        c = 2.0 * ATTITUDE_CORRELATION_TIME / dt
        m0, m1, m2, m3, m4, m5, m6, m7, m8 = [d * c for d in self._attitude_density(u, v, w)]
        am = [a9[i] * m0 + a9[i + 1] * m3 + a9[i + 2] * m6 for i in (0, 3, 6)]
        am += [a9[i] * m1 + a9[i + 1] * m4 + a9[i + 2] * m7 for i in (0, 3, 6)]
        am += [a9[i] * m2 + a9[i + 1] * m5 + a9[i + 2] * m8 for i in (0, 3, 6)]
        # am[3 j + i] = (A M)[i, j]; att[i][k] = Σ_j (A M)[i, j] A[k, j].
        att = [[am[i] * a9[k] + am[3 + i] * a9[k + 1] + am[6 + i] * a9[k + 2]
                for k in (0, 3, 6)] for i in range(3)]
        q_pos = q_pp + CURRENT_SIGMA ** 2 * dt ** 3 / 3.0 if water else q_pp
        att[0][0] += q_pos
        att[1][1] += q_pos
        att[2][2] += q_pp
        # The rows of G = [A, B] and of Q (n x n), as lists.
        g0, g1, g2 = a9[0:3], a9[3:6], a9[6:9]
        ak = [a * k_cross for a in a9]
        q0, q1, q2 = att[0] + ak[0:3], att[1] + ak[3:6], att[2] + ak[6:9]
        q3, q4, q5 = ak[0::3], ak[1::3], ak[2::3]
        q3 += [q_vv, 0.0, 0.0]
        q4 += [0.0, q_vv, 0.0]
        q5 += [0.0, 0.0, q_vv]
        q_rows = [q0, q1, q2, q3, q4, q5]
        if water:
            qc = CURRENT_SIGMA ** 2
            q_pc, q_cc = qc * dt * dt / 2.0, qc * dt
            g0 += (dt, 0.0)
            g1 += (0.0, dt)
            g2 += (0.0, 0.0)
            q0 += [q_pc, 0.0]
            q1 += [0.0, q_pc]
            q2 += [0.0, 0.0]
            for row in (q3, q4, q5):
                row += [0.0, 0.0]
            q_rows += [[q_pc, 0.0, 0.0, 0.0, 0.0, 0.0, q_cc, 0.0],
                       [0.0, q_pc, 0.0, 0.0, 0.0, 0.0, 0.0, q_cc]]
        # One transition of the augmented state [l, x] (3 + n): l ← l + G v, x ← F x, with
        # covariance [[L, X], [Xᵀ, P]] and noise [[Q_pp, Q_p·], [Q_·p, Q]] (see above).
        m = n + 3
        f = self._identity_flat(m)
        for i, g_row in enumerate((g0, g1, g2)):
            f[i * m + 6:i * m + m] = g_row
            f[(i + 3) * m + 6:(i + 4) * m] = g_row
        q = []
        for row in q_rows[0:3]:
            q += row[0:3]
            q += row
        for row in q_rows:
            q += row[0:3]
            q += row
        aug = np.empty((m, m))
        aug[0:3, 0:3] = self.cov_p_local
        aug[0:3, 3:m] = self._cross
        aug[3:m, 0:3] = self._cross.T
        aug[3:m, 3:m] = self.P
        f_m = np.array(f).reshape(m, m)
        aug = f_m @ aug @ f_m.T
        aug += np.array(q).reshape(m, m)
        pm = aug[3:m, 3:m].copy()
        local = aug[0:3, 0:3].copy()
        cross = aug[0:3, 3:m].copy()
        if self.params.two_d:
            self._two_d_arrays(x, pm, p_local, local, cross)
        return x, pm, p_local, local, cross

    _IDENTITY_FLAT: dict[int, list[float]] = {}
    _SELECTION: dict[tuple[int, int, tuple[int, ...]], np.ndarray] = {}

    @classmethod
    def _selection(cls, n: int, offset: int, rows: tuple[int, ...]) -> np.ndarray:
        """Return a shared read-only H (len(rows) x n) with H[i, offset + rows[i]] = 1."""
        key = (n, offset, rows)
        try:
            return cls._SELECTION[key]
        except KeyError:
            h = np.zeros((len(rows), n))
            for i, row in enumerate(rows):
                h[i, offset + row] = 1.0
            h.flags.writeable = False
            return cls._SELECTION.setdefault(key, h)
    _IDENTITY: dict[int, np.ndarray] = {}

    @classmethod
    def _identity(cls, n: int) -> np.ndarray:
        """Return a shared read-only n x n identity."""
        try:
            return cls._IDENTITY[n]
        except KeyError:
            eye = np.eye(n)
            eye.flags.writeable = False
            return cls._IDENTITY.setdefault(n, eye)

    @classmethod
    def _identity_flat(cls, n: int) -> list[float]:
        try:
            return cls._IDENTITY_FLAT[n].copy()
        except KeyError:
            cls._IDENTITY_FLAT[n] = np.eye(n).reshape(-1).tolist()
            return cls._IDENTITY_FLAT[n].copy()

    def _attitude_density(self, u: float, v: float, w: float) -> tuple[float, ...]:
        """
        Return S(ν) P_Θ S(ν)ᵀ (row-major, nine floats), the attitude share of the noise density.

        The attitude is not a filter state, but its error moves the predicted position: with
        a small body-axis attitude error δΘ, R(q) = R(q̂)(I + S(δΘ)) and ṗ = R(q)ν gives
        δṗ = R S(δΘ) ν = −R S(ν) δΘ: the form of the attitude term of the standard INS error
        model, δv̇ = −R S(f) δΘ, with the body velocity in place of the specific force (Fossen,
        Handbook of Marine Craft Hydrodynamics and Motion Control, 2nd ed. 2021, ch. 14;
        Groves, Principles of GNSS, Inertial, and Multisensor Integrated Navigation Systems,
        2nd ed. 2013, ch. 14). An AHRS attitude error (magnetic heading, tilt) is correlated in
        time; modelled as first-order Gauss-Markov with variance P_Θ and correlation time
        τ = :data:`ATTITUDE_CORRELATION_TIME`, its integral is that of a white noise of the same
        low-frequency spectral density 2τ P_Θ (Brown and Hwang, Introduction to Random Signals
        and Applied Kalman Filtering, 4th ed. 2012, Gauss-Markov process), so

            Q_p += R S(ν) P_Θ S(ν)ᵀ Rᵀ · 2τ dt,

        linear in dt: the same total for any IMU rate or propagation step. Each variance of
        P_Θ is capped at :data:`ATTITUDE_SHARE_MAX_VARIANCE` (rad²) with its correlations
        kept: beyond about a radian the small-angle model no longer holds, and an unknown
        attitude (e.g. a heading-only compass's roll and pitch) bounds the velocity error by
        the speed. R is the step's mean R(q), ν the body velocity estimate. Cached while
        P_Θ and ν do not change; :meth:`_pending_applied` adds R̄ (this) R̄ᵀ · 2τ Δt.
        """
        key = (self._att_base, self._att_dt2, self.cov_omega, u, v, w)
        cached = self._density_cache
        if (cached is not None and cached[0][0] is key[0] and cached[0][2] is key[2]
                and cached[0][1] == key[1] and cached[0][3:] == key[3:]):
            return cached[1]
        (a0, a1, a2), (a3, a4, a5), (a6, a7, a8) = self.cov_att.tolist()
        if max(a0, a4, a8) > ATTITUDE_SHARE_MAX_VARIANCE:
            d0, d1, d2 = [math.sqrt(min(1.0, ATTITUDE_SHARE_MAX_VARIANCE / max(var, 1e-300)))
                          for var in (a0, a4, a8)]
            a0, a1, a2 = a0 * (d0 * d0), a1 * (d0 * d1), a2 * (d0 * d2)
            a3, a4, a5 = a3 * (d1 * d0), a4 * (d1 * d1), a5 * (d1 * d2)
            a6, a7, a8 = a6 * (d2 * d0), a7 * (d2 * d1), a8 * (d2 * d2)
        # T = S(ν) P_Θ with S(ν) = [[0, -w, v], [w, 0, -u], [-v, u, 0]], then T S(ν)ᵀ.
        t0, t1, t2 = v * a6 - w * a3, v * a7 - w * a4, v * a8 - w * a5
        t3, t4, t5 = w * a0 - u * a6, w * a1 - u * a7, w * a2 - u * a8
        t6, t7, t8 = u * a3 - v * a0, u * a4 - v * a1, u * a5 - v * a2
        density = (v * t2 - w * t1, w * t0 - u * t2, u * t1 - v * t0,
                   v * t5 - w * t4, w * t3 - u * t5, u * t4 - v * t3,
                   v * t8 - w * t7, w * t6 - u * t8, u * t7 - v * t6)
        self._density_cache = (key, density)
        return density

    def _inflate_gap(self, dt: float, integrating: bool) -> None:
        """Advance over a gap without integrating: widen the position by what it could move."""
        v_n = self.velocity_ned()
        speed2 = float(v_n @ v_n) + float(np.trace(self.P[3:, 3:]))
        grow = np.eye(3) * (speed2 * dt * dt)
        self.P[0:3, 0:3] += grow
        self.P[3:6, 3:6] += np.eye(3) * (ACCEL_SIGMA ** 2 * dt)
        self.cov_p_local = self.cov_p_local + grow
        self._cross[:, 0:3] += grow      # the same unknown displacement of both positions
        if self.water:
            self.P[6:8, 6:8] += np.eye(2) * (CURRENT_SIGMA ** 2 * dt)
        if integrating:
            self._att_dt2 += dt * dt
        self._two_d()

    def _two_d(self) -> None:
        if self.params.two_d:
            self._two_d_arrays(self.x, self.P, self.p_local, self.cov_p_local, self._cross)

    @staticmethod
    def _two_d_arrays(x: np.ndarray, pm: np.ndarray, p_local: np.ndarray,
                      local: np.ndarray, cross: np.ndarray) -> None:
        for i in (2, 5):
            x[i] = 0.0
            pm[i, :] = 0.0
            pm[:, i] = 0.0
            cross[:, i] = 0.0
        p_local[2] = 0.0
        local[2, :] = 0.0
        local[:, 2] = 0.0
        cross[2, :] = 0.0

    # ------------------------------------------------------------------ measurement updates

    def _kalman(self, h: np.ndarray, z: np.ndarray, r: np.ndarray,
                gate: float = 0.0) -> float | None:
        """
        Update with z = H x + noise(R); return the innovation's Mahalanobis distance.

        With ``gate`` > 0, a distance beyond it leaves the state untouched and returns it
        negated. Joseph form, symmetrised. The local position is a consider (Schmidt) state:
        not corrected, its covariance unchanged, its cross-covariance X ← X (I − K H)ᵀ.
        """
        y = z - h @ self.x
        ph = self.P @ h.T
        s = h @ ph + r
        s_inv = _inverse_small(s)
        if s_inv is None:
            return None
        d2 = float(y @ s_inv @ y)
        if not math.isfinite(d2):
            return None
        distance = math.sqrt(max(d2, 0.0))
        if gate > 0.0 and distance > gate:
            return -distance
        k = ph @ s_inv
        x = self.x + k @ y
        ikh = self._identity(self.x.size) - k @ h
        p = ikh @ self.P @ ikh.T + k @ r @ k.T
        p += p.T
        p *= 0.5
        if not math.isfinite(float(x.sum()) + float(p.sum())):
            return None
        self.x = x
        self.P = p
        self._cross = self._cross @ ikh.T
        self._two_d()
        return distance

    def fix(self, m: GnssFix) -> Rejection | None:
        """Fold in a GNSS fix; set the origin from it when there is none yet."""
        if not (math.isfinite(m.lat) and math.isfinite(m.lon) and _finite(m.cov_ned)):
            return Rejection('nan_field', 'fix with a non-finite position or covariance')
        if math.isinf(m.height):
            return Rejection('nan_field', 'fix with an infinite height')
        late = self._time(m.stamp_ns)
        if isinstance(late, Rejection):
            return late
        self._flush()
        horizontal = math.isnan(m.height) or self.params.two_d
        if self.origin is None:
            self._origin_from_fix(m)
        self.last_fix_ns = m.stamp_ns if self.last_fix_ns is None else max(
            self.last_fix_ns, m.stamp_ns)
        height = m.height
        if math.isnan(height):
            height = self.origin[2] - (self.x[2] if self.position_ok else 0.0)
        p_antenna = self.to_ned(m.lat, m.lon, height)
        if any(self.params.gnss_antenna_position):
            rot = self._rot
            lever = rot @ _flu_to_frd(self.params.gnss_antenna_position)
            z = p_antenna - lever
            # A small body-axis attitude error d moves the antenna by -S(R r_b) R d (m).
            s_lever = _skew(lever) @ rot
            r = m.cov_ned + s_lever @ self.cov_att @ s_lever.T
        else:                            # no lever arm: z = p_antenna, R = the fix's
            z = p_antenna
            r = np.array(m.cov_ned, dtype=float)
        if not self.position_ok:
            cov = r.copy()
            if horizontal:
                cov[2, :] = 0.0
                cov[:, 2] = 0.0
                cov[2, 2] = self.params.gnss_default_sigma ** 2
                z[2] = self.x[2]
            self._init_position(z, cov)
            return None
        if not self.params.gnss_enabled:
            return None
        n = self.x.size
        rows = (0, 1) if horizontal else (0, 1, 2)
        h = self._selection(n, 0, rows)
        if late > 0.0:
            # Compare against the position predicted back to the fix's stamp: p - R(q) nu dt.
            h = h.copy()
            h[:, 3:6] = -late * self._rot[rows, :]
            if self.water:               # ... - c dt through water
                for i, row in enumerate(rows):
                    if row < 2:
                        h[i, 6 + row] = -late
        if horizontal:
            z_rows, r_rows = z[0:2], r[0:2, 0:2]
        else:
            z_rows, r_rows = z, r
        distance = self._kalman(h, z_rows, r_rows, self.params.gnss_gate_sigma)
        if distance is None:
            return Rejection('numerical', 'fix update was not finite; state kept')
        if distance < 0.0:
            self._gate_rejections += 1
            if self._gate_rejections >= GATE_RESET_COUNT:
                self._init_position(z, r)
                return None
            return Rejection('innovation_gate',
                             f'fix {-distance:.1f} sigma from the estimate, beyond gate_sigma '
                             f'{self.params.gnss_gate_sigma}')
        self._gate_rejections = 0
        return None

    def _origin_from_fix(self, m: GnssFix) -> None:
        lat, lon, h = self.params.origin
        if math.isnan(lat):
            lat_r, lon_r = m.lat, m.lon
        else:
            lat_r, lon_r = math.radians(lat), math.radians(_wrap_lon_deg(lon))
        if math.isnan(h):
            h = 0.0 if math.isnan(m.height) else m.height
        self.origin = (float(lat_r), float(lon_r), float(h))
        self._origin_event = True

    def imu(self, m: ImuSample) -> Rejection | None:
        """Fold in an attitude and/or body rate."""
        q_nb, omega_b = m.q_nb, m.omega_b
        if q_nb is not None:
            q_nb = _floats(q_nb)
        if omega_b is not None:
            omega_b = _floats(omega_b)
        att_nonzero = omega_nonzero = False
        if not _finite(q_nb, omega_b):
            return Rejection('nan_field', 'IMU sample with a non-finite field')
        if m.att_cov is not None:
            att_nonzero = self._checked.check(m.att_cov)
        if m.omega_cov is not None:
            omega_nonzero = self._checked.check(m.omega_cov)
        if att_nonzero is None or omega_nonzero is None:
            return Rejection('nan_field', 'IMU sample with a non-finite field')
        q_meas = None
        if q_nb is not None and self.params.imu_use_orientation:
            q_meas = _yaw_only(q_nb) if self.params.two_d else q_nb
            if self.last_attitude_ns is not None and m.stamp_ns < self.last_attitude_ns:
                q_meas = None  # an older attitude than the one in use
        late = self._time(m.stamp_ns, q_meas)
        if isinstance(late, Rejection):
            return late
        if q_meas is not None:
            if late > 0.0:
                self.q = q_meas
            self.last_attitude_ns = m.stamp_ns
            cov = m.att_cov
            self.cov_att = (_DEFAULT_ATT_COV if not att_nonzero else
                            cov if isinstance(cov, np.ndarray) and not cov.flags.writeable
                            else np.array(cov, dtype=float))
        if omega_b is not None:
            self._set_rate(m.stamp_ns, omega_b, m.omega_cov, omega_nonzero)
            self.omega_from_imu = True
        self.last_imu_ns = m.stamp_ns if self.last_imu_ns is None else max(
            self.last_imu_ns, m.stamp_ns)
        return None

    def _set_rate(self, stamp_ns: int, omega: tuple[float, float, float],
                  cov: np.ndarray | None, nonzero: bool) -> None:
        if self.params.two_d:
            omega = (0.0, 0.0, omega[2])
        self.omega = omega
        cov_omega = (_DEFAULT_RATE_COV if not nonzero else
                     cov if isinstance(cov, np.ndarray) and not cov.flags.writeable
                     else np.array(cov, dtype=float))
        if cov_omega is not self.cov_omega:
            if self._att_dt2 != 0.0:
                self.cov_att = self.cov_att    # fold the rate integration so far in
            self.cov_omega = cov_omega
        self.last_rate_ns = stamp_ns if self.last_rate_ns is None else max(
            self.last_rate_ns, stamp_ns)

    def velocity(self, m: BodyVelocity) -> Rejection | None:
        """Fold in a body velocity measurement: over ground or through water, per the reference."""
        if (not _finite(m.nu_b, m.omega_b) or self._checked.check(m.cov) is None
                or (m.omega_cov is not None and self._checked.check(m.omega_cov) is None)):
            return Rejection('nan_field', 'velocity with a non-finite field')
        late = self._time(m.stamp_ns)
        if isinstance(late, Rejection):
            return late
        self._flush()
        self.last_velocity_ns = m.stamp_ns if self.last_velocity_ns is None else max(
            self.last_velocity_ns, m.stamp_ns)
        if (m.omega_b is not None and not (self.omega_from_imu and self._rates_fresh(self.t))
                and (m.omega_cov is None or m.omega_cov[2][2] < UNMEASURED_VARIANCE)):
            self._set_rate(m.stamp_ns, _floats(m.omega_b), m.omega_cov,
                           m.omega_cov is not None and bool(np.any(m.omega_cov)))
            self.omega_from_imu = False
        cov = np.asarray(m.cov, dtype=float).tolist()
        rows = [i for i in range(3) if cov[i][i] < UNMEASURED_VARIANCE
                and not (self.params.two_d and i == 2)]
        if not rows:
            return None
        n = self.x.size
        h = self._selection(n, 3, tuple(rows))   # z = ν over ground, or ν_r through water
        r = np.array([[cov[i][j] + _TINY_VARIANCE if i == j else cov[i][j] + 0.0 for j in rows]
                      for i in rows])
        nu = np.asarray(m.nu_b, dtype=float).tolist()
        if self._kalman(h, np.array([nu[i] for i in rows]), r) is None:
            return Rejection('numerical', 'velocity update was not finite; state kept')
        return None

    # ------------------------------------------------------------------ parameters

    def set_params(self, params: NavigatorParams) -> bool:
        """
        Apply new parameters; return True when the origin changed.

        A new origin or projection re-expresses the position through latitude, longitude and
        height, so the estimated geographic position does not move. A new velocity reference
        rebuilds the filter keeping position and the body velocity over ground (ν = ν_r +
        R(q)ᵀc; a new current starts at zero with its prior uncertainty).
        """
        old = self.params
        self._flush()
        llh = self.to_llh(self.x[0:3]) if self.ready else None
        self.params = params
        if params.velocity_reference != old.velocity_reference:
            x, p = self.x, self.P
            n = 8 if self.water else 6
            if n == 6 and x.size == 8:
                # ν over ground = ν_r + R(q)ᵀc: the same velocity, the current folded in.
                t = np.zeros((6, 8))
                t[0:6, 0:6] = np.eye(6)
                t[3:6, 6:8] = self._rot.T[:, 0:2]
                x, p = t @ x, t @ p @ t.T
                self._cross = self._cross @ t.T
            self.x = np.zeros(n)
            self.P = np.zeros((n, n))
            self.x[0:6] = x[0:6]
            self.P[0:6, 0:6] = p[0:6, 0:6]
            cross, self._cross = self._cross, np.zeros((3, n))
            self._cross[:, 0:6] = cross[:, 0:6]
            if self.water:
                # A current c of prior σ INITIAL_CURRENT_SIGMA: ν_r = ν − R(q)ᵀc, correlated.
                self.P[6:8, 6:8] = np.eye(2) * INITIAL_CURRENT_SIGMA ** 2
                t = np.eye(8)
                t[3:6, 6:8] = -self._rot.T[:, 0:2]
                self.x = t @ self.x
                self.P = t @ self.P @ t.T
                self._cross = self._cross @ t.T
        changed = self._set_origin_from_params(params)
        if llh is not None and (changed or params.projection != old.projection):
            self.x[0:3] = self.to_ned(*llh)
        if self.origin is not None and not params.gnss_enabled and not self.position_ok:
            self._init_position(np.zeros(3), np.zeros((3, 3)))
        self._two_d()
        return changed
