"""
The navigator's parameters: names, defaults, documentation and validation, in one place.

Both drivers use this module: the rclpy node declares every entry of :data:`PARAMETERS` as a
ROS parameter (the description becomes the ``ParameterDescriptor``), and the offline replay
reads the same names from a ROS 2 parameters file with :func:`load_params_file`. Either way the
values go through :meth:`NavigatorParams.from_flat`, so a bad value gets the same clear message
at start-up, at ``ros2 param set`` and in the replay.

This module imports the standard library and PyYAML only (and rclpy's params-file parser inside
:func:`load_params_file`, so that the replay reads files exactly as the node does).
"""

from __future__ import annotations

import array
from dataclasses import dataclass, fields
import enum
import math
from pathlib import Path
import re
from typing import Any, Callable, Mapping

from vessel_kinematics.core import frames
from vessel_kinematics.estimation.config import FilterConfig, Integrator, Motion, Projection
import yaml

__all__ = ['filter_config', 'flatten', 'FOREIGN_PARAMETER_PREFIXES', 'load_params_file',
           'MAX_ANTENNA_OFFSET', 'MAX_FRAME_ID_LENGTH', 'MAX_PUBLISH_RATE', 'MIN_PUBLISH_RATE',
           'NAN', 'NavigatorParams', 'node_pattern_matches', 'ORIGIN_HIGH', 'ORIGIN_LOW',
           'Parameter', 'ParameterError', 'PARAMETERS', 'TF_CHOICES', 'Declination',
           'SensorQos', 'VelocityReference', 'VelocitySource']

NAN = float('nan')


class ParameterError(ValueError):
    """A parameter value that the navigator refuses, with the parameter's name and the reason."""

    def __init__(self, name: str, reason: str) -> None:
        super().__init__(f'parameter {name!r}: {reason}')
        self.name = name
        self.reason = reason


@dataclass(frozen=True)
class Parameter:
    """
    One parameter: its ROS name, default value, a one-line description and its check.

    ``low``/``high``: the closed range of a number (of each component of a list), for the
    node's ``FloatingPointRange``/``IntegerRange`` descriptors; None where unbounded or not a
    number. ``check`` enforces at least that range (and may refuse more: ``publish_rate``
    takes 0 or [:data:`MIN_PUBLISH_RATE`, high]; ``origin`` bounds each component
    differently, see :data:`ORIGIN_LOW`/:data:`ORIGIN_HIGH`). ``read_only``: a run-time
    change makes no sense (set at start-up only; the descriptor's ``read_only``).
    """

    name: str
    default: Any
    description: str
    check: Callable[[Any], str | None]
    low: float | None = None
    high: float | None = None
    read_only: bool = False


def _one_of(*choices: str) -> Callable[[Any], str | None]:
    """Return a check that a value is one of ``choices`` (strings, or an enum's members)."""
    names = tuple(str(getattr(c, 'value', c)) for c in choices)

    def check(value: Any) -> str | None:
        if value not in names:
            return f'must be one of {", ".join(repr(c) for c in names)}, got {value!r}'
        return None
    return check


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
    #: The World Magnetic Model's at the origin and date.
    AUTO = 'auto'


#: Lowest non-zero ``publish_rate`` (Hz): one output per 10 s; slower is a silent node.
MIN_PUBLISH_RATE = 0.1
#: Highest ``publish_rate`` (Hz): above the fastest input (a 400 Hz IMU) with margin.
MAX_PUBLISH_RATE = 1000.0
#: Largest |component| of ``gnss.antenna_position`` (m): beyond the largest ship's length
#: (400 m) with margin; larger values turn lever-arm covariances inf/NaN.
MAX_ANTENNA_OFFSET = 1000.0
#: ``origin`` bounds [lat deg, lon deg, ellipsoidal height m] (NaN allowed: from the first
#: fix). Heights as ros_io's MIN_HEIGHT/MAX_HEIGHT: below the deepest ocean, above any vessel.
ORIGIN_LOW = (-90.0, -180.0, -12_000.0)
ORIGIN_HIGH = (90.0, 360.0, 50_000.0)
#: Longest frame id accepted (characters).
MAX_FRAME_ID_LENGTH = 256

# A ROS name: segments of letters, digits and underscores, not starting with a digit,
# separated by single slashes; no leading or trailing slash, no whitespace or control char.
_FRAME_ID = re.compile(r'[A-Za-z_][A-Za-z0-9_]*(?:/[A-Za-z_][A-Za-z0-9_]*)*')


