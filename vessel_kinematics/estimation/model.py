"""
The process model and the measurement models, on the state of :mod:`.layout`.

Kinematics (Fossen eq. 2.18 and 2.108, with the current of 2.4)::

    planar (surface, ground):  ṗ = R₂(ψ) w + c      w = [u, v]  (or [u_r, tan λ·u_r + b·U + κr])
    free:                      ṗ = R(q) ν + [c; 0]       ν = [u, v, w]

ψ = ψ_IMU + D + δψ + γ is the IMU heading corrected by the declination D, the estimated offset
δψ and the meridians' convergence γ between the vessel's north and the map's
(:mod:`.surface`); R₂(ψ) rotates the heading frame (x along the heading, horizontal) into the
map's NED. The current c is zero without a water reference. The velocity is held in physical
units (m/s), so only a log reading observes the log's scale.

Speed changes are an acceleration state a (m/s², of the surge; of each axis without a velocity
sensor), a Singer process (Singer 1970; Bar-Shalom et al. 2001, §8.2)::

    u̇ = a + w_u          ȧ = −a/τ + w_a,   E[w_a²] = 2σ_a²/τ

with τ = :data:`~.config.ACCEL_TAU` and σ_a the craft's acceleration level, adapted to what it
does (:class:`AccelerationLevel`). Over Δt, with φ = e^(−Δt/τ) and x = Δt/τ (exact)::

    u ← u + τ(1 − φ) a,  a ← φ a
    Q_aa = σ_a²(1 − φ²)   Q_ua = σ_a² τ (1 − φ)²   Q_uu = σ_a² τ² (2x − 3 + 4φ − φ²)

Every other velocity-like state is a first-order Gauss-Markov process (:class:`~.config.
Markov`): it cannot run away when nothing observes it.

A body velocity sensor measures, in BODY (rows it measures)::

    planar:  z = k · R_tiltᵀ [w; 0]          R(q) = Rz(ψ) R_tilt, R_tilt = Ry(θ) Rx(φ)
    free:    z = k · ν

with k the scale factor (reading / truth; 1 without a water reference). A fix measures the
antenna, p + R(q) r_b; a receiver's own velocity the antenna's ṗ + R(q)(ω × r_b).

The IMU messages advance the attitude only and accumulate A = Σ R dt (trapezoid), the
rotation integrated over the interval (:class:`Pending`); the position, the covariance and
the Markov states are propagated in one step from it (:func:`propagate`), the position by
A·(w + ẇ Δt/2): exact for a constant rotation, second order in the rotation's change.
"""

from __future__ import annotations

import math
from typing import Sequence

import numpy as np

from vessel_kinematics.estimation.attitude import heading_of, tilt_of
from vessel_kinematics.estimation.config import (ACCEL_MAX, ACCEL_RELAX_TIME,
                                                 ACCEL_SIGMA_CRUISE, ACCEL_TAU,
                                                 ATTITUDE_CORRELATION_TIME,
                                                 ATTITUDE_SHARE_MAX_VARIANCE, CURRENT,
                                                 HEADING_OFFSET, HEAVE, LEEWAY, LOG_SCALE,
                                                 Markov, SURGE, SWAY, SWAY_FLOOR_SPEED,
                                                 SWAY_RATIO, TURN_DRIFT,
                                                 TURN_DRIFT_MAX_ANGLE)
from vessel_kinematics.estimation.layout import StateLayout

__all__ = ['AccelerationLevel', 'MarkovTable', 'Pending', 'attitude_share', 'body_velocity',
           'fix_jacobian', 'ground_velocity_measurement', 'manoeuvre_covariance',
           'markov_steps', 'position_rate', 'propagate', 'rotation_now', 'singer_step',
           'turn_drift', 'velocity_measurement', 'velocity_rate', 'velocity_state',
           'velocity_vector']

