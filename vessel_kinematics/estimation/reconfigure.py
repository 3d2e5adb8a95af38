"""
The run-time configuration change (:class:`Reconfigure`).

A new origin, projection or state layout is applied without moving the estimated geographic
position.
"""

from __future__ import annotations

import numpy as np

from vessel_kinematics.estimation import model
from vessel_kinematics.estimation.config import FilterConfig
from vessel_kinematics.estimation.layout import StateLayout
from vessel_kinematics.estimation.propagation import Propagation

__all__ = ['Reconfigure']


class Reconfigure(Propagation):
    """Apply a new configuration at run time (see the module notes)."""

    def set_config(self, config: FilterConfig) -> bool:
        """
        Apply a new configuration at run time; return True when the origin changed.

        A new origin or projection re-expresses the position through latitude, longitude and
        height, so the estimated geographic position does not move. A configuration that
        changes the state (motion, velocity reference, estimated calibrations) rebuilds the
        filter keeping the position, the local position and the velocity over ground; the
        new states start from their priors.
        """
        old = self.config
        self._flush()
        llh = self._where(self.x)[1] if self.ready else None
        self.config = config
        if StateLayout.of(config) != self.layout or config.level != old.level:
            self._relayout()
        self.attitude.level = config.level
        self.attitude.integrator = config.integrator
        changed = self._set_origin_from_config(config)
        if changed:
            self._update_declination(self.t or 0)
        elif (config.declination is None) != (old.declination is None):
            self._update_declination(self.t or 0)
        if llh is not None and (changed or config.projection != old.projection):
            self.x[self.layout.p] = self.to_ned(*llh)[0:self.layout.dim]
        if self.origin is not None and not config.gnss_enabled and not self.position_ok:
            self._init_position(np.zeros(3), np.zeros((3, 3)))
        self._gamma_at = None
        self._update_convergence()
        return changed

    def _relayout(self) -> None:
        """Rebuild the state for a new layout, keeping position, local and ground velocity."""
        old_lay, x, pm = self.layout, self.x, self.P
        v_n = self.velocity_ned() if self.position_ok else np.zeros(3)
        keep = (self.t, self._t0, self.position_ok, self.attitude, self.last_fix_ns,
                self.last_imu_ns, self.last_velocity_ns, self.surface, self._started,
                self._gamma, self._gamma_at, self._fix_taken_ns)
        self._init_state()
        (self.t, self._t0, self.position_ok, self.attitude, self.last_fix_ns, self.last_imu_ns,
         self.last_velocity_ns, self.surface, self._started, self._gamma,
         self._gamma_at, self._fix_taken_ns) = keep
        lay = self.layout
        d = min(lay.dim, old_lay.dim)
        for new_b, old_b in ((lay.p, old_lay.p), (lay.l, old_lay.l)):
            self.x[new_b.start:new_b.start + d] = x[old_b.start:old_b.start + d]
        for nb1, ob1 in ((lay.p, old_lay.p), (lay.l, old_lay.l)):
            for nb2, ob2 in ((lay.p, old_lay.p), (lay.l, old_lay.l)):
                self.P[nb1.start:nb1.start + d, nb2.start:nb2.start + d] = (
                    pm[ob1.start:ob1.start + d, ob2.start:ob2.start + d])
        rot = model.rotation_now(lay, self.attitude.r9, self.heading_offset)
        self.x[lay.v] = model.velocity_state(lay, rot.T @ v_n[0:lay.dim])

    def set_params(self, config: FilterConfig) -> bool:
        """Alias of :meth:`set_config` (the pipeline's name for it)."""
        return self.set_config(config)