def _frame_id(value: Any) -> str | None:
    if (not isinstance(value, str) or len(value) > MAX_FRAME_ID_LENGTH
            or not _FRAME_ID.fullmatch(value)):
        return ('must be a frame id of letters, digits and underscores in /-separated '
                'segments not starting with a digit (no leading slash, whitespace or control '
                f'characters), got {value!r}')
    return None


def _boolean(value: Any) -> str | None:
    return None if isinstance(value, bool) else f'must be true or false, got {value!r}'


def _number(low: float, high: float, *, low_open: bool = False) -> Callable[[Any], str | None]:
    def check(value: Any) -> str | None:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            return f'must be a finite number, got {value!r}'
        if not math.isfinite(value):
            return f'must be a finite number, got {value!r}'
        if value < low or value > high or (low_open and value == low):
            bracket = '(' if low_open else '['
            return f'must be in {bracket}{low}, {high}], got {value!r}'
        return None
    return check


def _rate(value: Any) -> str | None:
    problem = _number(0.0, MAX_PUBLISH_RATE)(value)
    if problem is None and 0.0 < value < MIN_PUBLISH_RATE:
        problem = (f'must be 0 (publish on each update) or in [{MIN_PUBLISH_RATE}, '
                   f'{MAX_PUBLISH_RATE}] Hz, got {value!r}')
    return problem


def _vector3(*, allow_nan: bool = False, bound: float | None = None,
             ) -> Callable[[Any], str | None]:
    def check(value: Any) -> str | None:
        if not isinstance(value, (list, tuple)) or len(value) != 3:
            return f'must be a list of 3 numbers, got {value!r}'
        for v in value:
            if isinstance(v, bool) or not isinstance(v, (int, float)):
                return f'must be a list of 3 numbers, got {value!r}'
            if not allow_nan and not math.isfinite(v):
                return f'must hold finite numbers, got {value!r}'
            if allow_nan and math.isinf(v):
                return f'must hold finite numbers or NaN, got {value!r}'
            if bound is not None and abs(v) > bound:
                return f'each component must be in [{-bound:g}, {bound:g}], got {value!r}'
        return None
    return check


#: The transforms ``tf.publish`` can choose (REP-105 earth -> map -> odom -> base_link, and the
#: static NED/FRD twins ``map -> map_ned``, ``base_link -> base_link_frd`` of ``odometry/ned``).
TF_CHOICES = ('earth_map', 'map_odom', 'odom_base', 'frd_ned')


def _tf_list(value: Any) -> str | None:
    if not isinstance(value, (list, tuple)) or not all(isinstance(v, str) for v in value):
        return f'must be a list of names from {", ".join(TF_CHOICES)} (or [none]), got {value!r}'
    unknown = [v for v in value if v not in TF_CHOICES + ('none',)]
    if unknown:
        return (f'unknown transform {unknown[0]!r}: choose from {", ".join(TF_CHOICES)} '
                f'(or [none])')
    if 'none' in value and len(value) > 1:
        return f"'none' must stand alone, got {value!r}"
    return None


def _origin(value: Any) -> str | None:
    problem = _vector3(allow_nan=True)(value)
    if problem:
        return problem
    lat, lon, height = value
    if math.isnan(lat) != math.isnan(lon):
        return f'latitude and longitude must both be set or both be NaN, got {value!r}'
    names = ('latitude', 'longitude', 'height')
    units = ('degrees', 'degrees', 'm (ellipsoidal)')
    for name, unit, v, low, high in zip(names, units, value, ORIGIN_LOW, ORIGIN_HIGH):
        if not math.isnan(v) and not low <= v <= high:
            return f'{name} must be in [{low:g}, {high:g}] {unit}, got {v!r}'
    return None


