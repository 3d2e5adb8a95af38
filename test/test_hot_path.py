"""
The estimator's per-IMU hot path gives bit-identical results to its plain form.

The plain form is the code before the hot path was trimmed (kept here as the reference):
``Attitude.set_q`` without the cached heading, ``Attitude.measured`` always setting q,
``Pending`` always summing the 3-D rotation and computing both headings per step, and
``Estimator._propagate`` passing no headings. A simulated voyage is replayed through the
pipeline with each, and every state array after every message must be equal byte for byte
(``-0.0`` and ``0.0`` differ there).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
from vessel_kinematics.core.quaternion import rquat9
from vessel_kinematics.estimation import attitude, config, estimator, model
from vessel_kinematics.estimation.attitude import heading_of, yaw_only
from vessel_kinematics.ros.params import NavigatorParams
from vessel_kinematics.ros.pipeline import Pipeline
from vessel_kinematics.tools import replay, sim


# --- the plain form (the code before the change) -----------------------------------------------

def _plain_set_q(self: Any, q: Any) -> None:
    self.q = attitude.floats(q)
    self.r9 = rquat9(*self.q)


def _plain_measured(self: Any, q: Any, cov: Any, stamp_ns: int) -> None:
    self.set_q(yaw_only(q) if self.level else q)
    self.last_attitude_ns = stamp_ns
    self._base = attitude._DEFAULT_ATT_COV if cov is None else cov
    self._dt2 = 0.0
    self.known = True


def _plain_pending_init(self: Any, horizontal: bool = False) -> None:
    self.dt = 0.0
    self.a9 = (0.0,) * 9
    self.cs = (0.0, 0.0)
    self.horizontal = False


def _plain_add(self: Any, dt: float, r0: Any, r1: Any, *headings: Any) -> None:
    h = 0.5 * dt
    if r0 is r1:
        self.a9 = tuple([a + dt * r for a, r in zip(self.a9, r0)])
        c, s = heading_of(r0)
        self.cs = (self.cs[0] + dt * c, self.cs[1] + dt * s)
    else:
        self.a9 = tuple([a + h * (r + t) for a, r, t in zip(self.a9, r0, r1)])
        c0, s0 = heading_of(r0)
        c1, s1 = heading_of(r1)
        self.cs = (self.cs[0] + h * (c0 + c1), self.cs[1] + h * (s0 + s1))
    self.dt += dt


def _plain_propagate(self: Any, t1: int, q_end: Any) -> None:
    dt = (t1 - self.t) * 1e-9
    self.t = t1
    att = self.attitude
    if dt <= 0.0:
        if q_end is not None:
            att.set_q(q_end)
        return
    integrating = att.rates_fresh(t1, self.config.max_gap)
    if dt > self.config.max_gap:
        self._flush()
        self._inflate_gap(dt, integrating)
        if q_end is not None:
            att.set_q(q_end)
        return
    r0 = att.r9
    if q_end is not None:
        att.set_q(q_end)
    elif integrating:
        att.set_q(att.integrate(dt))
    self.pending.add(dt, r0, att.r9)
    if self.pending.dt >= config.LAZY_INTERVAL:
        self._flush()


# --- the comparison ----------------------------------------------------------------------------

def _trace(bag: Path, params: NavigatorParams) -> list[bytes]:
    """Return the bytes of x, P (and every 20th message the NavState's arrays) per message."""
    pipeline = Pipeline(params)
    est = pipeline.estimator
    out = []
    for i, item in enumerate(replay.input_messages(bag, params)):
        pipeline.handle(item.name, item.msg, item.arrival_ns)
        out.append(est.x.tobytes() + est.P.tobytes())
        if i % 20 == 0 and est.ready:
            s = est.state()
            out.append(b''.join(np.asarray(v, dtype=float).tobytes()
                                for v in (s.p, s.q, s.nu, s.omega, s.v_n, s.p_local, s.llh,
                                          s.course, s.sideslip, s.cov_p, s.cov_att, s.cov_nu,
                                          s.cov_omega, s.cov_p_local)))
    assert est.ready
    return out


@pytest.fixture(scope='module')
def voyage(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp('hot') / 'voyage'
    sim.generate(path, sim.VoyageConfig(duration=20.0))
    return path


@pytest.mark.parametrize('flat', [
    {},                                                          # surface, planar
    {'motion': 'free', 'velocity.reference': 'water'},           # 3-D rotation sums
    {'motion': 'ground', 'imu.use_orientation': False},          # level, integrated rate
    {'imu.use_orientation': False, 'integrator': 'euler'},
])
def test_hot_path_is_bit_identical_to_the_plain_form(flat: dict, voyage: Path,
                                                     monkeypatch: pytest.MonkeyPatch) -> None:
    params = NavigatorParams.from_flat(flat)
    fast = _trace(voyage, params)
    monkeypatch.setattr(attitude.Attitude, 'set_q', _plain_set_q)
    monkeypatch.setattr(attitude.Attitude, 'measured', _plain_measured)
    monkeypatch.setattr(model.Pending, '__init__', _plain_pending_init)
    monkeypatch.setattr(model.Pending, 'add', _plain_add)
    monkeypatch.setattr(estimator.Estimator, '_propagate', _plain_propagate)
    plain = _trace(voyage, params)
    assert len(fast) == len(plain) > 2000
    first = next((i for i, (a, b) in enumerate(zip(fast, plain)) if a != b), None)
    assert first is None, f'differs from step {first}'
