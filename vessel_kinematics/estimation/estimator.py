"""
The navigator's estimator: the time policy and the measurement updates, as one facade.

The pieces live beside it: :mod:`.config` (what kind of craft, the model constants),
:mod:`.layout` (the named state), :mod:`.attitude` (q_nb from the IMU), :mod:`.model` (the
kinematics and measurement models) and :mod:`.kalman` (the update). This module decides when
each runs.

Time
----
Stamps are the messages' header stamps (ns). A message newer than the state propagates it to
the message's stamp; no integration across a gap longer than ``max_gap`` (time advances and
the covariance is widened by what the vessel could have moved). A message older by at most
``reorder_window`` is used at the state's time without integrating backwards (a fix is
compared against the position predicted back to its stamp, p − ṗ·Δt); older by up to
``max_gap`` it is rejected as ``stale_stamp``; further back (a bag looped) the state is
re-initialised, keeping the origin.

Outliers and recovery
---------------------
Fixes and velocities pass a chi-square innovation gate (Mahalanobis distance
``gate_sigma``). A real jump (a relocated vessel, a moved antenna) is not locked out: after
:data:`~.config.GATE_RESET_COUNT` consecutive refused fixes, or
:data:`~.config.GATE_RESET_TIME` s of them, the position is re-initialised from the fix with
the fix's covariance and the velocity's uncertainty widened to its prior (counted in
:attr:`Estimator.recoveries`), so the reported σ covers the real error again. A velocity
update that would leave the state beyond physical bounds is refused.

Heading offset
--------------
With ``estimate_heading_offset`` a constant offset δψ of the IMU heading is a state. Any
angle is possible (a mounting yaw off by 90°), which a linearised filter cannot find from
zero: it is held (no gain, no coupling, the heading treated as unknown in the position's
process noise) until the vessel has moved at least :data:`OFFSET_INIT_DISTANCE` m along a
steady heading, then initialised from the course over ground of those fixes minus the mean
IMU heading (π more going astern), with σ :data:`OFFSET_INIT_SIGMA`, and refined by the
fixes from then on.
"""

from __future__ import annotations

from collections import deque
from itertools import chain
import marshal
import math
from operator import attrgetter
import pickle
from typing import Any, Callable, Collection, Sequence

import numpy as np

from vessel_kinematics.core import flow, geodesy
from vessel_kinematics.core.quaternion import mul4, rquat9
from vessel_kinematics.estimation import model
from vessel_kinematics.estimation.attitude import (Attitude, floats, heading_of, tilt_of,
                                                   yaw_only)
from vessel_kinematics.estimation.config import (ATTITUDE_SHARE_MAX_VARIANCE, CURRENT,
                                                 FilterConfig, FUSED_TIMEOUT, GATE_RESET_COUNT,
                                                 GATE_RESET_TIME, INITIAL_VELOCITY_SIGMA,
                                                 LAZY_INTERVAL, LEEWAY, LOG_SCALE,
                                                 MAX_STATE_POSITION, MAX_STATE_SPEED,
                                                 SURFACE_HEAVE_SIGMA, SURFACE_HEIGHT_SIGMA,
                                                 TURN_DRIFT, UNKNOWN_ATTITUDE_SIGMA,
                                                 UNMEASURED_VARIANCE, VELOCITY_GATE_RESET_COUNT)
from vessel_kinematics.estimation.kalman import update
from vessel_kinematics.estimation.layout import StateLayout
from vessel_kinematics.estimation.records import (BodyVelocity, Calibration, DEAD_RECKONING,
                                                  Estimate, FUSED, GnssFix, ImuSample, Mode,
                                                  NavPose, NavState, Reason, Rejection,
                                                  RelativeFlow, WAITING)

__all__ = ['Estimator', 'OFFSET_INIT_DISTANCE', 'OFFSET_INIT_SIGMA', 'OFFSET_INIT_WINDOW']

#: Distance over ground (m) the vessel must cover before the heading offset is initialised.
OFFSET_INIT_DISTANCE = 20.0
#: The fixes of the last this many seconds give the course for the heading offset.
OFFSET_INIT_WINDOW = 30.0
#: Largest spread (rad) of the IMU heading over that window: a steady heading.
OFFSET_INIT_MAX_TURN = math.radians(30.0)
#: Standard deviation (rad) of the first heading-offset estimate (course vs heading, which
#: includes sideslip and the current's drift).
OFFSET_INIT_SIGMA = math.radians(15.0)

_TINY_VARIANCE = 1e-12


#: What :meth:`Estimator.freeze` leaves out: the configuration and the state's layout (a
#: thawing estimator has the same, see ``_config_serial``), the cache of covariance arrays
#: already checked (about this process's arrays) and the samples of the heading-offset guess
#: (update machinery: no output reads them).
_NOT_FROZEN = frozenset({'config', 'layout', '_checked', '_offset_init', 'attitude', 'pending'})
#: The attitude's configuration, left out by :meth:`Estimator.freeze` too.
_NOT_FROZEN_ATTITUDE = frozenset({'level', 'integrator'})


#: The types marshal writes as themselves (it writes anything with a buffer, a numpy scalar
#: say, as bytes: such a value must go by pickle).
_MARSHAL_TYPES = frozenset({float, int, bool, str, type(None)})
#: The deferred time update's values, in the order of its slots.
_PENDING_VALUES = attrgetter(*model.Pending.__slots__)


