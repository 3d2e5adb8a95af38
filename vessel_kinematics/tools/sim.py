"""
A simulated voyage with ground truth: a manoeuvring vessel in an ocean current, written to a bag.

In four modules, the model apart from the messages: :mod:`~vessel_kinematics.tools.sim_model`
is the vessel as numbers (numpy; Fossen's 3-DOF manoeuvring model in a current, :func:`simulate`
to a :class:`Truth`), :mod:`~vessel_kinematics.tools.sim_sensors` its sensors (numpy,
:func:`sensor_readings` to :class:`Readings`),
:mod:`~vessel_kinematics.tools.sim_bag` turns readings into ROS messages (CDR,
:func:`sensor_records`) and writes the bag (:func:`write_bag`), and this module is the command
line (:func:`generate`, :func:`main`) and re-exports both.

The voyage (fractions of ``--duration``, default 300 s): a straight leg under a heading
autopilot, a starboard turning circle (25 deg rudder, 360 deg), a straight leg, a 20/20
zig-zag, and a final straight leg on a new heading; one GNSS outage during the zig-zag.

Sensors, stamped with their time of measurement (the simulation time) and logged when they
reach the ROS graph, their delivery latency later (see *Delivery latency* below):

* ``/fix`` sensor_msgs/NavSatFix, 5 Hz: the antenna (lever arm in ``base_link``) with white
  noise (1.5 m horizontal, 3 m vertical, covariance DIAGONAL_KNOWN); during the outage a
  1 Hz NO_FIX message with NaN position, as receivers send;
* ``/imu`` sensor_msgs/Imu, 100 Hz (REP-145: orientation ENU/FLU): heading noise 0.5 deg and
  roll/pitch noise 0.2 deg, angular rate with 0.1 deg/s white noise and a constant bias,
  specific force (gravity on +z) with noise; covariances filled;
* ``/velocity`` geometry_msgs/TwistWithCovarianceStamped, 5 Hz: a DVL in ``base_link`` in
  water-track (``--reference water``, the default: relative velocity, so the navigator has
  to estimate the current) or bottom-track mode (``ground``), 3 cm/s noise;
* ``/truth/odometry`` nav_msgs/Odometry (``map`` ENU about the origin / ``base_link`` FLU,
  twist over ground in ``base_link``), ``/truth/course_sideslip`` geometry_msgs/Vector3Stamped
  (x = chi, y = beta = asin(v/U), z = alpha, rad, over ground; at rest over ground, U = 0,
  chi = psi and beta = 0, Fossen's U = 0 convention), ``/truth/current`` (ENU, m/s) and
  ``/truth/calibration`` geometry_msgs/Vector3Stamped (x = the log's scale factor, y = the
  leeway angle lambda, rad, z = the IMU's yaw offset, rad, published - true ENU yaw; constant),
  20 Hz; ``/truth/origin`` sensor_msgs/NavSatFix, once: the origin of the truth's ``map`` (the
  navigator picks its own origin, by default its first fix).

Sensor and sailing effects, all off by default (``VoyageConfig`` fields, command-line flags):

* ``log_scale`` (``--log-scale``): the log's surge reads ``log_scale * u`` (water track: u_r);
  ``log_surge_only`` (``--log-surge-only``): a speed log, surge only, sway and heave 0 with
  variance 1e6 as NMEA logs publish them (default: a DVL with all three components);
* ``leeway`` (``--leeway`` DEG): a constant leeway angle lambda (positive to starboard) adds
  the sway through the water u_r tan(lambda) to the hull's own (see :func:`simulate`); the
  truth position, velocities, accelerations, course and sideslip include it;
* ``imu_yaw_offset`` (``--imu-yaw-offset`` DEG): the published Imu orientation's yaw (ENU,
  counter-clockwise) is the true yaw plus this offset (a mounting yaw or an uncorrected
  declination; any angle): the heading it gives is psi - offset. The navigator's
  ``imu.yaw_offset`` that corrects it is minus this value. Rates and specific force are
  unaffected (the offset is of the heading reference, not of the sensor axes);
* ``standstill_start``, ``standstill_end`` (``--standstill`` START END, s): the vessel brakes
  to rest through the water over the :data:`BRAKING_TIME` before START (rudder to 0), stays
  at rest until END (drifting with the current, if any; with ``--current 0 0`` it is at rest
  over ground and the truth's course is its heading), then gets under way again;
* ``helm`` (``--helm``): ``voyage`` (the schedule above), ``straight`` (the autopilot on the
  initial heading throughout) or ``figure8`` (full circles, starboard then port, after a tenth
  of the voyage): the figure-8 separates the current from the log's scale;
* ``surge_profile`` (``--surge-profile`` T:U ...): the surge through the water follows these
  knots (s, m/s), linear between them with its acceleration ramped over 1 s: a crash stop
  (``130:10 133:0``), a full-throttle run from rest (``160:0 163:14.7``, 0.5 g), a planing
  hull coming off the plane;
* ``log_outage``, ``log_freeze`` (``--log-outage``, ``--log-freeze`` START LENGTH, s): no log
  readings in the window, or the log holding its first reading there (a stuck paddle wheel);
* ``compass_freeze`` (``--compass-freeze`` START LENGTH): the Imu orientation holds its value
  (the rates and specific force go on: a frozen compass, a live gyro);
* ``fix_outlier_fraction``, ``fix_outlier_distance`` (``--fix-outliers`` FRACTION METRES): that
  share of the fixes displaced by that distance in a random horizontal direction;
* ``compass_rate`` (``--compass-rate`` HZ): a heading-only compass at that rate in place of the
  IMU (roll and pitch unknown, variance 1e3; no rate, no acceleration: covariance[0] = -1), as
  NMEA compasses are converted; ``imu_rate`` must be a multiple of it.

Delivery latency (``VoyageConfig`` fields, command-line flags; always on): on a real vessel's
ROS graph a GNSS receiver stamps a fix with its time of measurement and its driver delivers it
0.1 to 0.5 s later (the solution, the serial output, the parsing), while the IMU and the speed
log arrive within milliseconds. A navigator has to fuse each input at its stamp, not at its
arrival: the bag logs each input message at its stamp plus a latency drawn uniformly per
message (seeded, from streams of their own: the readings are those of the seed without
latency; each sensor first in first out), the truth at its stamp:

* ``fix_latency`` (``--fix-latency`` MIN MAX, s): default 0.1 0.5 (:data:`FIX_LATENCY`);
* ``imu_latency``, ``velocity_latency`` (``--imu-latency``, ``--velocity-latency`` MIN MAX, s):
  default 0.001 0.005 (:data:`FAST_LATENCY`), an IMU or log driver's few milliseconds;
  ``--no-latency`` sets all three to 0 (log time = header stamp for every message);
* ``stamp_on_receipt`` (``--stamp-on-receipt``): the other real case, drivers that stamp a
  message when they receive it (as ``nmea_navsat_driver`` does by default): every input's
  header stamp is its log time, so a fix's stamp is 0.1 to 0.5 s late, an error the navigator
  cannot see (a position lag of the speed times the latency: 1.5 m at 5 m/s and 0.3 s).

The fixes lie on the sea surface, the ellipsoid at the origin's height (the antenna above it),
at any distance: the truth's ``map`` is the origin's tangent plane, the surface below it by
the earth's curvature.

Run ``simulate OUTPUT_BAG`` (or ``python -m vessel_kinematics.tools.sim``); ``--help`` lists the
options. Deterministic for a given ``--seed``.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path
import shutil
import sys
from typing import Sequence

import numpy as np
from vessel_kinematics.tools.bags import BagError
from vessel_kinematics.tools.sim_bag import (Record, sensor_records, TOPIC_FIX, TOPIC_IMU,
                                             TOPIC_TRUTH_CALIBRATION,
                                             TOPIC_TRUTH_COURSE_SIDESLIP, TOPIC_TRUTH_CURRENT,
                                             TOPIC_TRUTH_ODOMETRY, TOPIC_TRUTH_ORIGIN,
                                             TOPIC_VELOCITY, TOPICS, write_bag)
from vessel_kinematics.tools.sim_model import (BRAKING_TIME, current_at, FAST_LATENCY,
                                               FIX_LATENCY, RHO, simulate, START_NS, Truth,
                                               UNMEASURED_VARIANCE, validate, Vessel,
                                               VoyageConfig)
from vessel_kinematics.tools.sim_sensors import (delivery_latencies, normal_gravity, Readings,
                                                 sensor_readings, surface_llh)

__all__ = ['BRAKING_TIME', 'config_from_args', 'current_at', 'delivery_latencies',
           'FAST_LATENCY', 'FIX_LATENCY', 'generate', 'main', 'normal_gravity',
           'Readings', 'Record', 'RHO', 'sensor_readings', 'sensor_records', 'simulate',
           'START_NS', 'surface_llh', 'TOPIC_FIX', 'TOPIC_IMU', 'TOPIC_TRUTH_CALIBRATION',
           'TOPIC_TRUTH_COURSE_SIDESLIP', 'TOPIC_TRUTH_CURRENT', 'TOPIC_TRUTH_ODOMETRY',
           'TOPIC_TRUTH_ORIGIN', 'TOPIC_VELOCITY', 'TOPICS', 'Truth', 'UNMEASURED_VARIANCE',
           'validate', 'Vessel', 'VoyageConfig', 'write_bag']


def _parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    defaults = VoyageConfig()
    parser = argparse.ArgumentParser(
        prog='simulate',
        description='Simulate a vessel voyage (3-DOF manoeuvring model in a current: straight '
                    'legs, a turning circle, a zig-zag, a GNSS outage) and write the '
                    "navigator's inputs and the ground truth to a rosbag2 mcap bag.")
    parser.add_argument('output', type=Path, help='the bag to write (a directory)')
    parser.add_argument('--duration', type=float, default=defaults.duration,
                        help='voyage length, s (default %(default)s)')
    parser.add_argument('--seed', type=int, default=defaults.seed,
                        help='random seed of the sensor noise (default %(default)s)')
    parser.add_argument('--reference', choices=('water', 'ground'), default=defaults.reference,
                        help='DVL mode: water track (the navigator estimates the current) or '
                             'bottom track (default %(default)s)')
    parser.add_argument('--origin', type=float, nargs=3, metavar=('LAT', 'LON', 'HEIGHT'),
                        default=list(defaults.origin),
                        help='start position: deg, deg, ellipsoidal m (default %(default)s, '
                             'Trondheimsfjord)')
    parser.add_argument('--speed', type=float, default=defaults.speed,
                        help='set speed through the water, m/s (default %(default)s)')
    parser.add_argument('--heading', type=float, default=round(math.degrees(defaults.heading), 9),
                        help='initial heading, deg from north (default %(default)s)')
    parser.add_argument('--current', type=float, nargs=2, metavar=('SPEED', 'DIRECTION'),
                        default=[defaults.current_speed,
                                 round(math.degrees(defaults.current_direction), 9)],
                        help='current speed m/s and the direction it sets towards, deg '
                             '(default %(default)s)')
    outage = parser.add_mutually_exclusive_group()
    outage.add_argument('--outage', type=float, nargs=2, metavar=('START', 'LENGTH'),
                        help='GNSS outage, s after the start (default: at 60 %% of the '
                             'voyage, 8.5 %% of it long, at most 25 s)')
    outage.add_argument('--no-outage', action='store_true', help='no GNSS outage')
    parser.add_argument('--log-scale', type=float, default=defaults.log_scale,
                        metavar='FACTOR',
                        help='the log reads FACTOR times the true surge, e.g. 0.8 = 20 %% low '
                             '(default %(default)s)')
    parser.add_argument('--log-surge-only', action='store_true',
                        help='a speed log: surge only, sway and heave unmeasured (variance '
                             '1e6), as NMEA logs are (default: all three DVL components)')
    parser.add_argument('--leeway', type=float, default=round(math.degrees(defaults.leeway), 9),
                        metavar='DEG',
                        help='constant leeway angle: adds a sway through the water u_r tan(DEG),'
                             ' positive to starboard (default %(default)s)')
    parser.add_argument('--imu-yaw-offset', type=float,
                        default=round(math.degrees(defaults.imu_yaw_offset), 9), metavar='DEG',
                        help="offset of the Imu orientation's yaw (ENU, counter-clockwise): "
                             'published - true, e.g. a mounting yaw or an uncorrected '
                             'declination (default %(default)s)')
    parser.add_argument('--standstill', type=float, nargs=2, metavar=('START', 'END'),
                        help='at rest (through the water) from START to END, s after the '
                             f'start, braking for {BRAKING_TIME:.0f} s before (default: none)')
    parser.add_argument('--helm', choices=('voyage', 'straight', 'figure8'), default=defaults.helm,
                        help='the manoeuvres (default %(default)s)')
    parser.add_argument('--surge-profile', nargs='+', metavar='T:U',
                        help='prescribed surge through the water, knots of time s and speed m/s '
                             '(e.g. 130:10 133:0 for a 3 s crash stop)')
    for flag, what in (('--log-outage', 'no log readings'),
                       ('--log-freeze', 'the log holds its reading (stuck)'),
                       ('--compass-freeze', 'the Imu orientation holds its value (frozen)')):
        parser.add_argument(flag, type=float, nargs=2, metavar=('START', 'LENGTH'),
                            help=f'{what} from START for LENGTH s (default: none)')
    parser.add_argument('--fix-outliers', type=float, nargs=2, metavar=('FRACTION', 'METRES'),
                        help='that share of the fixes displaced by METRES (default: none)')
    parser.add_argument('--compass-rate', type=float, metavar='HZ',
                        help='a heading-only compass at HZ in place of the IMU (default: the IMU)')
    for flag, what, default in (('--fix-latency', 'a GNSS fix', defaults.fix_latency),
                                ('--imu-latency', 'an IMU message', defaults.imu_latency),
                                ('--velocity-latency', 'a log or DVL message',
                                 defaults.velocity_latency)):
        parser.add_argument(flag, type=float, nargs=2, metavar=('MIN', 'MAX'),
                            default=list(default),
                            help=f'delivery latency of {what}: logged a time drawn uniformly '
                                 'in MIN..MAX s after its stamp (default %(default)s)')
    parser.add_argument('--no-latency', action='store_true',
                        help='no delivery latency: log time = header stamp for every message '
                             '(overrides the three above)')
    parser.add_argument('--stamp-on-receipt', action='store_true',
                        help='the drivers stamp on receipt: header stamp = log time, the '
                             'latency an error of the stamp (default: stamped with the '
                             'measurement time)')
    parser.add_argument('--overwrite', action='store_true',
                        help='replace OUTPUT if it exists')
    return parser.parse_args(argv)


def _knots(values: Sequence[str] | None) -> tuple[tuple[float, float], ...] | None:
    """Return T:U strings as (t, u) knots; a malformed one is a ValueError naming it."""
    if not values:
        return None
    knots = []
    for value in values:
        try:
            t, u = value.split(':')
            knots.append((float(t), float(u)))
        except ValueError:
            raise ValueError(f'--surge-profile takes knots T:U (s:m/s), got {value!r}') from None
    return tuple(knots)


def config_from_args(args: argparse.Namespace) -> VoyageConfig:
    """Return the voyage configuration of parsed command-line arguments."""
    outage = (0.0, 0.0) if args.no_outage else (tuple(args.outage) if args.outage else None)
    return VoyageConfig(
        duration=args.duration, seed=args.seed, origin=tuple(args.origin),
        reference=args.reference, speed=args.speed, heading=math.radians(args.heading),
        current_speed=args.current[0], current_direction=math.radians(args.current[1]),
        outage=outage, log_scale=args.log_scale, log_surge_only=args.log_surge_only,
        leeway=math.radians(args.leeway), imu_yaw_offset=math.radians(args.imu_yaw_offset),
        standstill_start=args.standstill[0] if args.standstill else None,
        standstill_end=args.standstill[1] if args.standstill else None,
        helm=args.helm, surge_profile=_knots(args.surge_profile),
        log_outage=tuple(args.log_outage) if args.log_outage else None,
        log_freeze=tuple(args.log_freeze) if args.log_freeze else None,
        compass_freeze=tuple(args.compass_freeze) if args.compass_freeze else None,
        fix_outlier_fraction=args.fix_outliers[0] if args.fix_outliers else 0.0,
        fix_outlier_distance=args.fix_outliers[1] if args.fix_outliers else 60.0,
        compass_rate=args.compass_rate,
        fix_latency=(0.0, 0.0) if args.no_latency else tuple(args.fix_latency),
        imu_latency=(0.0, 0.0) if args.no_latency else tuple(args.imu_latency),
        velocity_latency=(0.0, 0.0) if args.no_latency else tuple(args.velocity_latency),
        stamp_on_receipt=args.stamp_on_receipt)


def generate(path: str | Path, config: VoyageConfig, *, overwrite: bool = False) -> dict:
    """
    Simulate ``config`` and write its bag at ``path``; return a summary dict.

    The summary holds ``path``, ``duration`` (s), ``messages`` per topic, ``distance`` (m,
    over ground), ``outage`` (start, end) and the ``truth`` (:class:`Truth`).
    """
    validate(config)
    path = Path(path)
    if path.exists():
        if not overwrite:
            raise FileExistsError(f'{path} exists (use --overwrite to replace it)')
        shutil.rmtree(path) if path.is_dir() else path.unlink()
    truth = simulate(config)
    records = sensor_records(truth, config)
    write_bag(path, records)
    counts = dict.fromkeys(TOPICS, 0)
    for rec in records:
        counts[rec.topic] += 1
    steps = np.hypot(np.diff(truth.north), np.diff(truth.east))
    return {'path': path, 'duration': float(truth.t[-1]), 'messages': counts,
            'distance': float(steps.sum()), 'outage': config.outage_window(), 'truth': truth}


def _range(bounds: tuple[float, float]) -> str:
    """Return a latency range (s) as text in ms, e.g. '100..500 ms'."""
    return f'{1e3 * bounds[0]:g}..{1e3 * bounds[1]:g} ms'


def main(argv: Sequence[str] | None = None) -> int:
    """Run the ``simulate`` command line; return the exit status."""
    args = _parse_args(argv)
    try:
        config = config_from_args(args)
        summary = generate(args.output, config, overwrite=args.overwrite)
    except (ValueError, FileExistsError, OSError, BagError) as error:
        print(f'simulate: error: {error}', file=sys.stderr)
        return 2
    truth = summary['truth']
    print(f'simulate: wrote {summary["path"]} ({summary["duration"]:.0f} s, '
          f'{summary["distance"]:.0f} m over ground, seed {config.seed}, '
          f'{config.reference}-referenced DVL)')
    for topic, count in summary['messages'].items():
        print(f'  {topic:26s} {TOPICS[topic]:46s} {count:6d}')
    beta = np.degrees(truth.sideslip())
    print(f'  sideslip over ground {beta.min():+.1f} .. {beta.max():+.1f} deg; '
          f'gyro bias z {math.degrees(truth.gyro_bias[2]):+.3f} deg/s')
    if summary['outage'] is not None:
        print('  GNSS outage {:.1f} .. {:.1f} s'.format(*summary['outage']))
    if config.log_scale != 1.0 or config.log_surge_only:
        print(f'  log scale {config.log_scale:g}'
              + (', surge only' if config.log_surge_only else ''))
    if config.leeway or config.imu_yaw_offset:
        print(f'  leeway {math.degrees(config.leeway):+.2f} deg; IMU yaw offset '
              f'{math.degrees(config.imu_yaw_offset):+.2f} deg')
    window = config.standstill_window()
    if window is not None:
        print('  standstill {:.1f} .. {:.1f} s'.format(*window))
    for name in ('log_outage', 'log_freeze', 'compass_freeze'):
        window = config.window(name)
        if window is not None:
            print(f'  {name.replace("_", " ")} {window[0]:.1f} .. {window[1]:.1f} s')
    print(f'  delivery latency: fix {_range(config.fix_latency)}, imu '
          f'{_range(config.imu_latency)}, velocity {_range(config.velocity_latency)}; '
          + ('stamped on receipt (stamp = log time)' if config.stamp_on_receipt
             else 'stamped at measurement (log time = stamp + latency)'))
    if config.fix_outlier_fraction:
        print(f'  fix outliers {100.0 * config.fix_outlier_fraction:g} % of '
              f'{config.fix_outlier_distance:g} m')
    return 0


if __name__ == '__main__':
    sys.exit(main())
