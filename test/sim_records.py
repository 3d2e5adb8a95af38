"""
The simulator's readings as the estimator's records, for estimator tests against the truth.

The readings (:class:`vessel_kinematics.tools.sim_sensors.Readings`) are in the sensors' own ROS
conventions (ENU/FLU, ``xyzw``); here they become NED/FRD records through ``core.frames``, the
same conventions the ROS edge applies, without any ROS: the estimator alone is under test.
``run`` feeds them in stamp order and samples the state.
"""

from __future__ import annotations

from dataclasses import dataclass, field
import math
from typing import Callable, Iterator

import numpy as np
from vessel_kinematics import estimation
from vessel_kinematics.core import frames
from vessel_kinematics.estimation import (BodyVelocity, Estimator, FilterConfig, GnssFix,
                                          ImuSample, Rejection)
from vessel_kinematics.tools import sim

#: Input order at equal stamps (as the replay's merge: IMU before the others).
_ORDER = {'imu': 0, 'velocity': 1, 'fix': 2, 'ground_velocity': 3}


def _cov3(flat: list[float]) -> np.ndarray:
    return np.asarray(flat, dtype=float).reshape(3, 3)


def records(readings: sim.Readings, truth: sim.Truth, *, velocity: bool = True,
            ground_velocity: float | None = None) -> list[tuple[str, object]]:
    """
    Return (input name, record) of every reading, in stamp order.

    ``velocity`` False leaves the log out; ``ground_velocity`` the σ (m/s) of a receiver's own
    velocity over ground, made from the truth at each valid fix (None: none).
    """
    stamps = readings.stamps
    out: list[tuple[int, int, str, object]] = []
    att_flat, rate_flat, _ = readings.imu_covariances
    att_cov = None if att_flat[0] == -1.0 else frames.cov3_flu_to_frd(_cov3(att_flat))
    rate_cov = None if rate_flat[0] == -1.0 else frames.cov3_flu_to_frd(_cov3(rate_flat))
    for j, k in enumerate(readings.imu_steps):
        x, y, z, w = readings.imu_orientation[j]
        q = tuple(frames.q_nb_from_ros([x, y, z, w]).tolist())
        omega = (None if rate_cov is None
                 else frames.flip_body3(*readings.imu_angular_velocity[j]))
        sample = ImuSample(stamps[k], q, att_cov, omega, rate_cov)
        out.append((stamps[k], _ORDER['imu'], 'imu', sample))
    fix_cov = frames.cov3_enu_to_ned(_cov3(readings.fix_covariance))
    for k, llh in zip(readings.fix_steps, readings.fix_llh):
        if llh is None:
            continue
        out.append((stamps[k], _ORDER['fix'], 'fix',
                    GnssFix(stamps[k], math.radians(llh[0]), math.radians(llh[1]), llh[2],
                            fix_cov)))
    if velocity:
        cov6 = np.asarray(readings.velocity_covariance, dtype=float).reshape(6, 6)
        lin_cov = frames.cov3_flu_to_frd(cov6[0:3, 0:3])
        for k, nu in zip(readings.velocity_steps, readings.velocity):
            out.append((stamps[k], _ORDER['velocity'], 'velocity',
                        BodyVelocity(stamps[k], np.array(frames.flip_body3(*nu)), lin_cov)))
    if ground_velocity is not None:
        rng = np.random.default_rng(99)
        v_ned = truth.ground_velocity_ned()
        cov = np.diag([ground_velocity ** 2] * 2 + [1e6])
        for k, llh in zip(readings.fix_steps, readings.fix_llh):
            if llh is None:
                continue
            v = v_ned[k] + rng.normal(0.0, ground_velocity, 3) * [1.0, 1.0, 0.0]
            out.append((stamps[k], _ORDER['ground_velocity'], 'ground_velocity',
                        estimation.GroundVelocity(stamps[k], v, cov)))
    out.sort(key=lambda r: (r[0], r[1]))
    return [(name, rec) for _, _, name, rec in out]


@dataclass
class Run:
    """States sampled on a run, the rejections, the events and the truth."""

    truth: sim.Truth
    config: sim.VoyageConfig
    estimator: Estimator
    t: list[float] = field(default_factory=list)
    states: list = field(default_factory=list)
    rejections: list[tuple[float, str, Rejection]] = field(default_factory=list)
    events: list = field(default_factory=list)

    def at(self, t: float):
        """Return (state, truth index) at the sample nearest ``t`` s."""
        i = int(np.argmin(np.abs(np.array(self.t) - t)))
        return self.states[i], self.index(self.t[i])

    def index(self, t: float) -> int:
        """Return the truth's step index at ``t`` s."""
        return min(int(round(t * self.config.imu_rate)), self.truth.t.size - 1)

    def refused(self, name: str, reason: str | None = None) -> list[tuple[float, Rejection]]:
        """Return the (time, rejection) of input ``name`` (of ``reason``, if given)."""
        return [(t, r) for t, n, r in self.rejections
                if n == name and (reason is None or r.reason.value == reason)]


def run(config: sim.VoyageConfig, filter_config: FilterConfig, *, every: float = 0.1,
        velocity: bool = True, ground_velocity: float | None = None,
        watch: Callable[[float, str, Estimator], None] | None = None,
        alter: Callable[[sim.Readings], None] | None = None) -> Run:
    """
    Simulate ``config``, feed the estimator, sample its state every ``every`` s.

    ``alter`` changes the sensor readings in place before they are fed (a fault the simulator
    does not model).
    """
    truth = sim.simulate(config)
    readings = sim.sensor_readings(truth, config)
    if alter is not None:
        alter(readings)
    est = Estimator(filter_config)
    out = Run(truth, config, est)
    start = sim.START_NS
    next_t = 0.0
    for name, rec in records(readings, truth, velocity=velocity,
                             ground_velocity=ground_velocity):
        t = (rec.stamp_ns - start) * 1e-9
        result = getattr(est, name)(rec)
        if result is not None:
            out.rejections.append((t, name, result))
        out.events.extend((t, e) for e in est.pop_events())
        if watch is not None:
            watch(t, name, est)
        if t >= next_t and est.ready:
            out.t.append(t)
            out.states.append(est.state())
            next_t = t + every
    return out


def water_config(config: sim.VoyageConfig, **changes) -> FilterConfig:
    """Return the FilterConfig of a water-referenced log for ``config``'s antenna (FLU -> FRD)."""
    ax, ay, az = config.antenna
    values: dict = {'water': True, 'antenna_b': (ax, -ay, -az)}
    values.update(changes)
    return FilterConfig(**values)


def speeds(result: Run) -> Iterator[tuple[float, float, float]]:
    """Yield (t, estimated speed over ground, true speed over ground) of each sample (m/s)."""
    v = result.truth.ground_velocity_ned()
    for t, s in zip(result.t, result.states):
        k = result.index(t)
        yield t, math.hypot(s.v_n[0], s.v_n[1]), math.hypot(v[k, 0], v[k, 1])
