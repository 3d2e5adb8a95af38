"""
The GNSS fix update (:class:`FixUpdate`).

The origin from the first fix, the lever arm, the position gate and its manoeuvre test, the
recovery after a run of refused fixes, and the first heading-offset estimate from the course
over ground.
"""

from __future__ import annotations

import math

import numpy as np

from vessel_kinematics.core.quaternion import rquat9
from vessel_kinematics.estimation import faults, model
from vessel_kinematics.estimation.attitude import heading_of
from vessel_kinematics.estimation.config import (ATTITUDE_SHARE_MAX_VARIANCE,
                                                 COURSE_HEADING_MIN_SPEED,
                                                 COURSE_HEADING_TURN_RATE, GATE_RESET_COUNT,
                                                 GATE_RESET_TIME, LOG_SCALE,
                                                 SETTLE_CONTINUE_SIGMA, SETTLE_TIME,
                                                 STEP_SIGMA, SURFACE_TILT_SIGMA,
                                                 SWAY_FLOOR_SPEED)
from vessel_kinematics.estimation.filter_state import OFFSET_INIT_SIGMA, wrap_lon_deg
from vessel_kinematics.estimation.imu_update import detector_q
from vessel_kinematics.estimation.kalman import Update, update
from vessel_kinematics.estimation.records import GnssFix, Level, Reason, Rejection
from vessel_kinematics.estimation.updates import finite, MANOEUVRE_GROWTH, skew, Updates

__all__ = ['FixUpdate']


#: The least variance (m², σ 1 mm) of each axis of a fix in the start-up test (a receiver
#: claiming an axis exact would make its covariance singular).
SETTLE_VARIANCE_FLOOR = 1e-6


