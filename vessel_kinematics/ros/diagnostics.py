"""
The navigator's ``/diagnostics``: what came in, what was refused and why, and how the estimate is.

:class:`Diagnostics` counts, per input, the messages received (with their arrival time), the
accepted and the rejected by reason (the pipeline tells it), and builds a
diagnostic_msgs/DiagnosticArray as diagnostic_updater does: one status per task of
:data:`TASKS`, named ``'<node name>: <task>'``:

* ``estimate``: the mode, the origin, the ages of the inputs, the estimates
  (:func:`estimates`) and the counts; WARN waiting for the origin or dead reckoning with GNSS
  enabled for :data:`DEAD_RECKONING_WARN` s, ERROR after :data:`DEAD_RECKONING_ERROR` s;
* one per input: the rate measured since the previous array, the age of the last accepted
  message by its stamp and the time since the last one arrived; WARN beyond
  ``diagnostics.stale_warn`` s, ERROR beyond ``diagnostics.stale_error`` s or never received
  by then;
* each input's stamps against the clock (:mod:`.timing`): ahead or behind by more than half
  of ``future_tolerance`` or ``history_length``, WARN, beyond them ERROR, naming the offset;
* then one per part of the estimator's own health (:meth:`Estimator.health`) past its
  estimate, by one generic loop: ``heading`` (ok, or the frozen compass found) and, with a
  velocity sensor, ``log`` (ok, stuck, or missing with what it holds), each with its fault
  test and threshold; the estimate part's values the estimate status lacks (the acceleration
  and its level, the recoveries and the last one's reason) join the estimate status.

Ages never go negative: an age from a clock that went back below the stamp says
:data:`CLOCK_WENT_BACK`. The time is the driver's: the node's clock, the replay's bag time.
"""

from __future__ import annotations

import math
from typing import Mapping

from vessel_kinematics.estimation import Estimator, Health, Mode, NavState, Reason
from vessel_kinematics.estimation.config import FUSED_TIMEOUT
from vessel_kinematics.ros import cdr, interface
from vessel_kinematics.ros.mountings import LABELS
from vessel_kinematics.ros.params import GnssVelocitySource, NavigatorParams, VelocitySource
from vessel_kinematics.ros.timing import InputTiming

__all__ = ['CLOCK_WENT_BACK', 'DEAD_RECKONING_ERROR', 'DEAD_RECKONING_WARN', 'Diagnostics',
           'ERROR', 'estimates', 'OK', 'TASKS', 'WARN']

#: The pipeline's input names.
INPUTS = interface.input_names()
#: The tasks of ``/diagnostics``: the estimate, then each input.
TASKS = ('estimate',) + INPUTS
#: Dead reckoning with GNSS enabled but no fix for longer than this (s) is a warning...
DEAD_RECKONING_WARN = 10.0
#: ...and for longer than this (s) an error (the position σ has grown by hundreds of metres).
DEAD_RECKONING_ERROR = 300.0
#: What an age says instead of a negative number when the clock went back.
CLOCK_WENT_BACK = 'clock went back'
#: diagnostic_msgs/DiagnosticStatus levels.
OK, WARN, ERROR = 0, 1, 2


def _age(stamp: int | None, now_ns: int) -> tuple[float | None, str]:
    """Return (age s or None, its text): 'never', 'clock went back' or seconds."""
    if stamp is None:
        return None, 'never'
    if now_ns < stamp:
        return None, CLOCK_WENT_BACK
    age = (now_ns - stamp) * 1e-9
    return age, f'{age:.3f}'


def estimates(estimator: Estimator, state: NavState | None) -> dict[str, str]:
    """
    Return the calibrations and the current as a navigator reads them (value ± σ).

    The estimator's own (:meth:`Estimator.estimates`: log scale, leeway, heading offset,
    declination, the current's set and drift), whether the course has fallen back to the
    heading at low speed, and the recoveries if any. For ``/diagnostics`` and the replay's
    summary; empty before the first state.
    """
    if state is None:
        return {}
    values = estimator.estimates()
    values['course'] = ('heading (speed below course.min_speed)' if state.low_speed
                        else 'over ground')
    if estimator.recoveries:
        values['recoveries'] = str(estimator.recoveries)
    return values


