"""
The estimator's health as plain records: what /diagnostics and the replay's summary show.

:func:`health` returns one :class:`~.records.Health` per part, each final text (units in the
keys), so that the ROS layer and the replay show them with one generic loop
(:meth:`Estimator.health` states the contract):

``estimate``
    The mode (OK fused, WARN dead reckoning or waiting), the calibrations and the current with
    their σ, the acceleration level σ_a the process noise follows, the recoveries and the last
    one's reason.
``heading``
    The compass: OK, or WARN frozen (the test of :mod:`.faults` that found it), or WARN
    silent with no gyro: the heading taken from the course through the water.
``log`` (with a velocity sensor)
    OK; WARN stuck (:mod:`.faults`); ERROR missing: no reading accepted for
    ``velocity_timeout`` s, with the calibrations it holds (water reference); at a standstill
    (a speed log reading below 0.5 kn, not fused while the fixes give the speed): OK, WARN
    while the fixes give more than 2 kn; settling (just started or back, its reading still
    rising: :data:`~.config.LOG_SETTLE_TIME`): OK.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from vessel_kinematics.core.frames import KNOT
from vessel_kinematics.estimation.config import (LOG_SETTLE_TIME, LOG_STALL_READING,
                                                 LOG_STALL_SPEED)
from vessel_kinematics.estimation.records import Health, Level, Mode

#: What the functions read: an :class:`~.estimator.Estimator` (which imports this module).
Estimator = Any

__all__ = ['estimates', 'health']


def _pm(estimate: Any, scale: float = 1.0, digits: int = 3) -> str:
    """Return ``value ± σ`` of an :class:`~.records.Estimate`, times ``scale``."""
    return f'{estimate.value * scale:.{digits}f} ± {estimate.sigma * scale:.{digits}f}'


def estimates(est: Estimator) -> dict[str, str]:
    """
    Return the calibrations and the current as a navigator reads them (value ± σ).

    Log scale (reading / truth), leeway and heading offset in degrees (+ clockwise), the
    turning drift, the declination applied (or why none is), the current as set (the
    direction it flows to, degrees from the vessel's true north: the map's axes turned back
    by the meridians' convergence γ) and its drift (kn, with the σ of its two axes).
    """
    cal = est.calibration()
    values: dict[str, str] = {}
    if cal.log_scale is not None:
        values['log scale'] = _pm(cal.log_scale)
    if cal.leeway is not None:
        values['leeway (deg)'] = _pm(cal.leeway, math.degrees(1.0), 1)
    if cal.turn_drift is not None:
        values['turn drift (m/rad)'] = _pm(cal.turn_drift, 1.0, 1)
    if est.layout.dpsi is not None:
        values['heading offset (deg)'] = ('waiting for the vessel to move'
                                          if cal.heading_offset is None
                                          else _pm(cal.heading_offset, math.degrees(1.0), 1))
    if cal.declination is not None:
        error = est.declination_error
        values['declination (deg)'] = (f'{math.degrees(cal.declination):.2f}' if error is None
                                       else f'not applied: {error}')
    c = est.layout.c
    if c is not None:
        n, e = float(est.x[c.start]), float(est.x[c.start + 1])
        sigma = math.sqrt(max(0.0, float(est.P[c.start, c.start]
                                         + est.P[c.start + 1, c.start + 1])))
        values['current set (deg)'] = f'{math.degrees(math.atan2(e, n) - est._gamma) % 360.0:.0f}'
        values['current drift (kn)'] = f'{math.hypot(n, e) / KNOT:.2f} ± {sigma / KNOT:.2f}'
    return values


def _estimate(est: Estimator) -> Health:
    mode = est.mode
    values: dict[str, str] = {'mode': mode.value}
    if mode is Mode.FUSED:
        level, summary = Level.OK, 'fused'
    elif mode is Mode.DEAD_RECKONING:
        level, summary = Level.WARN, 'dead reckoning'
    else:
        level, summary = Level.WARN, 'waiting for the origin and a first fix'
    values.update(estimates(est))
    values['acceleration (m/s^2)'] = f'{float(est.x[est.layout.a.start]):+.2f}'
    values['acceleration level (m/s^2)'] = f'{est.accel.sigma:.2f}'
    values['recoveries'] = str(est.recoveries)
    if est.last_recovery is not None:
        values['last recovery'] = est.last_recovery
    return Health('estimate', level, summary, values)


def _heading(est: Estimator) -> Health:
    why = est.faults.get('heading')
    values = {'frozen-compass test': 'heading within 1 deg while the gyro turns 10 deg '
                                     'in 10 s, or the course over ground 45 deg'}
    if why is not None:
        return Health('heading', Level.WARN, why, values)
    att = est.attitude
    if not att.known and att.omega is None:
        return Health('heading', Level.WARN, 'no heading yet', values)
    if est.course_heading_ns is not None and att.last_attitude_ns is not None:
        silent = (est.course_heading_ns - att.last_attitude_ns) * 1e-9
        return Health('heading', Level.WARN, f'compass silent for {silent:.0f} s: heading from '
                      'the course through the water', values)
    return Health('heading', Level.OK, 'ok', values)


def _log(est: Estimator) -> Health:
    cfg = est.config
    values = {'timeout (s)': f'{cfg.velocity_timeout:g}',
              'stuck-log test': "reading within 0.05 m/s while the fixes' speed through the "
                                'water changes 1 m/s'}
    last = est._log_used_ns
    if last is not None and est.t is not None:
        values['age (s)'] = f'{(est.t - last) * 1e-9:.1f}'
    why = est.faults.get('log')
    if est.log_settling and not est.log_missing:
        summary = (f'settling: just started or turning again, its reading not yet steady '
                   f'(at most {LOG_SETTLE_TIME:g} s); the fixes tell the speed, scale and '
                   f'current held')
        return Health('log', Level.OK if why is None else Level.WARN,
                      summary if why is None else f'{summary}; {why}', values)
    if last is None and not est.log_missing:
        return Health('log', Level.WARN, 'no reading yet', values)
    if est.log_missing and est.log_stalled:
        speed = float(np.linalg.norm(est.velocity_ned()[:2]))
        summary = (f'at a standstill: readings below {LOG_STALL_READING / KNOT:.1f} kn not '
                   f'used while the fixes give {speed / KNOT:.1f} kn')
        return Health('log', Level.WARN if speed > 2.0 * LOG_STALL_SPEED else Level.OK,
                      summary if why is None else f'{summary}; {why}', values)
    if est.log_missing:
        held = [name for name, i in (('log scale', est.layout.k), ('leeway', est.layout.lam),
                                     ('turn drift', est.layout.kap)) if i is not None]
        summary = ('missing: no reading yet' if last is None else
                   f'missing: no reading accepted for more than {cfg.velocity_timeout:g} s')
        if held:
            summary += f' ({", ".join(held)} held)'
        if why is not None:
            summary += f'; {why}'
        return Health('log', Level.ERROR, summary, values)
    if why is not None:
        return Health('log', Level.WARN, why, values)
    return Health('log', Level.OK, 'ok', values)


def health(est: Estimator) -> tuple[Health, ...]:
    """Return the :class:`~.records.Health` of each part of ``est`` (see the module notes)."""
    parts = [_estimate(est), _heading(est)]
    if est.config.velocity_input:
        parts.append(_log(est))
    return tuple(parts)
