"""
The inputs' stamps against their arrival: future stamps, clock offsets, and time jumps.

The estimator orders its inputs by header stamp (:mod:`vessel_kinematics.estimation.timeline`);
this module compares each stamp with the driver's clock at its arrival (the node's ROS clock,
``/clock`` under ``use_sim_time``; the replay's bag log time):

* ``<input>.time_offset`` (s) is added to every stamp of that input first: a known offset of a
  driver's clock (``-18`` for a GNSS driver stamping GPS time instead of UTC);
* a stamp more than ``future_tolerance`` ahead of its arrival is refused as ``future_stamp``:
  it never moves the state's time, the output schedule or an output's stamp; so is one more
  than ``history_length`` (at least 1 s) ahead of the last stamp of every other input that
  flows (taken, it would make all of them too late), which catches a glitch where the clock
  says nothing (a bag played without ``/clock``); a real pause of the recording costs one
  message, since the next input's stamp agrees with it;
* each input's offset, stamp minus arrival, is followed as the median of its last
  :data:`OFFSET_WINDOW` messages (latency makes it negative; a driver's clock makes it
  anything). /diagnostics says so on that input (:meth:`InputTiming.status`): WARN from half
  the bound, ERROR beyond it (``future_tolerance`` ahead, ``history_length`` behind),
  naming the offset in seconds and its likely cause;
* an input whose stamps sit steadily (all :data:`OFFSET_WINDOW` messages within
  :data:`STEADY_SPREAD` of each other: a driver's clock, not a glitch) ahead of the other
  inputs' by more than ``future_tolerance``, or behind them by more than
  :data:`CLOCK_BEHIND_NS`, has that offset taken off its stamps until it goes away (18 s
  exactly where it is GPS time), so that the vessel keeps its position while /diagnostics
  says ERROR and names the ``time_offset`` to set; the messages before it is known are
  refused. Inputs that all sit off the clock alike (a bag played without ``/clock``) keep
  their stamps;
* a time jump re-initialises the estimator, counted and logged as robot_localization's
  ``reset_on_time_jump`` does: the clock going back by more than ``history_length`` (a bag
  played again, ``/clock`` restarting) and staying there for :data:`CLOCK_CONFIRM_NS`, or
  every input that flows (one arrived within :data:`FLOWING_NS`) coming in stamped too late
  :data:`JUMP_MESSAGES` times in a row (a looped bag without ``/clock``). One message never
  causes it.
"""

from __future__ import annotations

from collections import deque
import dataclasses
import statistics
from typing import Any, Mapping

from vessel_kinematics.core.frames import GPS_WEEK_ROLLOVER_S
from vessel_kinematics.estimation import Level, Reason, Rejection

__all__ = ['AHEAD_MIN_NS', 'CLOCK_BEHIND_NS', 'CLOCK_CONFIRM_NS', 'FLOWING_NS',
           'GPS_UTC_OFFSET', 'InputTiming', 'JUMP_MESSAGES', 'OFFSET_WINDOW', 'STEADY_SPREAD']

#: Messages per input whose median offset (stamp minus arrival) /diagnostics reports.
OFFSET_WINDOW = 25
#: Largest spread (ns) of a full window of offsets that is a steady clock offset.
STEADY_SPREAD = 1_000_000_000
#: Stamps steadily further behind than this (ns) are a clock's error, not a latency: taken off.
#: Less, they may be a real delivery latency, which is refused as too late beyond
#: ``history_length``, never moved to the arrival time.
CLOCK_BEHIND_NS = 60_000_000_000
#: Consecutive too-late messages of every flowing input that make a time jump.
JUMP_MESSAGES = 3
#: The least lead (ns) over every other input's last stamp that refuses a stamp.
AHEAD_MIN_NS = 1_000_000_000
#: An input flows while its last message arrived within this long (ns).
FLOWING_NS = 2_000_000_000
#: How long (ns) arrivals must agree with a move of the driver's clock of more than
#: ``history_length`` before it is taken: one ``/clock`` message far off never moves it.
CLOCK_CONFIRM_NS = 500_000_000
#: GPS time minus UTC since 2017-01-01 (s): 18 leap seconds.
GPS_UTC_OFFSET = 18.0


def _cause(offset: float) -> str:
    """Return the likely cause of a clock offset (s, stamps ahead when positive), or ''."""
    ahead = abs(offset)
    if abs(ahead - GPS_UTC_OFFSET) < 1.0:
        return ': GPS time instead of UTC?' if offset > 0 else ': UTC stamps on a GPS-time clock?'
    turns = round(ahead / GPS_WEEK_ROLLOVER_S)
    if turns >= 1 and abs(ahead - turns * GPS_WEEK_ROLLOVER_S) < 30 * 86400.0:
        return ': a GPS week-number rollover?'
    if ahead > 86400.0:
        return ": the driver's clock is not set?"
    return ''


