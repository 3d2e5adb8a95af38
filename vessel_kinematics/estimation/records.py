"""
The estimator's records: measurements in, the navigation state out, rejections as values.

Everything here is in Fossen's frames: NED world, BODY x forward, y starboard, z down
(FRD), scalar-first unit quaternions q_nb rotating BODY to NED, radians, metres, seconds, and
stamps in integer nanoseconds. ``ros.inputs`` makes the measurement records from messages
and ``ros.outputs`` turns :class:`NavState` into messages; nothing here knows a message type.
"""

from __future__ import annotations

from dataclasses import dataclass
import enum
from typing import Sequence

import numpy as np

__all__ = [
    'BodyVelocity', 'Calibration', 'DEAD_RECKONING', 'Estimate', 'Event', 'FUSED', 'GnssFix',
    'GroundVelocity', 'Health', 'ImuSample', 'Level', 'Mode', 'NavPose', 'NavState', 'Reason',
    'Rejection', 'RelativeFlow', 'WAITING',
]


class Mode(enum.StrEnum):
    """
    The estimator's mode, as /diagnostics and the replay summary show it (its value).

    A ``StrEnum``: a member is its value in comparisons, ``str()`` and f-strings.
    """

    #: Before the origin and the first position are known.
    WAITING = 'waiting_for_origin'
    #: A position, but no fix used recently (or GNSS disabled).
    DEAD_RECKONING = 'dead_reckoning'
    #: A fix used recently.
    FUSED = 'fused'


#: The modes by their old names.
WAITING = Mode.WAITING
DEAD_RECKONING = Mode.DEAD_RECKONING
FUSED = Mode.FUSED


@dataclass(frozen=True, eq=False)
class GnssFix:
    """
    A GNSS fix of the antenna.

    ``lat``, ``lon`` in rad, ``height`` ellipsoidal in m (NaN: a horizontal-only fix),
    ``cov_ned`` the 3x3 position covariance in NED (m²); ``lever_b`` the antenna in BODY
    (FRD, m), None: the configuration's ``antenna_b``.
    """

    stamp_ns: int
    lat: float
    lon: float
    height: float
    cov_ned: np.ndarray
    lever_b: tuple[float, float, float] | None = None


@dataclass(frozen=True, eq=False)
class ImuSample:
    """
    An attitude and/or body rate of the base frame, already corrected for the IMU mounting.

    ``q_nb`` the unit quaternion BODY (FRD) to NED, scalar first (a tuple of floats from
    ``ros.inputs``, or any sequence or array), or None; ``att_cov`` its 3x3 covariance (rad²,
    small rotations about the BODY axes: roll, pitch, yaw near level) or None (unknown);
    ``omega_b`` the body rate [p, q, r] in FRD (rad/s) or None, ``omega_cov`` its 3x3
    covariance ((rad/s)²) or None.
    """

    stamp_ns: int
    q_nb: Sequence[float] | None
    att_cov: np.ndarray | None
    omega_b: Sequence[float] | None
    omega_cov: np.ndarray | None


@dataclass(frozen=True, eq=False)
class BodyVelocity:
    """
    A body velocity ν = [u, v, w] (m/s, FRD) of the base frame with its 3x3 covariance.

    Over ground or through water per the filter's reference; components with a variance of
    at least ``UNMEASURED_VARIANCE`` (a speed log's sway and heave) are not measured.
    ``omega_b`` an optional body rate (rad/s, FRD, e.g. a wheel odometry's yaw rate) used when
    the IMU gives none.
    """

    stamp_ns: int
    nu_b: np.ndarray
    cov: np.ndarray
    omega_b: np.ndarray | None = None
    omega_cov: np.ndarray | None = None


@dataclass(frozen=True, eq=False)
class GroundVelocity:
    """
    A receiver's own velocity over ground ``v_ned`` = [v_N, v_E, v_D] (m/s, NED at the antenna).

    ``cov`` its 3x3 covariance (m²/s²); a component with a variance of at least
    ``UNMEASURED_VARIANCE`` or a NaN value is not measured (a 2-D receiver's v_D). It is the
    antenna's velocity: R(q)(ω × r_b) of the lever arm ``lever_b`` (BODY FRD, m; None: the
    configuration's ``antenna_b``) is taken off with the body rate known then. Never a body
    velocity: it goes to :meth:`Estimator.ground_velocity`.
    """

    stamp_ns: int
    v_ned: np.ndarray
    cov: np.ndarray
    lever_b: tuple[float, float, float] | None = None


