"""
The estimator's time update: bring the state to a message's stamp (:class:`Propagation`).

The time policy is the one :mod:`.estimator` describes: a newer message propagates the state
(lazily: the time update is deferred up to ``LAZY_INTERVAL``), a gap longer than ``max_gap``
and than ``GAP_STEPS`` usual steps is crossed without integrating, an older one is refused
(:mod:`.timeline` sees that none is).
"""

from __future__ import annotations

import numpy as np

from vessel_kinematics.estimation import model
from vessel_kinematics.estimation.config import GAP_STEPS, LAZY_INTERVAL
from vessel_kinematics.estimation.filter_state import FilterState
from vessel_kinematics.estimation.records import Reason, Rejection

__all__ = ['Propagation']


class Propagation(FilterState):
    """The time update of the state (see the module notes)."""

    def _time(self, stamp_ns: int, q_end: tuple | None = None) -> Rejection | None:
        """
        Bring the state to ``stamp_ns``; return None, or the rejection of an unusable stamp.

        Stamps reach the estimator in order (:mod:`.timeline` re-applies a late one at its
        stamp); one older than the state is refused as ``too_late``, never integrated back.
        """
        if stamp_ns <= 0:
            return Rejection(Reason.ZERO_STAMP, 'header stamp is zero: the driver does not stamp')
        if self.t is None:
            self.t = self._t0 = stamp_ns
            if q_end is not None:
                self.attitude.set_q(q_end)
            return None
        if stamp_ns < self.t:
            return Rejection(Reason.TOO_LATE, f'stamp {(self.t - stamp_ns) * 1e-9:.3f} s older '
                                              'than the state')
        self._propagate(stamp_ns, q_end)
        return None

    def _propagate(self, t1: int, q_end: tuple | None) -> None:
        """Advance the attitude and the deferred time update from ``self.t`` to ``t1``."""
        dt = (t1 - self.t) * 1e-9  # type: ignore[operator]
        self.t = t1
        att = self.attitude
        if dt <= 0.0:
            if q_end is not None:
                att.set_q(q_end)
            return
        integrating = att.rates_fresh(t1, self.config.max_gap)
        if integrating and att.omega_from_imu and not att.derived:
            # The gyro's turn about the vertical, R(q)ω's down component, for the compass test.
            p, q, r = att.omega  # type: ignore[misc]
            r9 = att.r9
            self.frozen_heading.rate(dt, r9[6] * p + r9[7] * q + r9[8] * r)
        steps = self._steps
        gap = dt > self.config.max_gap and dt > GAP_STEPS * (
            sorted(steps)[len(steps) // 2] if steps else 0.0)
        steps.append(dt)
        if gap:
            self._flush()
            self._inflate_gap(dt, integrating)
            if q_end is not None:
                att.set_q(q_end)
            return
        r0, cs0 = att.r9, att.cs
        if q_end is not None:
            att.set_q(q_end)
        elif integrating:
            att.set_q(att.integrate(dt))
        self.pending.add(dt, r0, att.r9, cs0, att.cs)
        if self.pending.dt >= LAZY_INTERVAL:
            self._flush()

    def _flush(self) -> None:
        """Apply the deferred time update to the state."""
        if self.pending.dt > 0.0:
            self.x, self.P = self._pending_applied()
            self.pending = model.Pending(self.layout.horizontal)
            self._update_convergence()

    def _pending_applied(self) -> tuple[np.ndarray, np.ndarray]:
        """Return x and P after the deferred interval (new arrays)."""
        pending = self.pending
        a_rot = pending.rotation(self.layout, self.heading_offset)
        return model.propagate(self.x, self.P, self.layout, self.table, a_rot, pending.dt,
                               self.attitude.cov, self.accel.sigma, self._yaw_variance(),
                               self._frozen(), self._held(), self.yaw_rate)

    def _inflate_gap(self, dt: float, integrating: bool) -> None:
        """Advance over a gap without integrating: widen the position by what it could move."""
        lay = self.layout
        v_n = self.velocity_ned()
        speed2 = float(v_n @ v_n) + float(np.trace(self.P[lay.v, lay.v]))
        if lay.c is not None:
            speed2 += float(np.trace(self.P[lay.c, lay.c]))
        grow = np.eye(lay.dim) * (speed2 * dt * dt)
        for rows in (lay.p, lay.l):
            for cols in (lay.p, lay.l):
                self.P[rows, cols] += grow
        frozen, held = self._frozen(), self._held()
        for i, phi, var, rest in model.markov_steps(lay, dt):
            if i in frozen:
                continue
            if i in held:
                phi = 1.0
            self.x[i] = rest + phi * (self.x[i] - rest)
            self.P[i, :] *= phi
            self.P[:, i] *= phi
            self.P[i, i] += var
        _, _, q_uu, _, _ = model.singer_step(dt, self.accel.sigma)
        for iv, ia in lay.accelerated:      # the acceleration forgotten, its share on the speed
            self.x[ia] = 0.0
            self.P[ia, :] = 0.0
            self.P[:, ia] = 0.0
            self.P[ia, ia] = self.accel.sigma ** 2
            self.P[iv, iv] += q_uu
        if integrating:
            self.attitude.grow(dt)