class Diagnostics:
    """The counts of one pipeline, and its DiagnosticArray at a given time."""

    def __init__(self) -> None:
        self._counts: dict[str, int] = dict.fromkeys(INPUTS, 0)
        self._counts['resets'] = 0
        self._received: dict[str, int] = dict.fromkeys(INPUTS, 0)
        self._arrived: dict[str, int] = {}
        # The previous array's time and received counts (the measured rates); the first's.
        self._previous: tuple[int, dict[str, int]] | None = None
        self._start: int | None = None

    @property
    def counts(self) -> dict[str, int]:
        """
        Return accepted messages per input and rejected ones per reason (``'fix/no_fix'``).

        ``'resets'`` counts the re-initialisations on a stamp that went back further than
        ``max_gap`` (a bag looped).
        """
        return dict(self._counts)

    def received(self, name: str, arrival_ns: int) -> None:
        """Count a message of input ``name`` that arrived at ``arrival_ns``."""
        self._received[name] += 1
        self._arrived[name] = arrival_ns

    def accepted(self, name: str) -> None:
        """Count an accepted message of input ``name``."""
        self._counts[name] += 1

    def rejected(self, name: str, reason: Reason) -> str:
        """Count a rejected message of input ``name``; return its key (``'fix/no_fix'``)."""
        key = f'{name}/{reason.value}'
        self._counts[key] = self._counts.get(key, 0) + 1
        return key

    def resets(self, count: int) -> None:
        """Count re-initialisations of the estimator."""
        self._counts['resets'] += count

    def array(self, now_ns: int, node_name: str, estimator: Estimator, state: NavState | None,
              params: NavigatorParams, sources: Mapping[str, str],
              extra: Mapping[str, int] | None = None, paused: bool = False,
              heading_in_use: str | None = None, timing: InputTiming | None = None) -> bytes:
        """
        Return the CDR of the DiagnosticArray at ``now_ns`` (the driver's clock).

        ``sources``: the mounting source per input; ``extra``: the driver's own counts (the
        node's internal errors, refused /clock messages), added to the estimate's values;
        ``paused``: fusion is paused (``~/enable``): the estimate is WARN, ``paused``;
        ``heading_in_use``: the imu topic in use when several fail over (``in use``);
        ``timing``: each input's clock offset, said on its status where it is off
        (:meth:`~.timing.InputTiming.status`).
        ``gnss_velocity`` has a status only when ``gnss_velocity.source`` is not none.
        """
        if self._start is None or now_ns < self._start:
            self._start = now_ns
        clock_back = self._previous is not None and now_ns < self._previous[0]
        parts = estimator.health()
        statuses = [self._estimate_status(now_ns, node_name, estimator, state, params, extra,
                                          paused, parts)]
        statuses += [self._timed(self._input_status(name, now_ns, node_name, estimator, params,
                                                    sources, clock_back, heading_in_use),
                                 name, timing) for name in INPUTS
                     if name != 'gnss_velocity'
                     or params.gnss_velocity_source is not GnssVelocitySource.NONE]
        statuses += [cdr.Status(int(part.level), f'{node_name}: {part.name}', part.summary,
                                tuple(part.values.items()))
                     for part in parts if part.name != 'estimate']
        self._previous = (now_ns, dict(self._received))
        return cdr.diagnostic_array(now_ns, statuses)

    @staticmethod
    def _timed(status: cdr.Status, name: str, timing: InputTiming | None) -> cdr.Status:
        """Add input ``name``'s clock offset to its status; say it where it is the worse."""
        if timing is None:
            return status
        level, text, values = timing.status(name)
        items = status.values + tuple(values.items())
        if text is None or int(level) < status.level:
            return cdr.Status(status.level, status.name, status.message, items)
        message = text if status.level == OK else f'{text}; {status.message}'
        return cdr.Status(int(level), status.name, message, items)

    def _estimate_status(self, now_ns: int, node_name: str, est: Estimator,
                         state: NavState | None, params: NavigatorParams,
                         extra: Mapping[str, int] | None, paused: bool = False,
                         parts: tuple[Health, ...] = ()) -> cdr.Status:
        mode = est.mode
        values: dict[str, str] = {'mode': mode.value}
        if paused:
            values['paused'] = 'true'
        if est.origin is not None:
            values['origin'] = (f'{math.degrees(est.origin[0]):.8f}, '
                                f'{math.degrees(est.origin[1]):.8f}, {est.origin[2]:.3f}')
        for name, stamp in zip(INPUTS, self._last_stamps(est)):
            if name != 'gnss_velocity' or stamp is not None:
                values[f'age {name} (s)'] = _age(stamp, now_ns)[1]
        values.update(estimates(est, state))
        for key, count in sorted(self._counts.items()):
            label = f'rejected {key}' if '/' in key else (
                key if key == 'resets' else f'accepted {key}')
            values[label] = str(count)
        if extra is not None:
            values.update((key, str(count)) for key, count in extra.items())
        for part in parts:
            if part.name == 'estimate':
                for key, value in part.values.items():
                    values.setdefault(key, value)
        level, summary = OK, mode.replace('_', ' ')
        if mode is Mode.WAITING:
            level = WARN
        elif mode is Mode.DEAD_RECKONING and params.gnss_enabled:
            fix_age, fix_text = _age(est.last_fix_ns, now_ns)
            if fix_text == CLOCK_WENT_BACK:
                level, summary = WARN, f'{summary} ({CLOCK_WENT_BACK})'
            elif fix_age is None:
                level, summary = WARN, summary + ' without GNSS'
            elif fix_age <= FUSED_TIMEOUT:
                level, summary = WARN, summary + ' (fixes arrive, every one refused)'
            elif fix_age > DEAD_RECKONING_WARN:
                level = ERROR if fix_age > DEAD_RECKONING_ERROR else WARN
                summary += f' for {fix_age:.0f} s'
        elif mode is Mode.FUSED and params.gnss_enabled:
            # The mode follows the stamps, which stand still when nothing arrives.
            silent, _ = _age(self._arrived.get('fix'), now_ns)
            if silent is not None and silent > FUSED_TIMEOUT:
                level, summary = WARN, f'fused until {silent:.0f} s ago: no fix has arrived since'
        if paused:
            level, summary = max(level, WARN), f'paused (~/enable false): {summary}'
        return cdr.Status(level, f'{node_name}: estimate', summary, tuple(values.items()))

    @staticmethod
    def _last_stamps(est: Estimator) -> tuple[int | None, ...]:
        """Return the stamps of the last accepted fix, imu, velocity, gnss_velocity (INPUTS)."""
        return (est.last_fix_ns, est.last_imu_ns, est.last_velocity_ns,
                est.last_ground_velocity_ns)

    def _input_status(self, name: str, now_ns: int, node_name: str, est: Estimator,
                      params: NavigatorParams, sources: Mapping[str, str],
                      clock_back: bool, heading_in_use: str | None = None) -> cdr.Status:
        stamp = dict(zip(INPUTS, self._last_stamps(est)))[name]
        received = self._received[name]
        rejected = sum(c for k, c in self._counts.items() if k.startswith(name + '/'))
        values = {'received': str(received), 'accepted': str(self._counts[name]),
                  'rejected': str(rejected)}
        if name in sources:
            values[LABELS[name]] = sources[name]
        if name == 'imu' and len(params.imu_topics) > 1:
            values['in use'] = heading_in_use or 'none yet'
        rate = None
        if self._previous is not None and now_ns > self._previous[0]:
            elapsed = (now_ns - self._previous[0]) * 1e-9
            rate = (received - self._previous[1][name]) / elapsed
        values['rate (Hz)'] = CLOCK_WENT_BACK if clock_back else (
            'n/a' if rate is None else f'{rate:.2f}')
        age, age_text = _age(stamp, now_ns)
        values['age (s)'] = age_text
        values['since received (s)'] = _age(self._arrived.get(name), now_ns)[1]
        warn_s, error_s = params.diagnostics_stale_warn, params.diagnostics_stale_error
        values['stale warn (s)'], values['stale error (s)'] = f'{warn_s:g}', f'{error_s:g}'
        status_name = f'{node_name}: {name}'
        items = tuple(values.items())
        if name == 'velocity' and params.velocity_source is VelocitySource.NONE:
            return cdr.Status(OK, status_name, 'not used (velocity.source none)', items)
        if age_text == CLOCK_WENT_BACK or clock_back:
            return cdr.Status(WARN, status_name, CLOCK_WENT_BACK, items)
        if age is None:
            waited = (now_ns - (self._start or now_ns)) * 1e-9
            what = 'nothing accepted' if received else 'no message'
            return cdr.Status(ERROR if waited > error_s else WARN, status_name,
                              f'{what} for {waited:.0f} s', items)
        if age > error_s:
            return cdr.Status(ERROR, status_name, f'stale: last message {age:.1f} s ago', items)
        if age > warn_s:
            return cdr.Status(WARN, status_name, f'late: last message {age:.1f} s ago', items)
        return cdr.Status(OK, status_name, 'ok' if rate is None else f'{rate:.1f} Hz', items)