#: Every parameter of the navigator, in the order of ``config/navigator.yaml``.
PARAMETERS: tuple[Parameter, ...] = (
    Parameter('map_frame', 'map', 'ENU frame about the origin (REP-105 map): fused pose',
              _frame_id, read_only=True),
    Parameter('odom_frame', 'odom', 'continuous dead-reckoned frame (REP-105 odom)',
              _frame_id, read_only=True),
    Parameter('base_frame', 'base_link', 'the vessel body frame, FLU (REP-103)', _frame_id,
              read_only=True),
    Parameter('earth_frame', 'earth', 'ECEF frame (REP-105 earth), parent of map in TF',
              _frame_id, read_only=True),
    Parameter('origin', [NAN, NAN, NAN],
              'NED/ENU origin [lat deg, lon deg, ellipsoidal height m]; NaN = first valid fix; '
              'NaN height = height of the first fix', _origin),
    Parameter('projection', 'tangent',
              "'tangent': exact local NED through ECEF; "
              "'flat': Fossen's flat-earth approximation",
              _one_of(*Projection), read_only=True),
    Parameter('gnss.enabled', True, 'false: pure dead reckoning, fixes only set the origin',
              _boolean),
    Parameter('gnss.antenna_position', [0.0, 0.0, 0.0],
              'GNSS antenna in the base frame (FLU, m), removed with the current attitude',
              _vector3(bound=MAX_ANTENNA_OFFSET), -MAX_ANTENNA_OFFSET, MAX_ANTENNA_OFFSET),
    Parameter('gnss.default_sigma', 2.5,
              'standard deviation (m) of each axis of a fix whose covariance is unknown',
              _number(1e-3, 1e4), 1e-3, 1e4),
    Parameter('gnss.gate_sigma', 5.0,
              'reject a fix whose innovation (Mahalanobis distance) exceeds this many standard '
              'deviations (0 = accept all); a run of refused fixes re-initialises the position',
              _number(0.0, 1e3), 0.0, 1e3),
    Parameter('imu.mounting_rpy', [0.0, 0.0, 0.0],
              'IMU frame in the base frame, [roll, pitch, yaw] rad, '
              'R = Rz(yaw) Ry(pitch) Rx(roll)',
              _vector3(bound=2 * math.pi), -2 * math.pi, 2 * math.pi),
    Parameter('imu.use_orientation', True,
              'take attitude from Imu.orientation when provided, else integrate angular rate',
              _boolean),
    Parameter('imu.yaw_offset', 0.0,
              'added to the IMU yaw (rad, ENU counter-clockwise), a fixed correction',
              _number(-2 * math.pi, 2 * math.pi), -2 * math.pi, 2 * math.pi),
    Parameter('imu.declination', 'none',
              "'none', or 'auto': the magnetic declination at the origin and date from the "
              'World Magnetic Model, for a magnetic IMU heading',
              _one_of(*Declination)),
    Parameter('imu.estimate_yaw_offset', False,
              'estimate a constant offset of the IMU heading (any angle) from the course over '
              'ground of the fixes while moving',
              _boolean),
    Parameter('velocity.source', 'twist_with_covariance',
              'body velocity input type: twist_with_covariance, twist, odometry or none',
              _one_of(*VelocitySource)),
    Parameter('velocity.reference', 'ground',
              'ground (bottom track, wheels) or water (speed log, water track: '
              'current estimated)',
              _one_of(*VelocityReference)),
    Parameter('velocity.mounting_rpy', [0.0, 0.0, 0.0],
              'velocity sensor frame in the base frame, [roll, pitch, yaw] rad, '
              'R = Rz(yaw) Ry(pitch) Rx(roll); used when its frame is not in /tf_static',
              _vector3(bound=2 * math.pi), -2 * math.pi, 2 * math.pi),
    Parameter('velocity.sensor_position', [0.0, 0.0, 0.0],
              'velocity sensor in the base frame (FLU, m): its lever arm, v_base = '
              'R v_sensor - omega x r; used when its frame is not in /tf_static',
              _vector3(bound=MAX_ANTENNA_OFFSET), -MAX_ANTENNA_OFFSET, MAX_ANTENNA_OFFSET),
    Parameter('velocity.default_sigma', 0.1,
              'standard deviation (m/s) of a body velocity whose covariance is unknown or zero',
              _number(1e-4, 100.0), 1e-4, 100.0),
    Parameter('velocity.gate_sigma', 5.0,
              'reject a velocity whose innovation exceeds this many standard deviations '
              '(0 = accept all); a run of refused velocities re-initialises the velocity',
              _number(0.0, 1e3), 0.0, 1e3),
    Parameter('velocity.estimate_scale', True,
              "water reference: estimate the log's scale factor (reading / truth) with the "
              'current', _boolean),
    Parameter('velocity.estimate_leeway', True,
              'water reference, surface motion: estimate a constant leeway angle',
              _boolean),
    Parameter('motion', 'surface',
              "'surface': a vessel, height and vertical velocity held at zero, roll and pitch "
              "from the IMU; 'ground': a planar vehicle, roll and pitch zero too; "
              "'free': full 3-D (underwater vehicles)",
              _one_of(*Motion)),
    Parameter('course.min_speed', 0.3,
              'speed over ground (m/s) below which course falls back to heading and sideslip '
              'to zero (blended smoothly up to twice this)',
              _number(0.0, 100.0), 0.0, 100.0),
    Parameter('integrator', 'exponential',
              "'exponential' (exact for constant rate) or 'euler' "
              "(Fossen's step + normalisation)",
              _one_of(*Integrator)),
    Parameter('two_d', False, "deprecated: true is motion 'ground'",
              _boolean),
    Parameter('max_gap', 1.0, 'no integration across a gap between stamps longer than this (s)',
              _number(1e-3, 3600.0), 1e-3, 3600.0),
    Parameter('reorder_window', 0.1,
              'a message older than the state by at most this (s) is used without integrating '
              'backwards; older ones are rejected; a stamp further back than max_gap resets',
              _number(0.0, 10.0), 0.0, 10.0),
    Parameter('publish_rate', 30.0,
              f'output rate (Hz), in [{MIN_PUBLISH_RATE}, {MAX_PUBLISH_RATE}]; 0 = publish on '
              "each update. 30 Hz as robot_localization's frequency: an autopilot wants a "
              'steady rate, not one output set per IMU message (400 a second from a 400 Hz IMU)',
              _rate, 0.0, MAX_PUBLISH_RATE),
    Parameter('sensor_qos', 'sensor_data',
              "subscription QoS: 'sensor_data' (best effort) or 'reliable'",
              _one_of(*SensorQos)),
    Parameter('tf.publish', list(TF_CHOICES),
              'transforms to publish on /tf and /tf_static: earth_map (static), map_odom, '
              'odom_base, frd_ned (static map->map_ned, base->base_frd); [none] for none',
              _tf_list),
    Parameter('publish_tf', True,
              'deprecated: false is tf.publish [none]', _boolean),
    Parameter('diagnostics.stale_warn', 2.0,
              'an input whose last message is older than this (s) is WARN (late)',
              _number(0.01, 3600.0), 0.01, 3600.0),
    Parameter('diagnostics.stale_error', 5.0,
              'an input whose last message is older than this (s) is ERROR (gone)',
              _number(0.01, 3600.0), 0.01, 3600.0),
)

