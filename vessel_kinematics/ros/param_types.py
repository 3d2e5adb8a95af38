"""
The kinds of the navigator's parameters: their choices (enums), their bounds and their checks.

Each check takes a value as ROS holds it and returns why it is refused, in one line with at
most a short excerpt of the value (:func:`excerpt`), or None. :mod:`.params` declares the
parameters with them. The standard library only.
"""

from __future__ import annotations

import enum
import math
import re
import reprlib
from typing import Any, Callable

__all__ = ['boolean', 'Check', 'Declination', 'excerpt', 'frame_id', 'MAX_ANTENNA_OFFSET',
           'is_number', 'MAX_FRAME_ID_LENGTH', 'MAX_PUBLISH_RATE', 'MIN_PUBLISH_RATE', 'NAN',
           'number',
           'one_of', 'origin', 'ORIGIN_HIGH', 'ORIGIN_LOW', 'ParameterError', 'publish_rate',
           'REMOVED', 'SensorQos', 'TF_CHOICES', 'tf_list', 'TfTransform', 'vector3',
           'vectors3', 'topic_list', 'MAX_TOPICS', 'ImuSource', 'GnssVelocitySource',
           'VelocityReference', 'VelocitySource']

NAN = float('nan')


class ParameterError(ValueError):
    """A parameter value that the navigator refuses, with the parameter's name and the reason."""

    def __init__(self, name: str, reason: str) -> None:
        super().__init__(f'parameter {name!r}: {reason}')
        self.name = name
        self.reason = reason


_REPR = reprlib.Repr()
_REPR.maxstring, _REPR.maxother, _REPR.maxlist, _REPR.maxlevel = 40, 40, 6, 2


def excerpt(value: Any) -> str:
    """Return a short repr of ``value`` for a one-line reason (a 100k-entry list is cut)."""
    return _REPR.repr(value)


class VelocitySource(enum.StrEnum):
    """The ``velocity`` input's message type (parameter ``velocity.source``)."""

    #: geometry_msgs/TwistWithCovarianceStamped (a DVL's or a speed log's driver).
    TWIST_WITH_COVARIANCE = 'twist_with_covariance'
    #: geometry_msgs/TwistStamped (no covariance: ``velocity.default_sigma``).
    TWIST = 'twist'
    #: nav_msgs/Odometry (its twist, in its child frame).
    ODOMETRY = 'odometry'
    #: No velocity input.
    NONE = 'none'


class ImuSource(enum.StrEnum):
    """The ``imu`` inputs' message type (parameter ``imu.source``)."""

    #: sensor_msgs/Imu (REP-145): attitude and body rate.
    IMU = 'imu'
    #: geometry_msgs/QuaternionStamped: a heading or attitude only (a GNSS compass,
    #: nmea_navsat_driver's ``heading``); the yaw rate is derived from successive headings.
    QUATERNION = 'quaternion'


class GnssVelocitySource(enum.StrEnum):
    """The ``gnss_velocity`` input's message type (parameter ``gnss_velocity.source``)."""

    #: No receiver velocity input.
    NONE = 'none'
    #: geometry_msgs/TwistStamped, ENU over ground (nmea_navsat_driver's ``vel``).
    TWIST = 'twist'
    #: geometry_msgs/TwistWithCovarianceStamped, ENU over ground.
    TWIST_WITH_COVARIANCE = 'twist_with_covariance'


class VelocityReference(enum.StrEnum):
    """What the velocity is relative to (parameter ``velocity.reference``)."""

    #: The ground: bottom track, wheels.
    GROUND = 'ground'
    #: The water: a speed log, water track; the current is estimated.
    WATER = 'water'


class SensorQos(enum.StrEnum):
    """The inputs' subscription QoS (parameter ``sensor_qos``)."""

    #: rclpy's ``qos_profile_sensor_data``: best effort.
    SENSOR_DATA = 'sensor_data'
    #: Reliable.
    RELIABLE = 'reliable'


