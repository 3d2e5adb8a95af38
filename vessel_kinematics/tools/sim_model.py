"""
The simulated vessel and its voyage: a manoeuvring model in an ocean current, with sensors.

Numbers only (numpy and the kinematics core): :func:`simulate` integrates the voyage into a
:class:`Truth`. What the sensors read from it is :mod:`vessel_kinematics.tools.sim_sensors`';
turning that into ROS messages and a bag is :mod:`vessel_kinematics.tools.sim_bag`'s; the
command line is :mod:`vessel_kinematics.tools.sim`.

The vessel is Fossen's 3-DOF (surge, sway, yaw) manoeuvring model of a surface vessel with a
rudder, in relative velocity nu_r = nu - nu_c (Fossen's Handbook, 2nd ed., the maneuvering
models in a current):

* sway and yaw: the linear manoeuvring model M nu_r' + N(u_r) nu_r = b delta,
  with hydrodynamic derivatives from Clarke et al. (1983) (Fossen's MSS ``clarke83``) plus
  strip-theory cross-flow drag (MSS ``crossFlowDrag``), so that the drift angle of a hard turn
  stays realistic (about 12 deg) instead of growing without bound as in the purely linear
  model;
* surge: (m - X_u') u_r' = X_prop - d_uu |u_r| u_r + k m v_r r, a quadratic resistance with a
  constant propeller thrust and the net centripetal coupling that makes the vessel lose speed
  in a turn (about 15 % on the turning circle);
* kinematics (Fossen ch. 2, planar): n' = u_r cos psi - v_r sin psi + V_n, e' = u_r sin psi +
  v_r cos psi + V_e, psi' = r, in an irrotational current (V_n, V_e) that varies slowly; its
  own acceleration (about 1e-3 m/s^2) is left out of the hull's force balance, not out of the
  truth or the accelerometer.

A dynamic model rather than prescribed rates, because the point of the voyage is sideslip:
here the drift angle through the water comes out of the hull's physics in every turn and
zig-zag, and the current adds the ground sideslip on the straight legs, so the navigator sees
the same couplings as on a real vessel. The motion is planar (roll = pitch = 0, heave = 0).

The voyage (fractions of ``duration``, default 300 s): a straight leg under a heading
autopilot, a starboard turning circle (25 deg rudder, 360 deg), a straight leg, a 20/20
zig-zag, and a final straight leg on a new heading; one GNSS outage during the zig-zag. The
sensors, their delivery latencies and the sailing effects (log scale, leeway, IMU yaw offset,
standstill) are described in :mod:`vessel_kinematics.tools.sim`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
import math
from typing import Any

import numpy as np
from vessel_kinematics.core.flow import course, sideslip, ssa

__all__ = ['BRAKING_TIME', 'current_at', 'FAST_LATENCY', 'FIX_LATENCY', 'MAX_LATENCY', 'RHO',
           'simulate', 'START_NS', 'Truth', 'UNMEASURED_VARIANCE', 'validate', 'Vessel',
           'VoyageConfig']

#: Header stamp of the voyage's first sample: 2024-06-01T12:00:00Z, ns.
START_NS = 1_717_243_200 * 1_000_000_000
#: Sea water density, kg/m^3.
RHO = 1025.0
#: Variance given to an unmeasured component of a covariance.
UNMEASURED_VARIANCE = 1e6

#: Time (s) over which a prescribed surge's acceleration builds up and falls off (_Profile).
PROFILE_RAMP = 1.0

#: Time (s) the vessel takes to brake to rest before a standstill (its velocities through the
#: water fall linearly to zero, a crash stop of about 0.5 m/s^2 at 5 m/s).
BRAKING_TIME = 10.0

#: Default delivery latency of a GNSS fix, (min, max) s: the receiver's position solution, its
#: NMEA or UBX output over a serial line and the driver's parsing put a fix on the ROS graph
#: 0.1 to 0.5 s after its time of measurement, with jitter.
FIX_LATENCY = (0.1, 0.5)
#: Default delivery latency of an IMU message and of a log or DVL message, (min, max) s: their
#: drivers read a sample and publish it within milliseconds.
FAST_LATENCY = (0.001, 0.005)
#: Largest delivery latency accepted, s: the navigator's longest ``history_length``.
MAX_LATENCY = 10.0


@dataclass(frozen=True)
class Vessel:
    """
    Main particulars of the simulated vessel and of its rudder and propulsion.

    The default is a 32 m patrol-boat-sized hull with the proportions of Fossen's Mariner
    class vessel (L/B = 7, B/T = 2.8), which is directionally stable; at 5 m/s and 25 deg of
    rudder its turning circle is about 110 m (3.5 L) across, with a drift angle of about
    12 deg and a speed loss of about 15 %.
    """

    length: float = 32.0                   # L, m
    beam: float = 4.6                      # B, m
    draught: float = 1.65                  # T, m
    block_coefficient: float = 0.6         # C_b
    yaw_gyration_ratio: float = 0.25       # R_66 / L
    rudder_area_ratio: float = 0.03        # A_R / (L T)
    rudder_lift_slope: float = 2.5         # dC_L / d delta, 1/rad
    cross_flow_drag: float = 0.5           # C_d of the hull's lateral strips (Hoerner)
    resistance_coefficient: float = 0.008  # C_T on the wetted surface
    centripetal_coupling: float = 0.5      # k: share of m v_r r felt in surge
    rudder_limit: float = math.radians(35.0)  # rad
    rudder_rate: float = math.radians(10.0)   # rad/s


@dataclass(frozen=True)
class VoyageConfig:
    """Everything that defines a voyage; angles in rad, speeds in m/s, sigmas per axis."""

    duration: float = 300.0
    seed: int = 1
    origin: tuple[float, float, float] = (63.44, 10.40, 42.0)  # lat deg, lon deg, h m
    reference: str = 'water'            # the DVL's mode: 'water' track or 'ground' (bottom)
    speed: float = 5.0                  # set speed through the water, m/s
    heading: float = math.radians(30.0)  # initial heading psi, rad
    current_speed: float = 0.6          # m/s
    current_direction: float = math.radians(120.0)  # direction the current sets TOWARDS, rad
    imu_rate: float = 100.0             # Hz; also the integration rate
    fix_rate: float = 5.0               # Hz
    velocity_rate: float = 5.0          # Hz
    truth_rate: float = 20.0            # Hz
    fix_sigma: float = 1.5              # horizontal, m
    fix_sigma_up: float = 3.0           # vertical, m
    outage: tuple[float, float] | None = None  # (start s, length s); None: the default outage
    antenna: tuple[float, float, float] = (-3.0, 0.0, 5.0)  # GNSS antenna in base_link FLU, m
    heading_sigma: float = math.radians(0.5)
    tilt_sigma: float = math.radians(0.2)   # roll and pitch noise of the IMU's orientation
    gyro_sigma: float = math.radians(0.1)   # rad/s per sample
    gyro_bias_sigma: float = math.radians(0.05)  # rad/s, the constant bias is drawn from it
    accel_sigma: float = 0.05           # m/s^2
    velocity_sigma: float = 0.03        # m/s
    log_scale: float = 1.0              # the log's surge reading is log_scale * u (1: exact)
    log_surge_only: bool = False        # a speed log: surge only, sway/heave unmeasured
    leeway: float = 0.0                 # lambda, rad: adds v_r = u_r tan(lambda) (+: starboard)
    imu_yaw_offset: float = 0.0         # rad: published Imu yaw (ENU) - true yaw
    standstill_start: float | None = None   # s after the start; None: no standstill
    standstill_end: float | None = None     # s after the start, at rest until then
    helm: str = 'voyage'                # 'voyage', 'straight' or 'figure8' (see _Helmsman)
    #: Knots (t s, u_r m/s) of a prescribed surge through the water, linear between them (and
    #: held before the first and after the last): a crash stop, a full-throttle run from rest.
    surge_profile: tuple[tuple[float, float], ...] | None = None
    log_outage: tuple[float, float] | None = None     # (start s, length s): no log readings
    log_freeze: tuple[float, float] | None = None     # (start s, length s): log reading held
    compass_freeze: tuple[float, float] | None = None  # (start s, length s): orientation held
    fix_outlier_fraction: float = 0.0   # share of the fixes displaced by fix_outlier_distance
    fix_outlier_distance: float = 60.0  # m, in a random horizontal direction
    #: A heading-only compass at this rate (Hz) in place of the IMU: orientation from the
    #: heading alone (roll, pitch unknown), no rate, no acceleration. None: the full IMU.
    compass_rate: float | None = None
    #: Delivery latency of each GNSS fix, (min s, max s): its log time (the receipt by the ROS
    #: graph) is its header stamp (the measurement time) plus a latency drawn uniformly in the
    #: range, per fix (:data:`FIX_LATENCY`).
    fix_latency: tuple[float, float] = FIX_LATENCY
    #: Delivery latency of each IMU message (or compass heading), (min s, max s).
    imu_latency: tuple[float, float] = FAST_LATENCY
    #: Delivery latency of each log or DVL message, (min s, max s).
    velocity_latency: tuple[float, float] = FAST_LATENCY
    #: The drivers stamp on receipt: every input's header stamp is its log time, so the stamp
    #: carries the delivery latency as an error (False: stamped with the measurement time).
    stamp_on_receipt: bool = False
    vessel: Vessel = field(default_factory=Vessel)

    def outage_window(self) -> tuple[float, float] | None:
        """Return the GNSS outage (start, end) in s after the start, or None for no outage."""
        if self.outage is not None:
            start, length = self.outage
            return (start, start + length) if length > 0 else None
        start = round(0.6 * self.duration)
        return start, start + min(25.0, float(round(0.085 * self.duration)))

    def window(self, name: str) -> tuple[float, float] | None:
        """Return the (start, end) s of a window field (``log_outage``...), None for none."""
        value = getattr(self, name)
        if value is None or value[1] <= 0.0:
            return None
        return float(value[0]), float(value[0] + value[1])

    def standstill_window(self) -> tuple[float, float] | None:
        """Return the standstill (start, end) in s after the start, or None for none."""
        if self.standstill_start is None or self.standstill_end is None:
            return None
        return float(self.standstill_start), float(self.standstill_end)


@dataclass
class Truth:
    """
    The true state at every integration step (``imu_rate``), arrays of shape (n,).

    NED position about the origin (m), heading psi (rad, unwrapped), relative and ground body
    velocities (FRD, m/s; the sway through the water v_r includes the leeway's u_r tan(lambda)),
    yaw rate r (rad/s), current (NED, m/s), rudder angle (rad), body acceleration over ground
    (FRD, m/s^2), the gyro bias (FLU, rad/s) the IMU carried, and the phase of each step
    ('straight', 'turning circle', 'zig-zag', 'stopping', 'standstill').
    """

    t: np.ndarray
    north: np.ndarray
    east: np.ndarray
    psi: np.ndarray
    u_r: np.ndarray
    v_r: np.ndarray
    r: np.ndarray
    u: np.ndarray
    v: np.ndarray
    current_n: np.ndarray
    current_e: np.ndarray
    rudder: np.ndarray
    accel_x: np.ndarray
    accel_y: np.ndarray
    phase: list[str]
    gyro_bias: np.ndarray = field(default_factory=lambda: np.zeros(3))

    def ground_velocity_ned(self) -> np.ndarray:
        """Return the velocity over ground in NED, (n, 3), m/s."""
        c, s = np.cos(self.psi), np.sin(self.psi)
        return np.stack([c * self.u - s * self.v, s * self.u + c * self.v,
                         np.zeros_like(self.u)], axis=-1)

    def course(self) -> np.ndarray:
        """Return the course over ground chi (rad), Fossen 2.4."""
        return course(self.ground_velocity_ned(), self.psi)

    def sideslip(self) -> np.ndarray:
        """Return the sideslip over ground beta = asin(v/U) (rad), the seed's sign."""
        return sideslip(np.stack([self.u, self.v, np.zeros_like(self.u)], axis=-1))


class _Hull:
    """The 3-DOF manoeuvring model's constants and right-hand side (pure-Python floats)."""

    def __init__(self, vessel: Vessel, set_speed: float) -> None:
        length, beam, draught = vessel.length, vessel.beam, vessel.draught
        cb = vessel.block_coefficient
        half_rho = 0.5 * RHO
        mass = RHO * length * beam * draught * cb
        inertia = mass * (vessel.yaw_gyration_ratio * length) ** 2
        # Clarke, Gedling and Hine (1983), non-dimensional (prime system, Fossen's clarke83).
        s = math.pi * (draught / length) ** 2
        y_vdot = -s * (1.0 + 0.16 * cb * beam / draught - 5.1 * (beam / length) ** 2)
        y_rdot = -s * (0.67 * beam / length - 0.0033 * (beam / draught) ** 2)
        n_vdot = -s * (1.1 * beam / length - 0.041 * beam / draught)
        n_rdot = -s * (1.0 / 12.0 + 0.017 * cb * beam / draught - 0.33 * beam / length)
        y_v = -s * (1.0 + 0.4 * cb * beam / draught)
        y_r = -s * (-0.5 + 2.2 * beam / length - 0.08 * beam / draught)
        n_v = -s * (0.5 + 2.4 * draught / length)
        n_r = -s * (0.25 + 0.039 * beam / draught - 0.56 * beam / length)
        m11 = mass - y_vdot * half_rho * length ** 3
        m12 = -y_rdot * half_rho * length ** 4
        m21 = -n_vdot * half_rho * length ** 4
        m22 = inertia - n_rdot * half_rho * length ** 5
        det = m11 * m22 - m12 * m21
        self.minv = (m22 / det, -m12 / det, -m21 / det, m11 / det)
        self.mass = mass
        # Damping per unit speed U (dimensional N(u_r) = U * these, plus m u_r in N_12).
        self.n11 = -y_v * half_rho * length ** 2
        self.n12 = -y_r * half_rho * length ** 3
        self.n21 = -n_v * half_rho * length ** 3
        self.n22 = -n_r * half_rho * length ** 4
        # Rudder at the stern, x_R = -L/2: delta > 0 pushes the stern to port, turns starboard.
        self.y_delta = -half_rho * vessel.rudder_area_ratio * length * draught \
            * vessel.rudder_lift_slope
        self.n_delta = -0.5 * length * self.y_delta
        # Surge: added mass 5 %, quadratic resistance, thrust holding set_speed on a straight.
        wetted = 1.7 * length * draught + cb * length * beam
        self.m_surge = 1.05 * mass
        self.d_uu = half_rho * wetted * vessel.resistance_coefficient
        self.thrust = self.d_uu * set_speed * set_speed
        self.coupling = vessel.centripetal_coupling * mass
        # Cross-flow drag strips along the hull.
        strips = 8
        dx = length / strips
        self.strips = [-0.5 * length + dx * (i + 0.5) for i in range(strips)]
        self.cross_flow = half_rho * draught * vessel.cross_flow_drag * dx

    def accelerations(self, u_r: float, v_r: float, r: float,
                      delta: float) -> tuple[float, float, float]:
        """Return (u_r', v_r', r') (m/s^2, m/s^2, rad/s^2) for rudder angle delta (rad)."""
        speed = math.sqrt(u_r * u_r + v_r * v_r)
        y_cf = 0.0
        n_cf = 0.0
        for x in self.strips:
            v_local = v_r + x * r
            force = -self.cross_flow * abs(v_local) * v_local
            y_cf += force
            n_cf += x * force
        u2 = speed * speed
        y = self.y_delta * u2 * delta + y_cf - speed * self.n11 * v_r \
            - (self.mass * u_r + speed * self.n12) * r
        n = self.n_delta * u2 * delta + n_cf - speed * self.n21 * v_r - speed * self.n22 * r
        a11, a12, a21, a22 = self.minv
        u_dot = (self.thrust - self.d_uu * abs(u_r) * u_r + self.coupling * v_r * r) \
            / self.m_surge
        return u_dot, a11 * y + a12 * n, a21 * y + a22 * n


class _Helmsman:
    """
    The voyage's manoeuvres: a heading autopilot, a turning circle, a 20/20 zig-zag.

    ``helm`` 'voyage' (the default schedule), 'straight' (the autopilot on the initial heading
    throughout) or 'figure8' (after a tenth of the voyage on the autopilot, full circles at
    25 deg of rudder, starboard then port, to the end).
    """

    CIRCLE_RUDDER = math.radians(25.0)
    ZIGZAG_RUDDER = math.radians(20.0)
    ZIGZAG_HEADING = math.radians(20.0)
    FINAL_TURN = math.radians(-70.0)
    KP = 1.5    # rad of rudder per rad of heading error
    KD = 12.0   # rad of rudder per rad/s of yaw rate

    def __init__(self, duration: float, heading: float, helm: str = 'voyage') -> None:
        self.bounds = (0.08 * duration, 0.42 * duration, 0.48 * duration, 0.78 * duration)
        self.base_heading = heading
        self.helm = helm
        self.first = 0.1 * duration
        self.circle_start: float | None = None
        self.zigzag_start: float | None = None
        self.zigzag_sign = 1.0

    def _autopilot(self, psi: float, r: float, psi_d: float) -> float:
        return -self.KP * ssa(psi - psi_d) - self.KD * r

    def command(self, t: float, psi: float, r: float) -> tuple[float, str]:
        """Return the commanded rudder angle, rad, and the name of the phase at time t, s."""
        if self.helm == 'straight':
            return self._autopilot(psi, r, self.base_heading), 'straight'
        if self.helm == 'figure8':
            if t < self.first:
                return self._autopilot(psi, r, self.base_heading), 'straight'
            if self.circle_start is None:
                self.circle_start = psi
            turned = psi - self.circle_start
            if abs(turned) >= 2.0 * math.pi:
                self.circle_start = psi
                self.zigzag_sign = -self.zigzag_sign
            return self.zigzag_sign * self.CIRCLE_RUDDER, 'figure-8'
        t_circle, t_circle_end, t_zigzag, t_zigzag_end = self.bounds
        if t < t_circle:
            return self._autopilot(psi, r, self.base_heading), 'straight'
        if t < t_circle_end:
            if self.circle_start is None:
                self.circle_start = psi
            if psi - self.circle_start < 2.0 * math.pi:
                return self.CIRCLE_RUDDER, 'turning circle'
            return self._autopilot(psi, r, self.base_heading), 'straight'
        if t < t_zigzag:
            return self._autopilot(psi, r, self.base_heading), 'straight'
        if t < t_zigzag_end:
            if self.zigzag_start is None:
                self.zigzag_start = psi
            deviation = ssa(psi - self.zigzag_start)
            if self.zigzag_sign > 0 and deviation >= self.ZIGZAG_HEADING:
                self.zigzag_sign = -1.0
            elif self.zigzag_sign < 0 and deviation <= -self.ZIGZAG_HEADING:
                self.zigzag_sign = 1.0
            return self.zigzag_sign * self.ZIGZAG_RUDDER, 'zig-zag'
        return self._autopilot(psi, r, self.base_heading + self.FINAL_TURN), 'straight'


def current_at(config: VoyageConfig, t: np.ndarray | float) -> tuple[Any, Any, Any, Any]:
    """
    Return the current (V_n, V_e) (m/s) and its rate (m/s^2) at time(s) t (s), NED.

    It sets towards ``current_direction`` at ``current_speed``, its direction swinging
    +-10 deg over a 600 s period and its speed +-10 % over 420 s: slowly varying.
    """
    w_dir = 2.0 * math.pi / 600.0
    w_speed = 2.0 * math.pi / 420.0
    direction = config.current_direction + math.radians(10.0) * np.sin(w_dir * t)
    direction_rate = math.radians(10.0) * w_dir * np.cos(w_dir * t)
    magnitude = config.current_speed * (1.0 + 0.1 * np.sin(w_speed * t))
    magnitude_rate = config.current_speed * 0.1 * w_speed * np.cos(w_speed * t)
    c, s = np.cos(direction), np.sin(direction)
    return (magnitude * c, magnitude * s,
            magnitude_rate * c - magnitude * s * direction_rate,
            magnitude_rate * s + magnitude * c * direction_rate)


class _Stop:
    """
    The standstill: braking to rest over :data:`BRAKING_TIME`, then at rest until its end.

    The hull's velocities through the water (u_r, the hull's own sway, r) are prescribed while
    it lasts: from the state at the first step of the braking they fall linearly to exactly
    zero at the standstill's start and stay zero until its end, when the manoeuvring model takes
    over again from rest (its thrust brings the speed back within a minute or two).
    """

    def __init__(self, window: tuple[float, float]) -> None:
        self.rest, self.end = window
        self.brake = self.rest - BRAKING_TIME
        self.t0: float | None = None
        self.state0 = (0.0, 0.0, 0.0)

    def active(self, t: float) -> bool:
        """Return whether the velocities are prescribed at time t (s)."""
        return self.brake <= t < self.end

    def begin(self, t: float, state: tuple[float, float, float]) -> None:
        """Start braking at time t (s) from the hull state (u_r, v, r), once."""
        if self.t0 is None:
            self.t0 = t
            self.state0 = state

    def at(self, t: float) -> tuple[float, float, float, float, float, float]:
        """Return (u_r, v, r) and their rates at time t (s) of the braking or the standstill."""
        span = self.rest - (self.t0 if self.t0 is not None else self.rest)
        if span <= 0.0 or t >= self.rest:
            return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
        frac = min(1.0, (self.rest - t) / span)
        u0, v0, r0 = self.state0
        return u0 * frac, v0 * frac, r0 * frac, -u0 / span, -v0 / span, -r0 / span


class _Profile:
    """
    A prescribed surge through the water u_r(t) from knots (t s, u_r m/s), jerk-limited.

    Linear between the knots, held before the first and after the last, and averaged over a
    moving window of :data:`PROFILE_RAMP` s, so that the acceleration ramps up and down over
    that time (a throttle or a reversing gear taking hold) instead of jumping.
    """

    def __init__(self, knots: tuple[tuple[float, float], ...]) -> None:
        self.t = [float(k[0]) for k in knots]
        self.u = [float(k[1]) for k in knots]

    def _linear(self, t: float) -> float:
        ts, us = self.t, self.u
        if t <= ts[0]:
            return us[0]
        for i in range(1, len(ts)):
            if t < ts[i]:
                return us[i - 1] + (us[i] - us[i - 1]) * (t - ts[i - 1]) / (ts[i] - ts[i - 1])
        return us[-1]

    def _integral(self, t: float) -> float:
        """Return the integral of the linear profile from the first knot to t (m)."""
        ts, us = self.t, self.u
        if t <= ts[0]:
            return us[0] * (t - ts[0])
        total = 0.0
        for i in range(1, len(ts)):
            end = min(t, ts[i])
            total += 0.5 * (us[i - 1] + self._linear(end)) * (end - ts[i - 1])
            if t <= ts[i]:
                return total
        return total + us[-1] * (t - ts[-1])

    def at(self, t: float) -> tuple[float, float]:
        """Return u_r (m/s) and its rate (m/s^2) at time t (s)."""
        half = 0.5 * PROFILE_RAMP
        u = (self._integral(t + half) - self._integral(t - half)) / PROFILE_RAMP
        return u, (self._linear(t + half) - self._linear(t - half)) / PROFILE_RAMP


def simulate(config: VoyageConfig) -> Truth:
    """
    Integrate the voyage (RK4 at ``imu_rate``) and return the true state at every step.

    With a ``surge_profile`` the surge through the water follows it (the hull's sway and yaw
    dynamics run at that speed), as under a throttle that makes exactly that speed.

    With a leeway lambda the sway through the water is v_r = v_h + u_r tan(lambda), where v_h
    is the hull's own sway from the manoeuvring model: the sails' side force is taken to balance
    the hull's reaction to the leeway component, so the hull's dynamics act on v_h alone, while
    the kinematics (position, ground velocity, course, sideslip, accelerations) use all of v_r.
    """
    hull = _Hull(config.vessel, config.speed)
    helm = _Helmsman(config.duration, config.heading, config.helm)
    profile = _Profile(config.surge_profile) if config.surge_profile else None
    window = config.standstill_window()
    stop = _Stop(window) if window is not None else None
    tan_leeway = math.tan(config.leeway)
    h = 1.0 / config.imu_rate
    steps = int(round(config.duration * config.imu_rate)) + 1
    t_all = np.arange(steps) * h
    vn_all, ve_all, vn_rate, ve_rate = current_at(config, t_all)
    vn_all, ve_all = vn_all.tolist(), ve_all.tolist()
    out = np.empty((steps, 9))
    phases: list[str] = []
    north = east = 0.0
    psi = config.heading
    u_r, v_r, r = config.speed, 0.0, 0.0     # v_r here: the hull's own sway v_h
    if profile is not None:
        u_r = profile.at(0.0)[0]
    delta = 0.0
    max_step = config.vessel.rudder_rate * h
    limit = config.vessel.rudder_limit

    def rates(psi_: float, u_: float, v_: float, r_: float, rudder: float,
              current: tuple[float, float], tau: float) -> tuple[float, ...]:
        c, s = math.cos(psi_), math.sin(psi_)
        if profile is not None:
            u_, du = profile.at(tau)
            _, dv, dr = hull.accelerations(u_, v_, r_, rudder)
        else:
            du, dv, dr = hull.accelerations(u_, v_, r_, rudder)
        v_total = v_ + u_ * tan_leeway
        return (c * u_ - s * v_total + current[0], s * u_ + c * v_total + current[1], r_,
                du, dv, dr)

    def kinematics(psi_: float, tau: float, current: tuple[float, float]) -> tuple[float, ...]:
        assert stop is not None        # only called while stopped
        u_, v_, r_ = stop.at(tau)[:3]
        c, s = math.cos(psi_), math.sin(psi_)
        v_total = v_ + u_ * tan_leeway
        return c * u_ - s * v_total + current[0], s * u_ + c * v_total + current[1], r_

    for k in range(steps):
        t = k * h
        stopped = stop is not None and stop.active(t)
        if stop is not None and stopped:
            stop.begin(t, (u_r, v_r, r))
            u_r, v_r, r, du, dv, _ = stop.at(t)
            command, phase = 0.0, ('stopping' if t < stop.rest else 'standstill')
        else:
            command, phase = helm.command(t, psi, r)
        command = max(-limit, min(limit, command))
        delta += max(-max_step, min(max_step, command - delta))
        if not stopped:
            du, dv, _ = hull.accelerations(u_r, v_r, r, delta)
            if profile is not None:
                du = profile.at(t)[1]
        out[k] = (north, east, psi, u_r, v_r, r, du, dv, delta)
        phases.append(phase)
        if k == steps - 1:
            break
        now = (vn_all[k], ve_all[k])
        nxt = (vn_all[k + 1], ve_all[k + 1])
        mid = (0.5 * (now[0] + nxt[0]), 0.5 * (now[1] + nxt[1]))
        sixth = h / 6.0
        if stop is not None and stopped:
            k1 = kinematics(psi, t, now)
            k2 = kinematics(psi + 0.5 * h * k1[2], t + 0.5 * h, mid)
            k3 = kinematics(psi + 0.5 * h * k2[2], t + 0.5 * h, mid)
            k4 = kinematics(psi + h * k3[2], t + h, nxt)
            north += sixth * (k1[0] + 2.0 * k2[0] + 2.0 * k3[0] + k4[0])
            east += sixth * (k1[1] + 2.0 * k2[1] + 2.0 * k3[1] + k4[1])
            psi += sixth * (k1[2] + 2.0 * k2[2] + 2.0 * k3[2] + k4[2])
            u_r, v_r, r = stop.at(t + h)[:3]
            continue
        k1 = rates(psi, u_r, v_r, r, delta, now, t)
        k2 = rates(psi + 0.5 * h * k1[2], u_r + 0.5 * h * k1[3], v_r + 0.5 * h * k1[4],
                   r + 0.5 * h * k1[5], delta, mid, t + 0.5 * h)
        k3 = rates(psi + 0.5 * h * k2[2], u_r + 0.5 * h * k2[3], v_r + 0.5 * h * k2[4],
                   r + 0.5 * h * k2[5], delta, mid, t + 0.5 * h)
        k4 = rates(psi + h * k3[2], u_r + h * k3[3], v_r + h * k3[4], r + h * k3[5], delta,
                   nxt, t + h)
        north += sixth * (k1[0] + 2.0 * k2[0] + 2.0 * k3[0] + k4[0])
        east += sixth * (k1[1] + 2.0 * k2[1] + 2.0 * k3[1] + k4[1])
        psi += sixth * (k1[2] + 2.0 * k2[2] + 2.0 * k3[2] + k4[2])
        u_r += sixth * (k1[3] + 2.0 * k2[3] + 2.0 * k3[3] + k4[3])
        if profile is not None:
            u_r = profile.at(t + h)[0]
        v_r += sixth * (k1[4] + 2.0 * k2[4] + 2.0 * k3[4] + k4[4])
        r += sixth * (k1[5] + 2.0 * k2[5] + 2.0 * k3[5] + k4[5])
    north_a, east_a, psi_a, u_r_a, v_h_a, r_a, du_a, dv_h_a, rudder_a = out.T
    # Sway through the water with the leeway, and its rate.
    v_r_a = v_h_a + u_r_a * tan_leeway
    dv_a = dv_h_a + du_a * tan_leeway
    vn_a, ve_a = np.asarray(vn_all), np.asarray(ve_all)
    c, s = np.cos(psi_a), np.sin(psi_a)
    # nu = nu_r + R(psi)^T v_c; body acceleration over ground nu_r' + S(r) nu_r + R^T v_c'.
    return Truth(
        t=t_all, north=north_a, east=east_a, psi=psi_a, u_r=u_r_a, v_r=v_r_a, r=r_a,
        u=u_r_a + c * vn_a + s * ve_a, v=v_r_a - s * vn_a + c * ve_a,
        current_n=vn_a, current_e=ve_a, rudder=rudder_a,
        accel_x=du_a - r_a * v_r_a + c * vn_rate + s * ve_rate,
        accel_y=dv_a + r_a * u_r_a - s * vn_rate + c * ve_rate,
        phase=phases)


def validate(config: VoyageConfig) -> None:
    """Raise ValueError with a clear message for a configuration that cannot be simulated."""
    if not 1.0 <= config.duration <= 24 * 3600.0:
        raise ValueError(f'--duration must be between 1 s and 24 h, got {config.duration}')
    if not 0.5 <= config.speed <= 15.0:
        raise ValueError(f'--speed must be between 0.5 and 15 m/s, got {config.speed}')
    if not 0.0 <= config.current_speed < config.speed:
        raise ValueError('--current speed must be >= 0 and below the set speed, got '
                         f'{config.current_speed}')
    lat, lon, height = config.origin
    if not (-89.0 <= lat <= 89.0 and -180.0 <= lon <= 180.0 and math.isfinite(height)):
        raise ValueError(f'--origin must be a latitude within 89 deg of the equator, a '
                         f'longitude in [-180, 180] and a finite height, got {config.origin}')
    if config.outage is not None and (config.outage[0] < 0 or config.outage[1] < 0):
        raise ValueError(f'--outage start and length must be >= 0, got {config.outage}')
    if not (math.isfinite(config.log_scale) and 0.2 <= config.log_scale <= 5.0):
        raise ValueError(f'--log-scale must be between 0.2 and 5, got {config.log_scale}')
    if not (math.isfinite(config.leeway) and abs(config.leeway) <= math.radians(30.0)):
        raise ValueError('--leeway must be within 30 deg of zero, got '
                         f'{math.degrees(config.leeway)} deg')
    if not math.isfinite(config.imu_yaw_offset):
        raise ValueError(f'--imu-yaw-offset must be finite, got {config.imu_yaw_offset}')
    if (config.standstill_start is None) != (config.standstill_end is None):
        raise ValueError('a standstill needs both its start and its end')
    window = config.standstill_window()
    if window is not None and not (math.isfinite(window[0]) and math.isfinite(window[1])
                                   and 0.0 <= window[0] < window[1] <= config.duration):
        raise ValueError('--standstill must be 0 <= START < END <= the duration, got '
                         f'{window}')
    if config.helm not in ('voyage', 'straight', 'figure8'):
        raise ValueError(f"--helm must be 'voyage', 'straight' or 'figure8', got {config.helm!r}")
    if config.surge_profile is not None:
        times = [k[0] for k in config.surge_profile]
        speeds = [k[1] for k in config.surge_profile]
        if (not times or any(b <= a for a, b in zip(times, times[1:]))
                or not all(math.isfinite(v) and 0.0 <= v <= 25.0 for v in speeds)):
            raise ValueError('--surge-profile needs knots of increasing time and speeds within '
                             f'0..25 m/s, got {config.surge_profile}')
    for name in ('log_outage', 'log_freeze', 'compass_freeze'):
        value = getattr(config, name)
        if value is not None and not (value[0] >= 0.0 and value[1] >= 0.0):
            raise ValueError(f'--{name.replace("_", "-")} start and length must be >= 0, '
                             f'got {value}')
    if not (0.0 <= config.fix_outlier_fraction <= 0.5
            and math.isfinite(config.fix_outlier_distance)):
        raise ValueError('--fix-outliers must be a fraction within 0..0.5 and a finite '
                         f'distance, got {config.fix_outlier_fraction}, '
                         f'{config.fix_outlier_distance}')
    if config.compass_rate is not None and not config.compass_rate > 0.0:
        raise ValueError(f'--compass-rate must be > 0 Hz, got {config.compass_rate}')
    for name in ('fix_latency', 'imu_latency', 'velocity_latency'):
        low, high = getattr(config, name)
        if not 0.0 <= low <= high <= MAX_LATENCY:
            raise ValueError(f'--{name.replace("_", "-")} must be 0 <= MIN <= MAX <= '
                             f'{MAX_LATENCY:g} s, got {low}, {high}')
