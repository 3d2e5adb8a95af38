"""
The process model and the measurement models, on the state of :mod:`.layout`.

Kinematics (Fossen eq. 2.18 and 2.108, with the current of 2.4)::

    planar (surface, ground):  ṗ = R₂(ψ) w + c          w = [u, v]  (or [u_r, tan λ·u_r + κr + δv])
    free:                      ṗ = R(q) ν + [c; 0]       ν = [u, v, w]

ψ = ψ_IMU + D + δψ is the IMU heading corrected by the declination D and the estimated
offset δψ; R₂(ψ) rotates the heading frame (x along the heading, horizontal) into NED. The
current c is zero without a water reference. Every velocity-like state is a first-order
Gauss-Markov process (:class:`~.config.Markov`): it cannot run away when nothing observes it.

A body velocity sensor measures, in BODY (rows it measures)::

    planar:  z = k · R_tiltᵀ [w; 0]          R(q) = Rz(ψ) R_tilt, R_tilt = Ry(θ) Rx(φ)
    free:    z = k · ν

with k the scale factor (reading / truth; 1 without a water reference). A fix measures the
antenna, p + R(q) r_b.

The IMU messages advance the attitude only and accumulate A = Σ R dt (trapezoid), the
rotation integrated over the interval (:class:`Pending`); the position, the covariance and
the Markov states are propagated in one step from it (:func:`propagate`). Since the
velocity is constant between measurements, the mean position is exact; the covariance
differs from per-message propagation only by the variation of R within the interval.
"""

from __future__ import annotations

import math
from typing import Sequence

import numpy as np

from vessel_kinematics.estimation.attitude import heading_of, tilt_of
from vessel_kinematics.estimation.config import (ATTITUDE_CORRELATION_TIME,
                                                 ATTITUDE_SHARE_MAX_VARIANCE, CURRENT,
                                                 HEADING_OFFSET, HEAVE, LEEWAY, LOG_SCALE,
                                                 Markov, SURGE, SWAY, TURN_DRIFT)
from vessel_kinematics.estimation.layout import StateLayout

__all__ = ['MarkovTable', 'Pending', 'attitude_share', 'body_velocity', 'fix_jacobian',
           'markov_steps', 'position_rate', 'propagate', 'rotation_now', 'sensor_velocity',
           'velocity_measurement', 'velocity_vector']

_S2 = np.array([[0.0, -1.0], [1.0, 0.0]])          # d/dψ R₂(ψ) = S₂ R₂(ψ)
_S3 = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 0.0]])


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