def _plain(attributes: dict[str, Any],
           left_out: frozenset[str]) -> tuple[dict[str, Any], dict[str, Any]]:
    """Split the attributes not ``left_out`` into other values and arrays (bytes, dtype, shape)."""
    plain = attributes.copy()
    for name in left_out:
        plain.pop(name, None)
    arrays = {name: (value.tobytes(), value.dtype.str, value.shape)
              for name, value in plain.items() if type(value) is np.ndarray}
    for name in arrays:
        del plain[name]
    return plain, arrays


def _marshals(values: Collection[Any]) -> bool:
    """Return True when marshal gives all ``values`` back as they are (see _MARSHAL_TYPES)."""
    kinds = set(map(type, values))                  # C loops; tuples looked into, level by level
    while tuple in kinds:
        values = list(chain.from_iterable([v for v in values if type(v) is tuple]))
        kinds.discard(tuple)
        kinds.update(map(type, values))
    return kinds <= _MARSHAL_TYPES


def _unplain(target: Any, plain: dict[str, Any], arrays: dict[str, Any]) -> None:
    """Set the attributes of :func:`_plain` on ``target`` (arrays writable, of their own)."""
    attributes = vars(target)
    attributes.update(plain)
    for name, (data, dtype, shape) in arrays.items():
        array = np.frombuffer(bytearray(data), dtype=dtype)    # writable, its own buffer
        array.shape = shape
        attributes[name] = array


class _CheckedCovariances:
    """
    Remember read-only covariance arrays already found finite (and whether all zero).

    ``ros_io`` hands out one shared read-only array per distinct covariance a driver sends, so
    the per-message checks reduce to an identity test. Writable arrays are always checked.
    """

    def __init__(self) -> None:
        self._known: list[tuple[np.ndarray, bool]] = []

    def check(self, cov: Any) -> bool | None:
        """Return None when not finite, else whether any entry is non-zero."""
        for known, nonzero in self._known:
            if known is cov:
                return nonzero
        if not _finite(cov):
            return None
        nonzero = bool(np.any(cov))
        if isinstance(cov, np.ndarray) and not cov.flags.writeable:
            if len(self._known) >= 8:
                self._known.pop(0)
            self._known.append((cov, nonzero))
        return nonzero


def _finite(*arrays: Any) -> bool:
    """Return True when no array holds a NaN or an infinity (a sum is non-finite then)."""
    for a in arrays:
        if a is None:
            continue
        if isinstance(a, tuple):
            if not math.isfinite(sum(a)):
                return False
        elif not math.isfinite(sum(np.ravel(a).tolist())):
            return False
    return True


def _wrap_lon_deg(lon: float) -> float:
    """Return a longitude in degrees in [-180, 180] (parameters allow up to 360)."""
    return lon - 360.0 if lon > 180.0 else lon


def _skew(a: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])


def _smoothstep(speed: float, low: float) -> float:
    """Return the weight of course/sideslip: 0 below ``low``, 1 above 2·low, smooth between."""
    if low <= 0.0:
        return 1.0 if speed > 0.0 else 0.0
    s = (speed - low) / low
    if s <= 0.0:
        return 0.0
    if s >= 1.0:
        return 1.0
    return s * s * (3.0 - 2.0 * s)


class _OffsetInit:
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


