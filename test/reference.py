"""A closed-form reference trajectory shared by the estimator and pipeline tests."""

from __future__ import annotations

import math

import numpy as np


class ConstantTurn:
    """
    A vessel at constant body velocity (u, v) over ground and yaw rate r from heading psi0.

    Level (phi = theta = 0), no heave; time t in s after the start, angles in rad, NED in m.
    """

    def __init__(self, u: float, v: float = 0.0, r: float = 0.0, psi0: float = 0.0) -> None:
        self.u, self.v, self.r, self.psi0 = u, v, r, psi0

    def psi(self, t: float) -> float:
        """Return the heading ψ (rad) at time t."""
        return self.psi0 + self.r * t

    def position(self, t: float) -> np.ndarray:
        """Return where the vessel is at time t, NED (m): the integral of R(ψ) [u, v] dt."""
        u, v, r, p0, p1 = self.u, self.v, self.r, self.psi0, self.psi(t)
        if r == 0.0:
            return t * np.array([u * math.cos(p0) - v * math.sin(p0),
                                 u * math.sin(p0) + v * math.cos(p0), 0.0])
        d_sin = math.sin(p1) - math.sin(p0)
        d_cos = math.cos(p1) - math.cos(p0)
        return np.array([(u * d_sin + v * d_cos) / r, (-u * d_cos + v * d_sin) / r, 0.0])

    def course(self, t: float) -> float:
        """Return the course chi = psi + atan2(v, u) (rad), wrapped to (-pi, pi]."""
        chi = self.psi(t) + math.atan2(self.v, self.u)
        return math.atan2(math.sin(chi), math.cos(chi))
