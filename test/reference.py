"""A closed-form reference trajectory and scipy's rotations, shared by the tests."""

from __future__ import annotations

import math

from hypothesis import strategies as st
import numpy as np
import pymap3d
from scipy.spatial.transform import Rotation

#: Rotations of every angle up to 3 rad about any axis (hypothesis).
rotations = st.builds(lambda v: Rotation.from_rotvec(v),
                      st.lists(st.floats(-3.0, 3.0), min_size=3, max_size=3).map(np.array))


def r_nb(q_nb) -> np.ndarray:
    """Return R_b^n of a scalar-first q_nb through scipy."""
    w, x, y, z = q_nb
    return Rotation.from_quat([x, y, z, w]).as_matrix()


def convergence(lat_deg: float, lon_deg: float, origin_deg) -> float:
    """
    Return the heading (rad, clockwise) of the local north at lat, lon in the origin's NED.

    The meridians' convergence by pymap3d: the local north rotated to ECEF, then into the
    ENU of the origin (``origin_deg``: latitude, longitude in degrees).
    """
    north = pymap3d.enu2uvw(0.0, 1.0, 0.0, lat_deg, lon_deg)
    e, n, _ = pymap3d.uvw2enu(*north, origin_deg[0], origin_deg[1])
    return math.atan2(e, n)


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
