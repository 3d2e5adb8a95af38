"""
The filter's configuration and its model constants: what kind of craft, which sensors.

:class:`FilterConfig` is all the estimator reads: the ROS edge (``params.filter_config``)
builds it from the node's parameters, so the estimator never sees a parameter class, a YAML
file or a message. The model constants below are the filter's physics; each states its unit
and its reason.
"""

from __future__ import annotations

from dataclasses import dataclass
import enum
import math
from typing import Callable

__all__ = [
    'ACCEL_SIGMA', 'ATTITUDE_CORRELATION_TIME', 'ATTITUDE_SHARE_MAX_VARIANCE', 'CURRENT',
    'DEFAULT_ATTITUDE_SIGMA', 'DEFAULT_RATE_SIGMA', 'DeclinationModel', 'FilterConfig',
    'FUSED_TIMEOUT', 'GATE_RESET_COUNT', 'GATE_RESET_TIME', 'HEADING_OFFSET', 'HEAVE',
    'INITIAL_VELOCITY_SIGMA', 'Integrator', 'LAZY_INTERVAL', 'LEEWAY', 'LOG_SCALE',
    'MAX_STATE_POSITION', 'MAX_STATE_SPEED', 'Markov', 'Motion', 'Projection',
    'SURFACE_HEIGHT_SIGMA', 'SURFACE_HEAVE_SIGMA',
    'SURGE', 'SWAY', 'TURN_DRIFT', 'UNKNOWN_ATTITUDE_SIGMA', 'UNMEASURED_VARIANCE',
    'VELOCITY_GATE_RESET_COUNT',
]


class Motion(str, enum.Enum):
    """What kind of craft the filter navigates (parameter ``motion``)."""

    #: A vessel on the sea surface: height and vertical velocity in NED held at zero (they are
    #: not states), roll and pitch from the IMU.
    SURFACE = 'surface'
    #: A ground vehicle on a plane: as SURFACE, and roll and pitch forced to zero.
    GROUND = 'ground'
    #: Free 3-D motion (underwater vehicles): 3-D position and body velocity.
    FREE = 'free'


class Projection(enum.StrEnum):
    """How positions about the origin are computed (parameter ``projection``)."""

    #: The exact local NED frame through ECEF (Fossen eqs. 2.91-2.100).
    TANGENT = 'tangent'
    #: Fossen's flat-earth approximation (eqs. 2.105-2.108).
    FLAT = 'flat'


class Integrator(enum.StrEnum):
    """How the attitude is integrated from the body rate (parameter ``integrator``)."""

    #: The exact exponential step for a constant rate.
    EXPONENTIAL = 'exponential'
    #: Fossen's Euler step q + T(q)ω dt, normalised (eqs. 2.84-2.85).
    EULER = 'euler'


@dataclass(frozen=True)
class Markov:
    """
    A first-order Gauss-Markov process ẋ = −x/τ + w (Brown and Hwang 2012, ch. 2.9).

    ``sigma`` the stationary standard deviation (the unit of the state), ``tau`` the
    correlation time (s). Over a step Δt the mean decays by φ = exp(−Δt/τ) toward its rest
    value and the variance gains σ²(1 − φ²): exact, and bounded by σ² when nothing observes the
    state.
    """

    sigma: float
    tau: float

    def decay(self, dt: float) -> float:
        """Return φ = exp(−Δt/τ)."""
        return math.exp(-dt / self.tau)

    def noise(self, dt: float) -> float:
        """Return the variance gained over Δt, σ²(1 − φ²)."""
        return self.sigma * self.sigma * -math.expm1(-2.0 * dt / self.tau)


#: Surge (forward speed, over ground or through water): a vessel holds its speed for minutes;
#: stationary σ 15 m/s bounds it by the fastest craft the filter is meant for, and τ gives
#: white acceleration of density √(2σ²/τ) ≈ 0.15 m/s² per √Hz, a vessel's speed changes.
SURGE = Markov(sigma=15.0, tau=20000.0)
#: Sway (over ground, or through the water beyond the leeway): a hull's drift in a turn lasts
#: as long as the turn; 1 m/s stationary σ covers the drift of a small craft turning hard
#: (15° at 4 m/s), τ 30 s is a turn's time scale. Unmeasured by a speed log: this prior keeps
#: it bounded, and the fixes (through the course) tell it.
SWAY = Markov(sigma=0.5, tau=60.0)
#: Heave through the water or over ground (motion ``free`` only): 0.5 m/s, 10 s.
HEAVE = Markov(sigma=0.5, tau=10.0)
#: The ocean current (NED, each horizontal axis): 0.5 m/s typical tidal set and drift
#: (stationary σ and the prior), changing over an hour.
CURRENT = Markov(sigma=0.5, tau=10800.0)
#: The speed log's scale factor about 1 (reading / truth): an uncalibrated paddle wheel or
#: electromagnetic log is commonly 10-30 % off; σ 0.2, constant over a day.
LOG_SCALE = Markov(sigma=0.2, tau=86400.0)
#: The leeway angle (rad): a sailing yacht's leeway is typically 3-8° close-hauled, a motor
#: vessel's about zero; σ 5°, changing over ten minutes (a new tack, a new wind).
LEEWAY = Markov(sigma=math.radians(5.0), tau=3600.0)
#: The turning drift κ (m/rad): the sway through the water per unit yaw rate, v = κ r, a
#: constant of the hull and of where the base frame sits on it (negative forward of the pivot
#: point: the bow points into the turn). A 15 m motor boat turning at 2°/s drifts about 14°,
#: κ ≈ −20 m; σ 20 m covers small craft to small ships.
TURN_DRIFT = Markov(sigma=20.0, tau=86400.0)
#: The heading offset (rad): a constant of the installation (mounting yaw, deviation),
#: random walk density per √s; its prior comes from the first course-vs-heading comparison.
HEADING_OFFSET = Markov(sigma=math.pi, tau=1e7)

