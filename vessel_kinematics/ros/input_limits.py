"""
The inputs' limits and checks: what makes a finite value implausible, a stamp or a covariance bad.

Each limit is a constant with its reason; the checks are plain float arithmetic (the IMU's run
at 400 Hz). :mod:`.inputs` applies them to every message it converts and re-exports them.
"""

from __future__ import annotations

import math
from typing import Any, Sequence

import numpy as np
from vessel_kinematics.core import frames
from vessel_kinematics.estimation import Reason, Rejection

__all__ = ['all_finite', 'bad_stamp', 'COVARIANCE_TOLERANCE', 'cov3_problem', 'MAX_BODY_RATE',
           'MAX_HEIGHT', 'MAX_SPEED', 'MAX_STAMP_SEC', 'MAX_VARIANCE', 'MIN_HEIGHT',
           'QUATERNION_NORM_TOLERANCE', 'stamp_problem']

#: A quaternion whose norm differs from 1 by more than this is rejected; less is normalised.
QUATERNION_NORM_TOLERANCE = 1e-3

#: Largest body speed |ν| accepted (m/s), 194 kn. Fast ferries and patrol craft do 20-30 m/s,
#: racing hydroplanes under 100 m/s; a ground robot far less. Only outright water-speed
#: record attempts (142 m/s) go beyond, and they are not this package's users. A larger
#: reading is a sensor or driver fault, and dead-reckoning it would throw the track km away.
MAX_SPEED = 100.0

#: Largest body rate |ω| accepted (rad/s), 1146 deg/s or 3.2 turns/s. A vessel's roll rate
#: stays below ~2 rad/s and its yaw rate far below; the bound is 10x that and below the
#: ±2000 deg/s full scale of common MEMS gyros, so only spikes and glitches exceed it.
MAX_BODY_RATE = 20.0

#: Lowest ellipsoidal height of a fix accepted (m): below the deepest ocean floor (Challenger
#: Deep, -10.9 km, geoid-ellipsoid separation at most ±110 m) with margin.
MIN_HEIGHT = -12_000.0

#: Highest ellipsoidal height of a fix accepted (m): above any aircraft-borne or balloon
#: survey (the stratosphere ends at 50 km); no vessel or robot fixes from higher.
MAX_HEIGHT = 50_000.0

#: Largest header stamp ``sec`` accepted: builtin_interfaces/Time.sec is an int32, and the
#: outputs carry the inputs' stamps, so a later stamp would come out wrapped negative (ROS 1
#: bags hold uint32 seconds, garbage CDR anything).
MAX_STAMP_SEC = 2 ** 31 - 1

#: Largest variance accepted in a used covariance (m², (m/s)², rad², (rad/s)²): σ = 1e6 is
#: beyond "unknown" (drivers mark unobserved axes with 1e3 .. 1e6 variances), and products of
#: two such variances (1e24) stay far from overflow in the filter.
MAX_VARIANCE = 1e12

#: Relative tolerance of the covariance checks: |c_ij - c_ji| <= tol sqrt(c_ii c_jj), and the
#: smallest eigenvalue >= -tol trace (rounding of drivers that compute their covariance in
#: float32 or print it with few digits passes; a singular, e.g. rank-1, covariance too).
COVARIANCE_TOLERANCE = 1e-6

_NS = frames.NS_PER_S


def stamp_problem(sec: int, nanosec: int) -> str | None:
    """Return why a header stamp is unusable (see :data:`MAX_STAMP_SEC`), None if it is fine."""
    if not 0 <= nanosec < _NS:
        return f'stamp nanosec {nanosec} is not in [0, 1e9)'
    if sec < 0:
        return f'stamp sec {sec} is negative'
    if sec > MAX_STAMP_SEC:
        return f'stamp sec {sec} exceeds {MAX_STAMP_SEC} (int32 builtin_interfaces/Time)'
    return None


def bad_stamp(stamp: Any) -> Rejection | None:
    """Return the rejection of an unusable stamp, None if it is fine (two comparisons)."""
    sec, nanosec = stamp.sec, stamp.nanosec
    if 0 <= sec <= MAX_STAMP_SEC and 0 <= nanosec < _NS:
        return None
    return Rejection(Reason.BAD_STAMP, stamp_problem(sec, nanosec) or 'bad stamp')


def cov3_problem(c: Sequence[float]) -> str | None:
    """
    Return why a row-major 3x3 covariance (9 finite floats) is unusable, None if it is fine.

    Usable: variances in [0, :data:`MAX_VARIANCE`], symmetric (|c_ij - c_ji| <= tol
    sqrt(c_ii c_jj)), and positive semi-definite to tol: every principal minor (the three 2x2
    and the determinant) of C + tol trace(C) I is >= 0, which for a symmetric matrix means its
    smallest eigenvalue is >= -tol trace(C) (tol = :data:`COVARIANCE_TOLERANCE`). Plain float
    arithmetic, no numpy.
    """
    a, b, c2, d, e, f, g, h, i = (float(v) for v in c)
    for v in (a, e, i):
        if v < 0.0:
            return 'a negative variance'
        if v > MAX_VARIANCE:
            return f'a variance above {MAX_VARIANCE:g}'
    tol = COVARIANCE_TOLERANCE
    if (abs(b - d) > tol * math.sqrt(a * e) or abs(c2 - g) > tol * math.sqrt(a * i)
            or abs(f - h) > tol * math.sqrt(e * i)):
        return 'not symmetric'
    shift = tol * (a + e + i)
    a, e, i = a + shift, e + shift, i + shift
    b, c2, f = 0.5 * (b + d), 0.5 * (c2 + g), 0.5 * (f + h)
    if a * e < b * b or a * i < c2 * c2 or e * i < f * f:
        return 'not positive semi-definite (an off-diagonal term exceeds its variances)'
    if a * (e * i - f * f) - b * (b * i - f * c2) + c2 * (b * f - e * c2) < 0.0:
        return 'not positive semi-definite (negative determinant)'
    return None


def all_finite(values: Any) -> bool:
    """Return True when no value is NaN or infinite (their sum is then finite, bar overflow)."""
    if isinstance(values, np.ndarray):
        values = values.tolist()
    return math.isfinite(sum(values))