_BY_NAME: dict[str, Parameter] = {p.name: p for p in PARAMETERS}


@dataclass(frozen=True)
class NavigatorParams:
    """
    The validated parameters, with Python names (``gnss.enabled`` becomes ``gnss_enabled``).

    Angles are in radians except ``origin``, which keeps the ROS convention of degrees for
    latitude and longitude (as in ``sensor_msgs/NavSatFix``).
    """

    map_frame: str = 'map'
    odom_frame: str = 'odom'
    base_frame: str = 'base_link'
    earth_frame: str = 'earth'
    origin: tuple[float, float, float] = (NAN, NAN, NAN)
    projection: str = 'tangent'
    gnss_enabled: bool = True
    gnss_antenna_position: tuple[float, float, float] = (0.0, 0.0, 0.0)
    gnss_default_sigma: float = 2.5
    gnss_gate_sigma: float = 5.0
    imu_mounting_rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)
    imu_use_orientation: bool = True
    imu_yaw_offset: float = 0.0
    imu_declination: str = 'none'
    imu_estimate_yaw_offset: bool = False
    velocity_source: str = 'twist_with_covariance'
    velocity_reference: str = 'ground'
    velocity_mounting_rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)
    velocity_sensor_position: tuple[float, float, float] = (0.0, 0.0, 0.0)
    velocity_default_sigma: float = 0.1
    velocity_gate_sigma: float = 5.0
    velocity_estimate_scale: bool = True
    velocity_estimate_leeway: bool = True
    motion: str = 'surface'
    course_min_speed: float = 0.3
    integrator: str = 'exponential'
    two_d: bool = False
    max_gap: float = 1.0
    reorder_window: float = 0.1
    publish_rate: float = 30.0
    sensor_qos: str = 'sensor_data'
    tf_publish: tuple[str, ...] = TF_CHOICES
    publish_tf: bool = True
    diagnostics_stale_warn: float = 2.0
    diagnostics_stale_error: float = 5.0

    @property
    def tf_set(self) -> frozenset[str]:
        """Return the transforms to publish: ``tf.publish`` less 'none' (none w/o publish_tf)."""
        if not self.publish_tf:
            return frozenset()
        return frozenset(self.tf_publish) - {'none'}

    @classmethod
    def from_flat(cls, values: Mapping[str, Any]) -> NavigatorParams:
        """
        Validate ROS-named values (``{'gnss.enabled': False, ...}``) over the defaults.

        Integers are accepted where a float is expected. Unknown names raise
        :class:`ParameterError`, as do values of the wrong type or out of range.
        """
        merged = {p.name: p.default for p in PARAMETERS}
        for name, value in values.items():
            if name not in _BY_NAME:
                raise ParameterError(name, 'unknown parameter of the navigator')
            merged[name] = value
        kwargs: dict[str, Any] = {}
        if _as_number(merged.get('diagnostics.stale_warn')) > _as_number(
                merged.get('diagnostics.stale_error')):
            raise ParameterError('diagnostics.stale_warn',
                                 'must not exceed diagnostics.stale_error')
        for name, value in merged.items():
            problem = _BY_NAME[name].check(value)
            if problem:
                raise ParameterError(name, problem)
            if isinstance(value, (list, tuple)) and name == 'tf.publish':
                value = tuple(value)
            elif isinstance(value, (list, tuple)):
                value = tuple(float(v) for v in value)
            elif isinstance(_BY_NAME[name].default, float):
                value = float(value)
            kwargs[name.replace('.', '_')] = value
        return cls(**kwargs)

    def to_flat(self) -> dict[str, Any]:
        """Return the ROS-named values (lists for vectors), the inverse of :meth:`from_flat`."""
        out: dict[str, Any] = {}
        by_attr = {p.name.replace('.', '_'): p.name for p in PARAMETERS}
        for f in fields(self):
            value = getattr(self, f.name)
            out[by_attr[f.name]] = list(value) if isinstance(value, tuple) else value
        return out


