"""
A navigator run as numpy data, and its scores: data in, numbers out (no figure, no driver).

Everything here works from the navigator's outputs (``/odometry``, ``/course_sideslip``,
``/current``, ``/fix/filtered``, ``/origin``), whether the offline replay wrote them or a live
node's outputs were recorded, plus what else the bag or the messages hold:

- the GNSS fixes (the ``fix`` input topic, default ``/fix``), as ENU about the origin;
- ground truth from the simulator, when present:

  * ``/truth/odometry`` nav_msgs/Odometry, pose ENU (m) about ``/truth/origin`` (a NavSatFix)
    when the bag holds one, otherwise about the navigator's own ``/origin``; orientation
    ENU/FLU as REP-103; twist in the child frame;
  * ``/truth/course_sideslip`` geometry_msgs/Vector3Stamped: x = course χ, y = sideslip β (rad);
  * ``/truth/current`` geometry_msgs/Vector3Stamped: the current, ENU, m/s;

- a receiver's own course and speed over ground (``/gnss/cog_sog`` Vector3Stamped, x = COG
  rad from north clockwise, y = SOG m/s) to compare the estimated course with.

:func:`run_from_messages` turns {topic: [(stamp ns, message)]} (e.g. from
:func:`vessel_kinematics.tools.replay.replay_in_memory`) into a :class:`Run` of numpy time
series; :func:`load_run` does the same for bags, read through
:func:`vessel_kinematics.tools.bags.read_topics`. :func:`accuracy` scores a run against truth
(RMS and max of the errors of position, heading, course, sideslip and current),
:func:`course_vs_reference` against a receiver's COG, :func:`format_accuracy` makes the table.
``replay.dead_reckoning_run`` replays the bag's inputs again with ``gnss.enabled: false`` for
the dead-reckoning-only comparison, ``replay.accuracy_report`` is the whole accuracy paragraph
in one call (the replay runs the second replay: this module imports no driver);
:mod:`vessel_kinematics.tools.plot` draws the figure (matplotlib lives there alone).

Angles are radians inside, degrees in the text; heading ψ, course χ and sideslip β follow
Fossen (from north, clockwise; χ = ψ + β).
"""

from __future__ import annotations

from dataclasses import dataclass, field
import math
from pathlib import Path
from typing import Any, Iterable, Mapping, Sequence

import numpy as np
from vessel_kinematics.core import frames, geodesy
from vessel_kinematics.core.flow import ssa
from vessel_kinematics.ros import interface
from vessel_kinematics.tools.bags import read_topics

__all__ = ['accuracy', 'COG_SOG_TOPIC', 'course_vs_reference', 'ErrorStats', 'format_accuracy',
           'load_run', 'MIN_SPEED', 'OUTPUT_TOPICS', 'reference_line', 'Run',
           'run_from_messages', 'Series', 'speed_vs_reference', 'TRUTH_TOPICS']

#: Truth topics written by the simulator (the interface table's truth rows).
TRUTH_TOPICS = tuple(t.absolute for t in interface.by_role(interface.Role.TRUTH))
#: The receiver's own course and speed over ground, a reference for the course.
COG_SOG_TOPIC = interface.topic('/gnss/cog_sog').absolute
#: Navigator outputs read into a :class:`Run`.
OUTPUT_TOPICS = tuple(interface.topic(name).absolute for name in (
    'odometry', 'odometry/local', 'course_sideslip', 'current', 'fix/filtered', 'origin'))
#: Course and sideslip are scored only where the speed over ground is at least this (m/s).
MIN_SPEED = 0.5


def _yaw_enu(q: Any) -> float:
    """Return the ENU yaw (rad, counter-clockwise from east) of a geometry_msgs/Quaternion."""
    return float(frames.yaw_from_ros((q.x, q.y, q.z, q.w)))


def _heading(yaw_enu: Any) -> Any:
    """Return the heading ψ (rad, clockwise from north) of an ENU yaw (REP-103)."""
    return ssa(np.pi / 2 - np.asarray(yaw_enu))


