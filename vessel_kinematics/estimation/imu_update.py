"""
The IMU update (:class:`ImuUpdate`): the attitude and the body rate.

A rate-less compass's yaw rate from its headings, and the frozen-compass test
(:class:`~.faults.FrozenHeading`).
"""

from __future__ import annotations

import math
from typing import Any, Sequence

import numpy as np

from vessel_kinematics.core import flow
from vessel_kinematics.core.quaternion import mul4, rquat9
from vessel_kinematics.estimation import model
from vessel_kinematics.estimation.attitude import floats, heading_of, yaw_only
from vessel_kinematics.estimation.filter_state import yaw_quaternion
from vessel_kinematics.estimation.records import ImuSample, Level, Reason, Rejection
from vessel_kinematics.estimation.updates import finite, Updates

__all__ = ['detector_q', 'HEADING_RATE_WINDOW', 'ImuUpdate']

#: The window (s) of the headings whose slope is a rate-less compass's yaw rate: two samples
#: of a 1 Hz compass, twenty of a 10 Hz one.
HEADING_RATE_WINDOW = 2.0


class ImuUpdate(Updates):
    """The IMU update (see the module notes)."""

    def imu(self, m: ImuSample) -> Rejection | None:
        """Fold in an attitude and/or body rate; a frozen compass's attitude is refused."""
        q_nb, omega_b = m.q_nb, m.omega_b
        if q_nb is not None:
            q_nb = floats(q_nb)
        if omega_b is not None:
            omega_b = floats(omega_b)
        att_cov = self._covariance('att', m.att_cov)
        omega_cov = self._covariance('omega', m.omega_cov)
        if (not finite(q_nb, omega_b) or isinstance(att_cov, bool)
                or isinstance(omega_cov, bool)):
            return Rejection(Reason.NAN_FIELD, 'IMU sample with a non-finite field')
        repeated = self._repeated('imu', (m.stamp_ns, q_nb, omega_b))
        if repeated is not None:
            return repeated
        att = self.attitude
        q_meas = None
        refused: Rejection | None = None
        if q_nb is not None and self.config.use_orientation:
            q_meas = yaw_only(q_nb) if att.level else q_nb
            if att.last_attitude_ns is not None and m.stamp_ns < att.last_attitude_ns:
                q_meas = None  # an older attitude than the one in use
        if q_meas is not None:
            refused = self._compass(m.stamp_ns, q_meas)
            if refused is not None:
                q_meas = None
        new_axes = q_meas is not None and self.layout.isotropic and (
            not att.known or self._compass_silent(m.stamp_ns))
        late = self._time(m.stamp_ns, None if new_axes else q_meas)
        if late is not None:
            return late
        if new_axes:
            self._turn_axes(q_meas)  # type: ignore[arg-type]
        if q_meas is not None:
            att.measured(q_meas, att_cov, m.stamp_ns)
            if self.course_heading_ns is not None:
                self.course_heading_ns = None
                self._event(Level.OK, 'compass back: heading from the compass again')
        if omega_b is not None:
            att.rate(m.stamp_ns, omega_b, omega_cov)
            att.omega_from_imu, att.derived = True, False
        elif q_meas is not None:
            self._heading_rate(m.stamp_ns, q_meas)
        self.last_imu_ns = m.stamp_ns if self.last_imu_ns is None else max(
            self.last_imu_ns, m.stamp_ns)
        return refused

    def _turn_axes(self, q: Sequence[float]) -> None:
        """
        Turn the velocity over ground into the axes of a first or returning heading ``q``.

        With no velocity sensor and no heading told yet, the velocity and the acceleration
        are held in the axes of heading 0, north and east (:meth:`_yaw_variance`): a receiver's
        fixes or its own velocity may come before the compass. The first heading ψ₁ would
        turn them with it (a yacht going 142° at 2.2 kn went out at 284°, then 212° at 0.9 kn,
        its receiver's velocity refused until the fixes had turned it back). So the state
        is brought to the heading's stamp in the old axes, and v' = R(ψ₁)ᵀ R(ψ₀) v, a' the
        same, P' = T P Tᵀ: the velocity over ground and its uncertainty stay what they were.
        The same when the compass comes back after ``velocity_timeout`` s of silence
        (:meth:`_compass_silent`): the fixes and the receiver's velocity since have turned the
        velocity over ground already, in the axes of the stale heading ψ₀ (a yacht's log
        resumed after 858 s at 050° with its last heading 254°: the velocity swung 156°, its
        receiver's velocity was refused, and a manoeuvre taken instead gave 22 kn).
        """
        self._flush()
        lay = self.layout
        before = model.rotation_now(lay, self.attitude.r9, self.heading_offset)
        after = model.rotation_now(lay, rquat9(*q), self.heading_offset)
        turn = np.eye(lay.size)
        for block in (lay.v, lay.a):
            turn[block, block] = after.T @ before
        self.x = turn @ self.x
        self.P = turn @ self.P @ turn.T

    def _covariance(self, slot: str, cov: Any) -> np.ndarray | None | bool:
        """
        Return a sample's 3x3 covariance as the estimator's own array, None or False.

        None when absent or all zero (unknown), False when not finite. A driver sends the same
        covariance with every message: the last one of each ``slot`` is kept with its values,
        and the same values give the same array, the attitude's cue that nothing changed
        (``Attitude.rate``), without a new array per message at 400 Hz. The ROS edge hands
        the same read-only array for the same values: that one is known without reading it.
        """
        if cov is None:
            return None
        last = self._covariances.get(slot)
        if last is not None and cov is last[2]:     # the read-only array of the last sample
            return last[1]
        flat = tuple(np.ravel(cov).tolist())
        if not math.isfinite(sum(flat)):
            return False
        if last is not None and last[0] == flat:
            array = last[1]
        else:
            array = np.array(flat).reshape(3, 3) if any(flat) else None
        fixed = cov if isinstance(cov, np.ndarray) and not cov.flags.writeable else None
        self._covariances[slot] = (flat, array, fixed)
        return array

    def _heading_rate(self, stamp_ns: int, q: Sequence[float]) -> None:
        """
        Derive the yaw rate of a compass that gives none from its last headings.

        r = the least-squares slope of ψ over the last :data:`HEADING_RATE_WINDOW` s (at least
        three samples spanning half of it): between samples the heading is integrated
        forward with it, and the turning drift sees the turn. Never when a gyro or the
        velocity sensor gives a rate, nor for the frozen-compass test (it would test the
        compass against itself).
        """
        att = self.attitude
        fresh = att.rates_fresh(stamp_ns, self.config.max_gap)
        if att.omega is not None and not att.derived and fresh:
            return
        psi = math.atan2(*heading_of(rquat9(*q))[::-1])
        samples = self._headings
        if samples and stamp_ns <= samples[-1][0]:
            return
        if samples:
            psi = samples[-1][1] + float(flow.ssa(psi - samples[-1][1]))    # unwrapped
        samples.append((stamp_ns, psi))
        while (stamp_ns - samples[0][0]) * 1e-9 > HEADING_RATE_WINDOW:
            samples.popleft()
        if len(samples) < 3 or (stamp_ns - samples[0][0]) * 1e-9 < 0.5 * HEADING_RATE_WINDOW:
            return
        t = np.array([(k - samples[0][0]) * 1e-9 for k, _ in samples])
        y = np.array([v for _, v in samples])
        t -= t.mean()
        den = float(t @ t)
        rate = float(t @ (y - y.mean())) / den
        var = float(np.array(att.cov)[2, 2]) / den
        att.rate(stamp_ns, (0.0, 0.0, rate), np.diag([var, var, var]))
        att.omega_from_imu, att.derived = True, True

    def _compass(self, stamp_ns: int, q: Sequence[float]) -> Rejection | None:
        """Test a compass sample for a frozen compass (:class:`~.faults.FrozenHeading`)."""
        w, x, y, z = q
        psi = math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))   # the zyx yaw
        detector = self.frozen_heading
        was = detector.frozen
        why = detector.heading(stamp_ns, psi, self.track.course, self.heading_offset)
        if why is None:
            if self.faults.pop('heading', None) is not None:
                self._event(Level.OK, 'compass live again')
            return None
        if detector.jump is not None:
            # A jump held: never fused, so the attitude goes on from the rates as it was.
            if 'heading' not in self.faults:
                self.faults['heading'] = why
                self._event(Level.WARN, why)
        elif not was:
            # Found now: the heading since the run began is the frozen one turned by the gyro
            # (or the course over ground): put the attitude there, then integrate the rates.
            turn = detector.correction(self.track.course)
            att = self.attitude
            att.set_q(mul4(yaw_quaternion(turn), detector_q(att.q, detector.value)))
            self.faults['heading'] = why
            self._event(Level.WARN, why)
        return Rejection(Reason.FROZEN_INPUT, self.faults.get('heading', why))


def detector_q(q: Sequence[float], value: float | None) -> tuple[float, float, float, float]:
    """Return ``q`` with its heading set to ``value`` (rad), roll and pitch kept."""
    if value is None:
        return tuple(q)  # type: ignore[return-value]
    psi = math.atan2(*heading_of(rquat9(*q))[::-1])
    return mul4(yaw_quaternion(float(flow.ssa(value - psi))), q)
