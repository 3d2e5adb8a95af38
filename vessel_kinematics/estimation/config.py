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
    'ACCEL_MAX', 'ACCEL_RELAX_TIME', 'ACCEL_SIGMA', 'ACCEL_SIGMA_CRUISE', 'ACCEL_TAU',
    'ATTITUDE_CORRELATION_TIME', 'ATTITUDE_SHARE_MAX_VARIANCE', 'COURSE_HEADING_MIN_SPEED',
    'COURSE_HEADING_TURN_RATE', 'CURRENT', 'DeclinationModel', 'DEFAULT_ATTITUDE_SIGMA',
    'DEFAULT_RATE_SIGMA', 'FilterConfig', 'FROZEN_COG_BASELINE',
    'FROZEN_COG_MIN_SPEED', 'FROZEN_HEADING_COG_TURN', 'FROZEN_HEADING_JUMP',
    'FROZEN_HEADING_JUMP_HOLD', 'FROZEN_HEADING_JUMP_RATE', 'FROZEN_HEADING_TOLERANCE',
    'FROZEN_HEADING_TURN', 'FROZEN_HEADING_WINDOW', 'FROZEN_LOG_SPEED_CHANGE',
    'FROZEN_LOG_TOLERANCE', 'FROZEN_LOG_WINDOW', 'FUSED_TIMEOUT', 'GAP_STEPS', 'GAP_STEPS_KEPT',
    'GATE_RESET_COUNT', 'GATE_RESET_TIME', 'HEADING_OFFSET', 'HEAVE', 'INITIAL_VELOCITY_SIGMA',
    'Integrator', 'LAZY_INTERVAL', 'LEEWAY', 'LOG_SCALE', 'LOG_SETTLE_RISE', 'LOG_SETTLE_SHARE',
    'LOG_SETTLE_MIN', 'LOG_SETTLE_TIME', 'LOG_STALL_READING', 'LOG_STALL_SPEED',
    'Markov', 'MAX_STATE_POSITION', 'MAX_STATE_SPEED', 'Motion', 'Projection',
    'READY_SPEED_SIGMA', 'READY_WAIT', 'SETTLE_CONTINUE_SIGMA', 'SETTLE_TIME',
    'STEADY_READING_JUMP', 'STEADY_READING_TIME', 'STEP_SIGMA', 'SURFACE_HEAVE_SIGMA',
    'SURFACE_HEIGHT_DRIFT', 'SURFACE_HEIGHT_SIGMA', 'SURFACE_TILT_SIGMA', 'SURGE', 'SWAY',
    'SWAY_FLOOR_SPEED', 'SWAY_RATIO', 'TURN_DRIFT', 'TURN_DRIFT_MAX_ANGLE',
    'UNKNOWN_ATTITUDE_SIGMA', 'UNMEASURED_VARIANCE', 'VELOCITY_GATE_RESET_COUNT',
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


