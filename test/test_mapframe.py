"""
The map frame's geodesy (``estimation.mapframe``) against pymap3d: what ``fromLL``/``toLL`` answer.

pymap3d's ``geodetic2enu`` / ``enu2geodetic`` (WGS-84) are an independent implementation of the
exact tangent plane; the helper must agree with them to 1 mm over a voyage's distances, both
ways, and round-trip to the float. Flat earth is checked against Fossen's eqs. 2.105-2.108
written out here.
"""

from __future__ import annotations

import math

import numpy as np
import pymap3d
import pytest
from vessel_kinematics.estimation.config import Projection
from vessel_kinematics.estimation.mapframe import geodetic_of_map_enu, map_enu

ORIGINS = [(52.73, 5.41, 43.0), (46.45, 6.55, 425.0), (-33.86, 151.21, 20.0),
           (78.2, 15.6, 30.0), (0.5, 179.99, 0.0)]
MM = 1e-3


def _points(origin, rng):
    lat0, lon0, h0 = origin
    out = []
    for distance in (1.0, 100.0, 5e3, 50e3):
        for _ in range(4):
            e, n = rng.normal(size=2) * distance
            out.append(pymap3d.enu2geodetic(e, n, rng.normal() * 20.0, lat0, lon0, h0))
    return out


@pytest.mark.parametrize('origin', ORIGINS)
def test_from_ll_agrees_with_pymap3d_to_a_millimetre(origin) -> None:
    rng = np.random.default_rng(7)
    rad = (math.radians(origin[0]), math.radians(origin[1]), origin[2])
    for lat, lon, h in _points(origin, rng):
        lon = (lon + 180.0) % 360.0 - 180.0
        got = map_enu(rad, Projection.TANGENT, lat, lon, h)
        expected = pymap3d.geodetic2enu(lat, lon, h, *origin)
        assert np.max(np.abs(np.subtract(got, expected))) < MM, (lat, lon, h)


@pytest.mark.parametrize('origin', ORIGINS)
def test_to_ll_agrees_with_pymap3d_to_a_millimetre(origin) -> None:
    rng = np.random.default_rng(11)
    rad = (math.radians(origin[0]), math.radians(origin[1]), origin[2])
    for distance in (1.0, 100.0, 5e3, 50e3):
        x, y, z = rng.normal(size=3) * (distance, distance, 20.0)
        lat, lon, h = geodetic_of_map_enu(rad, Projection.TANGENT, x, y, z)
        assert -180.0 < lon <= 180.0
        # the answer, projected back by pymap3d, lands on the point asked for
        back = pymap3d.geodetic2enu(lat, lon, h, *origin)
        assert np.max(np.abs(np.subtract(back, (x, y, z)))) < MM
        ref = pymap3d.enu2geodetic(x, y, z, *origin)
        assert abs(h - ref[2]) < MM


def test_round_trip_and_nan_height() -> None:
    rad = (math.radians(52.73), math.radians(5.41), 43.0)
    for projection in Projection:
        x, y, z = 1234.5, -987.25, 3.5
        lat, lon, h = geodetic_of_map_enu(rad, projection, x, y, z)
        assert np.allclose(map_enu(rad, projection, lat, lon, h), (x, y, z), atol=1e-6)
    # a 2-D waypoint (NaN altitude) is taken at the origin's height
    same = map_enu(rad, Projection.TANGENT, 52.74, 5.42, 43.0)
    assert map_enu(rad, Projection.TANGENT, 52.74, 5.42, math.nan) == same


def test_flat_earth_is_fossens() -> None:
    """Fossen (2.105)-(2.108): dN = dlat / atan2(1, R_M), dE = dlon / atan2(1, R_N cos lat0)."""
    lat0, lon0, h0 = 52.73, 5.41, 43.0
    a, e2 = 6378137.0, 6.69437999014e-3
    phi = math.radians(lat0)
    r_n = a / math.sqrt(1 - e2 * math.sin(phi) ** 2)
    r_m = r_n * (1 - e2) / (1 - e2 * math.sin(phi) ** 2)
    lat, lon, h = 52.75, 5.38, 40.0
    x, y, z = map_enu((phi, math.radians(lon0), h0), Projection.FLAT, lat, lon, h)
    assert y == pytest.approx(math.radians(lat - lat0) / math.atan2(1, r_m), abs=MM)
    assert x == pytest.approx(math.radians(lon - lon0) / math.atan2(1, r_n * math.cos(phi)),
                              abs=MM)
    assert z == pytest.approx(h - h0, abs=MM)
