"""
What every measurement update shares (:class:`Updates`).

The plausibility test and the acceptance of a new state, the repeated-sample test, the
manoeuvre test of a refused measurement, the widening of a block and the recovery count.
"""

from __future__ import annotations

import math
from typing import Any, Sequence

import numpy as np

from vessel_kinematics.estimation import faults, model
from vessel_kinematics.estimation.config import MAX_STATE_POSITION, MAX_STATE_SPEED
from vessel_kinematics.estimation.kalman import Update, update
from vessel_kinematics.estimation.propagation import Propagation
from vessel_kinematics.estimation.records import Level, Reason, Rejection

__all__ = ['finite', 'flat_values', 'MANOEUVRE_GATE', 'MANOEUVRE_GROWTH', 'skew', 'Updates']

#: Mahalanobis distance within which a manoeuvre (:func:`~.model.manoeuvre_covariance`) must
#: explain a refused measurement: about the acceleration :data:`~.config.ACCEL_MAX` itself.
MANOEUVRE_GATE = 1.5
#: How many times farther (σ) than the fix before it a refused fix may lie and still continue
#: a manoeuvre, where no velocity is measured (``FixUpdate._growing``).
MANOEUVRE_GROWTH = 4.0


def finite(*arrays: Any) -> bool:
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


def flat_values(a: Any) -> tuple:
    """Return a vector or matrix as a flat tuple of floats (for the repeated-sample test)."""
    return () if a is None else tuple(np.ravel(a).tolist())


def skew(a: np.ndarray) -> np.ndarray:
    """Return the skew-symmetric matrix S(a) (S(a) b = a × b)."""
    return np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])


class Updates(Propagation):
    """The helpers of the measurement updates (see the module notes)."""

    @staticmethod
    def _plausible_position(p: np.ndarray) -> bool:
        """Return True when a position (NED, m from the origin) is finite and within bounds."""
        return bool(np.isfinite(p).all()) and float(np.abs(p).max()) <= MAX_STATE_POSITION

    def _plausible(self, x: np.ndarray) -> bool:
        """Return True when a state is physically possible (speeds, position, scale)."""
        lay = self.layout
        if float(np.abs(x[lay.v]).max()) > MAX_STATE_SPEED:
            return False
        if float(np.abs(x[lay.p]).max()) > MAX_STATE_POSITION:
            return False
        if lay.c is not None and float(np.abs(x[lay.c]).max()) > MAX_STATE_SPEED:
            return False
        return lay.k is None or 0.05 < float(x[lay.k]) < 20.0

    def _accept(self, x: np.ndarray, pm: np.ndarray, what: str) -> Rejection | None:
        if not self._plausible(x):
            return Rejection(Reason.IMPLAUSIBLE_STATE,
                             f'{what} would give a physically impossible state; state kept')
        self.x, self.P = x, pm
        return None

    def _repeated(self, name: str, key: tuple) -> Rejection | None:
        """Refuse a sample with the stamp and values of the last one of ``name``."""
        if faults.repeated(self._last_sample.get(name), key):
            return Rejection(Reason.FROZEN_INPUT,
                             f'{name} sample repeated: the same stamp and values as the last')
        self._last_sample[name] = key
        return None

    def _admit(self, name: str, key: tuple, stamp_ns: int) -> Rejection | None:
        """
        Refuse a repeated sample or an unusable stamp; else bring the state to ``stamp_ns``.

        The time update is applied (not deferred), so the measurement update that follows
        works on the state at its stamp.
        """
        rejection = self._repeated(name, key) or self._time(stamp_ns)
        if rejection is None:
            self._flush()
        return rejection

    def _observed(self, stamp_ns: int) -> None:
        """Note an accepted velocity-observing update: its time, the acceleration it shows."""
        lay = self.layout
        self._observed_ns = stamp_ns if self._observed_ns is None else max(self._observed_ns,
                                                                           stamp_ns)
        a = self.x[lay.a]
        # An acceleration within twice its own σ is noise, not the craft's: it counts as none.
        a2 = float(a @ a)
        significant = a2 > 4.0 * float(np.trace(self.P[lay.a, lay.a]))
        self.accel.observe(stamp_ns, math.sqrt(a2) if significant else 0.0)

    def _manoeuvre(self, stamp_ns: int, y: np.ndarray, h: np.ndarray, r: np.ndarray,
                   x_lin: np.ndarray, consider: Sequence[int],
                   since_ns: int | None = None) -> Update | None:
        """
        Return the update of a refused measurement as a manoeuvre, or None when it is not one.

        The covariance of an acceleration up to ACCEL_MAX begun since the last measurement
        that agreed (:func:`~.model.manoeuvre_covariance`; ``since_ns`` an earlier start, where
        the fixes' innovations have pointed one way since, but never before the last accepted
        velocity over ground, and never more than ``velocity_timeout`` back) is added; the
        measurement must lie within :data:`MANOEUVRE_GATE` of the prediction then. The
        acceleration level is raised to what the update finds.
        """
        if self._observed_ns is None or self.t is None:
            return None
        start = self._observed_ns if since_ns is None else min(since_ns, self._observed_ns)
        measured = self._velocity_measured_ns()
        if measured is not None:
            # A velocity measured since (over ground, or a log through the water: a manoeuvre
            # changes the speed through the water too) would have shown the manoeuvre: a fix
            # that only a change before it explains is an outlier (a wandering receiver, or a
            # position that steps 80 m and stays, as one of Irene's 2008 logs does).
            start = max(start, measured)
        # At most velocity_timeout back: a fix every 2 s falls behind a turn for longer than
        # that before it is refused, and the turn began within it.
        elapsed = min(max((self.t - start) * 1e-9, 1e-3), self.config.velocity_timeout)
        rot = model.rotation_now(self.layout, self.attitude.r9, self.heading_offset)
        pm = self.P + model.manoeuvre_covariance(self.layout, rot, elapsed)
        res = update(x_lin, pm, y, h, r, gate=MANOEUVRE_GATE, consider=consider)
        if res is None or res.distance < 0.0:
            return None
        self.accel.raise_to(float(np.linalg.norm(res.x[self.layout.a])))
        return res

    def _velocity_measured_ns(self) -> int | None:
        """Return the stamp (ns) of the last velocity taken, a log's or a receiver's, or None."""
        return max((t for t in (self._log_used_ns, self._ground_velocity_used_ns)
                    if t is not None), default=None)

    def _widen(self, block: slice | int, sigma: float | Sequence[float]) -> None:
        """Set a block's covariance to diag(σ²) (one σ, or one per state), uncorrelated."""
        self.P[block, :] = 0.0
        self.P[:, block] = 0.0
        if isinstance(block, slice):
            n = block.stop - block.start
            self.P[block, block] = np.diag(np.broadcast_to(np.square(sigma), n))
        else:
            self.P[block, block] = float(sigma) ** 2   # type: ignore[arg-type]

    def _recover(self, reason: str) -> None:
        self.recoveries += 1
        self.last_recovery = reason
        self._event(Level.WARN, f'recovery: {reason}')