def _stamp(msg: Any) -> float:
    return msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9


@dataclass
class Series:
    """Samples of named quantities at times ``t`` (s, bag time), all numpy arrays."""

    t: np.ndarray
    values: dict[str, np.ndarray] = field(default_factory=dict)

    def __getitem__(self, name: str) -> np.ndarray:
        """Return the samples of ``name``."""
        return self.values[name]

    def __len__(self) -> int:
        """Return the number of samples."""
        return len(self.t)

    @classmethod
    def of(cls, rows: list[tuple[float, ...]], names: Sequence[str]) -> Series:
        """Build from rows (t, value...)."""
        if not rows:
            return cls(np.zeros(0), {n: np.zeros(0) for n in names})
        data = np.asarray(rows, dtype=float)
        order = np.argsort(data[:, 0], kind='stable')
        data = data[order]
        return cls(data[:, 0], {n: data[:, i + 1] for i, n in enumerate(names)})


@dataclass
class Run:
    """
    A navigator run as time series (t in s of bag time; positions ENU m about ``origin``).

    ``odometry``: east, north, up, heading (rad), speed (m/s, horizontal body velocity),
    sigma_h (m, horizontal position standard deviation), w (heave, m/s); ``course_sideslip``:
    chi, beta;
    ``current``: east, north; ``fixes``: east, north (the GNSS input); ``truth``: east, north,
    heading, speed; ``truth_course_sideslip``: chi, beta; ``truth_current``: east, north;
    ``cog_sog``: cog, sog.
    """

    origin: tuple[float, float, float] | None
    odometry: Series
    local: Series
    course_sideslip: Series
    current: Series
    fixes: Series
    fix_filtered: Series
    truth: Series | None = None
    truth_course_sideslip: Series | None = None
    truth_current: Series | None = None
    cog_sog: Series | None = None
    label: str = 'fused'

    @property
    def has_truth(self) -> bool:
        """Return whether the run carries simulator truth."""
        return self.truth is not None and len(self.truth) > 1

    @property
    def t0(self) -> float:
        """Return the first output time (s), the origin of the figure's time axes."""
        candidates = [s.t[0] for s in (self.odometry, self.fixes) if len(s)]
        return min(candidates) if candidates else 0.0