#: Surge (forward speed, over ground or through water): its own white acceleration is small
#: (density √(2σ²/τ) = 0.02 m/s² per √Hz) because the acceleration state carries a vessel's speed
#: changes (:data:`ACCEL_TAU`, :data:`ACCEL_SIGMA_CRUISE`); σ 15 m/s bounds it by the fastest
#: craft the filter is meant for.
SURGE = Markov(sigma=15.0, tau=2.0 * 15.0 ** 2 / 0.02 ** 2)
#: Sway (over ground, or through the water beyond the leeway): a hull's drift in a turn lasts
#: as long as the turn; 1 m/s stationary σ covers the drift of a small craft turning hard
#: (15° at 4 m/s), τ 30 s is a turn's time scale. Unmeasured by a speed log: this prior keeps
#: it bounded, and the fixes (through the course) tell it.
SWAY = Markov(sigma=0.5, tau=60.0)
#: The drift ratio b through the water (surface, water reference): the sway beyond the leeway
#: and the turning drift per unit surge, v = b·u_r (b ≈ the drift angle, rad): a hull's own
#: transient drift (a gust, a wave, the compass's error) lasts seconds to a minute; σ 0.2
#: (11°). A ratio, so that a slow hull's sway is slow: at rest it has none.
SWAY_RATIO = Markov(sigma=0.2, tau=20.0)
#: The speed (m/s) the drift ratio acts on at rest, v = b·√(u_r² + U₀²): a stopped hull still
#: drifts with the wind, by up to about a tenth of a metre per second (1σ of b times this).
SWAY_FLOOR_SPEED = 0.5
#: Heave through the water or over ground (motion ``free`` only): 0.5 m/s, 10 s.
HEAVE = Markov(sigma=0.5, tau=10.0)
#: The ocean current (NED, each horizontal axis): 0.5 m/s typical tidal set and drift
#: (stationary σ and the prior), changing over an hour.
CURRENT = Markov(sigma=0.5, tau=10800.0)
#: The speed log's scale factor about 1 (reading / truth): an uncalibrated paddle wheel or
#: electromagnetic log is commonly 10-30 % off; σ 0.2, constant over a day.
LOG_SCALE = Markov(sigma=0.2, tau=30 * 86400.0)
#: Time constant (s) of the log's steady reading, the mean of its past readings at which the
#: log update takes ∂z/∂k (``VelocityUpdate._steady``); a minute without a reading starts
#: it anew, and so does the second reading in a row more than :data:`STEADY_READING_JUMP` of
#: its σ from it on the same side (a real change of speed or calibration, not the noise).
STEADY_READING_TIME = 60.0
STEADY_READING_JUMP = 4.0
#: The first output waits for a measured velocity (``FilterState.ready``): a log reading or a
#: receiver's velocity, or fixes until the speed's σ (m/s, 1 kn; both axes without a velocity
#: sensor) is within this, or :data:`READY_WAIT` s after the first fix. Before, a vessel under
#: way went out at the prior's 0 kn.
READY_SPEED_SIGMA = 0.5
#: The longest (s) the first output waits for the fixes to tell the velocity.
READY_WAIT = 5.0
#: The leeway angle (rad): a sailing yacht's leeway is typically 3-8° close-hauled, a motor
#: vessel's about zero; σ 5°, changing over ten minutes (a new tack, a new wind).
LEEWAY = Markov(sigma=math.radians(5.0), tau=3600.0)
#: The turning drift κ (m/rad): the sway through the water per unit yaw rate, v = κ r, a
#: constant of the hull and of where the base frame sits on it (negative forward of the pivot
#: point: the bow points into the turn). A 15 m motor boat turning at 2°/s drifts about 14°,
#: κ ≈ −20 m; σ 20 m covers small craft to small ships.
TURN_DRIFT = Markov(sigma=20.0, tau=86400.0)
#: The largest drift angle (rad) the turning drift may give, |κ r| ≤ tan(30°)·|u_r|: the linear
#: pivot-point model v = κ r holds for turning radii of a few hull lengths; in a slow turn at
#: low speed (radius near one length) it would give a drift of 60-90°, which no hull has.
TURN_DRIFT_MAX_ANGLE = math.radians(30.0)
#: The heading offset (rad): a constant of the installation (mounting yaw, deviation),
#: random walk density per √s; its prior comes from the first course-vs-heading comparison.
HEADING_OFFSET = Markov(sigma=math.pi, tau=1e7)

