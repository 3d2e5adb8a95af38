"""
Magnetic declination from the World Magnetic Model (WMM2025), for ``imu.declination: auto``.

The declination D (also called magnetic variation) is the angle from true north to magnetic
north in the horizontal plane, east positive, so that a compass heading converts as

    psi_true = psi_magnetic + D        (NED heading, clockwise from north)

and, in the ENU yaw of REP-103 (counter-clockwise from east), yaw_true = yaw_magnetic - D: the
navigator's ``imu.yaw_offset`` that corrects a magnetic IMU heading is -D.

The field comes from the World Magnetic Model 2025 (NOAA NCEI and the British Geological Survey,
epoch 2025.0, valid from 2025.0 up to, not including, 2030.0) through NOAA's own Python package
``wmm-calculator`` (import name ``wmm``, pinned in ``.ci/requirements.txt``), which carries the
WMM2025 coefficients in the package: nothing is downloaded at run time. It reproduces all 100
of NOAA's WMM2025 test values (``test/test_magnetic.py``).

Accuracy: the model itself reproduces the main (core) field only. The WMM2025 error model gives
the declination uncertainty as sqrt(0.26^2 + (5417 nT / H)^2) deg, H the horizontal intensity:
about 0.3-0.5 deg over most of the globe (0.37 deg at Boston, H of about 20,600 nT), growing
near the magnetic poles (3.6 deg at H = 1500 nT); :func:`declination_uncertainty` returns it.
Local crustal anomalies and magnetic storms can add a degree or more locally; a ship's own
magnetic deviation is not in it at all.

Outside 2025.0-2030.0 these functions raise ValueError (no extrapolation: the model's secular
variation is not meant for it, and a silently wrong declination is worse than none); use a
fixed ``imu.yaw_offset`` for recordings from other years. Latitudes and longitudes are geodetic
(WGS-84), in rad; heights are ellipsoidal, in m.
"""

from __future__ import annotations

import calendar
import datetime
import math
import warnings

from vessel_kinematics.core.frames import NS_PER_S

__all__ = [
    'WMM_VALID_FROM',
    'WMM_VALID_UNTIL',
    'declination',
    'declination_at_stamp',
    'declination_uncertainty',
    'decimal_year',
]

#: First decimal year of WMM2025's validity (its epoch, 2025-01-01T00:00Z).
WMM_VALID_FROM = 2025.0
#: End of WMM2025's validity, excluded (2030-01-01T00:00Z).
WMM_VALID_UNTIL = 2030.0
#: WMM2025 error model of the declination: constant (deg) and horizontal-intensity (nT) terms.
_D_OFFSET_DEG = 0.26
_D_COEF_NT = 5417.0

_NS_PER_S = NS_PER_S


def decimal_year(stamp_ns: int) -> float:
    """
    Return the decimal year of a UTC time stamp (ns since the Unix epoch, as ROS stamps are).

    The year's fraction is the time since its 1 January 00:00 UTC over the year's length (365
    or 366 days), NOAA's convention: 2025-07-02T12:00Z is 2025 + 182.5 / 365. Leap seconds are
    not counted (POSIX time, as ROS stamps).
    """
    seconds, nanoseconds = divmod(int(stamp_ns), _NS_PER_S)
    year = datetime.datetime.fromtimestamp(seconds, tz=datetime.timezone.utc).year
    start = calendar.timegm((year, 1, 1, 0, 0, 0))
    length = calendar.timegm((year + 1, 1, 1, 0, 0, 0)) - start
    return year + ((seconds - start) + nanoseconds * 1e-9) / length