def sensor_velocity(x: np.ndarray, layout: StateLayout,
                    r: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """
    Return w_m, the velocity as the velocity sensor reads it, and ∂w_m/∂x (d × n).

    The velocity block is kept in the sensor's units (w_m = k w, k the scale factor), so a
    reading is linear in the state and a log alone says nothing about k: with no fixes the
    scale stays at its prior instead of drifting along z = k·u. Through the water (planar)
    w_m = [u_m, tan λ · u_m + k κ r + δv_m]: the leeway λ and the hull's drift in a turn κ r
    (true units, so scaled) added to the sway; otherwise w_m is the velocity block. ``r`` the
    yaw rate (rad/s).
    """
    v = x[layout.v]
    jac = MarkovTable.of(layout).velocity_jacobian.copy()
    if layout.lam is None and layout.kap is None:
        return v.copy(), jac
    u = float(v[0])
    sway = float(v[1])
    if layout.lam is not None:
        t = math.tan(float(x[layout.lam]))
        jac[1, layout.v.start] = t
        jac[1, layout.lam] = u * (1.0 + t * t)
        sway += t * u
    if layout.kap is not None:
        k = 1.0 if layout.k is None else float(x[layout.k])
        kap = float(x[layout.kap])
        jac[1, layout.kap] = k * r
        if layout.k is not None:
            jac[1, layout.k] = kap * r
        sway += k * kap * r
    return np.array([u, sway]), jac


def velocity_vector(x: np.ndarray, layout: StateLayout,
                    r: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """
    Return w, the true velocity in its frame (heading frame or BODY), and ∂w/∂x (d × n).

    w = w_m / k (:func:`sensor_velocity`; k = 1 without a scale state): through the water
    (planar) w = [u_r, tan λ · u_r + κ r + δv]. ``r`` the yaw rate (rad/s).
    """
    w_m, jac = sensor_velocity(x, layout, r)
    if layout.k is None:
        return w_m, jac
    k = float(x[layout.k])
    w = w_m / k
    jac = jac / k
    jac[:, layout.k] -= w / k
    return w, jac


def position_rate(x: np.ndarray, layout: StateLayout, rot: np.ndarray,
                  dt_current: float = 1.0, r: float = 0.0,
                  w: tuple[np.ndarray, np.ndarray] | None = None,
                  ) -> tuple[np.ndarray, np.ndarray]:
    """
    Return Δp = rot·w + dt_current·c and its Jacobian ∂Δp/∂x (d × n).

    With ``rot`` the rotation now and ``dt_current`` = 1 this is ṗ; with ``rot`` = A (the
    rotation integrated over Δt, heading offset applied) and ``dt_current`` = Δt it is the
    displacement over the interval. The heading offset's column is S·rot·w (rotating the
    velocity by δψ). ``r`` the yaw rate (rad/s) of the turning drift; ``w`` the
    :func:`velocity_vector` (value, Jacobian) of ``x`` and ``r`` when already computed.
    """
    w_, jw = velocity_vector(x, layout, r) if w is None else w
    return _displacement(x, layout, rot, dt_current, w_, jw)


def _displacement(x: np.ndarray, layout: StateLayout, rot: np.ndarray, dt_current: float,
                  w: np.ndarray, jw: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Return :func:`position_rate` from the velocity ``w`` and its Jacobian ``jw``."""
    dp = rot @ w
    jac = rot @ jw
    if layout.c is not None:
        c0 = layout.c.start
        dp[0] += dt_current * x[c0]
        dp[1] += dt_current * x[c0 + 1]
        jac[0, c0] += dt_current
        jac[1, c0 + 1] += dt_current
    if layout.dpsi is not None:
        s = _S2 if layout.horizontal else _S3
        jac[:, layout.dpsi] = s @ (rot @ w)
    return dp, jac


def markov_steps(layout: StateLayout, dt: float) -> list[tuple[int, float, float, float]]:
    """Return (index, φ, added variance, rest value) of every Markov state over Δt."""
    return [(i, 1.0 if walk else proc.decay(dt), proc.noise(dt), rest)
            for i, proc, rest, walk in _processes(layout)]


class MarkovTable:
    """
    The Markov states of a layout as arrays, for one vectorised step (:func:`propagate`).

    The same processes as :func:`markov_steps`, evaluated at once: ``index`` the states,
    φ = exp(−Δt/τ) (1 for the heading offset's random walk), σ²(1 − exp(−2Δt/τ)) added, and
    the rest values. Built once per layout (:meth:`of`).
    """

    __slots__ = ('index', 'inv_tau', 'sigma2', 'rest', 'walk', 'identity', 'velocity_jacobian',
                 'positions', 'stack', 'layout', 'diagonal', 'any_walk')

    _cache: dict[int, MarkovTable] = {}

    def __init__(self, layout: StateLayout) -> None:
        #: The layout (kept: the cache is keyed by its id).
        self.layout = layout
        #: The other constants of the layout the propagation uses: I (n × n); ∂w_m/∂x of the
        #: velocity block alone (d × n); p and l together as one slice (they are adjacent,
        #: p first: :meth:`StateLayout.of`) and E = [I; I] (2d × d), so that the same d × d
        #: noise Q on p, l and their cross terms is E Q Eᵀ on that slice.
        d = layout.dim
        self.identity = np.eye(layout.size)
        self.velocity_jacobian = np.zeros((d, layout.size))
        self.velocity_jacobian[:, layout.v] = np.eye(d)
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

    @classmethod
    def of(cls, layout: StateLayout) -> MarkovTable:
        """Return the table of ``layout`` (cached per layout object: one per estimator)."""
        table = cls._cache.get(id(layout))
        if table is None or table.layout is not layout:
            if len(cls._cache) >= 64:
                cls._cache.clear()
            table = cls._cache[id(layout)] = cls(layout)
        return table

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
    held, φ = 1), the others decay toward their rest.
    """
    if layout.isotropic:
        procs: tuple = (SURGE,) * layout.dim
    else:
        procs = (SURGE, SWAY) if layout.horizontal else (SURGE, SWAY, HEAVE)
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


def propagate(x: np.ndarray, p_cov: np.ndarray, layout: StateLayout, a_rot: np.ndarray,
              dt: float, att_cov: np.ndarray, yaw_variance: float | None = None,
              frozen: Sequence[int] = (), r: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """
    Return x and P after the interval Δt with A = Σ R dt (heading offset applied).

    x ← f(x): p and l advance by Δp (:func:`position_rate`), the Markov states decay; P ←
    F P Fᵀ + Q with F = ∂f/∂x, Q the Markov states' exact discrete noise and the attitude
    share on p, l (the same unknown displacement of both). ``frozen`` indices (a heading
    offset not yet initialised) are held: no coupling, no noise. ``r`` the yaw rate (rad/s).
    """
    w, jw = velocity_vector(x, layout, r)
    dp, jac = _displacement(x, layout, a_rot, dt, w, jw)
    table = MarkovTable.of(layout)
    phi, q_var = table.step(dt)
    index, rest, diagonal = table.index, table.rest, table.diagonal
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
    p_new = f @ p_cov @ f.T
    p_new.ravel()[diagonal] += q_var
    q_p = attitude_share(layout, x, a_rot, att_cov, dt, yaw_variance, r, w)
    stack = table.stack                   # p and l take the same unknown displacement
    p_new[table.positions, table.positions] += stack @ q_p @ stack.T
    p_new += p_new.T
    p_new *= 0.5
    return x_new, p_new


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

    h = M w_m (:func:`sensor_velocity`: the velocity in the sensor's units, so k · M w) with
    M = R_tiltᵀ[:, 0:2] (planar: the heading frame seen from BODY) or I (free); ``r`` the
    yaw rate (rad/s).
    """
    w_m, jw = sensor_velocity(x, layout, r)
    if layout.horizontal:
        t = tilt_of(r9)
        m = np.array([[t[0], t[3]], [t[1], t[4]], [t[2], t[5]]])   # R_tiltᵀ[:, 0:2]
    else:
        m = np.eye(3)
    m = m[list(rows), :]
    return m @ w_m, m @ jw


def body_velocity(x: np.ndarray, layout: StateLayout, r9: Sequence[float], offset: float,
                  over_ground: bool = True, r: float = 0.0,
                  w: tuple[np.ndarray, np.ndarray] | None = None,
                  rot: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """
    Return the body velocity (FRD, m/s) and its Jacobian ∂ν/∂x (3 × n).

    Over ground (``over_ground``: the velocity through water plus the current seen from the
    body, Fossen eq. 2.108) or through the water (ν_r). Planar: ν = R_tiltᵀ [g; 0], g the
    horizontal velocity in the heading frame, g = w + R₂(ψ)ᵀ c over ground. ``r`` the yaw
    rate (rad/s); ``w`` the :func:`velocity_vector` (value, Jacobian) of ``x`` and ``r`` when
    already computed, ``rot`` the :func:`rotation_now` of ``r9`` and ``offset`` (neither is
    modified; the Jacobian returned is a new array).
    """
    n = layout.size
    if w is None:
        w_, jw = velocity_vector(x, layout, r)
    else:
        w_, jw = w
    current = over_ground and layout.c is not None
    if layout.horizontal:
        g, jg = w_, jw
        if current:
            if rot is None:
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
        r_full = rotation_now(layout, r9, offset) if rot is None else rot
        c3 = np.array([x[layout.c.start], x[layout.c.start + 1], 0.0])
        nu = w_ + r_full.T @ c3
        jac[:, layout.c] += r_full.T[:, 0:2]
        if layout.dpsi is not None:
            jac[:, layout.dpsi] += -(np.array(r9).reshape(3, 3).T @ (_S3 @ (_rz(offset).T @ c3)))
    return nu, jac if jac.shape == (3, n) else jac.reshape(3, n)
