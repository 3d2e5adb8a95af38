"""
The navigator's parameters, declared once: :class:`NavigatorParams` and its fields.

Each field of :class:`NavigatorParams` carries its ROS name, description, range and check
(:func:`_parameter`); :data:`PARAMETERS`, the table the node declares, is read off those fields,
and ``docs/parameters.md`` is generated from it (``python -m vessel_kinematics.ros.params
--markdown``; a test keeps the file in step). Both drivers validate with
:meth:`NavigatorParams.from_flat`, so a bad value gets the same one-line reason at start-up, at
``ros2 param set`` and in the replay. Parameters files are read by :mod:`.params_file`.

Choices are enums (:class:`~.param_types.VelocitySource`, :class:`~vessel_kinematics.
estimation.Motion`...): a field holds the member, ROS holds its string value. The kinds, bounds
and checks are :mod:`.param_types`'. This module imports the standard library and the
estimator's configuration only.
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass, Field, field, fields
import enum
import importlib.util
import math
import sys
from typing import Any, Mapping, Sequence

from vessel_kinematics.core import frames
from vessel_kinematics.estimation.config import (DeclinationModel, FilterConfig, Integrator,
                                                 Motion, Projection)
from vessel_kinematics.ros import param_types as checks
from vessel_kinematics.ros.param_types import (Check, Declination, excerpt, GnssVelocitySource,
                                               ImuSource, MAX_ANTENNA_OFFSET,
                                               MAX_FRAME_ID_LENGTH, MAX_PUBLISH_RATE,
                                               MIN_PUBLISH_RATE, NAN, ORIGIN_HIGH, ORIGIN_LOW,
                                               ParameterError, REMOVED, SensorQos, TF_CHOICES,
                                               TfTransform, VelocityReference, VelocitySource)

__all__ = ['Declination', 'declination_model', 'declination_problem', 'excerpt',
           'filter_config', 'GnssVelocitySource', 'ImuSource', 'markdown', 'MAX_ANTENNA_OFFSET',
           'MAX_FRAME_ID_LENGTH', 'MAX_PUBLISH_RATE', 'MIN_MAX_GAP', 'MIN_PUBLISH_RATE', 'NAN',
           'NavigatorParams', 'ORIGIN_HIGH', 'ORIGIN_LOW', 'Parameter', 'ParameterError',
           'PARAMETERS', 'REMOVED', 'SensorQos', 'TfTransform', 'time_offsets',
           'VelocityReference', 'VelocitySource', 'WMM_MISSING']


@dataclass(frozen=True)
class Parameter:
    """
    One ROS parameter: its name, default (as ROS holds it), description, check and range.

    ``low``/``high``: the closed range of a number (of each component of a list), for the
    node's ``FloatingPointRange``; None where unbounded or not a number. ``check`` enforces at
    least that range (``publish_rate`` takes 0 or [:data:`MIN_PUBLISH_RATE`, high]).
    ``choices``: the values of an enum parameter. ``read_only``: set at start-up only (a
    structural parameter: frames, the kind of craft, the projection).
    """

    name: str
    default: Any
    description: str
    check: Check
    low: float | None = None
    high: float | None = None
    read_only: bool = False
    choices: tuple[str, ...] | None = None

    @property
    def attribute(self) -> str:
        """Return the field of :class:`NavigatorParams` (``gnss.enabled``: ``gnss_enabled``)."""
        return self.name.replace('.', '_')


def _ros(value: Any) -> Any:
    """Return a field value as ROS holds it: enums as strings, tuples as lists."""
    if isinstance(value, enum.Enum):
        return value.value
    if isinstance(value, tuple):
        return [_ros(v) for v in value]
    return value


def _parameter(name: str, default: Any, description: str, check: Check | None = None, *,
               low: float | None = None, high: float | None = None,
               read_only: bool = False) -> Any:
    """
    Return the dataclass field of parameter ``name`` (its :class:`Parameter` as metadata).

    The check follows from the default and the range unless given: one of an enum's values, a
    boolean, a number in [low, high], a vector of 3 numbers each in [-high, high].
    """
    choices = None
    if isinstance(default, enum.Enum):
        kind = type(default)
        choices = tuple(member.value for member in kind)
        check = check or checks.one_of(kind)
    elif check is None and isinstance(default, bool):
        check = checks.boolean
    elif check is None and low is not None and high is not None:
        check = (checks.number(low, high) if isinstance(default, float)
                 else checks.vector3(high))
    if check is None:
        raise RuntimeError(f'parameter {name!r} has no check')
    spec = Parameter(name, _ros(default), description, check, low, high, read_only, choices)
    return field(default=default, metadata={'parameter': spec})


#: Largest ``<input>.time_offset`` (s): past a GPS week-number rollover (1024 weeks, 6.2e8 s).
MAX_TIME_OFFSET = 1e9

#: Smallest ``max_gap`` (s): 4 periods of the fastest IMU of a vessel (400 Hz). Shorter, each
#: step between two messages is a gap, and nothing is integrated (2.9 m off in 3 s at 1e-3).
MIN_MAX_GAP = 0.01

_TWO_PI = 2 * math.pi
_ALL_TF = tuple(TfTransform(t) for t in TF_CHOICES)


@dataclass(frozen=True)
class NavigatorParams:
    """
    The validated parameters, with Python names (``gnss.enabled`` is ``gnss_enabled``).

    Angles are in radians except ``origin``, which keeps the ROS convention of degrees for
    latitude and longitude (as in ``sensor_msgs/NavSatFix``). The fields are the declaration:
    their order is ``config/navigator.yaml``'s.
    """

    map_frame: str = _parameter(
        'map_frame', 'map', 'ENU frame about the origin (REP-105 map): fused pose',
        checks.frame_id, read_only=True)
    odom_frame: str = _parameter(
        'odom_frame', 'odom', 'continuous dead-reckoned frame (REP-105 odom)', checks.frame_id,
        read_only=True)
    base_frame: str = _parameter(
        'base_frame', 'base_link', 'the vessel body frame, FLU (REP-103)', checks.frame_id,
        read_only=True)
    earth_frame: str = _parameter(
        'earth_frame', 'earth', 'ECEF frame (REP-105 earth), parent of map in TF',
        checks.frame_id, read_only=True)
    origin: tuple[float, float, float] = _parameter(
        'origin', (NAN, NAN, NAN),
        'NED/ENU origin [lat deg, lon deg, ellipsoidal height m]; NaN = first valid fix; '
        'NaN height = height of the first fix', checks.origin)
    projection: Projection = _parameter(
        'projection', Projection.TANGENT,
        "'tangent': exact local NED through ECEF; 'flat': Fossen's flat-earth approximation",
        read_only=True)
    fix_topics: tuple[str, ...] = _parameter(
        'fix.topics', ('fix',),
        'the NavSatFix topics, all fused (one per receiver); each takes its antenna from '
        '/tf_static by its frame_id, else from gnss.antenna_position', checks.topic_list)
    gnss_enabled: bool = _parameter(
        'gnss.enabled', True, 'false: pure dead reckoning, fixes only set the origin')
    gnss_antenna_position: tuple[float, ...] = _parameter(
        'gnss.antenna_position', (0.0, 0.0, 0.0),
        'GNSS antenna in the base frame (FLU, m), removed with the current attitude; 3 numbers '
        'for every fix topic, or 3 per topic in fix.topics order',
        checks.vectors3(MAX_ANTENNA_OFFSET), low=-MAX_ANTENNA_OFFSET, high=MAX_ANTENNA_OFFSET)
    gnss_default_sigma: float = _parameter(
        'gnss.default_sigma', 2.5,
        'standard deviation (m) of each axis of a fix whose covariance is unknown',
        low=1e-3, high=1e4)
    gnss_gate_sigma: float = _parameter(
        'gnss.gate_sigma', 5.0,
        'reject a fix whose innovation (Mahalanobis distance) exceeds this many standard '
        'deviations (0 = accept all); a run of refused fixes re-initialises the position',
        low=0.0, high=1e3)
    imu_source: ImuSource = _parameter(
        'imu.source', ImuSource.IMU,
        "the imu topics' type: 'imu' (sensor_msgs/Imu) or 'quaternion' "
        '(geometry_msgs/QuaternionStamped, a GNSS compass: no rate, the yaw rate is derived '
        'from successive headings)')
    imu_topics: tuple[str, ...] = _parameter(
        'imu.topics', ('imu',),
        'the heading/attitude topics in priority order: the first fresh and healthy one is '
        'used, the others stand by (failover)', checks.topic_list)
    imu_failover_timeout: float = _parameter(
        'imu.failover_timeout', 1.0,
        'a heading topic is stale when its last usable message is older than this (s, by '
        'stamp) than the newest, or faulty for this long after a refusal: the next takes over',
        low=0.01, high=60.0)
    imu_mounting_rpy: tuple[float, ...] = _parameter(
        'imu.mounting_rpy', (0.0, 0.0, 0.0),
        'IMU frame in the base frame, [roll, pitch, yaw] rad, R = Rz(yaw) Ry(pitch) Rx(roll); '
        '3 numbers for every imu topic, or 3 per topic in imu.topics order',
        checks.vectors3(_TWO_PI), low=-_TWO_PI, high=_TWO_PI)
    imu_use_orientation: bool = _parameter(
        'imu.use_orientation', True,
        'take attitude from Imu.orientation when provided, else integrate angular rate')
    imu_yaw_offset: float = _parameter(
        'imu.yaw_offset', 0.0,
        'added to the IMU yaw (rad, ENU counter-clockwise), a fixed correction',
        low=-_TWO_PI, high=_TWO_PI)
    imu_declination: Declination = _parameter(
        'imu.declination', Declination.NONE,
        "'none', or 'auto': the magnetic declination at the origin and date from the World "
        'Magnetic Model (package wmm-calculator), for a magnetic IMU heading')
    imu_estimate_yaw_offset: bool = _parameter(
        'imu.estimate_yaw_offset', False,
        'estimate a constant offset of the IMU heading (any angle) from the course over '
        'ground of the fixes while moving')
    velocity_source: VelocitySource = _parameter(
        'velocity.source', VelocitySource.TWIST_WITH_COVARIANCE,
        'body velocity input type: twist_with_covariance, twist, odometry or none')
    velocity_reference: VelocityReference = _parameter(
        'velocity.reference', VelocityReference.GROUND,
        'ground (bottom track, wheels) or water (speed log, water track: current estimated)')
    velocity_mounting_rpy: tuple[float, float, float] = _parameter(
        'velocity.mounting_rpy', (0.0, 0.0, 0.0),
        'velocity sensor frame in the base frame, [roll, pitch, yaw] rad, '
        'R = Rz(yaw) Ry(pitch) Rx(roll); used when its frame is not in /tf_static',
        low=-_TWO_PI, high=_TWO_PI)
    velocity_sensor_position: tuple[float, float, float] = _parameter(
        'velocity.sensor_position', (0.0, 0.0, 0.0),
        'velocity sensor in the base frame (FLU, m): its lever arm, v_base = '
        'R v_sensor - omega x r; used when its frame is not in /tf_static',
        low=-MAX_ANTENNA_OFFSET, high=MAX_ANTENNA_OFFSET)
    velocity_default_sigma: float = _parameter(
        'velocity.default_sigma', 0.1,
        'standard deviation (m/s) of a body velocity whose covariance is unknown or zero',
        low=1e-4, high=100.0)
    velocity_gate_sigma: float = _parameter(
        'velocity.gate_sigma', 5.0,
        'reject a velocity whose innovation exceeds this many standard deviations '
        '(0 = accept all); a run of refused velocities re-initialises the velocity',
        low=0.0, high=1e3)
    velocity_estimate_scale: bool = _parameter(
        'velocity.estimate_scale', True,
        "water reference: estimate the log's scale factor (reading / truth) with the current")
    velocity_estimate_leeway: bool = _parameter(
        'velocity.estimate_leeway', True,
        'water reference, surface motion: estimate a constant leeway angle')
    gnss_velocity_source: GnssVelocitySource = _parameter(
        'gnss_velocity.source', GnssVelocitySource.NONE,
        "the receiver's own velocity over ground (ENU, in the map frame's axes, never a body "
        "velocity): 'none', 'twist' (TwistStamped, nmea_navsat_driver's vel) or "
        "'twist_with_covariance'")
    gnss_velocity_default_sigma: float = _parameter(
        'gnss_velocity.default_sigma', 0.2,
        'standard deviation (m/s) of each axis of a receiver velocity whose covariance is '
        'unknown or zero', low=1e-4, high=100.0)
    motion: Motion = _parameter(
        'motion', Motion.SURFACE,
        "'surface': a vessel, height and vertical velocity held at zero, roll and pitch from "
        "the IMU; 'ground': a planar vehicle, roll and pitch zero too; 'free': full 3-D "
        '(underwater vehicles)', read_only=True)
    course_min_speed: float = _parameter(
        'course.min_speed', 0.3,
        'speed over ground (m/s) below which course falls back to heading and sideslip to zero '
        '(blended smoothly up to twice this)', low=0.0, high=100.0)
    integrator: Integrator = _parameter(
        'integrator', Integrator.EXPONENTIAL,
        "'exponential' (exact for constant rate) or 'euler' (Fossen's step + normalisation)")
    max_gap: float = _parameter(
        'max_gap', 1.0, 'no integration across a gap between stamps longer than this (s) and '
        'than 3 of the usual steps (a receiver alone at 0.5 Hz: 6 s); at least 0.01 (4 '
        'periods of a 400 Hz IMU), and at run time at least 3 periods of the fastest input '
        'received', low=MIN_MAX_GAP, high=3600.0)
    history_length: float = _parameter(
        'history_length', 2.0,
        'an input stamped up to this (s) behind the newest is fused at its own stamp (the '
        "state history re-applied, as robot_localization's history_length); older, it is "
        'refused as too_late. 2 s: a GNSS fix comes 0.1-0.5 s after its stamp, with room for '
        'a hiccup', low=0.0, high=10.0)
    future_tolerance: float = _parameter(
        'future_tolerance', 0.5,
        'an input stamped more than this (s) ahead of its arrival (the node clock, /clock '
        'under use_sim_time; the log time in the replay) is refused as future_stamp. 0.5 s: '
        'clocks of one vessel agree better, and a GPS-time stamp (18 s ahead) is refused',
        low=0.0, high=60.0)
    fix_time_offset: float = _parameter(
        'fix.time_offset', 0.0,
        'added to every fix stamp (s): a known offset of the GNSS clock (-18 for GPS time '
        'stamped as UTC)', low=-MAX_TIME_OFFSET, high=MAX_TIME_OFFSET)
    imu_time_offset: float = _parameter(
        'imu.time_offset', 0.0, 'added to every imu stamp (s)',
        low=-MAX_TIME_OFFSET, high=MAX_TIME_OFFSET)
    velocity_time_offset: float = _parameter(
        'velocity.time_offset', 0.0, 'added to every velocity stamp (s)',
        low=-MAX_TIME_OFFSET, high=MAX_TIME_OFFSET)
    gnss_velocity_time_offset: float = _parameter(
        'gnss_velocity.time_offset', 0.0, 'added to every gnss_velocity stamp (s)',
        low=-MAX_TIME_OFFSET, high=MAX_TIME_OFFSET)
    publish_rate: float = _parameter(
        'publish_rate', 30.0,
        f'output rate (Hz), in [{MIN_PUBLISH_RATE}, {MAX_PUBLISH_RATE:g}]; 0 = publish on each '
        "update. 30 Hz as robot_localization's frequency: an autopilot wants a steady rate, "
        'not one output set per IMU message (400 a second from a 400 Hz IMU)',
        checks.publish_rate, low=0.0, high=MAX_PUBLISH_RATE)
    sensor_qos: SensorQos = _parameter(
        'sensor_qos', SensorQos.SENSOR_DATA,
        "subscription QoS: 'sensor_data' (best effort) or 'reliable'")
    tf_publish: tuple[TfTransform, ...] = _parameter(
        'tf.publish', _ALL_TF,
        'transforms to publish on /tf and /tf_static: earth_map (static), map_odom, odom_base, '
        'frd_ned (static map->map_ned, base->base_frd); [none] for none', checks.tf_list)
    diagnostics_stale_warn: float = _parameter(
        'diagnostics.stale_warn', 2.0,
        'an input whose last message is older than this (s) is WARN (late)',
        low=0.01, high=3600.0)
    diagnostics_stale_error: float = _parameter(
        'diagnostics.stale_error', 5.0,
        'an input whose last message is older than this (s) is ERROR (gone)',
        low=0.01, high=3600.0)

    @property
    def tf_set(self) -> frozenset[TfTransform]:
        """Return the transforms to publish: ``tf.publish`` less ``none``."""
        return frozenset(self.tf_publish) - {TfTransform.NONE}

    def antenna_position(self, index: int) -> tuple[float, float, float]:
        """Return the antenna position (FLU, m) of fix topic ``index`` from the parameters."""
        return _triple(self.gnss_antenna_position, index)

    def imu_mounting(self, index: int) -> tuple[float, float, float]:
        """Return the mounting [roll, pitch, yaw] (rad) of imu topic ``index``."""
        return _triple(self.imu_mounting_rpy, index)

    @property
    def water(self) -> bool:
        """Return True when a velocity input measures through the water: a current is estimated."""
        return (self.velocity_reference is VelocityReference.WATER
                and self.velocity_source is not VelocitySource.NONE)

    @classmethod
    def from_flat(cls, values: Mapping[str, Any]) -> NavigatorParams:
        """
        Validate ROS-named values (``{'gnss.enabled': False, ...}``) over the defaults.

        Integers are accepted where a float is expected. Unknown and removed names
        (:data:`REMOVED`) raise :class:`ParameterError`, as do values of the wrong type or
        out of range; the reason is one line, the value cut short (:func:`excerpt`).
        """
        merged = {p.name: p.default for p in PARAMETERS}
        for name, value in values.items():
            if name in REMOVED:
                raise ParameterError(name, f'was removed: {REMOVED[name][1]}')
            if name not in _BY_NAME:
                raise ParameterError(name, 'unknown parameter of the navigator')
            merged[name] = value
        for vectors, topics in (('gnss.antenna_position', 'fix.topics'),
                                ('imu.mounting_rpy', 'imu.topics')):
            n, names = merged[vectors], merged[topics]
            if (isinstance(n, (list, tuple)) and isinstance(names, (list, tuple))
                    and len(n) not in (3, 3 * len(names))):
                raise ParameterError(vectors, f'must hold 3 numbers, or 3 for each of the '
                                              f'{len(names)} {topics}, got {len(n)}')
        warn, error = merged['diagnostics.stale_warn'], merged['diagnostics.stale_error']
        if checks.is_number(warn) and checks.is_number(error) and warn > error:
            raise ParameterError('diagnostics.stale_warn',
                                 'must not exceed diagnostics.stale_error')
        kwargs = {}
        for f in fields(cls):
            spec = _parameter_of(f)
            value = merged[spec.name]
            problem = spec.check(value)
            if problem:
                raise ParameterError(spec.name, problem)
            kwargs[f.name] = _typed(f.default, value)
        return cls(**kwargs)

    def to_flat(self) -> dict[str, Any]:
        """Return the ROS-named values (lists for vectors, strings for choices)."""
        return {p.name: _ros(getattr(self, p.attribute)) for p in PARAMETERS}


def _triple(values: tuple[float, ...], index: int) -> tuple[float, float, float]:
    """Return the ``index``-th 3-vector of a flattened list (the only one when just 3)."""
    i = 3 * index if len(values) > 3 else 0
    return values[i], values[i + 1], values[i + 2]


def _typed(default: Any, value: Any) -> Any:
    """Return a checked ROS value as the field's type (the default's): enum, tuple, float."""
    if isinstance(default, enum.Enum):
        return type(default)(value)
    if isinstance(default, tuple):
        if default and isinstance(default[0], enum.Enum):
            return tuple(type(default[0])(v) for v in value)
        if default and isinstance(default[0], str):
            return tuple(str(v) for v in value)
        return tuple(float(v) for v in value)
    if isinstance(default, float):
        return float(value)
    return value


def _parameter_of(f: Field) -> Parameter:
    spec: Parameter = f.metadata['parameter']
    if spec.attribute != f.name:             # a typo in the declaration, said at import
        raise RuntimeError(f'parameter {spec.name!r} declared on the field {f.name!r}')
    return spec


#: Every parameter of the navigator, in the order of ``config/navigator.yaml``.
PARAMETERS: tuple[Parameter, ...] = tuple(_parameter_of(f) for f in fields(NavigatorParams))
_BY_NAME: dict[str, Parameter] = {p.name: p for p in PARAMETERS}

#: Why ``imu.declination: auto`` cannot be applied where NOAA's model is not installed.
WMM_MISSING = ('imu.declination auto needs the World Magnetic Model (pip install '
               'wmm-calculator): the declination is not applied')


def declination_problem(params: NavigatorParams) -> str | None:
    """Return the one line to say at start-up when the declination cannot be applied."""
    if params.imu_declination is not Declination.AUTO:
        return None
    try:
        found = importlib.util.find_spec('wmm') is not None
    except (ImportError, ValueError):
        found = False
    return None if found else WMM_MISSING


def _wmm_missing(lat: float, lon: float, height: float, stamp_ns: int) -> float:
    """Refuse as the model refuses a date out of range: the estimator says it in diagnostics."""
    raise ValueError(WMM_MISSING)


def declination_model(params: NavigatorParams) -> DeclinationModel | None:
    """Return the declination model of ``imu.declination`` (None for ``none``)."""
    if params.imu_declination is not Declination.AUTO:
        return None
    if declination_problem(params) is not None:
        return _wmm_missing
    from vessel_kinematics.estimation import magnetic
    return magnetic.declination_at_stamp


def time_offsets(params: NavigatorParams) -> dict[str, float]:
    """Return ``<input>.time_offset`` of each input (s)."""
    return {'fix': params.fix_time_offset, 'imu': params.imu_time_offset,
            'velocity': params.velocity_time_offset,
            'gnss_velocity': params.gnss_velocity_time_offset}


def filter_config(params: NavigatorParams) -> FilterConfig:
    """
    Return the estimator's configuration from the node's parameters (ROS -> Fossen frames).

    The antenna lever arm turns from FLU to FRD; ``imu.declination: auto`` becomes the World
    Magnetic Model at the origin (:func:`declination_model`).
    """
    frd = frames.flu_to_frd(params.antenna_position(0))
    return FilterConfig(
        motion=params.motion, origin=params.origin, projection=params.projection,
        gnss_enabled=params.gnss_enabled,
        antenna_b=(float(frd[0]), float(frd[1]), float(frd[2])),
        gnss_default_sigma=params.gnss_default_sigma, gnss_gate_sigma=params.gnss_gate_sigma,
        velocity_input=params.velocity_source is not VelocitySource.NONE, water=params.water,
        velocity_gate_sigma=params.velocity_gate_sigma,
        estimate_scale=params.velocity_estimate_scale,
        estimate_leeway=params.velocity_estimate_leeway,
        estimate_heading_offset=params.imu_estimate_yaw_offset,
        declination=declination_model(params), use_orientation=params.imu_use_orientation,
        integrator=params.integrator, course_min_speed=params.course_min_speed,
        max_gap=params.max_gap, history_length=params.history_length)


def _markdown_value(value: Any) -> str:
    if isinstance(value, list):
        return '[' + ', '.join(_markdown_value(v) for v in value) + ']'
    if isinstance(value, bool):
        return 'true' if value else 'false'
    if isinstance(value, float) and math.isnan(value):
        return '.nan'
    return str(value)


def markdown() -> str:
    """Return ``docs/parameters.md``: every parameter of :data:`PARAMETERS`, as a table."""
    lines = [
        '# Parameters of the navigator',
        '',
        'Generated from `vessel_kinematics/ros/params.py` by `python -m '
        'vessel_kinematics.ros.params --markdown`; `test/test_params_doc.py` keeps it in '
        'step. The replay takes the same names (`--params-file`, `-p NAME:=VALUE`).',
        '',
        "Read-only parameters (and rclpy's `use_sim_time`) are set at start-up only. Removed "
        'names are ignored with one warning, which names what replaces them: '
        + '; '.join(f'`{k}` ({hint})' for k, (_, hint) in REMOVED.items()) + '.',
        '',
        '| name | default | range or choices | read-only | description |',
        '| --- | --- | --- | --- | --- |',
    ]
    for p in PARAMETERS:
        if p.choices is not None:
            allowed = ', '.join(f'`{c}`' for c in p.choices)
        elif p.name == 'tf.publish':
            allowed = ', '.join(f'`{c}`' for c in TF_CHOICES) + ' or `[none]`'
        elif p.low is not None:
            allowed = f'[{p.low:g}, {p.high:g}]'
        else:
            allowed = ''
        description = p.description.replace('|', '\\|')
        lines.append(f'| `{p.name}` | `{_markdown_value(p.default)}` | {allowed} | '
                     f'{"yes" if p.read_only else ""} | {description} |')
    return '\n'.join(lines) + '\n'


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m vessel_kinematics.ros.params --markdown``: print docs/parameters.md."""
    parser = argparse.ArgumentParser(prog='python -m vessel_kinematics.ros.params',
                                     description="The navigator's parameter table.")
    parser.add_argument('--markdown', action='store_true', help='print docs/parameters.md')
    args = parser.parse_args(argv)
    if not args.markdown:
        parser.print_help()
        return 0
    sys.stdout.write(markdown())
    return 0


if __name__ == '__main__':
    sys.exit(main())