#: The acceleration state ȧ = −a/τ + w (Singer 1970: a manoeuvre's acceleration lasts seconds):
#: correlation time τ (s) of a craft's surge acceleration, a throttle change or a crash stop.
ACCEL_TAU = 3.0
#: Stationary σ (m/s²) of the acceleration while cruising: what the filter expects when nothing
#: manoeuvres (waves and trim give a few cm/s²). It sets how smooth the speed over ground from
#: fixes alone is (bench: 0.16 m/s σ at 9 Hz fixes of 1.5 m).
ACCEL_SIGMA_CRUISE = 0.05
#: The largest acceleration (m/s²) a surface craft makes: 0.6 g, a planing hull at full throttle
#: or in a crash stop. The manoeuvre test (:mod:`.manoeuvre`) takes a measurement that this
#: acceleration, begun since the last one, explains; the adaptive σ never exceeds it.
ACCEL_MAX = 0.6 * 9.80665
#: Time constant (s) over which the adaptive acceleration σ relaxes back toward cruising once
#: the measured acceleration has fallen: a throttle change or a stop is over in seconds.
ACCEL_RELAX_TIME = 3.0
#: White body-acceleration density (m/s² per √Hz) of the sway and heave random walks where a
#: velocity component has no prior of its own (SURGE's density equals it).
ACCEL_SIGMA = 0.02
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
#: A fix or a ground velocity older than this (s) no longer counts as fused: the speed over
#: ground is then unobserved (dead reckoning), and the log's scale is held.
FUSED_TIMEOUT = 3.0
#: Longest interval (s) over which the covariance propagation is deferred. The IMU messages
#: between two flushes only advance the attitude and sum the rotation (``model.Pending``): a
#: full propagation per message costs about eight times that (``bench/bench_estimator.py``),
#: more than the node's CPU guard allows at 400 Hz.
LAZY_INTERVAL = 0.1
#: A step between two stamps is a gap (crossed without integrating) when longer than
#: ``max_gap`` and than this many times the usual step, the median of the last
#: :data:`GAP_STEPS_KEPT`: a receiver alone at 0.5 Hz steps 2 s each time, and every step
#: would be a gap; its usual step makes a gap 6 s. The node refuses a ``max_gap`` set below
#: as many periods of the fastest input (``ros/node/checks.py``).
GAP_STEPS = 3.0
GAP_STEPS_KEPT = 15
#: Consecutive fixes refused by the innovation gate after which the position is re-initialised
#: from the fix (a relocated vessel, a moved origin): a real jump is never locked out.
GATE_RESET_COUNT = 10
#: Seconds of fixes all refused by the gate after which the position is re-initialised.
GATE_RESET_TIME = 10.0
#: A fix taken right after fixes refused, yet this many σ off, moves the position only: it
#: stepped while they were refused, and only its grown σ lets the fix in (a receiver's static
#: hold released: 21-32 m at 0-1 kn on anemomind's coach boat, which the velocity took as
#: 2-3 kn for seconds).
STEP_SIGMA = 3.0
#: Seconds after the first fix in which a fix :data:`STEP_SIGMA` of its own σ off, with a
#: velocity measured, moves the position only: a receiver just started wanders 10-25 m within
#: seconds (4 of 41 yacht logs), which the current took (up to 3.2 kn). A minute covers the
#: wander seen; after it, such a fix is a manoeuvre or an outlier, for the gates to judge.
SETTLE_TIME = 60.0
#: In that minute, a fix this many σ of its own off that goes on the way of a wander found at
#: the fix before it is the wander too: a wander comes in several steps, each under 3σ after
#: the first (one receiver 11, 5.6 and 5.5 m at three fixes in a row, σ 2.5 m).
SETTLE_CONTINUE_SIGMA = 1.0
#: Consecutive velocities refused by the gate after which the filter acts on them: the scale
#: is relearnt when the fixes disagree with the log, the velocity re-initialised otherwise.
VELOCITY_GATE_RESET_COUNT = 10
#: A speed log (surge only) reads nothing below about 1 kn and too little just above: a paddle
#: wheel stalls and slips. Its reading z (m/s) gets a standard deviation of this times
#: (1 − |z| / 2·this) on top of its own, from this at rest to nothing at 2 kn.
LOG_STALL_SPEED = 0.5
#: A speed-log reading below this (m/s, 0.5 kn) is the wheel at a standstill: it reads nothing
#: of a boat drifting, going astern or sideways. While the fixes give the speed it is not fused
#: (150 s of zeros at 2 kn astern, in one of the psaros33's 2014 logs, took the scale from
#: 0.88 to 0.06, and the log's return then gave 21 kn), and with the hull making more than
#: :data:`LOG_STALL_SPEED` through the water the log counts as silent at once.
LOG_STALL_READING = 0.5 * LOG_STALL_SPEED
#: A speed log just started settles: at power-on or back after ``velocity_timeout`` s of
#: silence, its damping may ramp the reading up from where it was. Two of Irene's logs start
#: so, 0.8 → 2.9 kn over 6 s and 1.7 → 4.7 kn over 15 s at a steady 3.9 and 5.8 kn over
#: ground; fused as they came, the ramp went to the current (3.0 kn on a lake, above 1.5 kn
#: for three minutes). It has settled at its first reading that does not rise faster than
#: :data:`LOG_SETTLE_RISE` (a log reading steadily: at its second), at the latest this long
#: (s) after its first. Until then a reading z counts with σ = :data:`LOG_SETTLE_SHARE` · z,
#: and the log's calibrations and the current are held: the fixes tell the speed, the log
#: still that the boat moves (for the gates and the manoeuvre test).
LOG_SETTLE_TIME = 15.0
#: A wheel turning again after a stall (a reading below :data:`LOG_STALL_READING` under way)
#: settles for at least this long (s) after its last stalled reading: a wheel fouled by weed
#: turns for a few seconds between stalls, at a steady fraction of the speed (one of the
#: psaros33's 2014 logs: 0.0, 1.0 and 1.2 kn by turns for 30 s at 3 kn over ground).
LOG_SETTLE_MIN = 5.0
#: The rise (m/s per s) beyond which a log just started is still settling: a damped log's
#: ramp is 0.05-0.3 m/s per s; a steady 1 Hz reading's noise rarely rises this much twice.
LOG_SETTLE_RISE = 0.04
#: A settling reading's standard deviation as a share of itself: a ramp may read a third of
#: the speed.
LOG_SETTLE_SHARE = 2.0
#: Surface motion: standard deviation (m) of the base's height about the mean surface (waves,
#: squat, the antenna's heave), added to the surface height's own in the pose covariance.
SURFACE_HEIGHT_SIGMA = 1.0
#: Surface motion: standard deviation (rad) of roll and pitch where the IMU gives none (a
#: heading-only compass: variance 1e3): a sailing yacht's heel and the roll in a seaway stay
#: within about 20°. It bounds what the unknown tilt does to the antenna's lever arm.
SURFACE_TILT_SIGMA = math.radians(20.0)
#: Surface motion: standard deviation (m/s) of the vertical velocity in NED (wave heave).
SURFACE_HEAVE_SIGMA = 0.25
#: Surface motion: random-walk density (m per √s) of the mean surface's ellipsoidal height:
#: the tide and the geoid's slope along a passage, about a metre an hour.
SURFACE_HEIGHT_DRIFT = 1.0 / math.sqrt(3600.0)
#: A state speed beyond this (m/s) is impossible: an update that would give it is refused.
MAX_STATE_SPEED = 150.0
#: A state position beyond this from the origin (m) is refused (outside any local frame).
MAX_STATE_POSITION = 2.0e7