#: White body-acceleration density of the velocity states' coupling (m/s² per √Hz); used
#: where a velocity component is a plain random walk (SURGE's density equals it).
ACCEL_SIGMA = 0.15
#: Correlation time τ (s) of the attitude error, a first-order Gauss-Markov process: its
#: share of the position process noise is 2τ R S(ν) P_Θ S(ν)ᵀ Rᵀ per second. An AHRS heading
#: error (magnetic disturbance, declination, mounting) lasts seconds to minutes.
ATTITUDE_CORRELATION_TIME = 5.0
#: Attitude variance (rad²) above which the attitude share saturates (small-angle limit).
ATTITUDE_SHARE_MAX_VARIANCE = 1.0
#: Standard deviation of the velocity before any measurement (m/s).
INITIAL_VELOCITY_SIGMA = 3.0
#: Attitude standard deviation (rad, each axis) when the IMU gives an unknown (zero) covariance.
DEFAULT_ATTITUDE_SIGMA = 0.02
#: Body-rate standard deviation (rad/s) when the IMU gives an unknown (zero) covariance.
DEFAULT_RATE_SIGMA = 0.01
#: Attitude standard deviation (rad) while nothing has told the attitude yet.
UNKNOWN_ATTITUDE_SIGMA = math.pi
#: A velocity component with a variance at least this ((m/s)²) is treated as unmeasured.
UNMEASURED_VARIANCE = 1e4
#: A fix older than this (s) no longer counts as fused.
FUSED_TIMEOUT = 3.0
#: Longest interval (s) over which the covariance propagation is deferred.
LAZY_INTERVAL = 0.1
#: Consecutive fixes refused by the innovation gate after which the position is re-initialised
#: from the fix (a relocated vessel, a moved origin): a real jump is never locked out.
GATE_RESET_COUNT = 10
#: Seconds of fixes all refused by the gate after which the position is re-initialised.
GATE_RESET_TIME = 10.0
#: Consecutive velocities refused by the gate after which the velocity is re-initialised.
VELOCITY_GATE_RESET_COUNT = 10
#: Surface motion: standard deviation (m) of the height about the origin's (waves, tide,
#: squat, the antenna's heave), reported in the pose covariance; the height is not a state.
SURFACE_HEIGHT_SIGMA = 1.0
#: Surface motion: standard deviation (m/s) of the vertical velocity in NED (wave heave).
SURFACE_HEAVE_SIGMA = 0.25
#: A state speed beyond this (m/s) is impossible: an update that would give it is refused.
MAX_STATE_SPEED = 150.0
#: A state position beyond this from the origin (m) is refused (outside any local frame).
MAX_STATE_POSITION = 2.0e7

#: ``(lat rad, lon rad, height m, stamp ns) -> declination rad`` (east positive).
DeclinationModel = Callable[[float, float, float, int], float]


@dataclass(frozen=True)
class FilterConfig:
    """
    Everything the estimator reads, in Fossen's frames (radians, metres, NED/FRD).

    ``origin`` (lat deg, lon deg, height m; NaN = from the first fix) keeps the ROS degrees
    of ``sensor_msgs/NavSatFix``; ``antenna_b`` the GNSS antenna in BODY (FRD, m).
    ``velocity_input``: a velocity sensor is connected; ``water``: it measures through the
    water (then the current, and with ``estimate_scale``/``estimate_leeway`` the log's scale
    and the leeway, are states). ``estimate_heading_offset``: a constant IMU heading offset
    is a state, initialised from the course over ground once moving. ``declination``: a model
    giving the magnetic declination at the origin (None: none applied). ``gate_sigma``:
    Mahalanobis distance beyond which a fix (``gnss``) or a velocity (``velocity``) is
    refused (0 = no gate). ``course_min_speed``: speed over ground (m/s) below which the
    course falls back to the heading and the sideslip to zero.
    """

    motion: Motion = Motion.SURFACE
    origin: tuple[float, float, float] = (math.nan, math.nan, math.nan)
    projection: Projection = Projection.TANGENT
    gnss_enabled: bool = True
    antenna_b: tuple[float, float, float] = (0.0, 0.0, 0.0)
    gnss_default_sigma: float = 2.5
    gnss_gate_sigma: float = 5.0
    velocity_input: bool = True
    water: bool = False
    velocity_gate_sigma: float = 5.0
    estimate_scale: bool = True
    estimate_leeway: bool = True
    estimate_heading_offset: bool = False
    declination: DeclinationModel | None = None
    use_orientation: bool = True
    integrator: Integrator = Integrator.EXPONENTIAL
    course_min_speed: float = 0.3
    max_gap: float = 1.0
    reorder_window: float = 0.1

    @property
    def horizontal(self) -> bool:
        """Return True for the planar motions (surface, ground): 2-D position and velocity."""
        return self.motion is not Motion.FREE

    @property
    def level(self) -> bool:
        """Return True when roll and pitch are forced to zero (ground)."""
        return self.motion is Motion.GROUND
