"""
What the simulated voyage's sensors read: the IMU, the GNSS fixes and the log or DVL.

Numbers only (numpy and the kinematics core), from a :class:`~.sim_model.Truth`:
:func:`sensor_readings` draws the readings (noise, biases, outages and the sailing effects of
the :class:`~.sim_model.VoyageConfig`) into :class:`Readings`, in the sensors' own ROS
conventions; :func:`surface_llh` places the tangent-plane track on the sea surface and
:func:`normal_gravity` gives the accelerometer's gravity. The messages and the bag are
:mod:`vessel_kinematics.tools.sim_bag`'s.

Delivery latency: a sensor measures at one time and its message reaches the ROS graph later.
A GNSS receiver computes its solution, writes it out over a serial line and the driver parses
it: the fix arrives 0.1 to 0.5 s after the time it is stamped with
(:data:`~.sim_model.FIX_LATENCY`), with jitter; an IMU's and a log's drivers publish within
milliseconds (:data:`~.sim_model.FAST_LATENCY`). :func:`delivery_latencies` draws each
message's latency (ns) uniformly in its sensor's ``VoyageConfig.*_latency`` range (s), from
random streams of their own (the readings are those of the same seed without latency), and
keeps each sensor's messages first in first out, as one serial or USB link delivers them (a
message held up holds the next behind it, which stays within the range). The bag logs each
message at its measurement time plus its latency (:meth:`Readings.log_ns`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
import math
from typing import Sequence

import numpy as np
from vessel_kinematics.core.frames import q_nb_to_ros
from vessel_kinematics.core.geodesy import ned2llh
from vessel_kinematics.core.quaternion import euler2q
from vessel_kinematics.tools.sim_model import START_NS, Truth, UNMEASURED_VARIANCE, VoyageConfig

__all__ = ['delivery_latencies', 'FIFO_GAP_NS', 'normal_gravity', 'Readings', 'sensor_readings',
           'surface_llh']

#: How long after the message before it a message held up behind it is delivered, ns.
FIFO_GAP_NS = 1_000
#: The random stream of each sensor's delivery latencies: the seed's spawn key.
_LATENCY_STREAMS = {'imu': 1, 'fix': 2, 'velocity': 3}


def surface_llh(north: np.ndarray, east: np.ndarray,
                origin: tuple[float, float, float]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """
    Return (lat, lon, h) (rad, rad, m) of the sea surface at tangent-plane (north, east) (m).

    The point at the origin's ellipsoidal height h0 whose horizontal coordinates in the
    origin's tangent plane are (north, east): the plane's down coordinate found by Newton
    steps (the surface lies d^2 / 2R below the plane at a distance d).
    """
    lat0, lon0, h0 = origin
    north, east = np.asarray(north, dtype=float), np.asarray(east, dtype=float)
    down = (north * north + east * east) / (2.0 * 6_371_000.0)
    for _ in range(4):
        lat, lon, h = ned2llh(np.stack([north, east, down], axis=-1), lat0, lon0, h0)
        down = down + (np.asarray(h) - h0)
    lat, lon, _ = ned2llh(np.stack([north, east, down], axis=-1), lat0, lon0, h0)
    return np.asarray(lat), np.asarray(lon), np.full(np.shape(north), float(h0))


def normal_gravity(lat: float) -> float:
    """Return WGS-84 normal gravity (m/s^2) on the ellipsoid at latitude lat (rad), Somigliana."""
    s2 = math.sin(lat) ** 2
    return 9.7803253359 * (1.0 + 0.00193185265241 * s2) / math.sqrt(1.0 - 0.00669437999013 * s2)


def delivery_latencies(stamps_ns: Sequence[int], bounds: tuple[float, float],
                       rng: np.random.Generator) -> list[int]:
    """
    Return the delivery latency (ns) of each of one sensor's messages, measured at stamps_ns.

    Each is drawn uniformly in ``bounds`` (min, max, s) from ``rng``; a message that would
    arrive before the one measured before it (their draws differ by more than their period)
    arrives :data:`FIFO_GAP_NS` after it instead: first in first out, and still within the
    range when the messages are more than that gap apart. ``stamps_ns`` ascending.
    """
    low, high = bounds
    drawn = np.round(rng.uniform(low, high, len(stamps_ns)) * 1e9).astype(np.int64).tolist()
    latencies: list[int] = []
    previous: int | None = None
    for stamp, latency in zip(stamps_ns, drawn):
        arrival = stamp + latency
        if previous is not None and arrival <= previous:
            arrival = previous + FIFO_GAP_NS
        latencies.append(arrival - stamp)
        previous = arrival
    return latencies


@dataclass
class Readings:
    """
    What the voyage's sensors read and the truth to score them by, as numbers.

    In the sensors' own conventions, as their ROS messages carry them: the IMU (REP-145) its
    orientation as an ENU/FLU quaternion ``[x, y, z, w]``, rates (rad/s) and specific force
    (m/s^2) in FLU; the GNSS fixes latitude, longitude (deg) and height (m), ``None`` for a
    NO_FIX report of the outage; the log or DVL its body velocity (FLU, m/s). The truth is
    REP-103/105: position ENU about the origin (m), orientation ENU/FLU ``[x, y, z, w]``, twist
    over ground in FLU (m/s, rad/s), course, sideslip and angle of attack (rad), the current
    ENU (m/s). Each sensor's samples were measured at ``stamps`` (ns per integration step)
    through its list of step indices, and reach the ROS graph their delivery latency later
    (``*_latency_ns``, one per sample; empty: none): :meth:`log_ns` gives the arrival times,
    :meth:`header_ns` the header stamps (the measurement times, or with ``stamp_on_receipt``
    the arrival times). The truth is logged at its stamps.
    """

    stamps: list[int]
    imu_steps: list[int]
    imu_orientation: list[list[float]]
    imu_angular_velocity: list[list[float]]
    imu_linear_acceleration: list[list[float]]
    #: Row-major 3x3 covariances of the IMU's orientation, rate and specific force.
    imu_covariances: tuple[list[float], list[float], list[float]]
    fix_steps: list[int]
    fix_llh: list[list[float] | None]
    #: Row-major 3x3 ENU covariance of a fix (m^2, DIAGONAL_KNOWN).
    fix_covariance: list[float]
    velocity_steps: list[int]
    velocity: list[list[float]]
    #: Row-major 6x6 covariance of the velocity (unmeasured axes :data:`UNMEASURED_VARIANCE`).
    velocity_covariance: list[float]
    truth_steps: list[int]
    truth_position: list[tuple[float, float, float]]
    truth_orientation: list[list[float]]
    #: (linear x, y, z, angular z) over ground in FLU.
    truth_twist: list[tuple[float, float, float, float]]
    truth_course_sideslip: list[tuple[float, float, float]]
    truth_current: list[tuple[float, float, float]]
    #: (log scale factor, leeway lambda rad, IMU yaw offset rad), constant.
    calibration: tuple[float, float, float]
    #: The origin of the truth's map: latitude, longitude (deg), height (m).
    origin: tuple[float, float, float]
    #: Delivery latency (ns) of each IMU message, fix and log message, in their order.
    imu_latency_ns: list[int] = field(default_factory=list)
    fix_latency_ns: list[int] = field(default_factory=list)
    velocity_latency_ns: list[int] = field(default_factory=list)
    #: The drivers stamp on receipt: header stamp = arrival (log) time.
    stamp_on_receipt: bool = False

    def log_ns(self, sensor: str) -> list[int]:
        """Return the arrival (log) times, ns, of a sensor's messages: 'imu', 'fix', 'velocity'."""
        steps = getattr(self, f'{sensor}_steps')
        latencies = getattr(self, f'{sensor}_latency_ns') or [0] * len(steps)
        return [self.stamps[k] + latency for k, latency in zip(steps, latencies)]

    def header_ns(self, sensor: str) -> list[int]:
        """Return the header stamps, ns, of a sensor's messages (see :meth:`log_ns`)."""
        if self.stamp_on_receipt:
            return self.log_ns(sensor)
        return [self.stamps[k] for k in getattr(self, f'{sensor}_steps')]


