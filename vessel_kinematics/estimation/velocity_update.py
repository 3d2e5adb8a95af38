"""
The velocity updates (:class:`VelocityUpdate`): a body velocity and a ground velocity.

A body velocity (a speed log, a DVL, wheel odometry) with its scale, its gate and the
relearning of the scale, the stuck-log test (:class:`~.faults.StuckLog`), the log as an
accelerometer; and a receiver's own velocity over ground.
"""

from __future__ import annotations

import math
from typing import Sequence

import numpy as np

from vessel_kinematics.estimation import model
from vessel_kinematics.estimation.attitude import floats
from vessel_kinematics.estimation.config import (LOG_SCALE, LOG_SETTLE_MIN, LOG_SETTLE_RISE,
                                                 LOG_SETTLE_SHARE, LOG_SETTLE_TIME,
                                                 LOG_STALL_READING, LOG_STALL_SPEED,
                                                 STEADY_READING_JUMP, STEADY_READING_TIME,
                                                 SURFACE_TILT_SIGMA, UNMEASURED_VARIANCE,
                                                 VELOCITY_GATE_RESET_COUNT)
from vessel_kinematics.estimation.kalman import update
from vessel_kinematics.estimation.records import (BodyVelocity, GroundVelocity, Level, Reason,
                                                  Rejection)
from vessel_kinematics.estimation.updates import finite, flat_values, skew, Updates

__all__ = ['ACCEL_MEASURE_SPAN', 'VelocityUpdate']

#: Longest interval (s) between two log readings whose difference is taken as an acceleration.
ACCEL_MEASURE_SPAN = 2.0

_TINY_VARIANCE = 1e-12