def _year(when: datetime.date | float) -> float:
    """Return the decimal year of a date (00:00 UTC), a datetime (naive = UTC) or a float."""
    if isinstance(when, datetime.datetime):
        moment = when if when.tzinfo is None else when.astimezone(datetime.timezone.utc)
        seconds = calendar.timegm(moment.timetuple())
        return decimal_year(seconds * _NS_PER_S + moment.microsecond * 1000)
    if isinstance(when, datetime.date):
        return decimal_year(calendar.timegm(when.timetuple()) * _NS_PER_S)
    if isinstance(when, bool) or not isinstance(when, (int, float)):
        raise TypeError(f'when must be a datetime.date or a decimal year, got {when!r}')
    return float(when)


def _field(lat_rad: float, lon_rad: float, height_m: float,
           when: datetime.date | float) -> tuple[float, float]:
    """Return WMM2025's declination (deg) and horizontal intensity H (nT) at a place and time."""
    year = _year(when)
    if not WMM_VALID_FROM <= year < WMM_VALID_UNTIL:
        raise ValueError(
            f'the World Magnetic Model (WMM2025) is valid from {WMM_VALID_FROM} up to '
            f'{WMM_VALID_UNTIL}, not at {year:.3f}: set a fixed imu.yaw_offset instead')
    values = (float(lat_rad), float(lon_rad), float(height_m))
    if not all(math.isfinite(v) for v in values):
        raise ValueError(f'latitude, longitude and height must be finite, got {values}')
    lat_deg = math.degrees(values[0])
    if abs(lat_deg) > 90.0:
        raise ValueError(f'latitude must be within [-pi/2, pi/2] rad, got {lat_rad}')
    lon_deg = math.degrees(math.remainder(values[1], 2.0 * math.pi))
    if not -1000.0 <= values[2] <= 850_000.0:
        raise ValueError(f'height must be between -1 km and 850 km (WMM), got {height_m} m')
    from wmm import wmm_calc   # deferred: numpy and the model load only when asked for

    model = wmm_calc()
    with warnings.catch_warnings():
        # Its blackout-zone warnings near the magnetic poles: declination_uncertainty says it.
        warnings.simplefilter('ignore')
        model.setup_env(lat_deg, lon_deg, values[2], unit='m', msl=False)
        model.setup_time(dyear=year)
        return float(model.get_Bdec()[0]), float(model.get_Bh()[0])


def declination(lat_rad: float, lon_rad: float, height_m: float,
                when: datetime.date | float) -> float:
    """
    Return the magnetic declination D (rad, east positive; psi_true = psi_magnetic + D).

    ``lat_rad``, ``lon_rad``: geodetic WGS-84 latitude and longitude (rad); ``height_m``: height
    above the WGS-84 ellipsoid (m); ``when``: a ``datetime.date`` (00:00 UTC), a
    ``datetime.datetime`` (naive = UTC) or a decimal year (see :func:`decimal_year` for a ROS
    stamp). From WMM2025, uncertain by about 0.3-0.5 deg (:func:`declination_uncertainty`).
    Raises ValueError outside 2025.0-2030.0 and for a non-finite or impossible position.
    """
    return math.radians(_field(lat_rad, lon_rad, height_m, when)[0])


def declination_at_stamp(lat_rad: float, lon_rad: float, height_m: float, stamp_ns: int) -> float:
    """
    Return :func:`declination` at the date of a ROS stamp (ns since the epoch, UTC).

    The estimator's declination model (``imu.declination: auto``), evaluated at the origin.
    """
    return declination(lat_rad, lon_rad, height_m, decimal_year(stamp_ns))


def declination_uncertainty(lat_rad: float, lon_rad: float, height_m: float,
                            when: datetime.date | float) -> float:
    """
    Return the WMM2025 error model's declination uncertainty (rad) at a place and time.

    sqrt(0.26^2 + (5417 nT / H)^2) deg with the model's horizontal intensity H (WMM2025
    technical report): 0.3-0.5 deg at most places, several degrees near the magnetic poles.
    Arguments as :func:`declination`.
    """
    horizontal = _field(lat_rad, lon_rad, height_m, when)[1]
    return math.radians(math.hypot(_D_OFFSET_DEG, _D_COEF_NT / horizontal))
