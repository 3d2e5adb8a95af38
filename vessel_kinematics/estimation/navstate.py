"""
The estimator's output: the :class:`~.records.NavState` the outputs are built from.

Building it never changes the filter (a deferred time update is applied to copies).
"""

from __future__ import annotations

import math

import numpy as np

from vessel_kinematics.core import flow
from vessel_kinematics.core.quaternion import mul4, rquat9
from vessel_kinematics.estimation import model, surface
from vessel_kinematics.estimation.attitude import heading_of
from vessel_kinematics.estimation.config import (SURFACE_HEAVE_SIGMA, SURFACE_HEIGHT_SIGMA,
                                                 UNKNOWN_ATTITUDE_SIGMA)
from vessel_kinematics.estimation.filter_state import yaw_quaternion
from vessel_kinematics.estimation.propagation import Propagation
from vessel_kinematics.estimation.records import NavState, RelativeFlow

__all__ = ['NavStateOutput']


def _smoothstep(speed: float, low: float) -> float:
    """Return the weight of course/sideslip: 0 below ``low``, 1 above 2·low, smooth between."""
    if low <= 0.0:
        return 1.0 if speed > 0.0 else 0.0
    s = (speed - low) / low
    if s <= 0.0:
        return 0.0
    if s >= 1.0:
        return 1.0
    return s * s * (3.0 - 2.0 * s)


class NavStateOutput(Propagation):
    """The state for the outputs: pose, velocities, course, current, their covariances."""

    def state(self) -> NavState:
        """
        Return the current state for the outputs (call only when :attr:`ready`).

        A deferred time update is applied to copies: building outputs never changes the
        filter, so its result does not depend on when (or whether) outputs are built.
        """
        x, pm = self._pending_applied() if self.pending.dt > 0.0 else (self.x, self.P)
        lay, cfg, att = self.layout, self.config, self.attitude
        frozen = self._frozen()
        offset = self.heading_offset
        r = self.yaw_rate
        p, llh = self._where(x)
        # The attitude against the local NED (the IMU's, its heading corrected), then the map's.
        local_q = mul4(yaw_quaternion(offset - self._gamma), att.q)
        if cfg.level:      # level by definition (motion ground): the convergence alone
            q_out = mul4(yaw_quaternion(self._gamma), local_q)
        else:
            q_out = mul4(surface.map_quaternion(llh[0], llh[1],
                                                self.origin,  # type: ignore[arg-type]
                                                cfg.projection), local_q)
        if q_out[0] < 0.0:
            q_out = (-q_out[0], -q_out[1], -q_out[2], -q_out[3])
        r_full = rquat9(*q_out)
        w = model.velocity_vector(x, lay, r)
        nu, j_nu = model.body_velocity(x, lay, att.r9, offset, r=r, w=w)
        if frozen:
            j_nu[:, list(frozen)] = 0.0
        cov_nu = j_nu @ pm @ j_nu.T
        if lay.horizontal:   # the heave σ along NED down, seen from BODY: σ² r rᵀ, r = R[2, :]
            row = np.array(r_full[6:9])
            cov_nu += np.outer(row, row) * SURFACE_HEAVE_SIGMA ** 2
        cov_att = np.array(att.cov, dtype=float)
        if lay.dpsi is not None:
            cov_att[2, 2] += (UNKNOWN_ATTITUDE_SIGMA ** 2 if frozen
                              else float(pm[lay.dpsi, lay.dpsi]))
        d = lay.dim
        cov_p = np.zeros((3, 3))
        cov_local = np.zeros((3, 3))
        cov_p[0:d, 0:d] = pm[lay.p, lay.p]
        cov_local[0:d, 0:d] = pm[lay.l, lay.l]
        if d == 2:
            cov_p[2, 2] = self.surface.variance + SURFACE_HEIGHT_SIGMA ** 2
            cov_local[2, 2] = SURFACE_HEIGHT_SIGMA ** 2
        omega = np.zeros(3) if att.omega is None else np.array(att.omega)
        # Velocity over ground: ṗ in the map, then in the local NED (north the true one).
        rot = model.rotation_now(lay, att.r9, offset)
        v_map, _ = model.position_rate(x, lay, rot, r=r, w=w)
        cg, sg = math.cos(self._gamma), math.sin(self._gamma)
        v_n = np.array([cg * v_map[0] + sg * v_map[1], -sg * v_map[0] + cg * v_map[1],
                        v_map[2] if v_map.size == 3 else 0.0])
        # Course, sideslip (Fossen 2.4, the seed's sign: χ = ψ + β going ahead), α.
        psi = math.atan2(*heading_of(rquat9(*local_q))[::-1])
        vn, ve = float(v_n[0]), float(v_n[1])
        speed = math.hypot(vn, ve)
        weight = _smoothstep(speed, cfg.course_min_speed)
        chi_raw = math.atan2(ve, vn) if speed > 0.0 else psi
        cps, sps = math.cos(psi), math.sin(psi)
        g_u, g_v = cps * vn + sps * ve, -sps * vn + cps * ve
        beta_raw = math.atan2(g_v, abs(g_u)) if speed > 0.0 else 0.0
        course = float(flow.ssa(psi + weight * float(flow.ssa(chi_raw - psi))))
        sideslip = weight * beta_raw
        alpha = weight * float(flow.angle_of_attack(nu.tolist()))
        current = cov_current = relative = None
        if lay.c is not None:
            # In the map's axes, as published (``current`` is a vector in ``map``).
            current = np.array([float(x[lay.c.start]), float(x[lay.c.start + 1]), 0.0])
            cov_current = np.zeros((3, 3))
            cov_current[0:2, 0:2] = pm[lay.c, lay.c]
            nu_r, _ = model.body_velocity(x, lay, att.r9, offset, over_ground=False, r=r, w=w)
            w_r = w[0]
            speed_r = float(np.linalg.norm(nu_r))
            weight_r = _smoothstep(speed_r, cfg.course_min_speed)
            beta_r = (math.atan2(float(w_r[1]), abs(float(w_r[0]))) if lay.horizontal
                      else float(flow.sideslip(nu_r.tolist())))
            alpha_r = float(flow.angle_of_attack(nu_r.tolist()))
            relative = RelativeFlow(speed_r, weight_r * beta_r, weight_r * alpha_r)
        return NavState(
            stamp_ns=self.t, mode=self.mode, origin=self.origin,  # type: ignore[arg-type]
            p=p, q=np.array(q_out), nu=nu, omega=omega, p_local=self._local(x), cov_p=cov_p,
            cov_att=cov_att, cov_nu=cov_nu, cov_omega=np.array(att.cov_omega),
            cov_p_local=cov_local, v_n=v_n, current=current, llh=llh, course=course,
            sideslip=sideslip, angle_of_attack=alpha, cov_current=cov_current,
            low_speed=weight < 1.0, calibration=self.calibration(x, pm),
            relative_flow=relative, acceleration=float(x[lay.a.start]))
