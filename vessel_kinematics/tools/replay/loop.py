"""
The replay's loop: the navigator's pipeline driven by one bag, in one process.

The replay is the navigator's second driver (the node is the first): it hands every input
message of the bag (:mod:`.bag_input`, by header stamp, arrival = log time) to
:meth:`~vessel_kinematics.ros.pipeline.Pipeline.handle` and sends every emission it returns,
the very CDR bytes the node publishes, to a sink (the output bag of :mod:`.run`, or memory),
with ``/diagnostics`` once per second of bag time. The bag's ``/tf_static`` (the sensors'
mountings) is taken before the first input; every message read may be copied as it is read.
What it did is a :class:`Summary`. :func:`replay_in_memory` keeps the outputs as messages
(rosbags' dataclasses), e.g. for a dead-reckoning-only comparison.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field
import datetime
import math
from pathlib import Path
import sys
import time
from typing import Any, Callable, Mapping, Sequence

from vessel_kinematics.core import frames
from vessel_kinematics.estimation import Reason
from vessel_kinematics.estimation.config import READY_WAIT
from vessel_kinematics.ros import interface
from vessel_kinematics.ros.input_limits import MAX_STAMP_SEC
from vessel_kinematics.ros.params import declination_problem, NavigatorParams
from vessel_kinematics.ros.pipeline import (Emission, fewer_collections, INPUTS, Pipeline,
                                            Result)
from vessel_kinematics.tools import bags
from vessel_kinematics.tools.replay.bag_input import (BagInput, InputMessage, StampOrder,
                                                      TF_STATIC_TOPIC)
from vessel_kinematics.tools.replay.errors import ReplayError

__all__ = ['DIAGNOSTICS_PERIOD_NS', 'OUTPUT_TYPES', 'Progress', 'Replay', 'replay_in_memory',
           'Summary']

#: The output bag's topics written by the replay and their types (as the navigator publishes).
OUTPUT_TYPES: dict[str, str] = interface.types(interface.Role.OUTPUT, interface.Role.AUXILIARY)
#: How many of the estimator's events the summary lists (the rest are counted).
EVENTS_SHOWN = 20
#: Diagnostics period in bag time (ns): 1 Hz, as the node's timer.
DIAGNOSTICS_PERIOD_NS = 1_000_000_000
#: The latest arrival the replay's clock takes (ns): the outputs' stamps (``/diagnostics``'
#: among them) are builtin_interfaces/Time, int32 seconds (2038-01-19 03:14:07 UTC).
MAX_ARRIVAL_NS = (MAX_STAMP_SEC + 1) * DIAGNOSTICS_PERIOD_NS - 1
#: A step forward of the replay's clock beyond this (ns) is taken once the next message
#: arrives past it too (a recording pause); a single message alone that far ahead (a glitched
#: log time, or with ``--by-stamp`` or a marine log a glitched stamp) arrives at the clock.
ARRIVAL_JUMP_NS = 10_000_000_000
#: At most this many messages of one arrival time are held while a clock step is not confirmed.
_HELD_MAX = 1000


def _utc(ns: int) -> str:
    """Return a time in ns since the epoch as ``YYYY-MM-DD HH:MM:SS UTC``."""
    try:
        moment = datetime.datetime.fromtimestamp(ns * 1e-9, tz=datetime.timezone.utc)
    except (OverflowError, OSError, ValueError):
        return f'{ns} ns since 1970'
    return moment.strftime('%Y-%m-%d %H:%M:%S UTC')


@dataclass
class Summary:
    """
    What a replay did: the numbers of its closing report.

    Times are bag (header-stamp) times in ns; ``distance_m`` is the horizontal path length of
    ``odometry/local`` (the continuous dead-reckoned track, free of GNSS jumps), m;
    ``final_position`` the last ``fix/filtered`` as (latitude deg, longitude deg, height m).
    """

    input_path: Path
    output_path: Path | None
    start_ns: int = 0
    end_ns: int = 0
    messages_in: Counter = field(default_factory=Counter)
    messages_out: Counter = field(default_factory=Counter)
    messages_copied: int = 0
    rejected: Counter = field(default_factory=Counter)
    out_of_order: int = 0
    distance_m: float = 0.0
    final_position: tuple[float, float, float] | None = None
    wall_time_s: float = 0.0
    topics: dict[str, str] = field(default_factory=dict)
    plot: Path | None = None
    accuracy: str | None = None
    #: Course and speed against the receiver's own COG/SOG (``/gnss/cog_sog``), when held.
    reference: str | None = None
    notes: list[str] = field(default_factory=list)
    estimates: dict[str, str] = field(default_factory=dict)
    #: The estimator's health at the end, one line per part (``heading OK: ok``).
    health: list[str] = field(default_factory=list)
    #: What the estimator found on the way (recoveries, faults, the log gone or back), in order.
    events: list[str] = field(default_factory=list)
    #: Per input: the largest step between consecutive stamps (s) and the stamp it ended at.
    largest_gap: dict[str, tuple[float, int]] = field(default_factory=dict)
    #: Per input: steps forward longer than ``max_gap``, and stamps back by more than it.
    gaps: Counter = field(default_factory=Counter)
    stamp_resets: Counter = field(default_factory=Counter)
    #: Re-initialisations of the estimator (a position or velocity recovery, a new origin).
    resets: int = 0
    #: Why the output is suspect although written (most of an input refused): the replay
    #: command exits with :data:`~.cli.SUSPECT` and says these.
    problems: list[str] = field(default_factory=list)

    @property
    def duration_s(self) -> float:
        """Return the bag time spanned by the input messages (s)."""
        return max(0.0, (self.end_ns - self.start_ns) * 1e-9)

    def text(self) -> str:
        """Return the summary as the few lines the command prints."""
        n_in = sum(self.messages_in.values())
        n_out = sum(self.messages_out.values())
        lines = [f'replay {self.input_path} -> {self.output_path or "(memory)"}']
        lines.append(f'  bag time   {self.duration_s:.1f} s from {_utc(self.start_ns)}'
                     f' ({self.wall_time_s:.1f} s wall, '
                     f'{n_in / max(self.wall_time_s, 1e-9):.0f} msg/s)')
        per_input = ', '.join(f'{name} {self.messages_in[name]} ({self.topics.get(name, "-")})'
                              for name in INPUTS if name in self.topics)
        lines.append(f'  in         {n_in}: {per_input}')
        outs = ', '.join(f'{t} {n}' for t, n in sorted(self.messages_out.items()))
        lines.append(f'  out        {n_out}: {outs}'
                     + (f'; {self.messages_copied} input messages copied'
                        if self.messages_copied else ''))
        rejected = ', '.join(f'{k} {n}' for k, n in sorted(self.rejected.items())) or 'none'
        lines.append(f'  rejected   {sum(self.rejected.values())}: {rejected}')
        gaps = ', '.join(
            f'{name} {gap:.3g} s at {_utc(at)}'
            + (f' ({self.gaps[name]} over max_gap)' if self.gaps[name] else '')
            + (f', {self.stamp_resets[name]} back' if self.stamp_resets[name] else '')
            for name, (gap, at) in sorted(self.largest_gap.items()))
        lines.append(f'  gaps       {gaps or "none"} (largest stamp step per input)')
        lines.append(f'  resets     {self.resets} (estimator re-initialisations)')
        lines.append(f'  distance   {self.distance_m:.1f} m (dead-reckoned path)')
        if self.final_position is not None:
            lat, lon, height = self.final_position
            lines.append(f'  final      {abs(lat):.7f} {"N" if lat >= 0 else "S"}, '
                         f'{abs(lon):.7f} {"E" if lon >= 0 else "W"}, {height:.1f} m')
        else:
            lines.append('  final      no position (no valid fix for the origin)')
        if self.estimates:
            lines.append('  estimated  '
                         + ', '.join(f'{k} {v}' for k, v in self.estimates.items()))
        lines.extend(f'  health     {line}' for line in self.health)
        shown = self.events[:EVENTS_SHOWN]
        lines.extend(f'  event      {event}' for event in shown)
        if len(self.events) > len(shown):
            lines.append(f'  event      ... and {len(self.events) - len(shown)} more')
        lines.extend(f'  note       {note}' for note in self.notes)
        if self.reference is not None:
            lines.append(self.reference)
        if self.accuracy is not None:
            lines.append(self.accuracy)
        if self.plot is not None:
            lines.append(f'  plot       {self.plot}')
        return '\n'.join(lines)


class Progress:
    """A one-line progress bar on stderr, only when stderr is a terminal."""

    def __init__(self, total: int, enabled: bool | None = None) -> None:
        self.total = max(total, 1)
        self.enabled = sys.stderr.isatty() if enabled is None else enabled
        self.done = 0
        self.last = 0.0
        self.start = time.monotonic()

    def update(self) -> None:
        self.done += 1
        if not self.enabled:
            return
        now = time.monotonic()
        if now - self.last < 0.2 and self.done < self.total:
            return
        self.last = now
        fraction = min(self.done / self.total, 1.0)
        filled = int(round(30 * fraction))
        rate = self.done / max(now - self.start, 1e-9)
        sys.stderr.write(f'\rreplay [{"#" * filled}{"." * (30 - filled)}] '
                         f'{100 * fraction:5.1f}% {self.done}/{self.total} msg {rate:.0f} msg/s')
        sys.stderr.flush()

    def close(self) -> None:
        if self.enabled:
            sys.stderr.write('\n')
            sys.stderr.flush()


class Replay:
    """One run of the pipeline over a bag, sending to ``send``; what the summary learns."""

    def __init__(self, bag: BagInput, params: NavigatorParams, summary: Summary,
                 send: Callable[[Emission], None], by_stamp: bool = False) -> None:
        self.bag = bag
        self.by_stamp = by_stamp
        self.pipeline = Pipeline(params)
        self.summary = summary
        self._send = send
        self._last_local: tuple[float, float] | None = None
        self._clock: int | None = None
        self._next_diagnostics = 0
        self._input_stamps: dict[str, int] = {}
        self._max_gap_ns = int(params.max_gap * 1e9)
        #: Messages far ahead of the clock, held until the next one says whether the clock
        #: moves there (:meth:`_arrive`): (name, stamp, arrival, msg, source).
        self._held: list[tuple[str, int, int, Any, int]] = []

    def emit(self, emissions: Sequence[Emission]) -> None:
        counted = self.summary.messages_out
        for emission in emissions:
            self._send(emission)
            counted[emission.topic] += 1

    def run(self, copy: Callable[[Any, int, Any], None] | None,
            progress: Progress | None) -> None:
        """Feed the bag's inputs in arrival order; send what the pipeline emits."""
        bag, pipeline, summary = self.bag, self.pipeline, self.summary
        problem = declination_problem(pipeline.params)
        if problem is not None:
            summary.notes.append(problem)
        self.emit(pipeline.start())
        # The bag's static transforms first (latched: in force from the start), so that the
        # inputs' mountings come from them where their frames are.
        n_static = sum(pipeline.tf_static(msg) >= 0 for msg in bag.tf_static())
        if n_static:
            summary.notes.append(f'{TF_STATIC_TOPIC}: {n_static} messages read before the '
                                 f'inputs, {len(pipeline.mountings.tree)} static transforms')
        if bag.tf_static_errors:
            summary.notes.append(f'{TF_STATIC_TOPIC}: {bag.tf_static_errors} messages not '
                                 'readable (skipped)')
        # Arrival order (the bag's log time), as the node received them live; or merged by
        # header stamp (``by_stamp``), each arriving at its own stamp.
        order = StampOrder() if self.by_stamp else None
        by_topic = bag.by_topic
        for connection, log_ns, raw in bag.messages():
            if progress is not None:
                progress.update()
            if copy is not None:
                copy(connection, log_ns, raw)
            name = by_topic.get(connection.topic)
            if name is None:
                continue
            item = bag.decode(name, connection, log_ns, raw)
            if order is None:
                self._arrive(item.name, item.stamp_ns, log_ns, item.msg, item.source)
            else:
                for item in order.push(item):
                    self._merged(item)
        if order is not None:
            for item in order.flush():
                self._merged(item)
            summary.out_of_order = order.out_of_order
        self._release(confirmed=False)
        self._took(pipeline.flush(), 'flush')
        if self._clock is not None:
            self.emit([pipeline.diagnostics(self._clock)])
        summary.estimates = pipeline.estimates()
        summary.health = [f'{part.name} {part.level.name}: {part.summary}'
                          for part in pipeline.estimator.health()]
        summary.resets = pipeline.counts.get('resets', 0)
        summary.problems = self._problems()

    def _problems(self) -> list[str]:
        """Return a line per input of which most messages (more than half) were refused."""
        lines = []
        for name in INPUTS:
            n = self.summary.messages_in[name]
            refused = {k.split('/', 1)[1]: v for k, v in self.summary.rejected.items()
                       if k.startswith(f'{name}/')}
            if n and sum(refused.values()) * 2 > n:
                top = sorted(refused.items(), key=lambda kv: -kv[1])[:3]
                why = ', '.join(f'{k} {v}' for k, v in top)
                lines.append(f'{sum(refused.values())} of {n} {name} messages refused ({why})')
        return lines

    def _step(self, name: str, stamp: int) -> None:
        """Follow input ``name``'s stamps: the largest step, gaps, and stamps going back."""
        last = self._input_stamps.get(name)
        self._input_stamps[name] = stamp if last is None else max(last, stamp)
        if last is None:
            return
        summary = self.summary
        step = stamp - last
        best = summary.largest_gap.get(name)
        if best is None or step * 1e-9 > best[0]:
            summary.largest_gap[name] = (max(step, 0) * 1e-9, stamp)
        if step > self._max_gap_ns:
            summary.gaps[name] += 1
        elif -step > self._max_gap_ns:
            summary.stamp_resets[name] += 1

    def _handle(self, name: str, stamp: int, arrival_ns: int, msg: Any,
                source: int = 0) -> None:
        if not 0 <= arrival_ns <= MAX_ARRIVAL_NS:
            raise ReplayError(f'cannot replay {self.bag.path}: a {name} message arrives at '
                              f'{_utc(arrival_ns)} (its log time), which no ROS time stamp '
                              'holds (int32 seconds: 1970 to 2038-01-19); --by-stamp hands '
                              'the messages on at their header stamps')
        result = self.pipeline.handle(name, msg, arrival_ns, source)
        self.summary.messages_in[name] += 1
        self._took(result, name)
        if stamp >= 0 and result.rejected != Reason.FUTURE_STAMP.value:
            self._step(name, stamp)
        # The replay's clock is the log time, as the node's is its ROS clock.
        summary = self.summary
        if self._clock is None:
            summary.start_ns = arrival_ns
            self._next_diagnostics = arrival_ns + DIAGNOSTICS_PERIOD_NS
        self._clock = arrival_ns if self._clock is None else max(self._clock, arrival_ns)
        summary.end_ns = max(summary.end_ns, arrival_ns)
        if arrival_ns >= self._next_diagnostics:
            self.emit([self.pipeline.diagnostics(arrival_ns)])
            self._next_diagnostics += DIAGNOSTICS_PERIOD_NS * (
                (arrival_ns - self._next_diagnostics) // DIAGNOSTICS_PERIOD_NS + 1)

    def _merged(self, item: InputMessage) -> None:
        """Hand on a message merged by stamp: it arrives at its stamp (if it has one)."""
        arrival = item.stamp_ns if item.stamp_ns >= 0 else item.arrival_ns
        self._arrive(item.name, item.stamp_ns, arrival, item.msg, item.source)

    def _arrive(self, name: str, stamp: int, arrival_ns: int, msg: Any, source: int) -> None:
        """
        Hand on a message; one far ahead of the clock waits for the next to confirm the step.

        A message arriving over :data:`ARRIVAL_JUMP_NS` after the clock is held: when the next
        one of another arrival time is not back from it by more than that (a pause in the
        recording), the held go at their arrival times; when it is (a glitched time, in a
        marine log or by stamp the message's own stamp), they go at the clock, where the
        pipeline judges their stamps (a stamp years ahead is refused as future_stamp) and the
        clock stays where it was. What is held at the end goes at the clock.
        """
        held = self._held
        if held and arrival_ns != held[0][2]:
            self._release(confirmed=arrival_ns >= held[0][2] - ARRIVAL_JUMP_NS)
        if self._clock is not None and arrival_ns > self._clock + ARRIVAL_JUMP_NS:
            held.append((name, stamp, arrival_ns, msg, source))
            if len(held) >= _HELD_MAX:
                self._release(confirmed=True)
            return
        self._handle(name, stamp, arrival_ns, msg, source)

    def _clock_or(self, arrival_ns: int) -> int:
        return arrival_ns if self._clock is None else self._clock

    def _release(self, confirmed: bool) -> None:
        """Hand on the held messages: at their arrival times if ``confirmed``, else the clock."""
        held, self._held = self._held, []
        for name, stamp, arrival_ns, msg, source in held:
            self._handle(name, stamp, arrival_ns if confirmed else self._clock_or(arrival_ns),
                         msg, source)

    def _took(self, result: Result, name: str) -> None:
        """Count and send what one input (or the final flush) did."""
        summary = self.summary
        if result.emissions:
            self.emit(result.emissions)
            self._follow(result)
        if result.rejected is not None:
            summary.rejected[f'{name}/{result.rejected}'] += 1
        for held, reason, _ in result.later:
            summary.rejected[f'{held}/{reason}'] += 1
        if result.info is not None:
            summary.notes.append(result.info)
        for event in result.events:
            at = (event.stamp_ns - summary.start_ns) * 1e-9 if summary.start_ns else 0.0
            summary.events.append(f'{at:.1f} s {event.level.name}: {event.text}')

    def _follow(self, result: Result) -> None:
        """Add an emitted state to the summary: the dead-reckoned path and the position."""
        state = result.state
        if state is None:
            return
        east, north, _ = frames.swap_world3(*state.p_local.tolist())
        if self._last_local is not None:
            self.summary.distance_m += math.hypot(east - self._last_local[0],
                                                  north - self._last_local[1])
        self._last_local = (east, north)
        lat, lon, height = state.llh
        self.summary.final_position = (math.degrees(lat), math.degrees(lon), float(height))

    def check_usable(self) -> None:
        """
        Raise :class:`ReplayError` when the run had no usable input or no navigation output.

        No input message, none usable, or no odometry at all (the estimator never started).
        """
        n_in = sum(self.summary.messages_in.values())
        if n_in == 0:
            # A marine log's counts say why none of its lines made a message.
            why = ('; the log: ' + '; '.join(self.bag.reader.counts.text().splitlines())
                   if self.bag.marine else '')
            raise ReplayError(f'no messages on the input topics '
                              f'({", ".join(self.bag.topics.values())}) of {self.bag.path}: '
                              f'nothing to replay{why}')
        counts = self.pipeline.counts
        if not any(counts.get(name, 0) for name in INPUTS):
            reasons = ', '.join(f'{k} {n}' for k, n in sorted(self.summary.rejected.items()))
            raise ReplayError(f'no usable input message: all {n_in} were rejected ({reasons})')
        if not any(topic.lstrip('/') == 'odometry' for topic in self.summary.messages_out):
            accepted = ', '.join(f'{name} {counts.get(name, 0)} of '
                                 f'{self.summary.messages_in[name]}' for name in INPUTS)
            estimator = self.pipeline.estimator
            mode = estimator.mode.value.replace('_', ' ')
            if estimator.origin is None or not estimator.position_ok:
                hint = 'a fix or an origin parameter starts it'
            else:      # a position, but the run ended before the first output (Estimator.ready)
                hint = ('the first output waits for a heading no older than history_length '
                        '(without an IMU, max_gap after the first fix) and a measured velocity '
                        f'(a log reading, or fixes enough; {READY_WAIT:g} s after the first '
                        'fix at the latest): the input is too short')
            raise ReplayError(f'no navigation output: the estimator stayed {mode} (accepted: '
                              f'{accepted}); {hint}')


def replay_in_memory(input_path: str | Path, params: NavigatorParams | None = None,
                     remaps: Sequence[str] | Mapping[str, str] | None = None,
                     topics: Sequence[str] | None = None, *,
                     date: datetime.date | None = None,
                     ) -> tuple[dict[str, list[tuple[int, Any]]], Summary]:
    """
    Replay a bag without writing one: return {topic: [(stamp ns, message)]} and a summary.

    The messages are the emissions deserialised by rosbags (dataclasses with the fields of the
    rclpy messages). ``topics`` limits what is kept (default: the navigator's outputs and
    ``/diagnostics``).
    """
    params = params if params is not None else NavigatorParams()
    keep = set(topics) if topics is not None else {
        t for t in OUTPUT_TYPES if t not in ('/tf', '/tf_static')}
    kept: dict[str, list[Emission]] = {t: [] for t in keep}
    summary = Summary(input_path=Path(input_path), output_path=None)
    wall_start = time.monotonic()

    def send(emission: Emission) -> None:
        if emission.topic in keep:
            kept[emission.topic].append(emission)

    with BagInput(input_path, params, remaps, date=date) as bag:
        summary.topics = dict(bag.topics)
        summary.notes += bag.notes
        with fewer_collections():
            Replay(bag, bag.params, summary, send).run(None, None)
    summary.wall_time_s = time.monotonic() - wall_start
    return {topic: [(e.stamp_ns, bags.deserialize(e.cdr, OUTPUT_TYPES[topic])) for e in sent]
            for topic, sent in kept.items()}, summary