class Estimator:
    """The navigator's state and its time and measurement updates (see the module notes)."""

    def __init__(self, config: FilterConfig) -> None:
        self.config = config
        #: Counts the configurations applied (:meth:`set_config`), for :meth:`thaw`.
        self._config_serial = 0
        self.origin: tuple[float, float, float] | None = None
        self.resets = 0
        self.recoveries = 0
        self.declination = 0.0
        self.declination_error: str | None = None
        self._origin_event = False
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
        n = lay.size
        self.t: int | None = None
        self.x = np.zeros(n)
        self.P = np.zeros((n, n))
        self.P[lay.v, lay.v] = np.eye(lay.dim) * INITIAL_VELOCITY_SIGMA ** 2
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
        self._offset_init = _OffsetInit()
        self.position_ok = False
        self._position_ns: int | None = None
        self.attitude = Attitude(level=cfg.level, integrator=cfg.integrator)
        self.pending = model.Pending(lay.horizontal)
        self._checked = _CheckedCovariances()
        self.last_fix_ns: int | None = None
        self.last_imu_ns: int | None = None
        self.last_velocity_ns: int | None = None
        self._gate_streak = 0
        self._gate_first_ns = 0
        self._velocity_gate_streak = 0
        self._velocity_known = False
        self.last_surge = 0.0
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

    def _set_origin_from_config(self, config: FilterConfig) -> bool:
        """Take a complete origin from the configuration; return True when it changed."""
        lat, lon, h = config.origin
        if math.isnan(lat) or math.isnan(h):
            return False
        origin = (math.radians(lat), math.radians(_wrap_lon_deg(lon)), float(h))
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

    # ------------------------------------------------------------------ projection

    def to_ned(self, lat: float, lon: float, h: float) -> np.ndarray:
        """Return the NED position (m) of a latitude, longitude (rad) and height (m)."""
        lat0, lon0, h0 = self.origin  # type: ignore[misc]
        if self.config.projection == 'flat':
            return np.array(geodesy.llh2flat(lat, lon, h, lat0, lon0, h0), dtype=float)
        return np.array(geodesy.llh2ned(lat, lon, h, lat0, lon0, h0), dtype=float)

    def to_llh(self, p: np.ndarray) -> tuple[float, float, float]:
        """Return latitude, longitude (rad) and height (m) of a NED position about the origin."""
        lat0, lon0, h0 = self.origin  # type: ignore[misc]
        ned = (float(p[0]), float(p[1]), float(p[2]))
        if self.config.projection == 'flat':
            lat, lon, h = geodesy.flat2llh(ned, lat0, lon0, h0)
        else:
            lat, lon, h = geodesy.ned2llh(ned, lat0, lon0, h0)
        return float(lat), float(lon), float(h)

    def _p3(self, x: np.ndarray, block: slice) -> np.ndarray:
        """Return a position block as NED (3,), the height zero for the planar motions."""
        p = x[block]
        return p.copy() if p.size == 3 else np.array([p[0], p[1], 0.0])

    # ------------------------------------------------------------------ public queries

    @property
    def mode(self) -> Mode:
        """Return the mode: waiting_for_origin, dead_reckoning or fused."""
        if self.origin is None or not self.position_ok:
            return WAITING
        if (self.config.gnss_enabled and self.last_fix_ns is not None and self.t is not None
                and (self.t - self.last_fix_ns) * 1e-9 <= FUSED_TIMEOUT):
            return FUSED
        return DEAD_RECKONING

    @property
    def ready(self) -> bool:
        """
        Return True when there is a state to publish: origin, position and attitude known.

        Until an IMU has given an attitude (or a rate to integrate) the heading is unknown, so
        nothing is published for up to ``max_gap`` s after the position: a first fix must not
        go out with a heading of zero. A set-up without an IMU publishes after that wait.
        """
        if self.origin is None or not self.position_ok or self.t is None:
            return False
        att = self.attitude
        if att.known or att.omega is not None:
            return True
        return (self._position_ns is not None
                and (self.t - self._position_ns) * 1e-9 > self.config.max_gap)

    def pop_origin_event(self) -> bool:
        """Return True once after the origin has been set or changed."""
        event, self._origin_event = self._origin_event, False
        return event

    def freeze(self) -> bytes:
        """
        Return what the outputs are computed from, as bytes for :meth:`thaw` (any process).

        The state, its covariance and time, the deferred time update, the attitude, the origin
        and the flags: all of the estimator and its attitude but the configuration (checked
        by :meth:`thaw`) and the update machinery of :data:`_NOT_FROZEN`, taken at once (later
        updates do not change it). An estimator of the same configuration thawed from it
        answers :meth:`state`, :attr:`ready`, :attr:`mode` and the other queries of the
        outputs bit for bit as this one does now. ``marshal`` (a third of pickle's time), or
        pickle where a value is not a plain Python one (marshal writes a numpy scalar as its
        bytes).
        """
        pending_values = _PENDING_VALUES(self.pending)
        mine = _plain(self.__dict__, _NOT_FROZEN)
        attitude = _plain(vars(self.attitude), _NOT_FROZEN_ATTITUDE)
        parts = (mine, attitude, pending_values)
        if _marshals((*mine[0].values(), *attitude[0].values(), *pending_values)):
            return b'm' + marshal.dumps(parts)
        return b'p' + pickle.dumps(parts, protocol=pickle.HIGHEST_PROTOCOL)

    def thaw(self, frozen: bytes) -> None:
        """Take the state of a :meth:`freeze` (of an estimator of the same configuration)."""
        load = marshal.loads if frozen[:1] == b'm' else pickle.loads
        mine, attitude, pending = load(frozen[1:])
        if mine[0]['_config_serial'] != self._config_serial:
            raise ValueError('frozen with another configuration than this estimator has')
        _unplain(self, *mine)
        _unplain(self.attitude, *attitude)
        for name, value in zip(model.Pending.__slots__, pending):
            setattr(self.pending, name, value)

    @property
    def heading_offset(self) -> float:
        """Return the total heading correction (rad): declination plus the estimated offset."""
        lay = self.layout
        if lay.dpsi is None or not self.offset_ready:
            return self.declination
        return self.declination + float(self.x[lay.dpsi])

    @property
    def yaw_rate(self) -> float:
        """Return the body yaw rate r (rad/s, FRD; 0 when unknown) for the turning drift."""
        omega = self.attitude.omega
        return 0.0 if omega is None else omega[2]

    def _frozen(self) -> tuple[int, ...]:
        """
        Return the states held at their prior (no gain, no coupling, no noise).

        Until the heading offset is initialised the heading is unknown, so the velocity
        through the water says nothing about where the vessel goes: the offset, the current
        and the calibrations would only soak up the heading's error. They wait.
        """
        lay = self.layout
        if lay.dpsi is None or self.offset_ready:
            return ()
        held = [lay.dpsi]
        if lay.c is not None:
            held += [lay.c.start, lay.c.start + 1]
        held += [i for i in (lay.k, lay.lam, lay.kap) if i is not None]
        return tuple(held)

    def _consider(self) -> tuple[int, ...]:
        lay = self.layout
        return tuple(range(lay.l.start, lay.l.stop)) + self._frozen()

    def _yaw_variance(self) -> float | None:
        """Return the heading variance to use in the attitude share (None: the IMU's)."""
        return ATTITUDE_SHARE_MAX_VARIANCE if self._frozen() else None

    def _full_rotation(self) -> np.ndarray:
        """Return R(q) with the heading correction applied: Rz(o) R(q_IMU), 3x3."""
        o = self.heading_offset
        c, s = math.cos(o), math.sin(o)
        r = np.array(self.attitude.r9).reshape(3, 3)
        return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]) @ r

    def velocity_ned(self) -> np.ndarray:
        """Return the velocity over ground in NED (m/s)."""
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

    def state(self) -> NavState:
        """
        Return the current state for the outputs (call only when :attr:`ready`).

        A deferred time update is applied to copies: building outputs never changes the
        filter, so its result does not depend on when (or whether) outputs are built.
        """
        return self.staged_state()[1]()

    def staged_state(self) -> tuple[NavPose, Callable[[], NavState]]:
        """
        Return :meth:`state` in two stages: its :class:`NavPose` now, the rest when called.

        The odometry needs only the pose: a driver sends it before the course, the current,
        the geodetic position and the calibration are computed. The function returns the
        very :class:`NavState` that :meth:`state` returns; call it before the filter changes.
        """
        if self.pending.dt > 0.0:
            x, pm = self._pending_applied()
        else:
            x, pm = self.x.copy(), self.P.copy()
        lay = self.layout
        frozen = self._frozen()
        offset = self.heading_offset
        r9 = self.attitude.r9
        if offset == 0.0:                                      # no heading correction
            q_out, r_full = self.attitude.q, r9
        else:
            half = 0.5 * offset
            q_out = mul4((math.cos(half), 0.0, 0.0, math.sin(half)), self.attitude.q)
            r_full = rquat9(*q_out)                            # R(q) row-major
        rot = model.rotation_now(lay, r9, offset)
        yaw_rate = self.yaw_rate
        w = model.velocity_vector(x, lay, yaw_rate)
        nu, j_nu = model.body_velocity(x, lay, r9, offset, r=yaw_rate, w=w, rot=rot)
        if frozen:
            j_nu[:, list(frozen)] = 0.0
        cov_nu = j_nu @ pm @ j_nu.T
        if lay.horizontal:   # the heave σ along NED down, seen from BODY: σ² r rᵀ, r = R[2, :]
            r6, r7, r8 = r_full[6:9]
            s2 = SURFACE_HEAVE_SIGMA ** 2
            cov_nu += np.array([[r6 * r6 * s2, r6 * r7 * s2, r6 * r8 * s2],
                                [r7 * r6 * s2, r7 * r7 * s2, r7 * r8 * s2],
                                [r8 * r6 * s2, r8 * r7 * s2, r8 * r8 * s2]])
        cov_att = np.array(self.attitude.cov, dtype=float)
        if lay.dpsi is not None:
            cov_att[2, 2] += (UNKNOWN_ATTITUDE_SIGMA ** 2 if frozen
                              else float(pm[lay.dpsi, lay.dpsi]))
        p = self._p3(x, lay.p)
        p_local = self._p3(x, lay.l)
        cov_p = np.zeros((3, 3))
        cov_local = np.zeros((3, 3))
        d = lay.dim
        cov_p[0:d, 0:d] = pm[lay.p, lay.p]
        cov_local[0:d, 0:d] = pm[lay.l, lay.l]
        if d == 2:
            cov_p[2, 2] = cov_local[2, 2] = SURFACE_HEIGHT_SIGMA ** 2
        omega = (np.zeros(3) if self.attitude.omega is None
                 else np.array(self.attitude.omega))
        pose = NavPose(
            stamp_ns=self.t, mode=self.mode, origin=self.origin,  # type: ignore[arg-type]
            p=p, q=np.array(q_out), nu=nu, omega=omega, p_local=p_local, cov_p=cov_p,
            cov_att=cov_att, cov_nu=cov_nu, cov_omega=np.array(self.attitude.cov_omega),
            cov_p_local=cov_local)

        def complete() -> NavState:
            return self._completed(pose, x, pm, r9, r_full, rot, w)
        return pose, complete

    def _completed(self, pose: NavPose, x: np.ndarray, pm: np.ndarray, r9: Sequence[float],
                   r_full: Sequence[float], rot: np.ndarray,
                   w: tuple[np.ndarray, np.ndarray]) -> NavState:
        """Return the :class:`NavState` of ``pose``: course, sideslip, current, position."""
        lay, cfg = self.layout, self.config
        # ṗ = rot·w + c (model.position_rate without its Jacobian), NED, m/s.
        v_n = rot @ w[0]
        if lay.c is not None:
            v_n[0] += x[lay.c.start]
            v_n[1] += x[lay.c.start + 1]
        if lay.dim == 2:
            v_n = np.array([v_n[0], v_n[1], 0.0])
        # Course, sideslip (Fossen 2.4, the seed's sign: χ = ψ + β going ahead), α.
        psi = math.atan2(r_full[3], r_full[0])
        vn, ve = float(v_n[0]), float(v_n[1])
        speed = math.hypot(vn, ve)
        weight = _smoothstep(speed, cfg.course_min_speed)
        chi_raw = math.atan2(ve, vn) if speed > 0.0 else psi
        cps, sps = math.cos(psi), math.sin(psi)
        g_u, g_v = cps * vn + sps * ve, -sps * vn + cps * ve
        beta_raw = math.atan2(g_v, abs(g_u)) if speed > 0.0 else 0.0
        course = float(flow.ssa(psi + weight * float(flow.ssa(chi_raw - psi))))
        sideslip = weight * beta_raw
        alpha = weight * float(flow.angle_of_attack(pose.nu.tolist()))
        current = cov_current = relative = None
        if lay.c is not None:
            current = np.array([x[lay.c.start], x[lay.c.start + 1], 0.0])
            cov_current = np.zeros((3, 3))
            cov_current[0:2, 0:2] = pm[lay.c, lay.c]
            w_r = w[0]
            # ν_r: w itself (free) or seen from BODY, R_tiltᵀ [w; 0] (model.body_velocity
            # through the water, without its Jacobian).
            if lay.horizontal:
                t = tilt_of(r9)
                u_r, v_r = w_r.tolist()
                nu_r = [t[0] * u_r + t[3] * v_r, t[1] * u_r + t[4] * v_r,
                        t[2] * u_r + t[5] * v_r]
            else:
                nu_r = w_r.tolist()
            speed_r = math.sqrt(nu_r[0] ** 2 + nu_r[1] ** 2 + nu_r[2] ** 2)
            weight_r = _smoothstep(speed_r, cfg.course_min_speed)
            beta_r = (math.atan2(float(w_r[1]), abs(float(w_r[0]))) if lay.horizontal
                      else float(flow.sideslip(nu_r)))
            alpha_r = float(flow.angle_of_attack(nu_r))
            relative = RelativeFlow(speed_r, weight_r * beta_r, weight_r * alpha_r)
        return NavState(
            **vars(pose), v_n=v_n, current=current, llh=self.to_llh(pose.p), course=course,
            sideslip=sideslip, angle_of_attack=alpha, cov_current=cov_current,
            low_speed=weight < 1.0, calibration=self.calibration(x, pm), relative_flow=relative)

    # ------------------------------------------------------------------ time update

    def _time(self, stamp_ns: int, q_end: tuple | None = None) -> float | Rejection:
        """
        Bring the state to ``stamp_ns``; return how late the message is (s) or a rejection.

        0.0 for a message at or after the state's time (now propagated to it); the lateness
        in (0, reorder_window] for a message to use at the state's time; a reset for one more
        than ``max_gap`` back.
        """
        if stamp_ns <= 0:
            return Rejection(Reason.ZERO_STAMP, 'header stamp is zero: the driver does not stamp')
        if self.t is None:
            self.t = stamp_ns
            if q_end is not None:
                self.attitude.set_q(q_end)
            return 0.0
        if stamp_ns >= self.t:
            self._propagate(stamp_ns, q_end)
            return 0.0
        late = (self.t - stamp_ns) * 1e-9
        if late <= self.config.reorder_window:
            return late
        if late > self.config.max_gap:
            self.reset()
            self.t = stamp_ns
            if q_end is not None:
                self.attitude.set_q(q_end)
            return 0.0
        return Rejection(Reason.STALE_STAMP,
                         f'stamp {late:.3f} s older than the state, beyond '
                         f'reorder_window {self.config.reorder_window} s')

    def reset(self) -> None:
        """Re-initialise the state (time went backwards: a bag looped); keep the origin."""
        self.resets += 1
        self._init_state()

    def _propagate(self, t1: int, q_end: tuple | None) -> None:
        """Advance the attitude and the deferred time update from ``self.t`` to ``t1``."""
        dt = (t1 - self.t) * 1e-9  # type: ignore[operator]
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
        r0, cs0 = att.r9, att.cs
        if q_end is not None:
            att.set_q(q_end)
        elif integrating:
            att.set_q(att.integrate(dt))
        self.pending.add(dt, r0, att.r9, cs0, att.cs)
        if self.pending.dt >= LAZY_INTERVAL:
            self._flush()

    def _flush(self) -> None:
        """Apply the deferred time update to the state."""
        if self.pending.dt > 0.0:
            self.x, self.P = self._pending_applied()
            self.pending = model.Pending(self.layout.horizontal)

    def _pending_applied(self) -> tuple[np.ndarray, np.ndarray]:
        """Return x and P after the deferred interval (new arrays)."""
        pending = self.pending
        a_rot = pending.rotation(self.layout, self.heading_offset)
        return model.propagate(self.x, self.P, self.layout, a_rot, pending.dt,
                               self.attitude.cov, self._yaw_variance(), self._frozen(),
                               self.yaw_rate)

    def _inflate_gap(self, dt: float, integrating: bool) -> None:
        """Advance over a gap without integrating: widen the position by what it could move."""
        lay = self.layout
        v_n = self.velocity_ned()
        speed2 = float(v_n @ v_n) + float(np.trace(self.P[lay.v, lay.v]))
        if lay.c is not None:
            speed2 += float(np.trace(self.P[lay.c, lay.c]))
        grow = np.eye(lay.dim) * (speed2 * dt * dt)
        for rows in (lay.p, lay.l):
            for cols in (lay.p, lay.l):
                self.P[rows, cols] += grow
        for i, phi, var, rest in model.markov_steps(lay, dt):
            if i in self._frozen():
                continue
            self.x[i] = rest + phi * (self.x[i] - rest)
            self.P[i, :] *= phi
            self.P[:, i] *= phi
            self.P[i, i] += var
        if integrating:
            self.attitude.grow(dt)

    # ------------------------------------------------------------------ measurement updates

    def _plausible(self, x: np.ndarray) -> bool:
        """Return True when a state is physically possible (speeds, position, scale)."""
        lay = self.layout
        if float(np.abs(x[lay.v]).max()) > MAX_STATE_SPEED:
            return False
        if float(np.abs(x[lay.p]).max()) > MAX_STATE_POSITION:
            return False
        if lay.c is not None and float(np.abs(x[lay.c]).max()) > MAX_STATE_SPEED:
            return False
        return lay.k is None or 0.05 < float(x[lay.k]) < 20.0

    def _accept(self, x: np.ndarray, pm: np.ndarray, what: str) -> Rejection | None:
        if not self._plausible(x):
            return Rejection(Reason.IMPLAUSIBLE_STATE,
                             f'{what} would give a physically impossible state; state kept')
        self.x, self.P = x, pm
        return None

    def fix(self, m: GnssFix) -> Rejection | None:
        """Fold in a GNSS fix; set the origin from it when there is none yet."""
        if not (math.isfinite(m.lat) and math.isfinite(m.lon) and _finite(m.cov_ned)):
            return Rejection(Reason.NAN_FIELD, 'fix with a non-finite position or covariance')
        if math.isinf(m.height):
            return Rejection(Reason.NAN_FIELD, 'fix with an infinite height')
        late = self._time(m.stamp_ns)
        if isinstance(late, Rejection):
            return late
        self._flush()
        lay, cfg = self.layout, self.config
        horizontal = math.isnan(m.height) or lay.horizontal
        if self.origin is None:
            self._origin_from_fix(m)
        self.last_fix_ns = m.stamp_ns if self.last_fix_ns is None else max(
            self.last_fix_ns, m.stamp_ns)
        height = m.height
        if math.isnan(height):
            height = self.origin[2] - (  # type: ignore[index]
                float(self.x[lay.p.start + 2]) if lay.dim == 3 and self.position_ok else 0.0)
        p_antenna = self.to_ned(m.lat, m.lon, height)
        lever_b = np.array(cfg.antenna_b if m.lever_b is None else m.lever_b)
        rot_full = self._full_rotation()
        if lever_b.any():
            lever = rot_full @ lever_b
            z = p_antenna - lever
            # A small body-axis attitude error d moves the antenna by -S(R r_b) R d (m).
            s_lever = _skew(lever) @ rot_full
            att_cov = np.array(self.attitude.cov, dtype=float)
            if self._frozen():
                att_cov[2, 2] = max(att_cov[2, 2], ATTITUDE_SHARE_MAX_VARIANCE)
            r = m.cov_ned + s_lever @ att_cov @ s_lever.T
        else:
            z = p_antenna
            r = np.array(m.cov_ned, dtype=float)
        rows = 2 if horizontal else 3
        if not self.position_ok:
            cov = r.copy()
            if horizontal and lay.dim == 3:
                cov[2, :] = 0.0
                cov[:, 2] = 0.0
                cov[2, 2] = cfg.gnss_default_sigma ** 2
                z[2] = 0.0
            self._init_position(z, cov)
            return None
        if not cfg.gnss_enabled:
            return None
        h = model.fix_jacobian(lay, rot_full, lever_b, rows)
        for i in self._frozen():
            h[:, i] = 0.0
        y = z[0:rows] - self.x[lay.p][0:rows]
        if late > 0.0:
            # Compare against the position predicted back to the fix's stamp: p - ṗ late.
            rot = model.rotation_now(lay, self.attitude.r9, self.heading_offset)
            pdot, j = model.position_rate(self.x, lay, rot, r=self.yaw_rate)
            y = y + late * pdot[0:rows]
            h = h - late * j[0:rows]
        res = update(self.x, self.P, y, h, r[0:rows, 0:rows], gate=cfg.gnss_gate_sigma,
                     consider=self._consider())
        if res is None:
            return Rejection(Reason.NUMERICAL, 'fix update was not finite; state kept')
        if res.distance < 0.0:
            if self._gate_streak == 0:
                self._gate_first_ns = m.stamp_ns
            self._gate_streak += 1
            if (self._gate_streak >= GATE_RESET_COUNT
                    or (m.stamp_ns - self._gate_first_ns) * 1e-9 >= GATE_RESET_TIME):
                self._recover_position(z, r)
                return None
            return Rejection(Reason.INNOVATION_GATE,
                             f'fix {-res.distance:.1f} sigma from the estimate, beyond '
                             f'gate_sigma {cfg.gnss_gate_sigma}')
        self._gate_streak = 0
        rejection = self._accept(res.x, res.p, 'fix')
        if rejection is None and lay.dpsi is not None and not self.offset_ready:
            self._observe_offset(m.stamp_ns, z)
        return rejection

    def _recover_position(self, z: np.ndarray, r: np.ndarray) -> None:
        """Re-initialise the position from a fix after a run of gated fixes (counted)."""
        lay = self.layout
        self.recoveries += 1
        self._init_position(z, r)
        v = lay.v
        self.P[v, :] = 0.0
        self.P[:, v] = 0.0
        self.P[v, v] = np.eye(lay.dim) * INITIAL_VELOCITY_SIGMA ** 2

    def _observe_offset(self, stamp_ns: int, z: np.ndarray) -> None:
        """Collect fixes and IMU headings; initialise the heading offset once possible."""
        lay = self.layout
        if not self.attitude.known:
            return
        psi = heading_of(self.attitude.r9)
        c, s = math.cos(self.declination), math.sin(self.declination)
        psi = (psi[0] * c - psi[1] * s, psi[1] * c + psi[0] * s)
        self._offset_init.add(stamp_ns * 1e-9, float(z[0]), float(z[1]), psi, self.last_surge)
        guess = self._offset_init.course_minus_heading()
        if guess is None:
            return
        i = lay.dpsi
        self.x[i] = guess
        self.P[i, :] = 0.0
        self.P[:, i] = 0.0
        self.P[i, i] = OFFSET_INIT_SIGMA ** 2
        self.offset_ready = True

    def _origin_from_fix(self, m: GnssFix) -> None:
        lat, lon, h = self.config.origin
        if math.isnan(lat):
            lat_r, lon_r = m.lat, m.lon
        else:
            lat_r, lon_r = math.radians(lat), math.radians(_wrap_lon_deg(lon))
        if math.isnan(h):
            h = 0.0 if math.isnan(m.height) else m.height
        self.origin = (float(lat_r), float(lon_r), float(h))
        self._origin_event = True
        self._update_declination(m.stamp_ns)

    def imu(self, m: ImuSample) -> Rejection | None:
        """Fold in an attitude and/or body rate."""
        q_nb, omega_b = m.q_nb, m.omega_b
        if q_nb is not None:
            q_nb = floats(q_nb)
        if omega_b is not None:
            omega_b = floats(omega_b)
        att_nonzero: bool | None = False
        omega_nonzero: bool | None = False
        if not _finite(q_nb, omega_b):
            return Rejection(Reason.NAN_FIELD, 'IMU sample with a non-finite field')
        if m.att_cov is not None:
            att_nonzero = self._checked.check(m.att_cov)
        if m.omega_cov is not None:
            omega_nonzero = self._checked.check(m.omega_cov)
        if att_nonzero is None or omega_nonzero is None:
            return Rejection(Reason.NAN_FIELD, 'IMU sample with a non-finite field')
        att = self.attitude
        q_meas = None
        if q_nb is not None and self.config.use_orientation:
            q_meas = yaw_only(q_nb) if att.level else q_nb
            if att.last_attitude_ns is not None and m.stamp_ns < att.last_attitude_ns:
                q_meas = None  # an older attitude than the one in use
        late = self._time(m.stamp_ns, q_meas)
        if isinstance(late, Rejection):
            return late
        if q_meas is not None:
            att.measured(q_meas, _readonly(m.att_cov) if att_nonzero else None, m.stamp_ns)
        if omega_b is not None:
            att.rate(m.stamp_ns, omega_b, _readonly(m.omega_cov) if omega_nonzero else None)
            att.omega_from_imu = True
        self.last_imu_ns = m.stamp_ns if self.last_imu_ns is None else max(
            self.last_imu_ns, m.stamp_ns)
        return None

    def velocity(self, m: BodyVelocity) -> Rejection | None:
        """Fold in a body velocity: over ground or through water, per the reference."""
        if (not _finite(m.nu_b, m.omega_b) or self._checked.check(m.cov) is None
                or (m.omega_cov is not None and self._checked.check(m.omega_cov) is None)):
            return Rejection(Reason.NAN_FIELD, 'velocity with a non-finite field')
        late = self._time(m.stamp_ns)
        if isinstance(late, Rejection):
            return late
        self._flush()
        cfg, lay, att = self.config, self.layout, self.attitude
        self.last_velocity_ns = m.stamp_ns if self.last_velocity_ns is None else max(
            self.last_velocity_ns, m.stamp_ns)
        now = self.t if self.t is not None else m.stamp_ns
        if (m.omega_b is not None
                and not (att.omega_from_imu and att.rates_fresh(now, cfg.max_gap))
                and (m.omega_cov is None or m.omega_cov[2][2] < UNMEASURED_VARIANCE)):
            nonzero = m.omega_cov is not None and bool(np.any(m.omega_cov))
            att.rate(m.stamp_ns, floats(m.omega_b), _readonly(m.omega_cov) if nonzero else None)
            att.omega_from_imu = False
        if not cfg.velocity_input:
            return None
        cov = np.asarray(m.cov, dtype=float).tolist()
        rows = [i for i in range(3) if cov[i][i] < UNMEASURED_VARIANCE
                and not (att.level and i == 2)]
        nu = np.asarray(m.nu_b, dtype=float).tolist()
        self.last_surge = nu[0] if 0 in rows else self.last_surge
        if not rows:
            return None
        x_lin = self.x
        z = np.array([nu[i] for i in rows])
        h_x, h = model.velocity_measurement(x_lin, lay, att.r9, rows, self.yaw_rate)
        if not self._velocity_known:
            # The first velocity: linearise where the mean already explains it. At the prior's
            # zero velocity z = k·u says nothing of the scale k (∂h/∂k = u = 0), and an update
            # there would make u look known regardless of k, then the next one would pin k.
            step = np.linalg.lstsq(h[:, lay.v], z - h_x, rcond=None)[0]
            x_lin = self.x.copy()
            x_lin[lay.v] += step
            h_x, h = model.velocity_measurement(x_lin, lay, att.r9, rows, self.yaw_rate)
        for i in self._frozen():
            h[:, i] = 0.0
        y = z - h_x
        r = np.array([[cov[i][j] + _TINY_VARIANCE if i == j else cov[i][j] + 0.0 for j in rows]
                      for i in rows])
        # The first velocity meets an arbitrary prior: no gate until one was taken.
        gate = cfg.velocity_gate_sigma if self._velocity_known else 0.0
        res = update(x_lin, self.P, y, h, r, gate=gate, consider=self._consider())
        if res is not None and res.distance < 0.0:
            self._velocity_gate_streak += 1
            if self._velocity_gate_streak < VELOCITY_GATE_RESET_COUNT:
                return Rejection(Reason.INNOVATION_GATE,
                                 f'velocity {-res.distance:.1f} sigma from the estimate, '
                                 f'beyond gate_sigma {cfg.velocity_gate_sigma}')
            # A run of refused velocities: the estimate is what is wrong. Widen and take it.
            self.recoveries += 1
            pm = self.P.copy()
            pm[lay.v, :] = 0.0
            pm[:, lay.v] = 0.0
            pm[lay.v, lay.v] = np.eye(lay.dim) * INITIAL_VELOCITY_SIGMA ** 2
            res = update(self.x, pm, y, h, r, consider=self._consider())
        if res is None:
            return Rejection(Reason.NUMERICAL, 'velocity update was not finite; state kept')
        self._velocity_gate_streak = 0
        rejection = self._accept(res.x, res.p, 'velocity')
        self._velocity_known = self._velocity_known or rejection is None
        return rejection

    # ------------------------------------------------------------------ configuration

    def set_config(self, config: FilterConfig) -> bool:
        """
        Apply a new configuration at run time; return True when the origin changed.

        A new origin or projection re-expresses the position through latitude, longitude and
        height, so the estimated geographic position does not move. A configuration that
        changes the state (motion, velocity reference, estimated calibrations) rebuilds the
        filter keeping the position, the local position and the velocity over ground; the
        new states start from their priors.
        """
        old = self.config
        self._flush()
        llh = self.to_llh(self._p3(self.x, self.layout.p)) if self.ready else None
        self.config = config
        self._config_serial += 1
        if StateLayout.of(config) != self.layout or config.level != old.level:
            self._relayout()
        self.attitude.level = config.level
        self.attitude.integrator = config.integrator
        changed = self._set_origin_from_config(config)
        if changed:
            self._update_declination(self.t or 0)
        elif (config.declination is None) != (old.declination is None):
            self._update_declination(self.t or 0)
        if llh is not None and (changed or config.projection != old.projection):
            self.x[self.layout.p] = self.to_ned(*llh)[0:self.layout.dim]
        if self.origin is not None and not config.gnss_enabled and not self.position_ok:
            self._init_position(np.zeros(3), np.zeros((3, 3)))
        return changed

    def _relayout(self) -> None:
        """Rebuild the state for a new layout, keeping position, local and ground velocity."""
        old_lay, x, pm = self.layout, self.x, self.P
        v_n = self.velocity_ned() if self.position_ok else np.zeros(3)
        keep = (self.t, self.position_ok, self.attitude, self.last_fix_ns, self.last_imu_ns,
                self.last_velocity_ns)
        self._init_state()
        (self.t, self.position_ok, self.attitude, self.last_fix_ns, self.last_imu_ns,
         self.last_velocity_ns) = keep
        lay = self.layout
        d = min(lay.dim, old_lay.dim)
        for new_b, old_b in ((lay.p, old_lay.p), (lay.l, old_lay.l)):
            self.x[new_b.start:new_b.start + d] = x[old_b.start:old_b.start + d]
        for nb1, ob1 in ((lay.p, old_lay.p), (lay.l, old_lay.l)):
            for nb2, ob2 in ((lay.p, old_lay.p), (lay.l, old_lay.l)):
                self.P[nb1.start:nb1.start + d, nb2.start:nb2.start + d] = (
                    pm[ob1.start:ob1.start + d, ob2.start:ob2.start + d])
        rot = model.rotation_now(lay, self.attitude.r9, self.heading_offset)
        v = rot.T @ v_n[0:lay.dim]
        self.x[lay.v] = v

    def set_params(self, config: FilterConfig) -> bool:
        """Alias of :meth:`set_config` (the pipeline's name for it)."""
        return self.set_config(config)


def _readonly(cov: Any) -> np.ndarray:
    """Return a covariance as an array, shared when it is already a read-only one."""
    if isinstance(cov, np.ndarray) and not cov.flags.writeable:
        return cov
    return np.array(cov, dtype=float)