class Declination(enum.StrEnum):
    """The magnetic declination applied to the IMU heading (parameter ``imu.declination``)."""

    #: None: the IMU heading is true.
    NONE = 'none'
    #: The World Magnetic Model's at the origin and date (needs ``wmm-calculator``).
    AUTO = 'auto'


class TfTransform(enum.StrEnum):
    """A transform ``tf.publish`` can choose (REP-105 and the NED/FRD twins)."""

    #: earth -> map (static): the origin in ECEF.
    EARTH_MAP = 'earth_map'
    #: map -> odom: the fused pose's correction of the dead-reckoned one.
    MAP_ODOM = 'map_odom'
    #: odom -> base_link: the dead-reckoned pose.
    ODOM_BASE = 'odom_base'
    #: map -> map_ned and base_link -> base_link_frd (static): the frames of ``odometry/ned``.
    FRD_NED = 'frd_ned'
    #: Nothing (stands alone).
    NONE = 'none'


#: Lowest non-zero ``publish_rate`` (Hz): one output per 10 s; slower is a silent node.
MIN_PUBLISH_RATE = 0.1
#: Highest ``publish_rate`` (Hz): above the fastest input (a 400 Hz IMU) with margin.
MAX_PUBLISH_RATE = 1000.0
#: Largest |component| of a lever arm (m): beyond the largest ship's length (400 m) with
#: margin; larger values turn lever-arm covariances inf/NaN.
MAX_ANTENNA_OFFSET = 1000.0
#: ``origin`` bounds [lat deg, lon deg, ellipsoidal height m] (NaN allowed: from the first
#: fix). Heights as the inputs' limits: below the deepest ocean, above any vessel.
ORIGIN_LOW = (-90.0, -180.0, -12_000.0)
ORIGIN_HIGH = (90.0, 360.0, 50_000.0)
#: Longest frame id accepted (characters).
MAX_FRAME_ID_LENGTH = 256
#: Names that were parameters once: (their value that changed nothing, what replaces them).
#: The reader of parameters (:mod:`.params_file`) ignores them with one warning each, which
#: says when the value given meant something that is not applied.
REMOVED: dict[str, tuple[Any, str]] = {'two_d': (False, 'use motion: ground'),
                                       'publish_tf': (True, 'use tf.publish: [none]'),
                                       'reorder_window': (0.1, 'use history_length')}

# A ROS name: segments of letters, digits and underscores, not starting with a digit,
# separated by single slashes; no leading or trailing slash, no whitespace or control char.
_FRAME_ID = re.compile(r'[A-Za-z_][A-Za-z0-9_]*(?:/[A-Za-z_][A-Za-z0-9_]*)*')

#: A check: a value as ROS holds it -> why it is refused, or None.
Check = Callable[[Any], 'str | None']


def is_number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def frame_id(value: Any) -> str | None:
    if (not isinstance(value, str) or len(value) > MAX_FRAME_ID_LENGTH
            or not _FRAME_ID.fullmatch(value)):
        return ('must be a frame id of letters, digits and underscores in /-separated '
                'segments not starting with a digit (no leading slash, whitespace or control '
                f'characters), got {excerpt(value)}')
    return None


def boolean(value: Any) -> str | None:
    return None if isinstance(value, bool) else f'must be true or false, got {excerpt(value)}'


def number(low: float, high: float) -> Check:
    def check(value: Any) -> str | None:
        if not is_number(value) or not math.isfinite(value):
            return f'must be a finite number, got {excerpt(value)}'
        if value < low or value > high:
            return f'must be in [{low:g}, {high:g}], got {excerpt(value)}'
        return None
    return check


def publish_rate(value: Any) -> str | None:
    problem = number(0.0, MAX_PUBLISH_RATE)(value)
    if problem is None and 0.0 < value < MIN_PUBLISH_RATE:
        problem = (f'must be 0 (publish on each update) or in [{MIN_PUBLISH_RATE}, '
                   f'{MAX_PUBLISH_RATE:g}] Hz, got {excerpt(value)}')
    return problem


