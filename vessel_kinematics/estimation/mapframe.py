"""
The map frame's geodesy, in one place: latitude, longitude, height to and from map positions.

The map is the local frame about the origin (lat₀, lon₀, h₀): NED inside the estimator, ENU
(REP-105 ``map``) at the ROS edge. ``projection`` chooses the exact tangent plane through ECEF
(Fossen eqs. 2.91-2.100, :func:`~vessel_kinematics.core.geodesy.llh2ned`) or Fossen's flat-earth
approximation (eqs. 2.105-2.108). The estimator projects its fixes and its outputs with
:func:`to_ned` / :func:`to_llh`; the ``fromLL`` / ``toLL`` services answer with
:func:`map_enu` / :func:`geodetic_of_map_enu`, the same functions, so a waypoint converted by the
service lands where the navigator's own odometry would put a vessel at that point.
"""

from __future__ import annotations

import math
from typing import Sequence

import numpy as np
from vessel_kinematics.core import geodesy
from vessel_kinematics.estimation.config import Projection

__all__ = ['geodetic_of_map_enu', 'map_enu', 'to_llh', 'to_ned']

#: An origin: latitude, longitude (rad) and ellipsoidal height (m).
Origin = tuple[float, float, float]


def to_ned(origin: Origin, projection: Projection, lat: float, lon: float,
           h: float) -> np.ndarray:
    """Return the map NED position (m, (3,)) of latitude, longitude (rad) and height (m)."""
    lat0, lon0, h0 = origin
    if projection == Projection.FLAT:
        return np.array(geodesy.llh2flat(lat, lon, h, lat0, lon0, h0), dtype=float)
    return np.array(geodesy.llh2ned(lat, lon, h, lat0, lon0, h0), dtype=float)


def to_llh(origin: Origin, projection: Projection,
           p: Sequence[float]) -> tuple[float, float, float]:
    """Return latitude, longitude (rad) and height (m) of a map NED position ``p`` (m)."""
    lat0, lon0, h0 = origin
    ned = (float(p[0]), float(p[1]), float(p[2]))
    if projection == Projection.FLAT:
        lat, lon, h = geodesy.flat2llh(ned, lat0, lon0, h0)
    else:
        lat, lon, h = geodesy.ned2llh(ned, lat0, lon0, h0)
    return float(lat), float(lon), float(h)


def map_enu(origin: Origin, projection: Projection, lat_deg: float, lon_deg: float,
            h: float) -> tuple[float, float, float]:
    """
    Return the map ENU point (x east, y north, z up; m) of a geodetic point in degrees.

    A NaN height is taken as the origin's (a 2-D waypoint lies on the map's level, as
    nav2's GPS waypoints do).
    """
    height = origin[2] if math.isnan(h) else h
    n, e, d = to_ned(origin, projection, math.radians(lat_deg), math.radians(lon_deg), height)
    return float(e), float(n), float(-d)


def geodetic_of_map_enu(origin: Origin, projection: Projection, x: float, y: float,
                        z: float) -> tuple[float, float, float]:
    """Return latitude, longitude (deg, longitude in (-180, 180]) and height (m) of a map point."""
    lat, lon, h = to_llh(origin, projection, (y, x, -z))
    lon_deg = math.degrees(lon)
    lon_deg = (lon_deg + 180.0) % 360.0 - 180.0 if not -180.0 < lon_deg <= 180.0 else lon_deg
    return math.degrees(lat), lon_deg, h
