"""
The estimator's state: set-up and reset, origin, declination, projection, queries.

:class:`FilterState` holds what every update reads; the updates build on it
(:mod:`.propagation`, :mod:`.updates` and the measurement modules) and
:class:`~.estimator.Estimator` puts them together.
"""

from __future__ import annotations

from collections import deque
import math

import numpy as np

from vessel_kinematics.core import flow
from vessel_kinematics.estimation import faults, health, mapframe, model, surface
from vessel_kinematics.estimation.attitude import Attitude
from vessel_kinematics.estimation.config import (ACCEL_SIGMA_CRUISE, ATTITUDE_SHARE_MAX_VARIANCE,
                                                 CURRENT, FilterConfig, FUSED_TIMEOUT,
                                                 GAP_STEPS_KEPT, LEEWAY, LOG_SCALE,
                                                 READY_SPEED_SIGMA, READY_WAIT, TURN_DRIFT)
from vessel_kinematics.estimation.layout import StateLayout
from vessel_kinematics.estimation.records import (Calibration, DEAD_RECKONING, Estimate, Event,
                                                  FUSED, Health, Level, Mode, WAITING)

__all__ = ['FilterState', 'HEADING_RATE_SAMPLES', 'OFFSET_INIT_DISTANCE', 'OFFSET_INIT_SIGMA',
           'OFFSET_INIT_WINDOW', 'OffsetInit', 'wrap_lon_deg', 'yaw_quaternion']

#: Distance over ground (m) the vessel must cover before the heading offset is initialised.
OFFSET_INIT_DISTANCE = 20.0
#: The fixes of the last this many seconds give the course for the heading offset.
OFFSET_INIT_WINDOW = 30.0
#: Largest spread (rad) of the IMU heading over that window: a steady heading.
OFFSET_INIT_MAX_TURN = math.radians(30.0)
#: Standard deviation (rad) of the first heading-offset estimate (course vs heading, which
#: includes sideslip and the current's drift).
OFFSET_INIT_SIGMA = math.radians(15.0)
#: The most headings a rate-less compass's rate is fitted to: a 100 Hz compass's 2 s. A burst
#: of headings (a log's thousands within a second) shortens the window instead of making
#: every sample's fit, and every copy of the state, as long as the burst.
HEADING_RATE_SAMPLES = 200
#: Distance (m) the vessel moves before the meridians' convergence is found again.
CONVERGENCE_STEP = 100.0


def wrap_lon_deg(lon: float) -> float:
    """Return a longitude in degrees in [-180, 180] (parameters allow up to 360)."""
    return lon - 360.0 if lon > 180.0 else lon


def yaw_quaternion(angle: float) -> tuple[float, float, float, float]:
    """Return the quaternion of a turn by ``angle`` (rad) about NED down."""
    return (math.cos(0.5 * angle), 0.0, 0.0, math.sin(0.5 * angle))


class OffsetInit:
    """The fixes and IMU headings of the last window, for the first heading-offset guess."""

    def __init__(self) -> None:
        self.samples: deque[tuple[float, float, float, float, float, float]] = deque()

    def add(self, t: float, n: float, e: float, psi: tuple[float, float], surge: float) -> None:
        self.samples.append((t, n, e, psi[0], psi[1], surge))
        while self.samples and t - self.samples[0][0] > OFFSET_INIT_WINDOW:
            self.samples.popleft()

    def course_minus_heading(self) -> float | None:
        """Return χ − ψ̄ (π more astern) once the window is long and steady enough, else None."""
        s = self.samples
        if len(s) < 5:
            return None
        arr = np.array(s)
        t, n, e = arr[:, 0] - arr[0, 0], arr[:, 1], arr[:, 2]
        if math.hypot(n[-1] - n[0], e[-1] - e[0]) < OFFSET_INIT_DISTANCE:
            return None
        c, sn = float(arr[:, 3].mean()), float(arr[:, 4].mean())
        spread = math.sqrt(max(0.0, -2.0 * math.log(max(math.hypot(c, sn), 1e-12))))
        if spread > OFFSET_INIT_MAX_TURN:
            return None
        vn, ve = np.polyfit(t, n, 1)[0], np.polyfit(t, e, 1)[0]
        chi = math.atan2(ve, vn)
        offset = chi - math.atan2(sn, c)
        if float(np.median(arr[:, 5])) < 0.0:
            offset += math.pi
        return float(flow.ssa(offset))