def _enu_of(lat: np.ndarray, lon: np.ndarray, h: np.ndarray,
            origin: tuple[float, float, float]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Return ENU (m) about ``origin`` (deg, deg, m) of geodetic points (deg, deg, m)."""
    if len(lat) == 0:
        return np.zeros(0), np.zeros(0), np.zeros(0)
    lat0, lon0, h0 = origin
    h = np.where(np.isfinite(h), h, h0 if math.isfinite(h0) else 0.0)
    ned = np.asarray(geodesy.llh2ned(np.radians(lat), np.radians(lon), h, math.radians(lat0),
                                     math.radians(lon0), h0 if math.isfinite(h0) else 0.0))
    ned = ned.reshape(-1, 3)
    return ned[:, 1], ned[:, 0], -ned[:, 2]


def run_from_messages(messages: Mapping[str, Iterable[tuple[int, Any]]],
                      fix_topic: str = '/fix', label: str = 'fused') -> Run:
    """
    Build a :class:`Run` from {topic: [(stamp ns, message)]}.

    The messages may be rclpy instances or rosbags' (same field names).
    """
    def rows(topic: str) -> list[Any]:
        return [m for _, m in messages.get(topic, ())]

    origin_msgs = rows('/origin')
    origin = None
    if origin_msgs:
        o = origin_msgs[-1]
        origin = (o.latitude, o.longitude, o.altitude)

    odometry = Series.of([
        (_stamp(m), m.pose.pose.position.x, m.pose.pose.position.y, m.pose.pose.position.z,
         float(_heading(_yaw_enu(m.pose.pose.orientation))),
         math.hypot(m.twist.twist.linear.x, m.twist.twist.linear.y),
         math.sqrt(max(m.pose.covariance[0] + m.pose.covariance[7], 0.0)),
         m.twist.twist.linear.z)
        for m in rows('/odometry')],
        ('east', 'north', 'up', 'heading', 'speed', 'sigma_h', 'w'))
    local = Series.of([(_stamp(m), m.pose.pose.position.x, m.pose.pose.position.y)
                       for m in rows('/odometry/local')], ('east', 'north'))
    course_sideslip = Series.of([(_stamp(m), m.vector.x, m.vector.y, m.vector.z)
                                 for m in rows('/course_sideslip')], ('chi', 'beta', 'alpha'))
    current = Series.of([(_stamp(m), m.vector.x, m.vector.y) for m in rows('/current')],
                        ('east', 'north'))
    fix_filtered = Series.of([(_stamp(m), m.latitude, m.longitude, m.altitude)
                              for m in rows('/fix/filtered')], ('lat', 'lon', 'h'))
    raw_fixes = [(_stamp(m), m.latitude, m.longitude, m.altitude) for m in rows(fix_topic)
                 if m.status.status >= 0 and math.isfinite(m.latitude)
                 and math.isfinite(m.longitude) and abs(m.latitude) <= 90.0]
    fixes = Series.of([], ('east', 'north', 'up'))
    if raw_fixes and origin is not None:
        data = np.asarray(raw_fixes, dtype=float)
        east, north, up = _enu_of(data[:, 1], data[:, 2], data[:, 3], origin)
        fixes = Series(data[:, 0], {'east': east, 'north': north, 'up': up})

    run = Run(origin=origin, odometry=odometry, local=local, course_sideslip=course_sideslip,
              current=current, fixes=fixes, fix_filtered=fix_filtered, label=label)

    truth_odometry = rows('/truth/odometry')
    if truth_odometry:
        truth = Series.of([
            (_stamp(m), m.pose.pose.position.x, m.pose.pose.position.y, m.pose.pose.position.z,
             float(_heading(_yaw_enu(m.pose.pose.orientation))),
             math.hypot(m.twist.twist.linear.x, m.twist.twist.linear.y))
            for m in truth_odometry], ('east', 'north', 'up', 'heading', 'speed'))
        truth_origin = rows('/truth/origin')
        if truth_origin and origin is not None:
            o = truth_origin[-1]
            # Truth ENU about its own origin -> geodetic -> ENU about the navigator's origin.
            ned = np.stack([truth['north'], truth['east'], -truth['up']], axis=-1)
            lat, lon, h = geodesy.ned2llh(ned, math.radians(o.latitude),
                                          math.radians(o.longitude), o.altitude)
            east, north, up = _enu_of(np.degrees(lat), np.degrees(lon), np.asarray(h), origin)
            truth.values.update(east=east, north=north, up=up)
        run.truth = truth
    truth_cs = rows('/truth/course_sideslip')
    if truth_cs:
        run.truth_course_sideslip = Series.of([(_stamp(m), m.vector.x, m.vector.y)
                                               for m in truth_cs], ('chi', 'beta'))
    truth_current = rows('/truth/current')
    if truth_current:
        run.truth_current = Series.of([(_stamp(m), m.vector.x, m.vector.y)
                                       for m in truth_current], ('east', 'north'))
    cog = rows(COG_SOG_TOPIC)
    if cog:
        run.cog_sog = Series.of([(_stamp(m), m.vector.x, m.vector.y) for m in cog],
                                ('cog', 'sog'))
    return run


def load_run(bag: str | Path, fix_topic: str = '/fix',
             fixes_bag: str | Path | None = None, label: str = 'fused') -> Run:
    """
    Read a :class:`Run` from an output bag (replay output or a recording of the live node).

    ``fixes_bag`` is read for the fixes, truth and reference topics that ``bag`` lacks (e.g.
    the replay's input when it ran with ``--no-copy-inputs``).
    """
    bags = [bag] + ([fixes_bag] if fixes_bag is not None else [])
    topics = set(OUTPUT_TOPICS) | set(TRUTH_TOPICS) | {COG_SOG_TOPIC, fix_topic}
    return run_from_messages(read_topics(bags, topics), fix_topic=fix_topic, label=label)


# ---------------------------------------------------------------------------------------------
# Scores


@dataclass(frozen=True)
class ErrorStats:
    """RMS and maximum absolute error over ``n`` samples (unit of the quantity)."""

    rms: float
    maximum: float
    mean: float
    n: int


def _stats(error: np.ndarray) -> ErrorStats | None:
    error = np.asarray(error, dtype=float)
    error = error[np.isfinite(error)]
    if error.size == 0:
        return None
    return ErrorStats(rms=float(np.sqrt(np.mean(error ** 2))),
                      maximum=float(np.max(np.abs(error))), mean=float(np.mean(error)),
                      n=int(error.size))


def _interp(t: np.ndarray, ts: np.ndarray, values: np.ndarray, angle: bool = False,
            ) -> np.ndarray:
    """Interpolate ``values`` at ``ts`` onto ``t`` (NaN outside), angles through unwrapping."""
    if len(ts) < 2:
        return np.full(len(t), np.nan)
    v = np.unwrap(values) if angle else values
    out = np.interp(t, ts, v)
    out[(t < ts[0]) | (t > ts[-1])] = np.nan
    return ssa(out) if angle else out


def accuracy(run: Run) -> dict[str, ErrorStats | None] | None:
    """
    Score a run against truth: position (horizontal, m), heading, course, sideslip (rad), current.

    Truth is interpolated to the estimate's stamps; course and sideslip are scored where the
    true speed is at least :data:`MIN_SPEED`; current as the magnitude of the vector error
    (m/s). Return None when the run has no truth.
    """
    truth = run.truth
    if truth is None:
        return None
    scores: dict[str, ErrorStats | None] = {}
    odo = run.odometry
    east = _interp(odo.t, truth.t, truth['east'])
    north = _interp(odo.t, truth.t, truth['north'])
    scores['position'] = _stats(np.hypot(odo['east'] - east, odo['north'] - north))
    scores['heading'] = _stats(ssa(odo['heading'] - _interp(odo.t, truth.t, truth['heading'],
                                                            angle=True)))
    cs = run.course_sideslip
    tcs = run.truth_course_sideslip
    if tcs is not None and len(cs):
        fast = _interp(cs.t, truth.t, truth['speed']) >= MIN_SPEED
        chi = ssa(cs['chi'] - _interp(cs.t, tcs.t, tcs['chi'], angle=True))
        beta = ssa(cs['beta'] - _interp(cs.t, tcs.t, tcs['beta'], angle=True))
        scores['course'] = _stats(np.where(fast, chi, np.nan))
        scores['sideslip'] = _stats(np.where(fast, beta, np.nan))
    else:
        scores['course'] = scores['sideslip'] = None
    tc = run.truth_current
    if tc is not None and len(run.current):
        cur = run.current
        scores['current'] = _stats(np.hypot(cur['east'] - _interp(cur.t, tc.t, tc['east']),
                                            cur['north'] - _interp(cur.t, tc.t, tc['north'])))
    else:
        scores['current'] = None
    return scores


def course_vs_reference(run: Run, min_sog: float = 1.0,
                        lag: float = 0.0) -> dict[str, float] | None:
    """
    Compare the estimated course with a receiver's COG (``/gnss/cog_sog``) where SOG ≥ min_sog.

    Return (degrees, n samples) ``{'n', 'mean', 'rms', 'max', 'mean_abs'}`` of χ − COG, and
    ``'cog_minus_heading'`` (mean of COG − ψ: the reference's sideslip) beside ``'beta'`` (mean
    of our β), ``'beta_mean_abs'`` the mean of |β − (COG − ψ)|: with χ = ψ + β, the two agree
    when course and heading do. ``lag`` (s): the receiver's COG describes the motion this long
    before its stamp (receivers filter their velocity); our values are taken at t − lag. None
    without reference.
    """
    ref = run.cog_sog
    cs = run.course_sideslip
    if ref is None or len(ref) == 0 or len(cs) < 2:
        return None
    keep = (ref['sog'] >= min_sog) & (ref.t >= cs.t[0]) & (ref.t <= cs.t[-1])
    if not np.any(keep):
        return None
    t = ref.t[keep] - lag
    chi = _interp(t, cs.t, cs['chi'], angle=True)
    beta = _interp(t, cs.t, cs['beta'], angle=True)
    psi = _interp(t, run.odometry.t, run.odometry['heading'], angle=True)
    diff = np.degrees(ssa(chi - ref['cog'][keep]))
    stats = _stats(diff)
    assert stats is not None
    ref_beta = ssa(ref['cog'][keep] - psi)
    return {'n': stats.n, 'mean': stats.mean, 'rms': stats.rms, 'max': stats.maximum,
            'mean_abs': float(np.nanmean(np.abs(diff))),
            'cog_minus_heading': float(np.degrees(np.nanmean(ref_beta))),
            'beta': float(np.degrees(np.nanmean(beta))),
            'beta_mean_abs': float(np.degrees(np.nanmean(np.abs(ssa(beta - ref_beta)))))}


def speed_vs_reference(run: Run, min_sog: float = 1.0) -> dict[str, float] | None:
    """
    Compare the estimated speed over ground with a receiver's SOG where SOG ≥ ``min_sog``.

    Return ``{'n', 'mean', 'rms', 'max'}`` of speed − SOG (m/s), None without reference.
    """
    ref = run.cog_sog
    odo = run.odometry
    if ref is None or len(ref) == 0 or len(odo) < 2:
        return None
    keep = (ref['sog'] >= min_sog) & (ref.t >= odo.t[0]) & (ref.t <= odo.t[-1])
    if not np.any(keep):
        return None
    stats = _stats(_interp(ref.t[keep], odo.t, odo['speed']) - ref['sog'][keep])
    assert stats is not None
    return {'n': stats.n, 'mean': stats.mean, 'rms': stats.rms, 'max': stats.maximum}


def reference_line(run: Run, min_sog: float = 1.0, fused: bool = False) -> str | None:
    """
    Return the replay summary's line: course and speed against the receiver's COG/SOG.

    ``fused``: a receiver's velocity was an input (a marine log's ``/vel`` is this very
    COG/SOG): the line says so, as the scores are then partly against the estimate's input.
    """
    course = course_vs_reference(run, min_sog)
    speed = speed_vs_reference(run, min_sog)
    if course is None or speed is None:
        return None
    source = ', a receiver velocity fused' if fused else ''
    return (f"  reference  the receiver's COG/SOG ({course['n']} samples{source}, SOG >= "
            f"{min_sog:g} m/s): course - COG mean {course['mean']:.2f} deg, RMS "
            f"{course['rms']:.2f} deg; speed - SOG mean {speed['mean']:.3f} m/s, RMS "
            f"{speed['rms']:.3f} m/s")


def format_accuracy(fused: Mapping[str, ErrorStats | None],
                    dead_reckoning: Mapping[str, ErrorStats | None] | None = None) -> str:
    """Return the accuracy table: RMS / max per quantity, fused beside dead reckoning."""
    units = {'position': ('m', 1.0), 'heading': ('deg', math.degrees(1.0)),
             'course': ('deg', math.degrees(1.0)), 'sideslip': ('deg', math.degrees(1.0)),
             'current': ('m/s', 1.0)}

    def cell(stats: ErrorStats | None, scale: float) -> str:
        if stats is None:
            return f'{"-":>17}'
        return f'{stats.rms * scale:8.3f} / {stats.maximum * scale:6.3f}'

    header = f'  {"error vs truth":<16}{"fused RMS / max":>17}'
    if dead_reckoning is not None:
        header += f'   {"dead-reckoning RMS / max":>24}'
    lines = [header]
    for name, (unit, scale) in units.items():
        line = f'  {name + " (" + unit + ")":<16}{cell(fused.get(name), scale)}'
        if dead_reckoning is not None:
            line += f'   {cell(dead_reckoning.get(name), scale):>24}'
        lines.append(line)
    return '\n'.join(lines)