#: Instrument faults (:mod:`.faults`). A compass is frozen when its heading stays within this
#: (rad) of the value it held while the gyro turned the vessel by :data:`FROZEN_HEADING_TURN`
#: or the fixes' course turned by :data:`FROZEN_HEADING_COG_TURN`: one count of an
#: integer-degree compass, which repeats its value on a steady course.
FROZEN_HEADING_TOLERANCE = math.radians(1.0)
#: Turn (rad) by the gyro within :data:`FROZEN_HEADING_WINDOW`, the compass unchanged, that makes
#: it frozen: 10° is 3 s of a 3°/s turn, ten times the drift of a consumer MEMS gyro (0.1°/s)
#: over the window.
FROZEN_HEADING_TURN = math.radians(10.0)
#: The window (s) of the gyro's turn in the frozen-compass test.
FROZEN_HEADING_WINDOW = 10.0
#: Turn (rad) of the course over ground, the compass unchanged, that makes it frozen when no
#: gyro tells the turn: a turn, where a drift angle changes by far less on a steady heading
#: (a tide's set, a slowing sailing yacht's leeway), beyond the course noise of 1 Hz fixes of
#: 2.5 m over :data:`FROZEN_COG_BASELINE`.
FROZEN_HEADING_COG_TURN = math.radians(45.0)
#: Distance over ground (m) each course of :data:`FROZEN_HEADING_COG_TURN` spans.
FROZEN_COG_BASELINE = 50.0
#: Speed over ground (m/s, about 4 kn) below which the course over ground tells no compass
#: fault: at low speed the drift angle can be anything.
FROZEN_COG_MIN_SPEED = 2.0
#: A compass sample more than this (rad) from the last live one, and faster than
#: :data:`FROZEN_HEADING_JUMP_RATE`, is a jump no hull makes; while the compass then holds that
#: value (within :data:`FROZEN_HEADING_TOLERANCE`) it is frozen there. A compass that turns on
#: from it, or comes back, is live again: one sample of a glitch costs one sample.
FROZEN_HEADING_JUMP = math.radians(45.0)
#: Yaw rate (rad/s) beyond which a change of heading is a jump: a planing hull in a hard turn
#: reaches 30-40°/s, a yacht in a tack 20°/s.
FROZEN_HEADING_JUMP_RATE = math.radians(45.0)
#: The longest (s) a jumped value held is refused: then it is taken as the heading. Which of
#: two held values is right, only a turn tells (a gyro's, or the course over ground's), and a
#: moored vessel makes none.
FROZEN_HEADING_JUMP_HOLD = 60.0
#: A log is stuck when its reading stays within this (m/s, a log's 0.1 kn resolution) of the
#: value it held while the speed through the water from the fixes changed by
#: :data:`FROZEN_LOG_SPEED_CHANGE`.
FROZEN_LOG_TOLERANCE = 0.05
#: Change of the fixes' speed through the water (m/s, about 2 kn) that makes a constant log
#: stuck: beyond the fixes' speed noise over :data:`FROZEN_LOG_WINDOW` and a current's change.
FROZEN_LOG_SPEED_CHANGE = 1.0
#: Time (s) over which the fixes' speed is measured for the stuck-log test.
FROZEN_LOG_WINDOW = 10.0