class FilterState:
    """The estimator's state, its origin and projection, and what the updates read."""

    def __init__(self, config: FilterConfig) -> None:
        self.config = config
        self.origin: tuple[float, float, float] | None = None
        self.resets = 0
        self.recoveries = 0
        #: The reason of the last recovery (None before the first).
        self.last_recovery: str | None = None
        self.declination = 0.0
        self.declination_error: str | None = None
        self._origin_event = False
        self._events: list[Event] = []
        self._set_origin_from_config(config)
        self._init_state()

    # ------------------------------------------------------------------ state set-up

    @property
    def water(self) -> bool:
        """Return True for a velocity state through the water, with the current estimated."""
        return self.layout.water

    def _init_state(self) -> None:
        """(Re-)initialise everything but the origin."""
        cfg = self.config
        lay = self.layout = StateLayout.of(cfg)
        self.table = model.MarkovTable(lay)
        n = lay.size
        self.t: int | None = None
        #: The stamp of the first message (ns): the log's timeout counts from it.
        self._t0: int | None = None
        self.x = np.zeros(n)
        self.P = np.zeros((n, n))
        self.P[lay.v, lay.v] = np.diag(np.square(lay.velocity_prior))
        for _, ia in lay.accelerated:
            self.P[ia, ia] = ACCEL_SIGMA_CRUISE ** 2
        if lay.c is not None:
            self.P[lay.c, lay.c] = np.eye(2) * CURRENT.sigma ** 2
        if lay.k is not None:
            self.x[lay.k] = 1.0
            self.P[lay.k, lay.k] = LOG_SCALE.sigma ** 2
        if lay.lam is not None:
            self.P[lay.lam, lay.lam] = LEEWAY.sigma ** 2
        if lay.kap is not None:
            self.P[lay.kap, lay.kap] = TURN_DRIFT.sigma ** 2
        if lay.dpsi is not None:
            self.P[lay.dpsi, lay.dpsi] = math.pi ** 2
        self.offset_ready = lay.dpsi is None
        self._offset_init = OffsetInit()
        self.position_ok = False
        self._position_ns: int | None = None
        self.attitude = Attitude(level=cfg.level, integrator=cfg.integrator)
        self.pending = model.Pending(lay.horizontal)
        #: The last steps between stamps (s): the usual one tells a gap (:mod:`.propagation`).
        self._steps: deque[float] = deque(maxlen=GAP_STEPS_KEPT)
        self.accel = model.AccelerationLevel()
        self.surface = surface.SurfaceHeight(self.origin[2] if self.origin is not None else 0.0)
        self.track = faults.GnssTrack()
        self.frozen_heading = faults.FrozenHeading()
        self.stuck_log = faults.StuckLog()
        #: The faults found and not yet over, by part (``heading``, ``log``): their text.
        self.faults: dict[str, str] = {}
        self._last_sample: dict[str, tuple | None] = {}
        #: The last covariance of each IMU slot: its values, the estimator's array of them, and
        #: the read-only array it came as (None: a writable one, read each time).
        self._covariances: dict[str, tuple[tuple, np.ndarray | None, np.ndarray | None]] = {}
        self.last_fix_ns: int | None = None
        self.last_imu_ns: int | None = None
        self.last_velocity_ns: int | None = None
        self.last_ground_velocity_ns: int | None = None
        #: Last accepted fix, ground velocity and log reading; last accepted update of any of
        #: them (what observed the velocity last), ns.
        self._fix_used_ns: int | None = None
        #: The last fix taken (it initialised, updated or re-initialised the position), ns.
        self._fix_taken_ns: int | None = None
        self._ground_velocity_used_ns: int | None = None
        self._log_used_ns: int | None = None
        #: The last speed-log reading not fused for being the wheel at a standstill, ns, and
        #: whether the hull was under way through the water then (:meth:`_log_silent`).
        self._log_stalled_ns: int | None = None
        self._log_stalled_under_way = False
        #: The speed log's run of readings: its first and last stamps (ns), its last reading
        #: (m/s), and whether it has settled (:data:`~.config.LOG_SETTLE_TIME`). A run starts
        #: at a reading after ``velocity_timeout`` s without one, or after a stalled one.
        self._log_run: tuple[int, int, float, bool] | None = None
        self._observed_ns: int | None = None
        self._gate_streak = 0
        self._gate_first_ns = 0
        #: The last fix's distance from the estimate (σ, Mahalanobis), for a manoeuvre's test.
        self._fix_distance = 0.0
        #: The last fix found a receiver's start-up wander: (its stamp ns, its step N, E m).
        self._settle_last: tuple[int, np.ndarray] | None = None
        #: The last fixes' horizontal innovations (stamp ns, N, E m), for :meth:`_trend`.
        self._innovations: deque[tuple[int, float, float]] = deque(maxlen=50)
        self._velocity_gate_streak = 0
        self._velocity_known = False
        self._started = False
        #: The meridians' convergence γ (rad) at the vessel, and the map N, E (m) it is of.
        self._gamma = 0.0
        self._gamma_at: tuple[float, float] | None = None
        self.last_surge = 0.0
        #: The last accepted surge reading (stamp ns, m/s), for the measured acceleration.
        self._last_surge_reading: tuple[int, float] | None = None
        #: The log's steady reading (stamp ns, reading, the side of the last reading beyond its
        #: jump, 0 if none): ``VelocityUpdate._steady``.
        self._steady_reading: tuple[int, float, int] | None = None
        #: A rate-less compass's last headings (stamp ns, unwrapped ψ rad), for its rate.
        self._headings: deque[tuple[int, float]] = deque(maxlen=HEADING_RATE_SAMPLES)
        #: The last fix that set a silent compass's heading from the course (ns; None while
        #: the compass speaks): :meth:`FixUpdate._heading_from_course`.
        self.course_heading_ns: int | None = None
        if self.origin is not None and not cfg.gnss_enabled:
            self._init_position(np.zeros(3), np.zeros((3, 3)))

    def _init_position(self, p: np.ndarray, cov: np.ndarray) -> None:
        lay = self.layout
        d = lay.dim
        self.x[lay.p] = p[0:d]
        self.P[lay.p, :] = 0.0
        self.P[:, lay.p] = 0.0
        self.P[lay.p, lay.p] = cov[0:d, 0:d]
        if not self.position_ok:
            self._position_ns = self.t
        self.position_ok = True
        self._gate_streak = 0
        self._update_convergence()

    def _set_origin_from_config(self, config: FilterConfig) -> bool:
        """Take a complete origin from the configuration; return True when it changed."""
        lat, lon, h = config.origin
        if math.isnan(lat) or math.isnan(h):
            return False
        origin = (math.radians(lat), math.radians(wrap_lon_deg(lon)), float(h))
        if origin == self.origin:
            return False
        self.origin = origin
        self._origin_event = True
        return True

    def _update_declination(self, stamp_ns: int) -> None:
        """Evaluate the declination model at the origin and the date of ``stamp_ns``."""
        model_ = self.config.declination
        self.declination, self.declination_error = 0.0, None
        if model_ is None or self.origin is None:
            return
        try:
            value = float(model_(self.origin[0], self.origin[1], self.origin[2], stamp_ns))
        except (ValueError, ArithmeticError) as exc:
            self.declination_error = str(exc)
            return
        if math.isfinite(value):
            self.declination = value
        else:
            self.declination_error = 'declination model gave a non-finite value'

    def _event(self, level: Level, text: str) -> None:
        self._events.append(Event(self.t or 0, level, text))
        if len(self._events) > 100:
            del self._events[0]

    def reset(self) -> None:
        """Re-initialise the state (time went backwards: a bag looped); keep the origin."""
        self.resets += 1
        self._init_state()

    # ------------------------------------------------------------------ projection

    def to_ned(self, lat: float, lon: float, h: float) -> np.ndarray:
        """Return the map NED position (m) of a latitude, longitude (rad) and height (m)."""
        return mapframe.to_ned(self.origin, self.config.projection,  # type: ignore[arg-type]
                               lat, lon, h)

    def to_llh(self, p: np.ndarray) -> tuple[float, float, float]:
        """Return latitude, longitude (rad) and height (m) of a map NED position."""
        return mapframe.to_llh(self.origin, self.config.projection, p)  # type: ignore[arg-type]

    def _where(self, x: np.ndarray) -> tuple[np.ndarray, tuple[float, float, float]]:
        """Return the base's map NED position (3,) and its LLH, on the surface when planar."""
        lay = self.layout
        p = x[lay.p]
        if lay.dim == 3:
            p3 = p.copy()
            return p3, self.to_llh(p3)
        d, lat, lon, h = surface.surface_point(float(p[0]), float(p[1]), self.surface.height,
                                               self.origin,  # type: ignore[arg-type]
                                               self.config.projection)
        if self.config.level:
            # motion ground (two_d): planar in the map, z = 0 as robot_localization's two_d_mode
            # gives it; the geodetic position is still the surface's (d²/2R apart: 8 cm at 1 km).
            d = 0.0
        return np.array([p[0], p[1], d]), (lat, lon, h)

    def _local(self, x: np.ndarray) -> np.ndarray:
        """Return the local (odom) position (3,), the height zero for the planar motions."""
        p = x[self.layout.l]
        return p.copy() if p.size == 3 else np.array([p[0], p[1], 0.0])

    def _update_convergence(self) -> None:
        """
        Find the meridians' convergence γ at the position estimate (:mod:`.surface`).

        Again only once the vessel is :data:`CONVERGENCE_STEP` m from where it was last found:
        γ changes by at most 3e-7 rad per metre (at 70° latitude), 3e-5 rad over the step.
        """
        if self.origin is None or not self.position_ok:
            self._gamma, self._gamma_at = 0.0, None
            return
        p = self.x[self.layout.p]
        n, e = float(p[0]), float(p[1])
        if self._gamma_at is not None and math.hypot(n - self._gamma_at[0],
                                                     e - self._gamma_at[1]) < CONVERGENCE_STEP:
            return
        lat, lon, _ = self.to_llh(np.array([n, e, 0.0]))
        self._gamma = surface.convergence(lat, lon, self.origin, self.config.projection)
        self._gamma_at = (n, e)

    # ------------------------------------------------------------------ public queries

    @property
    def mode(self) -> Mode:
        """Return the mode: waiting_for_origin, dead_reckoning or fused."""
        if self.origin is None or not self.position_ok:
            return WAITING
        # Fused: a fix was taken (not merely received) within FUSED_TIMEOUT; while every fix
        # is refused the mode says dead reckoning.
        if (self.config.gnss_enabled and self._fix_taken_ns is not None and self.t is not None
                and (self.t - self._fix_taken_ns) * 1e-9 <= FUSED_TIMEOUT):
            return FUSED
        return DEAD_RECKONING

    @property
    def ready(self) -> bool:
        """
        Return True when there is a state to publish: origin, position, velocity, attitude.

        At start-up nothing is published from a heading older than ``history_length`` against
        the state (a compass 3 s stale when the first fix comes), nor before an IMU has given an
        attitude (or a rate to integrate): a first fix must not go out with a heading of zero.
        A set-up without an IMU publishes ``max_gap`` s after the position. Nor before a
        measurement told the velocity (:meth:`_velocity_told`): the first fix alone would go out
        at 0 kn, however fast the vessel goes.
        """
        if self.origin is None or not self.position_ok or self.t is None:
            return False
        if self._started:
            return True
        if not self._velocity_told():
            return False
        att = self.attitude
        if att.known and att.last_attitude_ns is not None:
            fresh = (self.t - att.last_attitude_ns) * 1e-9 <= self.config.history_length
        elif att.omega is not None:
            fresh = True
        else:
            fresh = (self._position_ns is not None and att.last_attitude_ns is None
                     and (self.t - self._position_ns) * 1e-9 > self.config.max_gap)
        self._started = fresh
        return fresh

    def _velocity_told(self) -> bool:
        """
        Return True once a measurement told the velocity, for the first output.

        A velocity sensor's reading or a receiver's velocity tells it at once; fixes tell it as
        they accumulate: when the speed's σ is within :data:`~.config.READY_SPEED_SIGMA` (at
        5 Hz after about 2.6 s), or at the latest :data:`~.config.READY_WAIT` s after the
        first fix (a sparse, noisy receiver, a log that never speaks). A log settling after
        its start may read a third of the speed: then the fixes tell it, READY_WAIT s after
        the first.
        """
        if self.t is None or self._position_ns is None:
            return False
        if self._ground_velocity_used_ns is not None:
            return True
        if self._log_used_ns is not None and not self.log_settling:
            return True
        if (self.t - self._position_ns) * 1e-9 >= READY_WAIT:
            return True
        if self.log_settling:
            return False
        lay = self.layout
        axes = range(lay.v.start, lay.v.stop) if lay.isotropic else (lay.v.start,)
        return (self._observed_ns is not None
                and max(float(self.P[i, i]) for i in axes) <= READY_SPEED_SIGMA ** 2)

    def pop_origin_event(self) -> bool:
        """Return True once after the origin has been set or changed."""
        event, self._origin_event = self._origin_event, False
        return event

    def pop_events(self) -> list[Event]:
        """
        Return the events since the last call, oldest first: what the node's log should say.

        A recovery (WARN, with its reason), an instrument fault found (WARN) or over (OK), a
        log gone missing (WARN) or back (OK), the heading offset found (OK). Each is said once.
        """
        events, self._events = self._events, []
        return events

    def health(self) -> tuple[Health, ...]:
        """
        Return the estimator's health as plain records, one per part (:mod:`.health`).

        Contract for the ROS layer: one generic loop turns each :class:`~.records.Health`
        into a ``diagnostic_msgs/DiagnosticStatus`` (``name`` appended to the node's, ``level``
        as its byte, ``summary`` as the message, ``values`` as the key-value pairs) and the
        replay prints the same in its summary. The parts: ``estimate`` (the mode, the
        calibrations and the current with σ, the acceleration level, recoveries and the last
        one's reason), ``heading`` (the compass: ok or frozen), and with a velocity sensor
        ``log`` (ok, stuck, or missing for ``velocity_timeout`` with what it holds). Keys
        carry their units; the texts are final (no formatting left to the caller).
        """
        return health.health(self)

    def estimates(self) -> dict[str, str]:
        """Return the calibrations and the current as text (:func:`.health.estimates`)."""
        return health.estimates(self)

    @property
    def heading_offset(self) -> float:
        """Return the heading correction (rad): declination, estimated offset, convergence γ."""
        lay = self.layout
        offset = self.declination + self._gamma
        if lay.dpsi is None or not self.offset_ready:
            return offset
        return offset + float(self.x[lay.dpsi])

    @property
    def yaw_rate(self) -> float:
        """Return the body yaw rate r (rad/s, FRD; 0 when unknown) for the turning drift."""
        omega = self.attitude.omega
        return 0.0 if omega is None else omega[2]

    @property
    def log_missing(self) -> bool:
        """
        Return True when a velocity sensor gave no reading accepted for ``velocity_timeout`` s.

        Counted from the first message when none came yet: at start-up the log is not missing
        for that long, though what it alone observes is held until it speaks
        (:meth:`_log_silent`).
        """
        cfg = self.config
        if not cfg.velocity_input or self.t is None:
            return False
        last = self._log_used_ns if self._log_used_ns is not None else self._t0
        return last is not None and (self.t - last) * 1e-9 > cfg.velocity_timeout

    @property
    def log_stalled(self) -> bool:
        """Return True when the log's readings since the last one fused were at a standstill."""
        stalled = self._log_stalled_ns
        return stalled is not None and (self._log_used_ns is None or stalled > self._log_used_ns)

    @property
    def log_settling(self) -> bool:
        """Return True while the log, just started, has not settled yet (LOG_SETTLE_TIME)."""
        run = self._log_run
        return (run is not None and not run[3] and self.t is not None
                and (self.t - run[1]) * 1e-9 <= self.config.velocity_timeout)

    def _log_silent(self) -> bool:
        """
        Return True while the log tells nothing of its calibrations.

        None yet, none for ``velocity_timeout``, settling, or stalled under way: a wheel at a
        standstill while the estimate has the hull making more than 1 kn through the water
        (:data:`~.config.LOG_STALL_SPEED`) is fouled or the boat goes astern, and nothing
        tells how the fixes' velocity splits into current and speed through the water.
        Stalled with the hull nearly still in the water (drifting), the fixes tell the
        current.
        """
        return self.config.velocity_input and (
            self._log_used_ns is None or self.log_missing or self.log_settling
            or (self.log_stalled and self._log_stalled_under_way))

    def _compass_silent(self, stamp_ns: int) -> bool:
        """
        Return True when a heading was measured once, none since ``velocity_timeout`` s ago.

        And no gyro turns it meanwhile (a rate within ``max_gap``, not one derived from the
        compass's own headings): the heading held is then stale.
        """
        att = self.attitude
        if att.last_attitude_ns is None:
            return False
        if (stamp_ns - att.last_attitude_ns) * 1e-9 <= self.config.velocity_timeout:
            return False
        return not (att.omega is not None and not att.derived
                    and att.rates_fresh(stamp_ns, self.config.max_gap))

    def _ground_observed(self) -> bool:
        """Return True when a fix or a receiver's velocity was used within FUSED_TIMEOUT."""
        if self.t is None or not self.config.gnss_enabled:
            return False
        for stamp in (self._fix_used_ns, self._ground_velocity_used_ns):
            if stamp is not None and (self.t - stamp) * 1e-9 <= FUSED_TIMEOUT:
                return True
        return False

    def _frozen(self) -> tuple[int, ...]:
        """
        Return the states held at their prior (no gain, no noise; no coupling in the motion).

        Until the heading offset is initialised the heading is unknown, so the velocity
        through the water says nothing about where the vessel goes: the offset, the current
        and the calibrations would only soak up the heading's error. They wait, as consider
        states: a log reading z = k·u still ties the speed to the scale's prior (a zero gain
        on k, not a zero ∂z/∂k), so the speed is as unsure as z/k and the fixes can tell
        the scale once it is free; only where the vessel goes (the propagation, the fixes)
        loses their coupling.
        """
        lay = self.layout
        if lay.dpsi is None or self.offset_ready:
            return ()
        held = [lay.dpsi]
        if lay.c is not None:
            held += [lay.c.start, lay.c.start + 1]
        held += [i for i in (lay.k, lay.lam, lay.kap) if i is not None]
        return tuple(held)

    def _held(self) -> tuple[int, ...]:
        """
        Return what the missing log alone observes: held (no gain, no decay, process noise).

        The scale, the leeway and the turning drift, and the current: without a speed through
        the water, the fixes tell the velocity over ground only; how it splits into the
        current and the vessel's own speed would be the process model's guess (a speed loss
        in a turn taken for a change of current), so the current keeps its last estimate and
        its variance grows as the current may have changed.
        """
        lay = self.layout
        if not self._log_silent():
            return ()
        held = [i for i in (lay.k, lay.lam, lay.kap) if i is not None]
        if lay.c is not None:
            held += [lay.c.start, lay.c.start + 1]
        return tuple(held)

    def _consider(self, *more: int | None) -> tuple[int, ...]:
        lay = self.layout
        extra = tuple(i for i in more if i is not None)
        return tuple(range(lay.l.start, lay.l.stop)) + self._frozen() + self._held() + extra

    def _yaw_variance(self) -> float | None:
        """
        Return the heading variance to use in the attitude share (None: the IMU's).

        With no velocity sensor and no heading ever told (a receiver alone), the velocity over
        ground is written in the axes of heading 0, north and east, and its own direction is
        the state's: no heading error moves the position (the IMU's unknown attitude, σ π,
        would make the position a random walk and the speed collapse in every turn).
        """
        if self.layout.isotropic and not self.attitude.known or self.course_heading_ns is not None:
            return 0.0
        return ATTITUDE_SHARE_MAX_VARIANCE if self._frozen() else None

    def _full_rotation(self) -> np.ndarray:
        """Return R(q) with the heading correction applied: Rz(o) R(q_IMU), 3x3."""
        o = self.heading_offset
        c, s = math.cos(o), math.sin(o)
        r = np.array(self.attitude.r9).reshape(3, 3)
        return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]) @ r

    def velocity_ned(self) -> np.ndarray:
        """Return the velocity over ground in the map's NED axes (m/s)."""
        rot = model.rotation_now(self.layout, self.attitude.r9, self.heading_offset)
        pdot, _ = model.position_rate(self.x, self.layout, rot, r=self.yaw_rate)
        return pdot if pdot.size == 3 else np.array([pdot[0], pdot[1], 0.0])

    def calibration(self, x: np.ndarray | None = None,
                    pm: np.ndarray | None = None) -> Calibration:
        """Return the estimated calibrations (log scale, leeway, heading offset) with σ."""
        x = self.x if x is None else x
        pm = self.P if pm is None else pm
        lay = self.layout

        def est(i: int | None) -> Estimate | None:
            if i is None:
                return None
            return Estimate(float(x[i]), math.sqrt(max(float(pm[i, i]), 0.0)))

        offset = est(lay.dpsi) if self.offset_ready else None
        return Calibration(log_scale=est(lay.k), leeway=est(lay.lam), turn_drift=est(lay.kap),
                           heading_offset=offset,
                           declination=self.declination if self.config.declination else None)