class InputTiming:
    """The timing of each input against the driver's clock (see the module notes)."""

    def __init__(self, inputs: tuple[str, ...], offsets: Mapping[str, float],
                 future_tolerance: float, history_length: float) -> None:
        self.inputs = inputs
        self.set_params(offsets, future_tolerance, history_length)
        self._offsets: dict[str, deque[int]] = {name: deque(maxlen=OFFSET_WINDOW)
                                                for name in inputs}
        #: The median of each input's full window of offsets when it is steady (ns), found
        #: when that input's window changes.
        self._steady_median: dict[str, int] = {}
        #: The steady clock offset taken off each input's stamps (ns; 0: none).
        self.corrections: dict[str, int] = dict.fromkeys(inputs, 0)
        self._late_run: dict[str, int] = dict.fromkeys(inputs, 0)
        self._arrived: dict[str, int] = {}
        #: The last stamp of each input (refused or not), for the test against the others.
        self._last_stamp: dict[str, int] = {}
        self._clock: int | None = None
        #: A move of the clock beyond ``history_length`` not yet taken: (first, last) arrival.
        self._jump: tuple[int, int] | None = None

    def set_params(self, offsets: Mapping[str, float], future_tolerance: float,
                   history_length: float) -> None:
        """Take the offsets (s per input), ``future_tolerance`` and ``history_length`` (s)."""
        self._shift = {name: int(round(offsets.get(name, 0.0) * 1e9)) for name in self.inputs}
        self.future_ns = int(round(future_tolerance * 1e9))
        self.history_ns = int(round(history_length * 1e9))

    def shifted(self, name: str, measurement: Any) -> Any:
        """Return ``measurement`` with ``<name>.time_offset`` added to its stamp."""
        shift = self._shift[name]
        if not shift or measurement.stamp_ns <= 0:
            return measurement
        return dataclasses.replace(measurement, stamp_ns=measurement.stamp_ns + shift)

    def corrected(self, name: str, measurement: Any) -> Any:
        """Return ``measurement`` with the steady clock offset of ``name`` taken off."""
        correction = self.corrections[name]
        if not correction:
            return measurement
        return dataclasses.replace(measurement, stamp_ns=measurement.stamp_ns - correction)

    def clock_went_back(self, arrival_ns: int) -> bool:
        """
        Follow the driver's clock; return True when it went back beyond ``history_length``.

        A move of more than ``history_length`` either way is taken only once the arrivals have
        agreed with it (each within ``history_length`` of the one before) for
        :data:`CLOCK_CONFIRM_NS`: a bag played again or a ``/clock`` restarted resets the
        estimate half a second later, and one ``/clock`` message far ahead or behind, which
        the node's clock shows until the next one, never does.
        """
        clock = self._clock
        if clock is None or abs(arrival_ns - clock) <= self.history_ns:
            self._clock = arrival_ns if clock is None else max(clock, arrival_ns)
            self._jump = None
            return False
        jump = self._jump
        if jump is None or abs(arrival_ns - jump[1]) > self.history_ns:
            self._jump = (arrival_ns, arrival_ns)
            return False
        if arrival_ns - jump[0] < CLOCK_CONFIRM_NS:
            self._jump = (jump[0], arrival_ns)
            return False
        self._clock, self._jump = arrival_ns, None
        return arrival_ns < clock

    def future(self, name: str, stamp_ns: int, arrival_ns: int) -> Rejection | None:
        """
        Note the input's offset; refuse a stamp beyond ``future_tolerance`` ahead.

        ``stamp_ns`` is after ``time_offset``; the steady offset found is taken off before the
        test (:meth:`corrected` gives the stamp to use).
        """
        window = self._offsets[name]
        window.append(stamp_ns - arrival_ns)
        if len(window) == OFFSET_WINDOW and max(window) - min(window) <= STEADY_SPREAD:
            self._steady_median[name] = int(statistics.median(window))
        else:
            self._steady_median.pop(name, None)
        self._arrived[name] = arrival_ns
        self.corrections[name] = self._steady(name)
        ahead = stamp_ns - self.corrections[name] - arrival_ns
        if ahead > self.future_ns:
            return Rejection(Reason.FUTURE_STAMP,
                             f'stamp {ahead * 1e-9:.3f} s ahead of the clock, beyond '
                             f'future_tolerance {self.future_ns * 1e-9:g} s')
        return None

    def _steady(self, name: str) -> int:
        """
        Return input ``name``'s steady offset against the other inputs (ns), else 0.

        Against the others, not the clock: inputs that all sit off the clock by the same
        amount (a bag played without ``/clock``, a node's clock not set) keep their stamps.
        """
        medians = self._steady_median
        if name not in medians or len(medians) < 2:
            return 0
        offset = medians[name] - int(statistics.median(
            [m for other, m in medians.items() if other != name]))
        if not (offset > self.future_ns or -offset > CLOCK_BEHIND_NS):
            return 0
        if abs(offset - GPS_UTC_OFFSET * 1e9) < 1e9:
            return int(GPS_UTC_OFFSET * 1e9)
        return offset

    def ahead_of_others(self, name: str, stamp_ns: int, arrival_ns: int) -> Rejection | None:
        """
        Refuse a stamp far ahead (``history_length``, at least 1 s) of every other input's.

        The others are the inputs that flow: one arrived within :data:`FLOWING_NS` of this
        arrival. After a pause of every input nothing flows, and the first message is taken.
        (A message that arrives at its own far-future stamp, a marine log's or a bag's by
        stamp, is the replay's to hold: :mod:`~vessel_kinematics.tools.replay.loop`.)
        """
        others = [self._last_stamp[n] for n, t in self._arrived.items()
                  if n != name and n in self._last_stamp and arrival_ns - t <= FLOWING_NS]
        self._last_stamp[name] = stamp_ns
        if not others:
            return None
        lead, bound = stamp_ns - max(others), max(self.history_ns, AHEAD_MIN_NS)
        if lead <= bound:
            return None
        return Rejection(Reason.FUTURE_STAMP, f'stamp {lead * 1e-9:.3f} s ahead of every other '
                                              f'input, beyond {bound * 1e-9:g} s')

    def outcome(self, name: str, too_late: bool, arrival_ns: int) -> bool:
        """
        Note whether a message of ``name`` was too late; return True for a time jump.

        A jump: every input that arrived within :data:`FLOWING_NS` has been too late
        :data:`JUMP_MESSAGES` times in a row.
        """
        self._late_run[name] = self._late_run[name] + 1 if too_late else 0
        if not too_late:
            return False
        flowing = [n for n, t in self._arrived.items() if arrival_ns - t <= FLOWING_NS]
        return all(self._late_run[n] >= JUMP_MESSAGES for n in flowing)

    def reset(self) -> None:
        """Start the jump tests anew (after a reset): the clock from the next arrival."""
        self._late_run = dict.fromkeys(self.inputs, 0)
        self._clock, self._jump = None, None

    def offset(self, name: str) -> float | None:
        """Return the median of input ``name``'s stamps minus their arrivals (s), or None."""
        window = self._offsets[name]
        return statistics.median(window) * 1e-9 if window else None

    def status(self, name: str) -> tuple[Level, str | None, dict[str, str]]:
        """
        Return the level and text of input ``name``'s clock offset, and its values.

        OK (text None) within half the bounds; WARN from half of ``future_tolerance`` ahead or
        half of ``history_length`` behind; ERROR beyond them (its messages are refused).
        """
        offset = self.offset(name)
        if offset is None:
            return Level.OK, None, {}
        values = {'stamp offset (s)': f'{offset:+.3f}'}
        others = [o for n in self.inputs if n != name and (o := self.offset(n)) is not None]
        if others:
            relative = offset - statistics.median(others)
            values['stamp offset to the other inputs (s)'] = f'{relative:+.3f}'
        ahead_bound, behind_bound = self.future_ns * 1e-9, self.history_ns * 1e-9
        if offset > 0.5 * ahead_bound and offset > 0.0:
            level = Level.ERROR if offset > ahead_bound else Level.WARN
            text = f'{name} stamps {offset:.1f} s ahead of the clock{_cause(offset)}'
        elif -offset > 0.5 * behind_bound and offset < 0.0:
            level = Level.ERROR if -offset > behind_bound else Level.WARN
            text = f'{name} stamps {-offset:.1f} s behind the clock{_cause(offset)}'
        else:
            return Level.OK, None, values
        if others:
            text += f' ({relative:+.1f} s against the other inputs)'
        correction = self.corrections[name] * 1e-9
        if correction:
            values['stamp correction (s)'] = f'{-correction:+.3f}'
            text += (f'; {-correction:+.1f} s taken off its stamps until it goes: set '
                     f'{name}.time_offset')
        return level, text, values