class Reason(str, enum.Enum):
    """
    Why a measurement was refused: every rejection reason of the package, in one place.

    The value is the snake_case key counted per input (``fix/nan_field`` in /diagnostics, the
    replay's summary and :meth:`Pipeline.counts`), the same text on every Python. Format a
    reason with ``.value``: ``str()`` and f-strings of a ``(str, Enum)`` member give
    ``'Reason.NAN_FIELD'`` (Python 3.11 and 3.12 alike), never the key. A member compares
    equal to its value (``Reason.NO_FIX == 'no_fix'``).
    """

    # ----- the edge (ros/inputs.py): a message that cannot be used
    #: A used field is NaN or infinite (edge), or a record with a non-finite field reached
    #: the estimator.
    NAN_FIELD = 'nan_field'
    #: |latitude| > 90 deg or |longitude| > 180 deg.
    LAT_OUT_OF_RANGE = 'lat_out_of_range'
    #: A NavSatFix whose status is NO_FIX.
    NO_FIX = 'no_fix'
    #: An Imu orientation that is the zero quaternion.
    ZERO_QUATERNION = 'zero_quaternion'
    #: An Imu orientation whose norm differs from 1 by more than the tolerance (1e-3).
    NON_UNIT_QUATERNION = 'non_unit_quaternion'
    #: An Imu with neither a usable orientation nor a usable angular velocity.
    NO_DATA = 'no_data'
    #: A used 3x3 covariance block not symmetric positive semi-definite, or too large.
    BAD_COVARIANCE = 'bad_covariance'
    #: A header stamp that is negative, has ``nanosec`` >= 1e9 or overflows int32 seconds.
    BAD_STAMP = 'bad_stamp'
    #: A body speed above the plausible maximum (m/s).
    IMPLAUSIBLE_SPEED = 'implausible_speed'
    #: A body rate above the plausible maximum (rad/s).
    IMPLAUSIBLE_RATE = 'implausible_rate'
    #: A fix height outside the plausible range (m).
    IMPLAUSIBLE_HEIGHT = 'implausible_height'
    # ----- the estimator: a measurement the filter refuses
    #: A header stamp of zero: the driver does not stamp.
    ZERO_STAMP = 'zero_stamp'
    #: A stamp older than the newest one taken by more than ``history_length``
    #: (:mod:`vessel_kinematics.estimation.timeline`); it never resets the filter.
    TOO_LATE = 'too_late'
    #: A stamp that repeats one already taken from the same topic (a sensor whose clock froze).
    REPEATED_STAMP = 'repeated_stamp'
    #: A stamp more than ``future_tolerance`` ahead of its arrival time (the node's clock, the
    #: bag's log time), after ``<input>.time_offset``: it never moves the state's time.
    FUTURE_STAMP = 'future_stamp'
    #: An update whose result was not finite (the state is kept).
    NUMERICAL = 'numerical'
    #: A fix or velocity whose innovation is beyond the gate (``*_gate_sigma``).
    INNOVATION_GATE = 'innovation_gate'
    #: An update that would give a physically impossible state (speed, position, log scale).
    IMPLAUSIBLE_STATE = 'implausible_state'
    #: A faulty instrument (:mod:`vessel_kinematics.estimation.faults`): a compass frozen while
    #: the gyro or the course over ground turns, a log stuck at one value while the speed
    #: through the water from the fixes changes by knots, or a sample repeated with its stamp.
    FROZEN_INPUT = 'frozen_input'
    # ----- the drivers
    #: A velocity message while ``velocity.source`` is ``none`` (the pipeline).
    UNUSED_INPUT = 'unused_input'
    #: A message whose payload cannot be deserialised, garbage CDR (the replay; the node's raw
    #: ``imu`` subscription).
    CDR_ERROR = 'cdr_error'
    #: A message while fusion is paused (the node's ``~/enable`` service set false): counted,
    #: not fused.
    PAUSED = 'paused'
    #: A heading from a lower-priority topic while a higher one is fresh and healthy
    #: (``imu.topics`` failover): counted, kept as the standby, not fused.
    STANDBY = 'standby'
    #: A static transform with an empty parent or child frame id (/tf_static).
    NO_FRAME_ID = 'no_frame_id'
    #: A static transform from a frame to itself (/tf_static).
    SELF_TRANSFORM = 'self_transform'
    #: A sensor mounting from /tf_static with a lever arm beyond the parameters' bound (1000 m
    #: per axis), or a mounting change too far from the one in use.
    IMPLAUSIBLE_MOUNTING = 'implausible_mounting'
    #: A /tf_static message with more transforms or bytes than its limit, or a new frame once
    #: the static tree holds its limit (/tf_static).
    TOO_LARGE = 'too_large'


@dataclass(frozen=True)
class Rejection:
    """A refused measurement: its :class:`Reason` (counted by value) and a human ``detail``."""

    reason: Reason
    detail: str


class Level(enum.IntEnum):
    """The severity of a :class:`Health` report: diagnostic_msgs/DiagnosticStatus's levels."""

    OK = 0
    WARN = 1
    ERROR = 2