#: A compass silent for ``velocity_timeout`` s with no gyro to turn the heading: the heading
#: follows the velocity through the water at each fix (:meth:`FixUpdate._heading_from_course`)
#: from this speed (m/s, about 1 kn) up; below it the direction of travel says nothing.
COURSE_HEADING_MIN_SPEED = 0.5
#: The turn rate (rad/s, about 6°/s: a yacht's tack) the heading may have made since the last
#: fix while no compass tells it: the velocity's direction gains a variance of (this·Δt)².
COURSE_HEADING_TURN_RATE = 0.1

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
    course falls back to the heading and the sideslip to zero. ``velocity_timeout`` (s): with
    a velocity sensor, no reading accepted for this long makes it missing: the calibrations
    it alone feeds (log scale, leeway, turning drift) are held until it returns.
    ``history_length`` (s): how old a measurement may be against the state; at start-up
    nothing is published from a heading older than this.
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
    velocity_timeout: float = 10.0
    history_length: float = 2.0

    @property
    def horizontal(self) -> bool:
        """Return True for the planar motions (surface, ground): 2-D position and velocity."""
        return self.motion is not Motion.FREE

    @property
    def level(self) -> bool:
        """Return True when roll and pitch are forced to zero (ground)."""
        return self.motion is Motion.GROUND

    def structure(self) -> tuple:
        """
        Return what a copy of the estimator's state depends on.

        The state's layout (motion, sensors, estimated calibrations), its frames (origin,
        projection, declination) and its attitude model: a change of any of these makes the
        state another kind of thing. The rest (gates, default σ, lever arms, timeouts, the
        course's low speed, ``history_length``) only says how measurements are taken, so a
        state copied before such a change still holds after it.
        """
        return (self.motion, tuple(repr(c) for c in self.origin), self.projection,
                self.gnss_enabled, self.velocity_input, self.water, self.estimate_scale,
                self.estimate_leeway, self.estimate_heading_offset, self.declination,
                self.integrator)
