"""
The figure of a navigator run: the one module that imports matplotlib.

:func:`plot` draws a :class:`vessel_kinematics.tools.evaluate.Run` (or the run read from an
output bag by :func:`vessel_kinematics.tools.evaluate.load_run`) into a PNG: the track with the
GNSS fixes under it, heading, course and sideslip, speed and the horizontal position standard
deviation, with truth, a receiver's COG/SOG and a dead-reckoning-only run beside when given.
The numbers come from :mod:`vessel_kinematics.tools.evaluate`; nothing here scores.
matplotlib is imported when a figure is drawn (Agg backend, no display), so importing this
module costs nothing.

Angles are radians in the run, degrees on the figure.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from vessel_kinematics.core.flow import ssa
from vessel_kinematics.tools.evaluate import load_run, Run

__all__ = ['break_at_wraps', 'plot']


def break_at_wraps(t: Any, angle: Any) -> tuple[np.ndarray, np.ndarray]:
    """
    Return (t, angle) wrapped to [-π, π) with a NaN inserted between samples that wrap.

    A line through an angle that crosses ±π (rad) would draw a vertical stroke across the
    whole axis; where two neighbours differ by more than π the NaN (at the middle time)
    breaks the line instead. Nothing else changes: every sample is still drawn.
    """
    t = np.asarray(t, dtype=float)
    angle = ssa(np.asarray(angle, dtype=float))
    wraps = np.flatnonzero(np.abs(np.diff(angle)) > np.pi) + 1
    if not len(wraps):
        return t, angle
    middle = 0.5 * (t[wraps - 1] + t[wraps])
    return np.insert(t, wraps, middle), np.insert(angle, wraps, np.nan)


def plot(source: str | Path | Run, path: str | Path, *, fix_topic: str = '/fix',
         fixes_bag: str | Path | None = None, dead_reckoning: Run | None = None,
         title: str | None = None) -> Path:
    """
    Draw a run and save it as a PNG: return the path.

    Panels: the track north/east (GNSS fixes under the estimate, start and end marked, truth
    and the dead-reckoning-only track when given), heading, course and sideslip over time (with
    truth or the receiver's COG when present), speed, and the horizontal position standard
    deviation. ``source`` is an output bag or a :class:`Run`.
    """
    import matplotlib
    matplotlib.use('Agg')
    from matplotlib import pyplot

    run = source if isinstance(source, Run) else load_run(source, fix_topic, fixes_bag)
    path = Path(path)
    t0 = run.t0
    figure = pyplot.figure(figsize=(12, 7.5), dpi=90, layout='constrained')
    grid = figure.add_gridspec(3, 2, width_ratios=(1.05, 1.0))
    track = figure.add_subplot(grid[:, 0])
    angles = figure.add_subplot(grid[0, 1])
    speed = figure.add_subplot(grid[1, 1], sharex=angles)
    sigma = figure.add_subplot(grid[2, 1], sharex=angles)

    if len(run.fixes):
        track.plot(run.fixes['east'], run.fixes['north'], '.', ms=3, color='0.6',
                   label=f'GNSS fixes ({len(run.fixes)})', zorder=1)
    if run.truth is not None:
        track.plot(run.truth['east'], run.truth['north'], '-', lw=1.0, color='k',
                   label='truth', zorder=2)
    if dead_reckoning is not None and len(dead_reckoning.odometry):
        track.plot(dead_reckoning.odometry['east'], dead_reckoning.odometry['north'], '--',
                   lw=1.0, color='tab:orange', label='dead reckoning only', zorder=3)
    odo = run.odometry
    if len(odo):
        track.plot(odo['east'], odo['north'], '-', lw=1.4, color='tab:blue',
                   label='estimate (odometry)', zorder=4)
        track.plot(odo['east'][0], odo['north'][0], 'o', ms=8, color='tab:green',
                   label='start', zorder=5)
        track.plot(odo['east'][-1], odo['north'][-1], 's', ms=8, color='tab:red',
                   label='end', zorder=5)
    track.set_xlabel('east (m)')
    track.set_ylabel('north (m)')
    track.set_aspect('equal', adjustable='datalim')
    track.grid(True, lw=0.3)
    track.legend(loc='best', fontsize=8)
    if run.origin is not None:
        lat, lon, _ = run.origin
        track.set_title(f'track about {lat:.5f}, {lon:.5f}', fontsize=10)

    def wrapped(t: np.ndarray, angle: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Return time from the start (s) and the angle in degrees, lines broken at ±180."""
        t, angle = break_at_wraps(t - t0, angle)
        return t, np.degrees(angle)

    if len(odo):
        angles.plot(*wrapped(odo.t, odo['heading']), lw=1.0, color='tab:blue',
                    label='heading ψ')
    cs = run.course_sideslip
    if len(cs):
        angles.plot(*wrapped(cs.t, cs['chi']), lw=1.0, color='tab:purple', label='course χ')
        angles.plot(*wrapped(cs.t, cs['beta']), lw=1.0, color='tab:red', label='sideslip β')
    if run.cog_sog is not None and len(run.cog_sog):
        angles.plot(run.cog_sog.t - t0, np.degrees(ssa(run.cog_sog['cog'])), '.', ms=3,
                    color='k', label='receiver COG')
    if run.truth_course_sideslip is not None:
        tcs = run.truth_course_sideslip
        angles.plot(*wrapped(tcs.t, tcs['chi']), ':', lw=1.0, color='k', label='truth χ, β')
        angles.plot(*wrapped(tcs.t, tcs['beta']), ':', lw=1.0, color='k')
    angles.set_ylabel('angle (deg)')
    angles.set_ylim(-185, 185)
    angles.set_yticks(range(-180, 181, 90))
    angles.grid(True, lw=0.3)
    angles.legend(loc='upper right', fontsize=7, ncol=3)

    if len(odo):
        speed.plot(odo.t - t0, odo['speed'], lw=1.0, color='tab:blue', label='estimate')
    if run.truth is not None:
        speed.plot(run.truth.t - t0, run.truth['speed'], ':', lw=1.0, color='k', label='truth')
    if run.cog_sog is not None and len(run.cog_sog):
        speed.plot(run.cog_sog.t - t0, run.cog_sog['sog'], '.', ms=3, color='k',
                   label='receiver SOG')
    if len(run.current):
        speed.plot(run.current.t - t0, np.hypot(run.current['east'], run.current['north']),
                   lw=1.0, color='tab:cyan', label='current')
    speed.set_ylabel('speed (m/s)')
    speed.grid(True, lw=0.3)
    speed.legend(loc='upper right', fontsize=7, ncol=2)

    if len(odo):
        sigma.plot(odo.t - t0, odo['sigma_h'], lw=1.0, color='tab:blue', label='fused')
    if dead_reckoning is not None and len(dead_reckoning.odometry):
        dr = dead_reckoning.odometry
        sigma.plot(dr.t - t0, dr['sigma_h'], '--', lw=1.0, color='tab:orange',
                   label='dead reckoning only')
    sigma.set_ylabel('position σ horiz. (m)')
    sigma.set_xlabel('time (s)')
    sigma.set_yscale('log')
    sigma.grid(True, lw=0.3, which='both')
    sigma.legend(loc='upper left', fontsize=7)

    if title:
        figure.suptitle(title, fontsize=11)
    path.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(path)
    pyplot.close(figure)
    return path