@dataclass(frozen=True)
class Health:
    """
    One part of the estimator's health (:meth:`Estimator.health`), as /diagnostics shows it.

    ``name`` the part (``estimate``, ``heading``, ``log``, ``gnss``), ``level`` its severity,
    ``summary`` one line, ``values`` its key-value pairs as text (units in the keys).
    """

    name: str
    level: Level
    summary: str
    values: dict[str, str]


@dataclass(frozen=True)
class Event:
    """Something a navigator's log should say once (a recovery, a fault): stamp ns, text."""

    stamp_ns: int
    level: Level
    text: str


@dataclass(frozen=True)
class Estimate:
    """A scalar estimate with its standard deviation (the units of the quantity)."""

    value: float
    sigma: float


@dataclass(frozen=True)
class Calibration:
    """
    The sensor calibrations the filter estimates, each None where it is not estimated.

    ``log_scale``: the velocity sensor reads ``log_scale`` times the true speed through the
    water (1 = calibrated, 0.8 = reads 20 % low); ``leeway``: the constant leeway angle λ
    (rad, sway through water = tan λ · surge, + to starboard); ``turn_drift``: κ (m/rad), the
    hull's sway through the water per unit yaw rate in a turn; ``heading_offset``: the
    constant offset δψ added to the IMU heading (rad, NED, clockwise positive) learnt from the
    fixes; ``declination``: the magnetic declination applied (rad, east positive; fixed, from
    the World Magnetic Model with ``imu.declination: auto``).
    """

    log_scale: Estimate | None = None
    leeway: Estimate | None = None
    turn_drift: Estimate | None = None
    heading_offset: Estimate | None = None
    declination: float | None = None


@dataclass(frozen=True)
class RelativeFlow:
    """
    The flow relative to the water (Fossen 2.4.2): U_r (m/s), β_r and α_r (rad).

    β_r = asin(v_r / U_r) in the horizontal plane (leeway plus turning drift, the seed's
    sign), α_r = atan2(w_r, u_r) of the body velocity through the water ν_r = ν − ν_c.
    """

    speed: float
    sideslip: float
    angle_of_attack: float


@dataclass
class NavPose:
    """
    The pose and twist of the navigation state at ``stamp_ns``: what the odometry outputs need.

    ``p`` NED position of the base about the origin (m); ``q`` q_nb (the heading corrected by
    the declination and the estimated heading offset); ``nu`` body velocity over ground (m/s,
    FRD); ``omega`` body rate (rad/s, FRD, zero when unknown); ``p_local`` the dead-reckoned
    position in the odom frame (NED axes, m); covariances 3x3 in the same frames; ``origin``
    (rad, rad, m). The pose part of :class:`NavState`: what the odometry outputs need.

    The map frame is the origin's tangent plane (NED, Fossen 2.3, or flat earth with
    ``projection: flat``). On the surface motions ``p[2]`` is where the sea surface lies in it
    (below the plane by the earth's curvature, d²/2R at a distance d), and ``q`` the attitude
    against the map's axes (the local vertical and north turn away from them by d/R and the
    meridians' convergence).
    """

    stamp_ns: int
    mode: Mode
    origin: tuple[float, float, float]
    p: np.ndarray
    q: np.ndarray
    nu: np.ndarray
    omega: np.ndarray
    p_local: np.ndarray
    cov_p: np.ndarray
    cov_att: np.ndarray
    cov_nu: np.ndarray
    cov_omega: np.ndarray
    cov_p_local: np.ndarray


@dataclass
class NavState(NavPose):
    """
    The navigation state at ``stamp_ns``, in Fossen's frames, for building the outputs.

    The :class:`NavPose` and: ``v_n`` the velocity over ground in the local NED at the vessel
    (m/s, north the true north there); ``current`` the current (m/s, water reference) or
    None, and ``cov_current`` its 3x3 covariance, both in the map's NED as published (far
    from the origin the map's north is turned from the vessel's true north by the meridians'
    convergence); ``llh`` the base's latitude, longitude (rad) and ellipsoidal height (m);
    ``course`` χ from true north, ``sideslip`` β and ``angle_of_attack`` α (rad; χ = ψ and
    β = α = 0 below ``course.min_speed``, blended smoothly up to twice that); ``low_speed``
    True where that fallback is active; ``calibration`` and ``relative_flow`` (water
    reference) as estimated; ``acceleration`` the estimated rate of the surge (m/s²,
    along the heading; through the water with a water reference).
    """

    v_n: np.ndarray
    current: np.ndarray | None
    llh: tuple[float, float, float]
    course: float
    sideslip: float
    angle_of_attack: float
    cov_current: np.ndarray | None
    low_speed: bool = False
    calibration: Calibration = Calibration()
    relative_flow: RelativeFlow | None = None
    acceleration: float = 0.0