class VelocityUpdate(Updates):
    """The body velocity and ground velocity updates (see the module notes)."""

    def velocity(self, m: BodyVelocity) -> Rejection | None:
        """Fold in a body velocity: over ground or through water, per the reference."""
        if (not finite(m.nu_b, m.omega_b, m.cov)
                or (m.omega_cov is not None and not finite(m.omega_cov))):
            return Rejection(Reason.NAN_FIELD, 'velocity with a non-finite field')
        key = (m.stamp_ns, flat_values(m.nu_b), flat_values(m.omega_b))
        refused = self._admit('velocity', key, m.stamp_ns)
        if refused is not None:
            return refused
        cfg, lay, att = self.config, self.layout, self.attitude
        self.last_velocity_ns = m.stamp_ns if self.last_velocity_ns is None else max(
            self.last_velocity_ns, m.stamp_ns)
        now = self.t if self.t is not None else m.stamp_ns
        if (m.omega_b is not None
                and not (att.omega_from_imu and att.rates_fresh(now, cfg.max_gap))
                and (m.omega_cov is None or m.omega_cov[2][2] < UNMEASURED_VARIANCE)):
            nonzero = m.omega_cov is not None and bool(np.any(m.omega_cov))
            att.rate(m.stamp_ns, floats(m.omega_b),
                     np.array(m.omega_cov, dtype=float) if nonzero else None)
            att.omega_from_imu = False
        if not cfg.velocity_input:
            return None
        cov = np.asarray(m.cov, dtype=float).tolist()
        rows = [i for i in range(3) if cov[i][i] < UNMEASURED_VARIANCE
                and not (att.level and i == 2)]
        nu = np.asarray(m.nu_b, dtype=float).tolist()
        if not rows:
            return None
        stuck = self._stuck(nu[0]) if 0 in rows else None
        if stuck is not None:
            return stuck
        self.last_surge = nu[0] if 0 in rows else self.last_surge
        ground = self._ground_observed()
        speed_log = rows == [0] and lay.k is not None        # a surge through the water
        if speed_log and ground and abs(nu[0]) < LOG_STALL_READING:
            # The wheel at a standstill: what it reads is not the boat's speed (config.py);
            # held like a silent log at once when under way (:meth:`_log_silent`), as the
            # fixes carry the speed. Turning again, it settles as at power-on.
            self._log_stalled_ns = m.stamp_ns
            self._log_stalled_under_way = abs(float(self.x[lay.v.start])) > LOG_STALL_SPEED
            self._log_run = None
            return None
        settling = speed_log and self._log_settling(m.stamp_ns, nu[0])
        returning = self._log_used_ns is not None and self.log_missing
        x_lin = self.x
        z = np.array([nu[i] for i in rows])
        h_x, h = model.velocity_measurement(x_lin, lay, att.r9, rows, self.yaw_rate)
        # The scale is told only where the fixes tell the speed over ground too, and not
        # while the heading offset is being found (:meth:`_frozen`).
        k_held = lay.k is not None and (not ground or lay.k in self._frozen())
        if not self._velocity_known or k_held:
            # Linearise where the mean explains the reading: for the first one (z = k·u at
            # u = 0 would leave u and k uncorrelated, though the reading ties them), and where
            # z = k·u is all there is of u and k is held (dead reckoning, or no heading yet):
            # the mean is u = z/k, the covariance ties u to k (the linearised update would lag
            # the reading, its gain cut by that very tie).
            step = np.linalg.lstsq(h[:, lay.v], z - h_x, rcond=None)[0]
            x_lin = self.x.copy()
            x_lin[lay.v] += step
            h_x, h = model.velocity_measurement(x_lin, lay, att.r9, rows, self.yaw_rate)
        # Every held state keeps its ∂z/∂x (a consider state: zero gain, its σ in the reading).
        y = z - h_x
        r = np.array([[cov[i][j] + _TINY_VARIANCE if i == j else cov[i][j] + 0.0 for j in rows]
                      for i in rows])
        r += self._tilt_share(h_x, rows)
        if rows == [0]:         # a speed log: unsure near its stall (config.LOG_STALL_SPEED)
            stall = LOG_STALL_SPEED * max(0.0, 1.0 - abs(z[0]) / (2.0 * LOG_STALL_SPEED))
            r[0, 0] += stall * stall
        if settling:            # just started, ramping up (config.LOG_SETTLE_TIME)
            r[0, 0] += (LOG_SETTLE_SHARE * z[0]) ** 2
        # The surge reading's own noise: what its change since the last one is tested against
        # (the turning drift below biases a reading in a turn; it is no noise of its change).
        surge_variance = float(r[0, 0]) if 0 in rows else 0.0
        steady_next = None
        if speed_log:
            steady, steady_next = self._steady(m.stamp_ns, float(z[0]), surge_variance)
            if not k_held:
                # ∂z/∂k = M w at the log's steady reading, not at the prior's speed: the prior
                # carries the noise of the readings before, which the innovation carries too
                # with the opposite sign, and a gain that moves with the innovation's noise
                # walks k where nothing observes it (a straight leg: k 1.0 → 0.43 in an hour
                # at 1 Hz; docs/validation.md).
                h[0, lay.k] = steady / float(x_lin[lay.k])
        if rows == [0] and lay.kap is not None:
            # In a turn the hull slides sideways at its turning drift v_t (about κ·r) across
            # the flow the log's wheel reads; cross-flow and heel make it read differently
            # turning to port and to starboard.
            sway = model.turn_drift(float(x_lin[lay.v.start]), float(x_lin[lay.kap]),
                                    self.yaw_rate)[0]
            r[0, 0] += sway * sway
        consider = self._consider(lay.k if k_held else None)
        # The first velocity meets an arbitrary prior: no gate until one was taken.
        gate = cfg.velocity_gate_sigma if self._velocity_known else 0.0
        res = update(x_lin, self.P, y, h, r, gate=gate, consider=consider)
        if res is not None and res.distance < 0.0:
            manoeuvre = None
            if not returning:
                manoeuvre = self._manoeuvre(m.stamp_ns, y, h, r, x_lin, consider)
            if manoeuvre is None:
                return self._gated_velocity(m, x_lin, y, h, r, -res.distance)
            res = manoeuvre
        if res is None:
            return Rejection(Reason.NUMERICAL, 'velocity update was not finite; state kept')
        self._velocity_gate_streak = 0
        rejection = self._accept(res.x, res.p, 'velocity')
        if rejection is None:
            if returning and not self.log_stalled:
                gap = (m.stamp_ns - self._log_used_ns) * 1e-9  # type: ignore[operator]
                self._event(Level.OK, f'velocity sensor back after {gap:.0f} s')
            elif 0 in rows:
                self._measured_acceleration(m.stamp_ns, nu[0], surge_variance)
            if steady_next is not None and not settling:
                self._steady_reading = steady_next
            self._log_used_ns = m.stamp_ns
            self._velocity_known = True
            self._observed(m.stamp_ns)
        return rejection

    def _log_settling(self, stamp_ns: int, reading: float) -> bool:
        """
        Return True while the log, just started, has not settled: its run extended to this.

        A run starts at a reading after ``velocity_timeout`` s without one (the log powered on,
        or back) or after a stalled one (the wheel turning again); its first reading is
        settling, and each after it while the reading still rises faster than
        :data:`~.config.LOG_SETTLE_RISE` or is within :data:`~.config.LOG_SETTLE_MIN` s of
        the last stalled reading, for at most :data:`~.config.LOG_SETTLE_TIME` s.
        """
        run = self._log_run
        if run is None or stamp_ns - run[1] > self.config.velocity_timeout * 1e9:
            self._log_run = (stamp_ns, stamp_ns, reading, False)
            return True
        first, last, last_reading, settled = run
        dt = (stamp_ns - last) * 1e-9
        if not settled and dt > 0.0:
            # A wheel turning again after a stall reads for LOG_SETTLE_MIN before it settles.
            stall = self._log_stalled_ns
            restarted = stall is not None and (stamp_ns - stall) * 1e-9 < LOG_SETTLE_MIN
            settled = ((stamp_ns - first) * 1e-9 >= LOG_SETTLE_TIME
                       or (not restarted and (reading - last_reading) / dt <= LOG_SETTLE_RISE))
        self._log_run = (first, max(last, stamp_ns), reading, settled)
        return not settled

    def _steady(self, stamp_ns: int, reading: float,
                variance: float) -> tuple[float, tuple[int, float, int]]:
        """
        Return the log's steady reading for ``reading``, and the next one, ``reading`` folded in.

        An exponential mean over :data:`~.config.STEADY_READING_TIME` s of the readings before
        this one (so that it carries none of this reading's noise), with the side (+1, -1, 0)
        of the last reading more than :data:`~.config.STEADY_READING_JUMP` σ of its own away.
        It starts anew at ``reading`` where there is none yet, where the last is older than
        STEADY_READING_TIME (a log silent or at a standstill since), and at the second reading
        in a row beyond the jump on the same side (a change of speed, or of the log's
        calibration; one such reading in ten thousand is the log's noise).
        """
        last = self._steady_reading
        if last is None or stamp_ns - last[0] > STEADY_READING_TIME * 1e9:
            return reading, (stamp_ns, reading, 0)
        side = 0
        if abs(reading - last[1]) > STEADY_READING_JUMP * math.sqrt(variance):
            side = 1 if reading > last[1] else -1
        if side * last[2] > 0:
            return reading, (stamp_ns, reading, 0)
        weight = min(1.0, max(0.0, (stamp_ns - last[0]) * 1e-9) / STEADY_READING_TIME)
        return last[1], (stamp_ns, last[1] + weight * (reading - last[1]), side)

    def _measured_acceleration(self, stamp_ns: int, surge: float, variance: float) -> None:
        """
        Raise the acceleration level to what two successive surge readings show, if they do.

        a = Δz / (k Δt) between this reading and the last accepted one (at most
        :data:`ACCEL_MEASURE_SPAN` s apart): the log as the craft's accelerometer. It counts
        when beyond three times its own noise, √(2R) / (k Δt); an IMU's specific force is not an
        input of the estimator (``ImuSample`` carries attitude and rate).
        """
        last = self._last_surge_reading
        self._last_surge_reading = (stamp_ns, surge)
        if last is None:
            return
        dt = (stamp_ns - last[0]) * 1e-9
        if not 0.0 < dt <= ACCEL_MEASURE_SPAN:
            return
        k = float(self.x[self.layout.k]) if self.layout.k is not None else 1.0
        accel = (surge - last[1]) / (k * dt)
        if abs(accel) > 3.0 * math.sqrt(2.0 * variance) / (abs(k) * dt):
            self.accel.raise_to(abs(accel))

    def _gated_velocity(self, m: BodyVelocity, x_lin: np.ndarray, y: np.ndarray,
                        h: np.ndarray, r: np.ndarray, distance: float) -> Rejection | None:
        """
        Count a refused velocity; after a run of them act on it (a recovery).

        While the fixes hold the speed over ground it is the log's calibration that changed:
        its scale is relearnt (its σ set back to the prior), the speed kept. Otherwise (dead
        reckoning, or no scale state) the velocity is re-initialised from the log.
        """
        lay = self.layout
        self._velocity_gate_streak += 1
        if self._velocity_gate_streak < VELOCITY_GATE_RESET_COUNT:
            return Rejection(Reason.INNOVATION_GATE,
                             f'velocity {distance:.1f} sigma from the estimate, beyond '
                             f'gate_sigma {self.config.velocity_gate_sigma}')
        count = self._velocity_gate_streak
        if lay.k is not None and self._ground_observed() and lay.k not in self._held():
            self._recover(f'the log disagreed with the fixes for {count} readings: its scale '
                          f'is relearnt')
            self._widen(lay.k, LOG_SCALE.sigma)
        else:
            self._recover(f'velocity re-initialised from the log after {count} readings '
                          f'refused')
            self._widen(lay.v, lay.velocity_prior)
        res = update(x_lin, self.P, y, h, r, consider=self._consider())
        self._velocity_gate_streak = 0
        if res is None:
            return Rejection(Reason.NUMERICAL, 'velocity update was not finite; state kept')
        rejection = self._accept(res.x, res.p, 'velocity')
        if rejection is None:
            self._log_used_ns = m.stamp_ns
            self._velocity_known = True
        return rejection

    def _tilt_share(self, h_x: np.ndarray, rows: Sequence[int]) -> np.ndarray:
        """
        Return what the roll and pitch error does to a body velocity reading (rows × rows).

        A small tilt error δΘ = [δφ, δθ, 0] turns the body velocity by δν = S(ν) δΘ: at speed,
        a DVL's heave row reads u δθ. The IMU's tilt covariance, bounded for a surface vessel.
        """
        nu = np.zeros(3)
        nu[list(rows)] = h_x
        s_nu = skew(nu)[:, 0:2]
        tilt = np.array(self.attitude.cov, dtype=float)[0:2, 0:2]
        if self.layout.horizontal:
            tilt = np.minimum(tilt, SURFACE_TILT_SIGMA ** 2)
        rows = list(rows)
        return s_nu[rows] @ tilt @ s_nu[rows].T

    def _stuck(self, surge: float) -> Rejection | None:
        """Test a log reading for a stuck log (:class:`~.faults.StuckLog`)."""
        detector = self.stuck_log
        was = detector.stuck
        lay = self.layout
        current: Sequence[float] = (0.0, 0.0)
        sigma = 0.0
        if lay.c is not None:
            current = self.x[lay.c].tolist()
            sigma = math.sqrt(max(0.0, 0.5 * float(np.trace(self.P[lay.c, lay.c]))))
        why = detector.reading((self.t or 0) * 1e-9, surge, self.track, current, sigma)
        if why is None:
            if was:
                self.faults.pop('log', None)
                self._event(Level.OK, 'log live again')
            return None
        if not was:
            # Found now: the surge it held is off by what the fixes saw change; they take over.
            self.faults['log'] = why
            self._event(Level.WARN, why)
            iu = lay.v.start
            self._widen(iu, math.sqrt(max(float(self.P[iu, iu]), detector.change ** 2)))
        return Rejection(Reason.FROZEN_INPUT, self.faults.get('log', why))

    def ground_velocity(self, m: GroundVelocity) -> Rejection | None:
        """
        Fold in a receiver's own velocity over ground (NED, at the antenna).

        A ground-referenced velocity in the map frame, h = ṗ + R(q)(ω × r_b) (Fossen 2.18 with
        the lever arm's rotation): it observes the velocity over ground directly, and with a
        water reference the velocity through the water plus the current.
        """
        v = np.asarray(m.v_ned, dtype=float)
        cov = np.asarray(m.cov, dtype=float)
        if v.shape != (3,) or cov.shape != (3, 3) or not finite(cov) or not (
                math.isfinite(v[0]) and math.isfinite(v[1])):
            return Rejection(Reason.NAN_FIELD, 'ground velocity with a non-finite field')
        refused = self._admit('ground_velocity', (m.stamp_ns, flat_values(v)), m.stamp_ns)
        if refused is not None:
            return refused
        lay, cfg, att = self.layout, self.config, self.attitude
        self.last_ground_velocity_ns = m.stamp_ns if self.last_ground_velocity_ns is None else \
            max(self.last_ground_velocity_ns, m.stamp_ns)
        if not self.position_ok or not cfg.gnss_enabled:
            return None
        rows = [0, 1] + ([2] if lay.dim == 3 and math.isfinite(v[2])
                         and cov[2, 2] < UNMEASURED_VARIANCE else [])
        # The receiver's NED (true north at the vessel) turned into the map's axes.
        cg, sg = math.cos(self._gamma), math.sin(self._gamma)
        z = np.array([cg * v[0] - sg * v[1], sg * v[0] + cg * v[1], v[2]])
        rot_c = np.array([[cg, -sg, 0.0], [sg, cg, 0.0], [0.0, 0.0, 1.0]])
        r_full = rot_c @ cov @ rot_c.T
        lever_b = np.array(cfg.antenna_b if m.lever_b is None else m.lever_b)
        if att.omega is not None and lever_b.any():
            z = z - self._full_rotation() @ np.cross(np.array(att.omega), lever_b)
        rot = model.rotation_now(lay, att.r9, self.heading_offset)
        h_x, h = model.ground_velocity_measurement(self.x, lay, rot, rows, self.yaw_rate)
        for i in self._frozen():
            h[:, i] = 0.0
        y = z[rows] - h_x
        r = r_full[np.ix_(rows, rows)] + np.eye(len(rows)) * _TINY_VARIANCE
        consider = self._consider()
        res = update(self.x, self.P, y, h, r, gate=cfg.velocity_gate_sigma, consider=consider)
        if res is not None and res.distance < 0.0:
            res = self._manoeuvre(m.stamp_ns, y, h, r, self.x, consider)
            if res is None:
                return Rejection(Reason.INNOVATION_GATE,
                                 'ground velocity beyond gate_sigma '
                                 f'{cfg.velocity_gate_sigma} of the estimate')
        if res is None:
            return Rejection(Reason.NUMERICAL, 'ground velocity update was not finite')
        rejection = self._accept(res.x, res.p, 'ground velocity')
        if rejection is None:
            self._ground_velocity_used_ns = m.stamp_ns
            self._observed(m.stamp_ns)
        return rejection