_S2 = np.array([[0.0, -1.0], [1.0, 0.0]])          # d/dψ R₂(ψ) = S₂ R₂(ψ)
_S3 = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
_TAN_DRIFT = math.tan(TURN_DRIFT_MAX_ANGLE)


def _r2(c: float, s: float) -> np.ndarray:
    return np.array([[c, -s], [s, c]])


def _rz(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


class Pending:
    """
    The deferred time update: elapsed time and the rotation integrated over it.

    ``a9`` = Σ R(q) dt row-major (free motion), ``cs`` = Σ (cos ψ, sin ψ) dt of the IMU
    heading (planar), both by the trapezoid rule over the attitude steps.
    """

    __slots__ = ('dt', 'a9', 'cs', 'horizontal')

    def __init__(self, horizontal: bool = False) -> None:
        self.dt = 0.0
        self.a9: tuple[float, ...] = (0.0,) * 9
        self.cs = (0.0, 0.0)
        #: A planar layout needs ``cs`` only (:meth:`rotation`): ``a9`` is not summed then.
        self.horizontal = horizontal

    def add(self, dt: float, r0: Sequence[float], r1: Sequence[float],
            cs0: tuple[float, float] | None = None,
            cs1: tuple[float, float] | None = None) -> None:
        """
        Add a step of ``dt`` s from attitude R(q₀) to R(q₁) (row-major nine floats).

        ``cs0``, ``cs1``: their headings :func:`heading_of` where already known (the attitude
        keeps its own), computed here otherwise. Runs per IMU message.
        """
        h = 0.5 * dt
        if r0 is r1:
            if not self.horizontal:
                self.a9 = tuple([a + dt * r for a, r in zip(self.a9, r0)])
            c, s = cs0 or heading_of(r0)
            self.cs = (self.cs[0] + dt * c, self.cs[1] + dt * s)
        else:
            if not self.horizontal:
                self.a9 = tuple([a + h * (r + t) for a, r, t in zip(self.a9, r0, r1)])
            c0, s0 = cs0 or heading_of(r0)
            c1, s1 = cs1 or heading_of(r1)
            self.cs = (self.cs[0] + h * (c0 + c1), self.cs[1] + h * (s0 + s1))
        self.dt += dt

    def rotation(self, layout: StateLayout, offset: float) -> np.ndarray:
        """Return A = Σ R dt with the heading offset applied: R₂(o) A₂ or Rz(o) A₃."""
        if layout.horizontal:                  # R₂(o) R₂(Σ (cos ψ, sin ψ) dt), one R₂
            co, so = math.cos(offset), math.sin(offset)
            c, s = self.cs
            return _r2(co * c - so * s, so * c + co * s)
        if self.horizontal:
            raise ValueError('a planar Pending has no 3-D rotation sum')
        return _rz(offset) @ np.array(self.a9).reshape(3, 3)


def rotation_now(layout: StateLayout, r9: Sequence[float], offset: float) -> np.ndarray:
    """Return the rotation velocity frame -> NED now: R₂(ψ_IMU + o) or Rz(o) R(q)."""
    if layout.horizontal:
        c, s = heading_of(r9)
        co, so = math.cos(offset), math.sin(offset)
        return _r2(c * co - s * so, s * co + c * so)
    return _rz(offset) @ np.array(r9).reshape(3, 3)


def turn_drift(u: float, kap: float, r: float) -> tuple[float, float, float]:
    """
    Return the sway of the turning drift v_t and its partials ∂v_t/∂u, ∂v_t/∂κ.

    v_t = s tanh(κr / s), s = tan(β_max)|u|: κ r where the pivot-point model holds (|κr| well
    below s), and never a drift angle beyond β_max (:data:`~.config.TURN_DRIFT_MAX_ANGLE`).
    """
    s = _TAN_DRIFT * abs(u)
    kr = kap * r
    if s < 1e-9:
        return 0.0, 0.0, 0.0
    z = kr / s
    t = math.tanh(z)
    sech2 = 1.0 - t * t
    du = _TAN_DRIFT * math.copysign(1.0, u) * (t - z * sech2)
    return s * t, du, r * sech2


def velocity_vector(x: np.ndarray, layout: StateLayout,
                    r: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """
    Return w, the velocity in its frame (heading frame or BODY, m/s), and ∂w/∂x (d × n).

    Through the water (planar) w = [u_r, tan λ · u_r + b · √(u_r² + U₀²) + v_t(u_r, κ, r)]
    with the drift ratio b the velocity block's second state, U₀ =
    :data:`~.config.SWAY_FLOOR_SPEED` and v_t the turning drift (:func:`turn_drift`): the sway
    scales with the surge, and at rest it is the wind's drift alone; otherwise w is the
    velocity block. ``r`` the yaw rate (rad/s).

    ∂v/∂u leaves out the drift ratio's share b·u/√(u_r² + U₀²): b is a transient drift of a
    tenth or so, its estimate mostly the fixes' noise, and that noise, multiplied into how the
    fixes tell the surge, walked the log's scale on a straight leg (k 1.0 → 1.24 in 30 minutes
    with an exact log; docs/validation.md). The sway itself keeps it.
    """
    d = layout.dim
    v = x[layout.v]
    jac = np.zeros((d, layout.size))
    jac.ravel()[layout.v.start::layout.size + 1][0:d] = 1.0       # ∂w/∂v = I
    if not layout.water or not layout.horizontal:
        return v.copy(), jac
    u, b = float(v[0]), float(v[1])
    u0 = layout.v.start
    speed = math.hypot(u, SWAY_FLOOR_SPEED)
    sway = b * speed
    jac[1, u0 + 1] = speed
    if layout.lam is not None:
        t = math.tan(float(x[layout.lam]))
        jac[1, layout.lam] = u * (1.0 + t * t)
        jac[1, u0] += t
        sway += t * u
    if layout.kap is not None:
        v_t, d_u, d_kap = turn_drift(u, float(x[layout.kap]), r)
        jac[1, u0] += d_u
        jac[1, layout.kap] = d_kap
        sway += v_t
    return np.array([u, sway]), jac


def velocity_state(layout: StateLayout, w: np.ndarray) -> np.ndarray:
    """
    Return the velocity block of a velocity w (its frame, m/s), the calibrations at rest.

    The inverse of :func:`velocity_vector` with no leeway and no turning drift: through the
    water [u_r, v_r / √(u_r² + U₀²)].
    """
    v = np.array(w[0:layout.dim], dtype=float)
    if layout.water and layout.horizontal:
        v[1] = v[1] / math.hypot(v[0], SWAY_FLOOR_SPEED)
    return v


def velocity_rate(x: np.ndarray, layout: StateLayout) -> tuple[np.ndarray, np.ndarray]:
    """
    Return ẇ = G(x) a, the velocity's rate (m/s², its frame) from the acceleration, and ∂ẇ/∂x.

    Through the water (planar) the sway follows the surge, ẇ = [a, (tan λ + b u/√(u² + U₀²))·a]
    (the ∂v/∂u of :func:`velocity_vector` without the turning drift's); otherwise each
    accelerated axis takes its own.
    """
    d = layout.dim
    wdot = np.zeros(d)
    jac = np.zeros((d, layout.size))
    for i, (_, ia) in enumerate(layout.accelerated):
        wdot[i] = x[ia]
        jac[i, ia] = 1.0
    if layout.water and layout.horizontal:
        a = float(x[layout.a.start])
        u = float(x[layout.v.start])
        b = float(x[layout.v.start + 1])
        ratio = b * u / math.hypot(u, SWAY_FLOOR_SPEED)    # ∂(b·√(u² + U₀²))/∂u
        jac[1, layout.v.start + 1] = a * u / math.hypot(u, SWAY_FLOOR_SPEED)
        if layout.lam is not None:
            t = math.tan(float(x[layout.lam]))
            ratio += t
            jac[1, layout.lam] = a * (1.0 + t * t)
        wdot[1] += ratio * a
        jac[1, layout.a.start] += ratio
    return wdot, jac


def position_rate(x: np.ndarray, layout: StateLayout, rot: np.ndarray, r: float = 0.0,
                  w: tuple[np.ndarray, np.ndarray] | None = None,
                  ) -> tuple[np.ndarray, np.ndarray]:
    """
    Return ṗ = rot·w + c (m/s, map NED) and its Jacobian ∂ṗ/∂x (d × n).

    ``w`` the :func:`velocity_vector` of ``x`` and ``r`` when already known.
    """
    w_, jw = velocity_vector(x, layout, r) if w is None else w
    return _displacement(x, layout, rot, 1.0, w_, jw)


def _displacement(x: np.ndarray, layout: StateLayout, rot: np.ndarray, dt_current: float,
                  w: np.ndarray, jw: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Return Δp = rot·w + dt_current·c and its Jacobian (the heading offset's column S·rot·w)."""
    dp = rot @ w
    jac = rot @ jw
    if layout.dpsi is not None:
        s = _S2 if layout.horizontal else _S3
        jac[:, layout.dpsi] = s @ dp
    if layout.c is not None:
        c0 = layout.c.start
        dp[0] += dt_current * x[c0]
        dp[1] += dt_current * x[c0 + 1]
        jac[0, c0] += dt_current
        jac[1, c0 + 1] += dt_current
    return dp, jac


def singer_step(dt: float, sigma: float, tau: float = ACCEL_TAU
                ) -> tuple[float, float, float, float, float]:
    """
    Return (g, φ, Q_uu, Q_ua, Q_aa) of the Singer acceleration over Δt (see the module notes).

    u ← u + g a with g = τ(1 − φ), a ← φ a, φ = e^(−Δt/τ); the exact discrete noise of the
    velocity and acceleration for the stationary σ ``sigma`` (m/s²), written with expm1 so
    that the small-Δt limits (Q_uu → 2σ²Δt³/3τ) keep their digits.
    """
    x = dt / tau
    e1 = math.expm1(-x)                       # φ − 1
    e2 = math.expm1(-2.0 * x)                 # φ² − 1
    s2 = sigma * sigma
    q_aa = -s2 * e2
    q_ua = s2 * tau * (e2 - 2.0 * e1)         # (1 − φ)² = φ² − 1 − 2(φ − 1)
    q_uu = s2 * tau * tau * (2.0 * x + 4.0 * e1 - e2)
    return -tau * e1, 1.0 + e1, max(q_uu, 0.0), q_ua, q_aa


def markov_steps(layout: StateLayout, dt: float) -> list[tuple[int, float, float, float]]:
    """Return (index, φ, added variance, rest value) of every Markov state over Δt."""
    return [(i, 1.0 if walk else proc.decay(dt), proc.noise(dt), rest)
            for i, proc, rest, walk in _processes(layout)]


class MarkovTable:
    """
    The Markov states of a layout as arrays, for one vectorised step (:func:`propagate`).

    The same processes as :func:`markov_steps`, evaluated at once: ``index`` the states,
    φ = exp(−Δt/τ) (1 for the heading offset's random walk), σ²(1 − exp(−2Δt/τ)) added, and
    the rest values. The estimator builds one for its layout.
    """

    __slots__ = ('index', 'inv_tau', 'sigma2', 'rest', 'walk', 'identity', 'positions',
                 'stack', 'diagonal', 'any_walk')

    def __init__(self, layout: StateLayout) -> None:
        #: The other constants of the layout the propagation uses: I (n × n); p and l together
        #: as one slice (they are adjacent, p first: :meth:`StateLayout.of`) and E = [I; I]
        #: (2d × d), so that the same d × d noise Q on p, l and their cross terms is E Q Eᵀ.
        d = layout.dim
        self.identity = np.eye(layout.size)
        if layout.l.start != layout.p.stop:
            raise ValueError('the layout must hold l right after p')
        self.positions = slice(layout.p.start, layout.l.stop)
        self.stack = np.vstack([np.eye(d), np.eye(d)])
        rows = _processes(layout)
        self.index = np.array([i for i, _, _, _ in rows], dtype=np.intp)
        self.inv_tau = np.array([1.0 / proc.tau for _, proc, _, _ in rows])
        self.sigma2 = np.array([proc.sigma ** 2 for _, proc, _, _ in rows])
        self.rest = np.array([rest for _, _, rest, _ in rows])
        #: The heading offset: a random walk, its mean held (φ = 1).
        self.walk = np.array([walk for _, _, _, walk in rows], dtype=bool)
        self.any_walk = bool(self.walk.any())
        #: The Markov states' diagonal elements of an n × n matrix, as flat indices.
        self.diagonal = self.index * (layout.size + 1)

    def step(self, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """Return φ and the added variance of every Markov state over Δt (s)."""
        a = -dt * self.inv_tau
        phi = np.exp(a)
        if self.any_walk:
            phi[self.walk] = 1.0
        return phi, self.sigma2 * -np.expm1(2.0 * a)


def _processes(layout: StateLayout) -> list[tuple[int, Markov, float, bool]]:
    """
    Return (index, process, rest value, random walk) of every Markov state, in state order.

    The log scale rests at 1, the others at 0; the heading offset is a random walk (its mean
    held, φ = 1), the others decay toward their rest. The accelerations are Singer processes
    of an adaptive σ (:func:`singer_step`), not in this table.
    """
    if layout.isotropic:
        procs: tuple = (SURGE,) * layout.dim
    elif layout.horizontal:
        procs = (SURGE, SWAY_RATIO if layout.water else SWAY)
    else:
        procs = (SURGE, SWAY, HEAVE)
    out = [(i, p, 0.0, False) for i, p in zip(range(layout.v.start, layout.v.stop), procs)]
    if layout.c is not None:
        out += [(i, CURRENT, 0.0, False) for i in range(layout.c.start, layout.c.stop)]
    named = ((layout.k, LOG_SCALE, 1.0, False), (layout.lam, LEEWAY, 0.0, False),
             (layout.kap, TURN_DRIFT, 0.0, False), (layout.dpsi, HEADING_OFFSET, 0.0, True))
    out += [(i, p, rest, walk) for i, p, rest, walk in named if i is not None]
    return out


def attitude_share(layout: StateLayout, x: np.ndarray, a_rot: np.ndarray, att_cov: np.ndarray,
                   dt: float, yaw_variance: float | None = None, r: float = 0.0,
                   w: np.ndarray | None = None) -> np.ndarray:
    """
    Return the attitude error's share of the position process noise over Δt (d × d).

    The attitude is not a filter state, but its error moves the predicted position: with a
    small body-axis attitude error δΘ, R(q) = R(q̂)(I + S(δΘ)) and ṗ = R(q)ν gives δṗ =
    −R S(ν) δΘ, the attitude term of the INS error model with the body velocity in place of
    the specific force (Fossen 2021, ch. 14; Groves 2013, ch. 14). An AHRS attitude error is
    correlated in time; as a first-order Gauss-Markov process of variance P_Θ and correlation
    time τ its integral is that of a white noise of density 2τ P_Θ, so Q_p = A S P_Θ Sᵀ Aᵀ ·
    2τ/Δt with A = Σ R dt. Planar: only the heading error matters, Q_p = a aᵀ σ_ψ² 2τ/Δt with
    a = S₂ A w. Variances are capped at :data:`~.config.ATTITUDE_SHARE_MAX_VARIANCE`
    (beyond about a radian the small-angle model fails; an unknown heading then bounds the
    velocity error by the speed). ``yaw_variance`` overrides the heading variance; ``w`` the
    velocity :func:`velocity_vector` when already known.
    """
    if w is None:
        w, _ = velocity_vector(x, layout, r)
    k = 2.0 * ATTITUDE_CORRELATION_TIME / dt
    if layout.horizontal:
        var = float(att_cov[2, 2]) if yaw_variance is None else yaw_variance
        var = min(var, ATTITUDE_SHARE_MAX_VARIANCE) * k
        (a00, a01), (a10, a11) = a_rot.tolist()
        w0, w1 = w.tolist()
        a0, a1 = -(a10 * w0 + a11 * w1), a00 * w0 + a01 * w1     # a = S₂ A w
        return np.array([[a0 * a0 * var, a0 * a1 * var], [a1 * a0 * var, a1 * a1 * var]])
    cov = np.array(att_cov, dtype=float)
    if yaw_variance is not None:
        cov[2, 2] = max(cov[2, 2], yaw_variance)
    d = np.sqrt(np.minimum(1.0, ATTITUDE_SHARE_MAX_VARIANCE / np.maximum(np.diag(cov), 1e-300)))
    cov = cov * np.outer(d, d)
    u, v, ww = w.tolist()
    s_nu = np.array([[0.0, -ww, v], [ww, 0.0, -u], [-v, u, 0.0]])
    m = a_rot @ s_nu
    return m @ cov @ m.T * k


def propagate(x: np.ndarray, p_cov: np.ndarray, layout: StateLayout, table: MarkovTable,
              a_rot: np.ndarray, dt: float, att_cov: np.ndarray, accel_sigma: float,
              yaw_variance: float | None = None, frozen: Sequence[int] = (),
              held: Sequence[int] = (), r: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """
    Return x and P after the interval Δt with A = Σ R dt (heading offset applied).

    x ← f(x): p and l advance by Δp = A(w + ẇ Δt/2) + Δt c, the velocity by its acceleration,
    the Markov states decay; P ← F P Fᵀ + Q with F = ∂f/∂x, Q the Markov states' and the
    accelerations' exact discrete noise (σ_a = ``accel_sigma``) and the attitude share on p,
    l (the same unknown displacement of both). ``frozen`` indices (a heading offset not yet
    initialised) are held: no coupling, no noise. ``held`` indices (calibrations nothing
    observes now) keep their mean (no decay toward rest) and gain their process noise.
    ``r`` the yaw rate (rad/s).
    """
    w, jw = velocity_vector(x, layout, r)
    wdot, jwdot = velocity_rate(x, layout)
    half = 0.5 * dt
    dp, jac = _displacement(x, layout, a_rot, dt, w + half * wdot, jw + half * jwdot)
    phi, q_var = table.step(dt)
    index, rest, diagonal = table.index, table.rest, table.diagonal
    if held:
        phi[np.isin(index, held)] = 1.0
    if frozen:
        jac[:, list(frozen)] = 0.0
        keep = ~np.isin(index, frozen)
        index, rest, phi, q_var = index[keep], rest[keep], phi[keep], q_var[keep]
        diagonal = diagonal[keep]
    f = table.identity.copy()
    f[layout.p] += jac
    f[layout.l] += jac
    f.ravel()[diagonal] = phi            # f[i, i] = φᵢ of the Markov states (a view: in place)
    x_new = x.copy()
    x_new[layout.p] += dp
    x_new[layout.l] += dp
    x_new[index] = rest + phi * (x[index] - rest)
    g, phi_a, q_uu, q_ua, q_aa = singer_step(dt, accel_sigma)
    for iv, ia in layout.accelerated:
        f[iv, ia] = g * f[iv, iv]
        f[ia, ia] = phi_a
        x_new[iv] += g * x[ia]
        x_new[ia] = phi_a * x[ia]
    p_new = f @ p_cov @ f.T
    p_new.ravel()[diagonal] += q_var
    for iv, ia in layout.accelerated:
        p_new[iv, iv] += q_uu
        p_new[iv, ia] += q_ua
        p_new[ia, iv] += q_ua
        p_new[ia, ia] += q_aa
    q_p = attitude_share(layout, x, a_rot, att_cov, dt, yaw_variance, r, w)
    stack = table.stack                   # p and l take the same unknown displacement
    p_new[table.positions, table.positions] += stack @ q_p @ stack.T
    p_new += p_new.T
    p_new *= 0.5
    return x_new, p_new


def manoeuvre_covariance(layout: StateLayout, rot: np.ndarray, elapsed: float,
                         accel: float = ACCEL_MAX) -> np.ndarray:
    """
    Return the covariance (n × n) a manoeuvre begun within ``elapsed`` s would add.

    The hypothesis of a constant extra acceleration δa ~ N(0, ``accel``²) along each
    accelerated axis since ``elapsed`` s ago (a throttle or a crash stop begun since the last
    measurement that agreed): it moves the acceleration by δa, the velocity by δa·Δt and the
    position (and the local position) by R δa Δt²/2. The variable-dimension idea of
    Bar-Shalom and Birmiwal (1982): a measurement this explains is a manoeuvre, not an outlier.
    """
    n = layout.size
    out = np.zeros((n, n))
    for i, (iv, ia) in enumerate(layout.accelerated):
        j = np.zeros(n)
        j[ia] = 1.0
        j[iv] = elapsed
        along = rot[:, i] * (0.5 * elapsed * elapsed)
        j[layout.p] = along
        j[layout.l] = along
        out += np.outer(j, j) * (accel * accel)
    return out


class AccelerationLevel:
    """
    The craft's acceleration level σ_a (m/s²), adapted to what it does.

    The mean square of the measured acceleration (each accepted update's posterior a where it
    is beyond twice its own σ, two successive log readings', a manoeuvre's), tracked with a
    time constant of :data:`ATTACK` going up and :data:`~.config.ACCEL_RELAX_TIME` coming down,
    with a floor of :data:`~.config.ACCEL_SIGMA_CRUISE` and a ceiling of
    :data:`~.config.ACCEL_MAX`: the process noise follows the craft, tight while it cruises,
    loose while it manoeuvres.
    """

    __slots__ = ('mean_square', 't_ns')

    #: Time constant (s) of the level going up.
    ATTACK = 1.0

    def __init__(self) -> None:
        self.mean_square = ACCEL_SIGMA_CRUISE ** 2
        self.t_ns: int | None = None

    @property
    def sigma(self) -> float:
        """Return σ_a (m/s²)."""
        return min(ACCEL_MAX, max(ACCEL_SIGMA_CRUISE, math.sqrt(self.mean_square)))

    def observe(self, t_ns: int, accel: float) -> None:
        """Take a measured acceleration (m/s², 0 for none shown) at ``t_ns``."""
        dt = 0.0 if self.t_ns is None else max(0.0, (t_ns - self.t_ns) * 1e-9)
        self.t_ns = t_ns if self.t_ns is None else max(self.t_ns, t_ns)
        a2 = accel * accel
        tau = self.ATTACK if a2 > self.mean_square else ACCEL_RELAX_TIME
        self.mean_square += (a2 - self.mean_square) * -math.expm1(-dt / tau)
        self.mean_square = min(self.mean_square, ACCEL_MAX ** 2)

    def raise_to(self, accel: float) -> None:
        """Raise the level at once to at least |accel| (a manoeuvre just found)."""
        self.mean_square = min(ACCEL_MAX ** 2, max(self.mean_square, accel * accel))


def fix_jacobian(layout: StateLayout, rot_full: np.ndarray, lever_b: np.ndarray,
                 rows: int) -> np.ndarray:
    """
    Return ∂h/∂x of a fix h(x) = p + R(q) r_b (the first ``rows`` NED rows), rows × n.

    The position block is the identity; a heading offset rotates the lever arm, S_z R r_b.
    """
    h = np.zeros((rows, layout.size))
    h[:, layout.p.start:layout.p.start + rows] = np.eye(rows)
    if layout.dpsi is not None:
        h[:, layout.dpsi] = (_S3 @ (rot_full @ lever_b))[0:rows]
    return h


def velocity_measurement(x: np.ndarray, layout: StateLayout, r9: Sequence[float],
                         rows: Sequence[int], r: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """
    Return the predicted body-velocity reading h(x) (``rows`` of [u, v, w]) and ∂h/∂x.

    h = k M w with M = R_tiltᵀ[:, 0:2] (planar: the heading frame seen from BODY) or I
    (free), k the scale (1 without one); ``r`` the yaw rate (rad/s).
    """
    w, jw = velocity_vector(x, layout, r)
    if layout.horizontal:
        t = tilt_of(r9)
        m = np.array([[t[0], t[3]], [t[1], t[4]], [t[2], t[5]]])   # R_tiltᵀ[:, 0:2]
    else:
        m = np.eye(3)
    m = m[list(rows), :]
    mw, mj = m @ w, m @ jw
    if layout.k is None:
        return mw, mj
    k = float(x[layout.k])
    mj *= k
    mj[:, layout.k] = mw
    return k * mw, mj


def ground_velocity_measurement(x: np.ndarray, layout: StateLayout, rot: np.ndarray,
                                rows: Sequence[int], r: float = 0.0,
                                ) -> tuple[np.ndarray, np.ndarray]:
    """Return the predicted velocity over ground in NED (``rows`` of ṗ) and its Jacobian."""
    pdot, jac = position_rate(x, layout, rot, r)
    rows = list(rows)
    return pdot[rows], jac[rows, :]


def body_velocity(x: np.ndarray, layout: StateLayout, r9: Sequence[float], offset: float,
                  over_ground: bool = True, r: float = 0.0,
                  w: tuple[np.ndarray, np.ndarray] | None = None,
                  ) -> tuple[np.ndarray, np.ndarray]:
    """
    Return the body velocity (FRD, m/s) and its Jacobian ∂ν/∂x (3 × n).

    Over ground (``over_ground``: the velocity through water plus the current seen from the
    body, Fossen eq. 2.108) or through the water (ν_r). Planar: ν = R_tiltᵀ [g; 0], g the
    horizontal velocity in the heading frame, g = w + R₂(ψ)ᵀ c over ground. ``r`` the yaw
    rate (rad/s); ``w`` the :func:`velocity_vector` of ``x`` and ``r`` when already known.
    """
    n = layout.size
    w_, jw = velocity_vector(x, layout, r) if w is None else w
    current = over_ground and layout.c is not None
    if layout.horizontal:
        g, jg = w_, jw
        if current:
            rot = rotation_now(layout, r9, offset)
            c = x[layout.c]
            g = w_ + rot.T @ c
            jg = jw.copy()
            jg[:, layout.c] += rot.T
            if layout.dpsi is not None:
                jg[:, layout.dpsi] += -_S2 @ (rot.T @ c)
        t = tilt_of(r9)
        m = np.array([[t[0], t[3]], [t[1], t[4]], [t[2], t[5]]])
        return m @ g, m @ jg
    nu, jac = w_, jw.copy()
    if current and layout.c is not None:
        r_full = rotation_now(layout, r9, offset)
        c3 = np.array([x[layout.c.start], x[layout.c.start + 1], 0.0])
        nu = w_ + r_full.T @ c3
        jac[:, layout.c] += r_full.T[:, 0:2]
        if layout.dpsi is not None:
            jac[:, layout.dpsi] += -(np.array(r9).reshape(3, 3).T @ (_S3 @ (_rz(offset).T @ c3)))
    return nu, jac if jac.shape == (3, n) else jac.reshape(3, n)