def sensor_readings(truth: Truth, config: VoyageConfig) -> Readings:
    """
    Return what the sensors read on the voyage ``truth``, and the truth at ``truth_rate``.

    Noise is drawn from ``numpy.random.default_rng(config.seed)`` in a fixed order, so the same
    configuration gives the same numbers; the delivery latencies from a stream of the seed per
    sensor (:func:`delivery_latencies`), so they leave the readings as they are. Sets
    ``truth.gyro_bias`` to the IMU's drawn bias.
    """
    rng = np.random.default_rng(config.seed)
    n = truth.t.size
    step_ns = int(round(1e9 / config.imu_rate))
    stamps = [START_NS + k * step_ns for k in range(n)]
    lat0, lon0, h0 = math.radians(config.origin[0]), math.radians(config.origin[1]), \
        config.origin[2]

    def stride(rate: float) -> int:
        ratio = config.imu_rate / rate
        if rate <= 0 or abs(ratio - round(ratio)) > 1e-9:
            raise ValueError(f'rate {rate} Hz must divide the IMU rate {config.imu_rate} Hz')
        return int(round(ratio))

    zeros = np.zeros(n)

    # IMU: orientation (heading and tilt noise), gyro (noise + constant bias), specific force.
    bias = rng.normal(0.0, config.gyro_bias_sigma, 3)
    truth.gyro_bias = bias
    phi_m = rng.normal(0.0, config.tilt_sigma, n)
    theta_m = rng.normal(0.0, config.tilt_sigma, n)
    psi_m = truth.psi + rng.normal(0.0, config.heading_sigma, n)
    if config.imu_yaw_offset:
        # The published yaw (ENU, counter-clockwise) is off by the offset: psi (NED) less it.
        psi_m = psi_m - config.imu_yaw_offset
    if config.compass_rate is not None:     # a heading-only compass: level, heading alone
        phi_m = theta_m = zeros
    freeze = config.window('compass_freeze')
    if freeze is not None:                  # the orientation holds its value at the start
        held = (truth.t >= freeze[0]) & (truth.t < freeze[1])
        if held.any():
            first = int(np.argmax(held))
            phi_m, theta_m, psi_m = (np.where(held, a[first], a) for a in (phi_m, theta_m, psi_m))
    q_imu = q_nb_to_ros(euler2q(phi_m, theta_m, psi_m)).tolist()
    gyro = (rng.normal(0.0, config.gyro_sigma, (n, 3)) + bias
            + np.stack([zeros, zeros, -truth.r], axis=-1)).tolist()
    gravity = normal_gravity(lat0)
    accel = (rng.normal(0.0, config.accel_sigma, (n, 3))
             + np.stack([truth.accel_x, -truth.accel_y, zeros + gravity], axis=-1)).tolist()
    imu_covariances = ([config.tilt_sigma ** 2, 0.0, 0.0, 0.0,
                        config.tilt_sigma ** 2, 0.0, 0.0, 0.0,
                        config.heading_sigma ** 2],
                       [config.gyro_sigma ** 2 if i % 4 == 0 else 0.0 for i in range(9)],
                       [config.accel_sigma ** 2 if i % 4 == 0 else 0.0 for i in range(9)])
    imu_steps = list(range(n))
    if config.compass_rate is not None:
        # Roll and pitch unknown (variance 1e3, as NMEA compasses are converted), no rate and
        # no acceleration (covariance[0] = -1, REP-145's "not given").
        imu_covariances = ([1e3, 0.0, 0.0, 0.0, 1e3, 0.0, 0.0, 0.0, config.heading_sigma ** 2],
                           [-1.0] + [0.0] * 8, [-1.0] + [0.0] * 8)
        imu_steps = list(range(0, n, stride(config.compass_rate)))
        q_imu = [q_imu[k] for k in imu_steps]
        gyro = [[0.0, 0.0, 0.0]] * len(imu_steps)
        accel = [[0.0, 0.0, 0.0]] * len(imu_steps)

    # GNSS: the antenna (lever arm rotated by the true heading) with white noise; outage.
    fix_idx = np.arange(0, n, stride(config.fix_rate))
    ax, ay, az = config.antenna
    c, s = np.cos(truth.psi[fix_idx]), np.sin(truth.psi[fix_idx])
    # FLU lever (ax, ay, az) is FRD (ax, -ay, -az); NED offset = R(psi) of that.
    ned = np.stack([truth.north[fix_idx] + c * ax + s * ay,
                    truth.east[fix_idx] + s * ax - c * ay,
                    np.full(fix_idx.size, -az)], axis=-1)
    ned += rng.normal(0.0, 1.0, ned.shape) * [config.fix_sigma, config.fix_sigma,
                                              config.fix_sigma_up]
    if config.fix_outlier_fraction > 0.0:   # a separate stream: the other noise is unchanged
        bad = np.random.default_rng(config.seed + 7919)
        jump = bad.random(fix_idx.size) < config.fix_outlier_fraction
        bearing = bad.uniform(0.0, 2.0 * math.pi, fix_idx.size)
        ned[:, 0] += np.where(jump, config.fix_outlier_distance * np.cos(bearing), 0.0)
        ned[:, 1] += np.where(jump, config.fix_outlier_distance * np.sin(bearing), 0.0)
    # On the sea surface (the ellipsoid at h0, the antenna az above it), at any distance.
    lat, lon, _ = surface_llh(ned[:, 0], ned[:, 1], (lat0, lon0, h0))
    height = h0 - ned[:, 2]
    llh = np.stack([np.degrees(lat), np.degrees(lon), height], axis=-1).tolist()
    window = config.outage_window()
    whole_second = stride(1.0) if config.imu_rate >= 1.0 else 1
    fix_steps: list[int] = []
    fix_llh: list[list[float] | None] = []
    for j, k in enumerate(fix_idx.tolist()):
        t = truth.t[k]
        if window is not None and window[0] <= t < window[1]:
            if k % whole_second:
                continue
            fix_llh.append(None)        # a NO_FIX report, once a second
        else:
            fix_llh.append(llh[j])
        fix_steps.append(k)
    fix_covariance = [config.fix_sigma ** 2, 0.0, 0.0, 0.0, config.fix_sigma ** 2, 0.0, 0.0,
                      0.0, config.fix_sigma_up ** 2]

    # DVL in base_link: water track (relative velocity) or bottom track (over ground), FLU.
    vel_idx = np.arange(0, n, stride(config.velocity_rate))
    outage = config.window('log_outage')
    if outage is not None:
        t_vel = truth.t[vel_idx]
        vel_idx = vel_idx[(t_vel < outage[0]) | (t_vel >= outage[1])]
    if config.reference == 'water':
        body_u, body_v = truth.u_r[vel_idx], truth.v_r[vel_idx]
    else:
        body_u, body_v = truth.u[vel_idx], truth.v[vel_idx]
    if config.log_scale != 1.0:
        body_u = config.log_scale * body_u    # the log's calibration error, on the surge
    measured = np.stack([body_u, -body_v, np.zeros(vel_idx.size)], axis=-1) \
        + rng.normal(0.0, config.velocity_sigma, (vel_idx.size, 3))
    measured_axes = 3
    if config.log_surge_only:     # a speed log: sway and heave unmeasured (0, variance 1e6)
        measured_axes = 1
        measured[:, 1:] = 0.0
    stuck = config.window('log_freeze')
    if stuck is not None:         # a stuck log: every reading of the window is its first
        t_vel = truth.t[vel_idx]
        held = (t_vel >= stuck[0]) & (t_vel < stuck[1])
        if held.any():
            measured[held] = measured[int(np.argmax(held))]
    variance = config.velocity_sigma ** 2
    velocity_covariance = [0.0] * 36
    for axis in range(6):   # measured linear axes; the angular ones not (a DVL has no gyro)
        velocity_covariance[7 * axis] = \
            variance if axis < measured_axes else UNMEASURED_VARIANCE

    # Truth: REP-103/105 pose and twist, course/sideslip/angle of attack, current (ENU).
    truth_idx = np.arange(0, n, stride(config.truth_rate))
    q_true = q_nb_to_ros(euler2q(zeros[truth_idx], zeros[truth_idx],
                                 truth.psi[truth_idx])).tolist()
    chi = truth.course()[truth_idx].tolist()
    beta = truth.sideslip()[truth_idx].tolist()
    truth_steps = truth_idx.tolist()
    velocity_steps = vel_idx.tolist()

    # Delivery: each sensor's latencies from a stream of its own (the noise above unchanged).
    def latencies(sensor: str, steps: list[int]) -> list[int]:
        stream = np.random.default_rng(
            np.random.SeedSequence(config.seed, spawn_key=(_LATENCY_STREAMS[sensor],)))
        return delivery_latencies([stamps[k] for k in steps],
                                  getattr(config, f'{sensor}_latency'), stream)

    return Readings(
        stamps=stamps, imu_steps=imu_steps, imu_orientation=q_imu,
        imu_angular_velocity=gyro, imu_linear_acceleration=accel,
        imu_covariances=imu_covariances,
        fix_steps=fix_steps, fix_llh=fix_llh, fix_covariance=fix_covariance,
        velocity_steps=velocity_steps, velocity=measured.tolist(),
        velocity_covariance=velocity_covariance,
        truth_steps=truth_steps,
        truth_position=[(float(truth.east[k]), float(truth.north[k]), 0.0)
                        for k in truth_steps],
        truth_orientation=q_true,
        truth_twist=[(float(truth.u[k]), -float(truth.v[k]), 0.0, -float(truth.r[k]))
                     for k in truth_steps],
        truth_course_sideslip=[(chi[j], beta[j], 0.0) for j in range(len(truth_steps))],
        truth_current=[(float(truth.current_e[k]), float(truth.current_n[k]), 0.0)
                       for k in truth_steps],
        calibration=(float(config.log_scale), float(config.leeway),
                     float(config.imu_yaw_offset)),
        origin=(float(config.origin[0]), float(config.origin[1]), float(config.origin[2])),
        imu_latency_ns=latencies('imu', imu_steps), fix_latency_ns=latencies('fix', fix_steps),
        velocity_latency_ns=latencies('velocity', velocity_steps),
        stamp_on_receipt=config.stamp_on_receipt)