class FixUpdate(Updates):
    """The GNSS fix update (see the module notes)."""

    def fix(self, m: GnssFix) -> Rejection | None:
        """Fold in a GNSS fix; set the origin from it when there is none yet."""
        if not (math.isfinite(m.lat) and math.isfinite(m.lon) and finite(m.cov_ned)):
            return Rejection(Reason.NAN_FIELD, 'fix with a non-finite position or covariance')
        if math.isinf(m.height):
            return Rejection(Reason.NAN_FIELD, 'fix with an infinite height')
        refused = self._admit('fix', (m.stamp_ns, m.lat, m.lon, m.height), m.stamp_ns)
        if refused is not None:
            return refused
        lay, cfg = self.layout, self.config
        if self.origin is None:
            self._origin_from_fix(m)
        self.last_fix_ns = m.stamp_ns if self.last_fix_ns is None else max(
            self.last_fix_ns, m.stamp_ns)
        lever_b = np.array(cfg.antenna_b if m.lever_b is None else m.lever_b)
        rot_full = self._full_rotation()
        lever = rot_full @ lever_b
        if lay.dim == 2:
            if math.isfinite(m.height):
                # The base's height: the antenna's less the lever arm's rise above the base.
                self.surface.update(m.stamp_ns, m.height + float(lever[2]), float(m.cov_ned[2][2]))
            # The surface point below the antenna: its map N, E (exact at any distance).
            p_antenna = self.to_ned(m.lat, m.lon, self.surface.height - float(lever[2]))
        else:
            height = m.height
            if math.isnan(height):
                height = self.origin[2] - (  # type: ignore[index]
                    float(self.x[lay.p.start + 2]) if self.position_ok else 0.0)
            p_antenna = self.to_ned(m.lat, m.lon, height)
        horizontal = math.isnan(m.height) or lay.horizontal
        if lever_b.any():
            z = p_antenna - lever
            # A small body-axis attitude error d moves the antenna by -S(R r_b) R d (m).
            s_lever = skew(lever) @ rot_full
            att_cov = np.array(self.attitude.cov, dtype=float)
            if self._frozen():
                att_cov[2, 2] = max(att_cov[2, 2], ATTITUDE_SHARE_MAX_VARIANCE)
            if lay.horizontal:          # a surface vessel's tilt is bounded, if unknown
                for i in (0, 1):
                    scale = min(1.0, SURFACE_TILT_SIGMA / math.sqrt(max(att_cov[i, i], 1e-300)))
                    att_cov[i, :] *= scale
                    att_cov[:, i] *= scale
            r = m.cov_ned + s_lever @ att_cov @ s_lever.T
        else:
            z = p_antenna
            r = np.array(m.cov_ned, dtype=float)
        rows = 2 if horizontal else 3
        t_s = m.stamp_ns * 1e-9
        if not self.position_ok:
            cov = r.copy()
            if horizontal and lay.dim == 3:
                cov[2, :] = 0.0
                cov[:, 2] = 0.0
                cov[2, 2] = cfg.gnss_default_sigma ** 2
                z[2] = 0.0
            if not self._plausible_position(z):
                return Rejection(Reason.IMPLAUSIBLE_STATE, 'fix would initialise the position '
                                 'beyond the physical bounds; not taken')
            self._init_position(z, cov)
            self._fix_taken_ns = m.stamp_ns
            self.track.add(t_s, float(z[0]), float(z[1]))
            return None
        if not cfg.gnss_enabled:
            return None
        h = model.fix_jacobian(lay, rot_full, lever_b, rows)
        for i in self._frozen():
            h[:, i] = 0.0
        y = z[0:rows] - self.x[lay.p][0:rows]
        consider = self._consider()
        rr = r[0:rows, 0:rows]
        res = update(self.x, self.P, y, h, rr, gate=cfg.gnss_gate_sigma, consider=consider)
        if res is None:
            return Rejection(Reason.NUMERICAL, 'fix update was not finite; state kept')
        since = self._trend(m.stamp_ns, y)
        previous, self._fix_distance = self._fix_distance, abs(res.distance)
        if res.distance < 0.0:
            heard = self._ground_velocity_used_ns
            if heard is not None and (m.stamp_ns - heard) * 1e-9 <= cfg.velocity_timeout:
                # A receiver's own velocity shows a manoeuvre as it happens: a fix that it does
                # not explain is an outlier, or a position that stepped (a receiver settling
                # after its start walked 180 m in 20 s at SOG 0: taken as a manoeuvre, 115 kn).
                manoeuvre = None
            elif self._fixes_alone(m.stamp_ns) and not self._growing(since, m.stamp_ns,
                                                                     previous, -res.distance):
                # With no velocity measured, a fix that jumps off alone is an outlier: the
                # 0.6 g allowed since the innovations last turned explains 60 m within 5 s (a
                # receiver alone at 1 Hz took such an outlier as 70 kn).
                manoeuvre = None
            else:
                manoeuvre = self._manoeuvre(m.stamp_ns, y, h, rr, self.x, consider, since)
            if manoeuvre is None:
                return self._gated_fix(m, z, r, -res.distance)
            res = manoeuvre
        elif self._gate_streak and res.distance > STEP_SIGMA:
            # The first fix taken after fixes refused, still far off, and no manoeuvre
            # explained them: the position stepped meanwhile (a receiver's static hold
            # released), and only its σ grown since lets the fix in. It moves the position only.
            res = self._position_step(y, h, rr, self.P) or res
        elif (step := self._settling(m.stamp_ns, y, rr)) is not None:
            # A receiver just started wanders: its fix stepped by y beyond what its noise
            # explains, the vessel did not. The position's σ grows by that step, and the fix
            # moves the position only.
            grown = self.P.copy()
            i = lay.p.start
            grown[i:i + 2, i:i + 2] += np.diag(np.square(step))
            res = self._position_step(y, h, rr, grown) or res
        self._gate_streak = 0
        rejection = self._accept(res.x, res.p, 'fix')
        if rejection is None:
            self._fix_used_ns = self._fix_taken_ns = m.stamp_ns
            self._observed(m.stamp_ns)
            self.track.add(t_s, float(z[0]), float(z[1]))
            self._update_convergence()
            if lay.dpsi is not None and not self.offset_ready:
                self._observe_offset(m.stamp_ns, z)
            self._heading_from_course(m.stamp_ns)
        return rejection

    def _growing(self, since_ns: int, stamp_ns: int, previous: float, distance: float) -> bool:
        """
        Return True when a refused fix continues the fixes before it, as a manoeuvre would.

        The previous fix was off the same way (``since_ns`` the start of the innovations'
        run, :meth:`_trend`), and was refused too or at least 1/:data:`MANOEUVRE_GROWTH` as
        far (σ): the position error of an acceleration grows as t², four-fold from the first
        second of it to the second; an outlier jumps from the noise to 20σ.
        """
        return since_ns < stamp_ns and (self._gate_streak > 0
                                        or previous * MANOEUVRE_GROWTH >= distance)

    def _fixes_alone(self, stamp_ns: int) -> bool:
        """Return True when no velocity (a log's, a receiver's) was taken in velocity_timeout."""
        measured = self._velocity_measured_ns()
        return measured is None or (stamp_ns - measured) * 1e-9 > self.config.velocity_timeout

    def _position_step(self, y: np.ndarray, h: np.ndarray, rr: np.ndarray,
                       p: np.ndarray) -> Update | None:
        """Return the fix's update of the position alone (covariance ``p``), or None."""
        lay = self.layout
        held = tuple(i for i in range(lay.size) if i not in range(lay.p.start, lay.p.stop))
        return update(self.x, p, y, h, rr, consider=held)

    def _settling(self, stamp_ns: int, y: np.ndarray, rr: np.ndarray) -> np.ndarray | None:
        """
        Return the step (N, E m) a fix's receiver made in its start-up, or None.

        In the first :data:`~.config.SETTLE_TIME` s after the first fix, with a velocity
        measured (a log, or the receiver's own) within ``velocity_timeout``: a fix beyond
        :data:`~.config.STEP_SIGMA` of its own σ is a receiver's start-up wander, and so is
        one beyond :data:`~.config.SETTLE_CONTINUE_SIGMA` (1σ) that goes on the way of a
        wander found at the fix before it. Just started, a receiver's fixes step and wander
        10-25 m within seconds while its own SOG and the log read a steady 1-3 kn (4 of 41
        yacht logs; one went 11, 5.6 and 5.5 m north at three fixes in a row, 2 s apart, while
        the boat sailed west at 1.5 kn); fused in full, the current took the wander, 2.8-3.2 kn
        within a minute of the start. The measured velocity says the speed meanwhile. The step
        is the part of y beyond that σ.
        """
        if self._position_ns is None or (stamp_ns - self._position_ns) * 1e-9 > SETTLE_TIME:
            return None
        if self._fixes_alone(stamp_ns):
            return None
        # A receiver may claim an axis exact (a zero variance): read it as 1 mm.
        r2 = rr[0:2, 0:2] + np.eye(2) * SETTLE_VARIANCE_FLOOR
        distance = math.sqrt(float(y[0:2] @ np.linalg.solve(r2, y[0:2])))
        last = self._settle_last
        limit = STEP_SIGMA
        if last is not None and last[0] == self._fix_taken_ns and float(last[1] @ y[0:2]) > 0.0:
            limit = SETTLE_CONTINUE_SIGMA      # the wander found at the fix before goes on
        if distance <= limit:
            return None
        step = y[0:2] * (1.0 - limit / distance)
        self._settle_last = (stamp_ns, step)
        return step

    def _heading_from_course(self, stamp_ns: int) -> None:
        """
        Turn a silent compass's heading to the velocity through the water, the velocity kept.

        With a velocity sensor the velocity is held along and across the heading ([u, v], or
        [u_r, b] through the water). A compass silent for ``velocity_timeout`` s with no gyro
        leaves the heading where it was, and when the vessel turns, the velocity over ground
        could only turn by the sway: the speed collapsed in every turn (a yacht's heading
        and log silent for 15 min: the speed 3 kn low). So at each fix the heading ψ is set
        where the velocity through the water w (NED; over ground without a current state) goes
        with no drift ratio: ψ = atan2(w_E, w_N) − α₀, α₀ the leeway's and the turning drift's
        angle. The velocity is re-expressed in the new axes, unchanged over ground: s' =
        g(Δ w(s)), Δ = R(ψ')ᵀR(ψ), P' = T P Tᵀ with T's velocity rows F'⁻¹(Δ J(x) − J(x') E)
        (J = ∂w/∂x, F' its velocity block at x', E the other columns). The direction then
        gains the variance of a turn at :data:`~.config.COURSE_HEADING_TURN_RATE` since the
        last fix, and the heading's own variance is that of the velocity's direction. Never
        for a velocity over ground alone (``isotropic``: its axes are north and east), below
        :data:`~.config.COURSE_HEADING_MIN_SPEED`, or while a gyro turns the heading.
        """
        lay, att = self.layout, self.attitude
        if lay.isotropic or not lay.horizontal or not self._compass_silent(stamp_ns):
            return
        w_ned = self.velocity_ned()[0:2]
        if lay.c is not None:
            w_ned = w_ned - self.x[lay.c]
        speed = math.hypot(w_ned[0], w_ned[1])
        if speed < COURSE_HEADING_MIN_SPEED:
            return
        if att.derived:
            att.omega = None        # the compass's last turn rate: stale, not the vessel's now
        r = self.yaw_rate
        iu, ib = lay.v.start, lay.v.start + 1
        along = self.x.copy()       # the same speed straight along the heading, no drift ratio
        along[iu], along[ib] = speed, 0.0
        w0, _ = model.velocity_vector(along, lay, r)
        alpha0 = math.atan2(w0[1], w0[0])
        before = model.rotation_now(lay, att.r9, self.heading_offset)
        psi = math.atan2(w_ned[1], w_ned[0]) - alpha0 - self.heading_offset
        q = detector_q(att.q, psi)
        after = model.rotation_now(lay, rquat9(*q), self.heading_offset)
        delta = after.T @ before
        w, jac = model.velocity_vector(self.x, lay, r)
        w_new = delta @ w
        x_new = self.x.copy()
        x_new[iu], x_new[ib] = w_new[0], 0.0
        if lay.water:
            base, _ = model.velocity_vector(x_new, lay, r)
            x_new[ib] = (w_new[1] - base[1]) / math.hypot(w_new[0], SWAY_FLOOR_SPEED)
        else:
            x_new[ib] = w_new[1]
        _, jac_new = model.velocity_vector(x_new, lay, r)
        f_new = jac_new[:, lay.v]
        rows = delta @ jac
        others = jac_new.copy()
        others[:, lay.v] = 0.0
        t = np.eye(lay.size)
        t[lay.v, :] = np.linalg.solve(f_new, rows - others)
        self.x, self.P = x_new, t @ self.P @ t.T
        last = self.course_heading_ns
        dt = 1.0 if last is None else min(max((stamp_ns - last) * 1e-9, 0.0),
                                          self.config.velocity_timeout)
        turn = (COURSE_HEADING_TURN_RATE * dt) ** 2          # rad² of the direction
        scale = math.hypot(w_new[0], SWAY_FLOOR_SPEED) if lay.water else 1.0
        self.P[ib, ib] += turn * (w_new[0] / scale) ** 2      # a turn δψ moves v by u·δψ
        v_sigma2 = float(self.P[ib, ib]) * scale ** 2
        att.assume(q, min(v_sigma2 / max(w_new[0] ** 2, 1e-6), math.pi ** 2))
        if last is None:
            silence = (stamp_ns - att.last_attitude_ns) * 1e-9  # type: ignore[operator]
            self._event(Level.WARN, f'compass silent for {silence:.0f} s: '
                                    'heading from the course through the water')
        self.course_heading_ns = stamp_ns

    def _trend(self, stamp_ns: int, y: np.ndarray) -> int:
        """
        Note a fix's horizontal innovation; return since when (ns) they point the way it does.

        Noise turns the innovations every way and an outlier is one alone; a manoeuvre the
        filter has not followed yet makes each lie on the side of the last (the position
        falling behind or running ahead): the start of that run is when it may have begun.
        """
        y0, y1 = float(y[0]), float(y[1])
        since = stamp_ns
        for t_ns, a, b in reversed(self._innovations):
            if a * y0 + b * y1 <= 0.0:
                break
            since = t_ns
        self._innovations.append((stamp_ns, y0, y1))
        return since

    def _gated_fix(self, m: GnssFix, z: np.ndarray, r: np.ndarray,
                   distance: float) -> Rejection | None:
        """Count a refused fix; after a run of them re-initialise the position (recovery)."""
        if self._gate_streak == 0:
            self._gate_first_ns = m.stamp_ns
        self._gate_streak += 1
        span = (m.stamp_ns - self._gate_first_ns) * 1e-9
        if self._gate_streak >= GATE_RESET_COUNT or span >= GATE_RESET_TIME:
            if not self._plausible_position(z):
                return Rejection(Reason.IMPLAUSIBLE_STATE,
                                 f'fix {distance:.1f} sigma off would re-initialise the position '
                                 'beyond the physical bounds; state kept')
            self._recover(f'position re-initialised from the fix after {self._gate_streak} '
                          f'fixes refused over {span:.1f} s (the last {distance:.0f} sigma off)')
            self._init_position(z, r)
            lay = self.layout
            heard = max((t for t in (self._log_used_ns, self._log_stalled_ns,
                                     self._ground_velocity_used_ns) if t is not None),
                        default=None)
            if heard is None or (m.stamp_ns - heard) * 1e-9 > self.config.velocity_timeout:
                # No velocity measured to say the speed: it is as unknown as the jump. A log
                # or a receiver's velocity heard keeps it.
                self._widen(lay.v, lay.velocity_prior)
            elif lay.k is not None and lay.k not in self._held():
                # The log heard and the fixes refused for so long: the dead reckoning from the
                # log is what went wrong (its calibration changed), as in the log's own
                # recovery (velocity_update).
                self._widen(lay.k, LOG_SCALE.sigma)
            self.track = faults.GnssTrack()      # the track before the jump is not this one
            self._fix_used_ns = self._fix_taken_ns = m.stamp_ns
            return None
        return Rejection(Reason.INNOVATION_GATE,
                         f'fix {distance:.1f} sigma from the estimate, beyond '
                         f'gate_sigma {self.config.gnss_gate_sigma}')

    def _observe_offset(self, stamp_ns: int, z: np.ndarray) -> None:
        """Collect fixes and IMU headings; initialise the heading offset once possible."""
        lay = self.layout
        if not self.attitude.known:
            return
        psi = heading_of(self.attitude.r9)
        known = self.declination + self._gamma
        c, s = math.cos(known), math.sin(known)
        psi = (psi[0] * c - psi[1] * s, psi[1] * c + psi[0] * s)
        self._offset_init.add(stamp_ns * 1e-9, float(z[0]), float(z[1]), psi, self.last_surge)
        guess = self._offset_init.course_minus_heading()
        if guess is None:
            return
        i = lay.dpsi
        assert i is not None                     # only with a heading-offset state
        self.x[i] = guess
        self._widen(i, OFFSET_INIT_SIGMA)
        self.offset_ready = True
        self._event(Level.OK, f'heading offset found from the course over ground: '
                              f'{math.degrees(guess):.1f} deg')

    def _origin_from_fix(self, m: GnssFix) -> None:
        lat, lon, h = self.config.origin
        if math.isnan(lat):
            lat_r, lon_r = m.lat, m.lon
        else:
            lat_r, lon_r = math.radians(lat), math.radians(wrap_lon_deg(lon))
        if math.isnan(h):
            h = 0.0 if math.isnan(m.height) else m.height
        self.origin = (float(lat_r), float(lon_r), float(h))
        self._origin_event = True
        if not self.surface.measured:
            self.surface.height = float(h)
        self._update_declination(m.stamp_ns)