def _as_number(value: Any) -> float:
    """Return ``value`` as a float for a comparison (NaN when it is no number)."""
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return float(value)
    return NAN


def flatten(tree: Mapping[str, Any], prefix: str = '') -> dict[str, Any]:
    """Flatten nested YAML mappings into ROS dotted names: ``{'gnss': {'enabled': x}}``."""
    flat: dict[str, Any] = {}
    for key, value in tree.items():
        name = f'{prefix}{key}'
        if isinstance(value, Mapping):
            flat.update(flatten(value, name + '.'))
        else:
            flat[name] = value
    return flat


#: Names in a params file or on the command line that are not the navigator's but belong to
#: every rclpy node (use_sim_time, qos_overrides.<topic>.<entity>.<policy>, ...): the node
#: takes them as rclpy does, the replay accepts and ignores them.
FOREIGN_PARAMETER_PREFIXES = ('use_sim_time', 'qos_overrides.',
                              'start_type_description_service')


def node_pattern_matches(pattern: str, node_fqn: str) -> bool:
    """
    Return whether a params-file key names the node ``node_fqn``, as rcl matches them.

    Keys are ``/**``, ``/**/navigator``, ``ns/navigator``...; ``node_fqn`` is ``/ns/navigator``.
    A key without a leading slash is absolute (rcl prepends one); ``/**`` stands for any
    number of namespace tokens, ``/*`` for exactly one.
    """
    key = pattern if pattern.startswith('/') else '/' + pattern
    regex = ''
    i = 0
    while i < len(key):
        if key.startswith('/**', i):
            regex += '(/[^/]+)*'
            i += 3
        elif key.startswith('/*', i):
            regex += '/[^/]+'
            i += 2
        else:
            regex += re.escape(key[i])
            i += 1
    return re.fullmatch(regex, node_fqn) is not None