def vector3(bound: float) -> Check:
    def check(value: Any) -> str | None:
        if (not isinstance(value, (list, tuple)) or len(value) != 3
                or not all(is_number(v) for v in value)):
            return f'must be a list of 3 numbers, got {excerpt(value)}'
        if not all(math.isfinite(v) for v in value):
            return f'must hold finite numbers, got {excerpt(value)}'
        if any(abs(v) > bound for v in value):
            return f'each component must be in [{-bound:g}, {bound:g}], got {excerpt(value)}'
        return None
    return check


def vectors3(bound: float) -> Check:
    """Return the check of one or more 3-vectors, flattened (3 numbers per sensor topic)."""
    one = vector3(bound)

    def check(value: Any) -> str | None:
        if not isinstance(value, (list, tuple)) or not value or len(value) % 3:
            return f'must be a list of 3 numbers per topic, got {excerpt(value)}'
        for i in range(0, len(value), 3):
            problem = one(value[i:i + 3])
            if problem is not None:
                return problem
        return None
    return check


#: Most topics of one kind (``fix.topics``, ``imu.topics``).
MAX_TOPICS = 8
_TOPIC = re.compile(r'(?:~/|/)?[A-Za-z_][A-Za-z0-9_]*(?:/[A-Za-z_][A-Za-z0-9_]*)*')


def topic_list(value: Any) -> str | None:
    """Check a list of 1 to :data:`MAX_TOPICS` distinct ROS topic names."""
    if (not isinstance(value, (list, tuple)) or not value or len(value) > MAX_TOPICS
            or not all(isinstance(v, str) and _TOPIC.fullmatch(v) for v in value)):
        return (f'must be a list of 1 to {MAX_TOPICS} topic names (letters, digits, '
                f'underscores, / separated), got {excerpt(value)}')
    if len(set(value)) != len(value):
        return f'names a topic twice: {excerpt(value)}'
    return None


def origin(value: Any) -> str | None:
    if (not isinstance(value, (list, tuple)) or len(value) != 3
            or not all(is_number(v) for v in value)):
        return f'must be a list of 3 numbers, got {excerpt(value)}'
    if any(math.isinf(v) for v in value):
        return f'must hold finite numbers or NaN, got {excerpt(value)}'
    lat, lon, _ = value
    if math.isnan(lat) != math.isnan(lon):
        return f'latitude and longitude must both be set or both be NaN, got {excerpt(value)}'
    for name, unit, v, low, high in zip(('latitude', 'longitude', 'height'),
                                        ('degrees', 'degrees', 'm (ellipsoidal)'), value,
                                        ORIGIN_LOW, ORIGIN_HIGH):
        if not math.isnan(v) and not low <= v <= high:
            return f'{name} must be in [{low:g}, {high:g}] {unit}, got {v!r}'
    return None


def one_of(kind: type[enum.Enum]) -> Check:
    names = tuple(member.value for member in kind)

    def check(value: Any) -> str | None:
        if value not in names:
            return f'must be one of {", ".join(map(repr, names))}, got {excerpt(value)}'
        return None
    return check


TF_CHOICES = tuple(t.value for t in TfTransform if t is not TfTransform.NONE)
_TF_NAMES = frozenset(t.value for t in TfTransform)


def tf_list(value: Any) -> str | None:
    if not isinstance(value, (list, tuple)) or not all(isinstance(v, str) for v in value):
        return (f'must be a list of names from {", ".join(TF_CHOICES)} (or [none]), '
                f'got {excerpt(value)}')
    unknown = [v for v in value if v not in _TF_NAMES]
    if unknown:
        return (f'unknown transform {excerpt(unknown[0])}: choose from '
                f'{", ".join(TF_CHOICES)} (or [none])')
    if 'none' in value and len(value) > 1:
        return f"'none' must stand alone, got {excerpt(value)}"
    if len(set(value)) != len(value):
        return f'names a transform twice: {excerpt(value)}'
    return None