def load_params_file(path: str | Path, node_fqn: str = '/navigator') -> dict[str, Any]:
    """
    Read a ROS 2 parameters file with rclpy's parser; return the node's values, flat.

    Every section whose key matches ``node_fqn`` as rcl matches it
    (:func:`node_pattern_matches`: ``/**``, ``/**/navigator``, ``/ns/navigator``,
    ``navigator``) contributes its ``ros__parameters``, later sections in the file overriding
    earlier ones, as ``--params-file`` does for the node. Values keep their YAML types
    (``max_gap: 2`` is an integer; :meth:`NavigatorParams.from_flat` takes it where a double
    is expected, as the node does). Names of :data:`FOREIGN_PARAMETER_PREFIXES` are dropped.
    Raises :class:`ParameterError` with one line when the file cannot be used.
    """
    from rclpy.parameter import Parameter as RosParameter, parameter_dict_from_yaml_file
    path = Path(path)
    if not node_fqn.startswith('/'):
        node_fqn = '/' + node_fqn
    try:
        document = yaml.safe_load(path.read_text())
    except OSError as error:
        raise ParameterError('--params-file', f'cannot read {path}: {error.strerror}') from error
    except (yaml.YAMLError, UnicodeDecodeError) as error:
        raise ParameterError('--params-file',
                             f'{path} is not valid YAML: {str(error).splitlines()[0]}') from error
    if not isinstance(document, Mapping):
        raise ParameterError('--params-file', f'{path} holds no parameters mapping')
    keys = [key for key in document
            if isinstance(key, str) and node_pattern_matches(key, node_fqn)]
    if not keys:   # as for the node: nothing in the file is for it (the caller may warn)
        return {}
    try:
        messages = parameter_dict_from_yaml_file(str(path), use_wildcard=False,
                                                 target_nodes=keys)
    except (RuntimeError, TypeError, ValueError) as error:
        raise ParameterError('--params-file', f'{path}: {error}') from error
    # rclpy's parser re-reads each value from its str(): a YAML .nan (a double for rcl) comes
    # back as the string 'nan'. Such a value is taken as YAML wrote it.
    raw: dict[str, Any] = {}
    for key in keys:
        section = document[key].get('ros__parameters') if isinstance(document[key], Mapping) \
            else None
        if isinstance(section, Mapping):
            raw.update(flatten(section))
    values: dict[str, Any] = {}
    for name, message in messages.items():
        if name.startswith(FOREIGN_PARAMETER_PREFIXES):
            continue
        value = RosParameter.from_parameter_msg(message).value
        value = list(value) if isinstance(value, (tuple, array.array)) else value
        if _has_nan(raw.get(name)):
            value = raw[name]
        values[name] = value
    return values


def filter_config(params: NavigatorParams) -> FilterConfig:
    """
    Return the estimator's configuration from the node's parameters (ROS -> Fossen frames).

    ``two_d: true`` is the deprecated spelling of ``motion: ground``. The antenna lever arm
    turns from FLU to FRD; ``imu.declination: auto`` becomes the World Magnetic Model at the
    origin (:mod:`vessel_kinematics.estimation.magnetic`).
    """
    motion = Motion.GROUND if params.two_d else Motion(params.motion)
    frd = frames.flu_to_frd(params.gnss_antenna_position)   # the lever arm, FLU -> FRD
    declination = None
    if params.imu_declination == 'auto':
        from vessel_kinematics.estimation import magnetic
        declination = magnetic.declination_at_stamp
    return FilterConfig(
        motion=motion, origin=params.origin, projection=Projection(params.projection),
        gnss_enabled=params.gnss_enabled,
        antenna_b=(float(frd[0]), float(frd[1]), float(frd[2])),
        gnss_default_sigma=params.gnss_default_sigma, gnss_gate_sigma=params.gnss_gate_sigma,
        velocity_input=params.velocity_source != 'none',
        water=params.velocity_reference == 'water' and params.velocity_source != 'none',
        velocity_gate_sigma=params.velocity_gate_sigma,
        estimate_scale=params.velocity_estimate_scale,
        estimate_leeway=params.velocity_estimate_leeway,
        estimate_heading_offset=params.imu_estimate_yaw_offset, declination=declination,
        use_orientation=params.imu_use_orientation, integrator=Integrator(params.integrator),
        course_min_speed=params.course_min_speed, max_gap=params.max_gap,
        reorder_window=params.reorder_window)


def _has_nan(value: Any) -> bool:
    """Return whether ``value`` is a float NaN or a list of floats holding one."""
    if isinstance(value, float):
        return math.isnan(value)
    return isinstance(value, list) and bool(value) and all(
        isinstance(v, (int, float)) and not isinstance(v, bool) for v in value) and any(
        isinstance(v, float) and math.isnan(v) for v in value)
