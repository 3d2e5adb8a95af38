"""
A marine log opened as the navigator's input messages: the reader the replay takes like a bag.

:func:`open_log` detects the format from the content (:func:`detect_format`: an NMEA 0183 log, or
an NMEA 2000 capture in one of ``nmea2000.CAPTURE_FORMATS``), whatever the file's name, and returns
a :class:`MarineLog`. Opening it reads the log once (the survey: what each line holds, which source
feeds each topic, the log's clock, :mod:`~vessel_kinematics.marine.assemble`) and raises
:class:`MarineLogError` with one line for what cannot be replayed: not a marine log, no usable
position (:class:`NoPositionError`), no time. :meth:`MarineLog.messages` then reads it again and
yields each message as rosbags' AnyReader does for a bag: ``(connection, arrival ns, CDR bytes)``,
in log order; :meth:`MarineLog.deserialize` reads the bytes back. ``counts`` says what the log
held: lines, sentences or PGNs by type, what was skipped by reason (``records.SKIP_REASONS``),
messages by topic, and which source fed each topic.

Stamps and arrival times:

* NMEA 0183: stamps from the log's clock, lines between two of its times spaced evenly
  (:class:`~vessel_kinematics.marine.nmea0183.Clock`); the arrival is the stamp, or the
  logger's own time where it timestamps the lines;
* NMEA 2000: the capture's timestamps (put on UTC by its GNSS time when the capture has no
  date), for stamp and arrival alike.

A malformed line is counted and skipped, never fatal; reading never writes.
"""

from __future__ import annotations

import calendar
from collections import Counter
from dataclasses import dataclass, field
import datetime
from functools import cached_property
import itertools
import math
from pathlib import Path
import re
from typing import Any, Iterable, Iterator

from vessel_kinematics.marine import dle, ebl, files, messages, nmea0183, nmea2000, pcap
from vessel_kinematics.marine.assemble import Assembler, ROLES, Source, Survey
from vessel_kinematics.marine.nmea0183 import Clock, Timed
from vessel_kinematics.marine.records import ClockTime, Decoded
from vessel_kinematics.tools import bags

__all__ = ['BINARY_FORMATS', 'Counts', 'detect_format', 'HEAD_BYTES', 'is_marine_log',
           'LogConnection', 'MarineLog', 'MarineLogError', 'MAX_LINE', 'NMEA0183',
           'NoPositionError', 'open_log']

#: The format name of an NMEA 0183 log (the others: ``'nmea2000/'`` + a capture format).
NMEA0183 = 'nmea0183'
#: The start of a file read to detect its format: this many bytes of text lines (bytes) ...
HEAD_BYTES = 1 << 16
#: ... past binary lines up to this many bytes (a receiver's binary records, junk) ...
HEAD_JUNK_BYTES = 1 << 20
#: ... and lines too long (a block of NULs, one 100 MB line), reading this much at most.
HEAD_SCAN_BYTES = 1 << 28
#: The longest line read (characters); longer ones are skipped (``too_long``).
MAX_LINE = 1024
#: An NMEA 0183 log whose first lines (:data:`HEAD_BYTES`) hold at least this many checksummed
#: sentences, more than this share of them wrong, has a logger that writes wrong checksums:
#: they are not compared (a corrupt line fails one now and then, never most of them).
WRONG_CHECKSUMS_MIN = 50
WRONG_CHECKSUMS_SHARE = 0.5

#: The frames of a capture whose kinds of time (a date, a time of day...) decide how it is dated.
_KIND_FRAMES = 2000
#: A capture frame stamped this long before the newest time is out of order (ns) ...
_STEP_BACK_NS = 5_000_000_000
#: ... unless the capture's frames stay back this long (ns): its clock was set back.
_STAYS_BACK_NS = 10_000_000_000
#: Consecutive frames that must agree on a time ahead of the capture's newest (or on its first
#: time) before the timeline takes it: one far-off stamp is a glitch, never the reference.
_CONFIRM_FRAMES = 5
#: A capture is dated by the median offset of its first this many GNSS times of one PGN: the
#: first alone may be wrong (a receiver's date 0 before its fix), the many agree.
_GNSS_TIMES = 1001
#: No GNSS time is before the GPS epoch, 1980-01-06 (ns).
_GNSS_EPOCH_NS = 315_964_800 * 1_000_000_000
#: What a log of times of day without a date needs.
_GIVE_DATE = 'give its date (replay --date YYYY-MM-DD; open_log(path, date=...))'
_NS = 1_000_000_000
_DAY_NS = 86_400 * _NS
#: The latest stamp a builtin_interfaces/Time holds (int32 seconds), ns.
_MAX_STAMP_NS = (2 ** 31 - 1) * _NS + _NS - 1
_SENTENCE_RE = re.compile(r'^[$!][A-Za-z0-9]{2,6},')
#: The binary capture formats, by name: their modules tell a file by its start, read it and
#: write it (the writer's).
BINARY_FORMATS = {'pcap': pcap, 'ebl': ebl, 'dle': dle}
#: A byte no text line holds: a control character, or one that is not ASCII (read as U+FFFD).
_BINARY_RE = re.compile('[\ufffd\x00-\x08\x0b\x0c\x0e-\x1f\x7f]')


def _reading_text(role: str, reading: tuple[float | None, ...]) -> str:
    """Return a source's one reading in a role, with units (radians shown in degrees)."""
    units = {'fix': ('deg', 'deg'), 'heading': ('rad',), 'attitude': ('rad', 'rad'),
             'rate': ('rad/s',), 'speed': ('m/s',), 'cog': ('rad', 'm/s')}[role]
    parts = []
    for value, unit in zip(reading, units):
        if value is None:
            parts.append('-')
        elif unit.startswith('rad'):
            parts.append(f'{math.degrees(value):.2f} {unit.replace("rad", "deg")}')
        else:
            parts.append(f'{value:.{6 if role == "fix" else 2}f} {unit}')
    return ', '.join(parts)


class MarineLogError(Exception):
    """A log that cannot be replayed; the message is one line."""


class NoPositionError(MarineLogError):
    """A log without a single usable position."""


@dataclass
class Counts:
    """What a log held and what became of it."""

    #: Non-empty lines read.
    lines: int = 0
    #: Well-formed sentences (NMEA 0183: type, ``'GGA'``) or messages (NMEA 2000: PGN).
    sentences: Counter = field(default_factory=Counter)
    #: Of those, the ones that fed a message, by type.
    used: Counter = field(default_factory=Counter)
    #: Lines, sentences and messages skipped, by reason (``records.SKIP_REASONS``).
    skipped: Counter = field(default_factory=Counter)
    #: Messages yielded, by topic.
    messages: Counter = field(default_factory=Counter)
    #: The source of each topic (``'/fix': 'GGA (GP)'``), or ``'-'``.
    sources: dict[str, str] = field(default_factory=dict)
    #: What else the summary should say (a heading without variation, a clock offset...).
    notes: list[str] = field(default_factory=list)

    def text(self) -> str:
        """Return the counts as the few lines a summary prints."""
        sentences = ', '.join(f'{k} {n}' for k, n in sorted(self.sentences.items()))
        used = ', '.join(f'{k} {n}' for k, n in sorted(self.used.items())) or 'none'
        skipped = ', '.join(f'{k} {n}' for k, n in sorted(self.skipped.items())) or 'none'
        sources = ', '.join(f'{t} {s}' for t, s in self.sources.items())
        lines = [f'{self.lines} lines; sentences {sentences or "none"}',
                 f'used {used}; skipped {sum(self.skipped.values())}: {skipped}',
                 f'sources {sources}']
        lines.extend(self.notes)
        return '\n'.join(lines)


# ---------------------------------------------------------------------------------------------
# Lines


def _lines(path: Path, limit: int | None = None) -> Iterator[str | None]:
    """
    Yield the non-empty lines of a file (CR, LF or CRLF), ASCII; None for each too long a line.

    A gzipped file is read decompressed (:mod:`.files`). Bytes that are not ASCII become U+FFFD
    (a sentence holding one fails its checksum). ``limit``: stop after that many bytes.
    """
    skipping = False
    carry = b''
    read = 0
    for chunk in files.chunks(path):
        read += len(chunk)
        if skipping:
            cut = min((i for i in (chunk.find(b'\n'), chunk.find(b'\r')) if i >= 0),
                      default=-1)
            if cut < 0:
                continue
            chunk, skipping = chunk[cut:], False
        parts = re.split(rb'[\r\n]+', carry + chunk)
        carry = parts.pop()
        for part in parts:
            if len(part) > MAX_LINE:
                yield None
            elif part.strip():
                yield part.decode('ascii', errors='replace')
        if len(carry) > MAX_LINE:
            yield None
            carry, skipping = b'', True
        if limit is not None and read >= limit:
            return
    if carry.strip() and not skipping:
        yield carry.decode('ascii', errors='replace')


def _head(path: Path) -> list[str]:
    """
    Return the lines at a log's start that tell its format: :data:`HEAD_BYTES` of text lines.

    Junk before them does not hide them (the same junk later in the log is skipped and
    counted): lines too long are left out, binary lines kept but not counted, up to
    :data:`HEAD_JUNK_BYTES` of them and :data:`HEAD_SCAN_BYTES` read in all.
    """
    head: list[str] = []
    text = junk = 0
    for line in _lines(path, HEAD_SCAN_BYTES):
        if line is None:
            continue
        head.append(line)
        if _BINARY_RE.search(line):
            junk += len(line) + 1
        else:
            text += len(line) + 1
        if text >= HEAD_BYTES or junk >= HEAD_JUNK_BYTES:
            break
    return head


def detect_format(path: str | Path) -> str:
    """
    Return the format of a log from its first lines (:func:`_head`).

    ``'nmea0183'`` or ``'nmea2000/<capture format>'``; raises :class:`MarineLogError` when it
    is neither.
    """
    path = Path(path)
    if not path.is_file():
        raise MarineLogError(f'{path} is not a file')
    try:
        start = next(files.chunks(path), b'')[:4]     # decompressed; b'' when none is
        for name, module in BINARY_FORMATS.items():
            if module.is_capture(start):
                return f'nmea2000/{name}'
        head = _head(path)
    except OSError as error:
        raise MarineLogError(f'cannot read {path}: {error.strerror}') from error
    # Binary records between the sentences (a receiver's raw output: u-blox UBX beside its
    # NMEA) are no lines of any format: left out of the count.
    lines = [line for line in head
             if not line.lstrip().startswith(nmea2000.COMMENTS) and not _BINARY_RE.search(line)]
    if not lines:
        raise MarineLogError(f'{path} holds no lines: not an NMEA 0183 log or NMEA 2000 '
                             'capture')
    capture = nmea2000.detect(lines)
    n0183 = n2000 = 0
    for line in lines:
        if capture is not None and nmea2000.matches(capture, line):
            n2000 += 1                  # iKonvert's lines look like sentences too: its own
            continue
        split = nmea0183.split_line(line)
        if split.sentence is not None and _SENTENCE_RE.match(split.sentence):
            n0183 += 1
    if capture is not None and n2000 >= n0183:
        return f'nmea2000/{capture}'
    if 3 * n0183 >= len(lines):
        return NMEA0183
    raise MarineLogError(
        f'{path} is not an NMEA 0183 log or an NMEA 2000 capture '
        f'({", ".join(nmea2000.CAPTURE_FORMATS)}'
        f'): {n0183} of its first {len(lines)} lines are NMEA 0183 sentences')


def is_marine_log(path: str | Path) -> bool:
    """Return True for a file that :func:`detect_format` takes for a marine log."""
    try:
        detect_format(path)
    except MarineLogError:
        return False
    return True


# ---------------------------------------------------------------------------------------------
# The two protocols: a survey pass and a timed pass each


class _Protocol:
    """What :class:`MarineLog` needs of a protocol."""

    priorities: dict[str, tuple[str, ...]]
    #: What the last reading noted of the log's clock (recounted with each reading).
    clock_note: str | None = None

    def survey(self, counts: Counts, survey: Survey) -> None:
        raise NotImplementedError

    def timed(self, roles: dict[str, Source | None]) -> Iterator[Timed]:
        raise NotImplementedError


class _Nmea0183(_Protocol):
    priorities = nmea0183.PRIORITIES

    def __init__(self, path: Path, date: datetime.date | None) -> None:
        self.path = path
        self.date = date
        head = [nmea0183.split_line(line) for line in _head(path)]
        sentences = [s for s in head if s.sentence is not None]
        #: The log's sentences carry checksums: one without is cut or corrupt.
        self.require_checksum = any(nmea0183.has_checksum(s.sentence or '') for s in sentences)
        #: Most of the checksums at the log's start are wrong: its logger writes wrong ones
        #: (one of Irene's 2013 loggers did, on 95 % of its sentences), so they say nothing of
        #: a sentence and are not compared; the fields are still read strictly.
        self.trust_checksum = True
        self.note: str | None = None
        summed = [s.sentence for s in sentences if nmea0183.has_checksum(s.sentence or '')]
        wrong = sum(not nmea0183.checksum_holds(text or '') for text in summed)
        if len(summed) >= WRONG_CHECKSUMS_MIN and wrong > WRONG_CHECKSUMS_SHARE * len(summed):
            self.trust_checksum = False
            self.note = (f'{wrong} of the first {len(summed)} checksums are wrong: the '
                         "logger's checksums are not compared")
        #: The logger times every line: spacing by logger time, and it is the arrival.
        self.logger_timed = bool(sentences) and all(s.logger_ns is not None for s in sentences)
        self.clock: Source | None = None
        self.date_ns: int | None = None

    def _decoded(self, kinds: frozenset[str] | None = None
                 ) -> Iterator[tuple[int, int | None, Decoded | None, str | None]]:
        """Yield (position, logger ns, decoded, line skip) per line (``kinds``: decode()'s)."""
        position = 0
        for index, line in enumerate(_lines(self.path)):
            if line is None:
                yield (position, None, None, 'too_long')
                continue
            split = nmea0183.split_line(line)
            if split.sentence is None and line.lstrip().startswith('#'):
                continue                            # a comment (gpsd's logs open with some)
            if self.logger_timed:
                if split.logger_ns is not None:
                    position = split.logger_ns
            else:
                position = index
            if split.sentence is None:
                yield (position, split.logger_ns, None, split.skip)
                continue
            yield (position, split.logger_ns,
                   nmea0183.decode(split.sentence, self.require_checksum, kinds,
                                   self.trust_checksum), None)

    def survey(self, counts: Counts, survey: Survey) -> None:
        clocks: Counter = Counter()
        if self.note is not None:
            counts.notes.append(self.note)
        first_date: int | None = None
        for _, _, decoded, skip in self._decoded():
            counts.lines += 1
            if decoded is None:
                counts.skipped[skip or 'not_nmea'] += 1
                continue
            if decoded.skip is not None:
                counts.skipped[decoded.skip] += 1
                continue
            counts.sentences[decoded.kind] += 1
            survey.add(decoded)
            for record in decoded.records:
                if isinstance(record, ClockTime) and record.fixed:
                    if record.utc_ns is not None:
                        clocks[(decoded.kind, decoded.source, 'utc')] += 1
                        if first_date is None:
                            first_date = record.utc_ns - record.day_ns
                    clocks[(decoded.kind, decoded.source, 'day')] += 1
        for kind in nmea0183.clock_priority():
            dated = kind in ('RMC', 'ZDA')
            candidates = {key: n for key, n in clocks.items()
                          if key[0] == kind and key[2] == ('utc' if dated else 'day')}
            if candidates:
                best = max(candidates, key=lambda key: (candidates[key], key[1]))
                self.clock = (best[0], best[1])
                break
        if self.clock is not None and self.clock[0] not in ('RMC', 'ZDA'):
            self.date_ns = first_date                     # the log's own date comes first
            if self.date_ns is None and self.date is not None:
                self.date_ns = _midnight_ns(self.date)
            if self.date_ns is None:
                raise MarineLogError(
                    f'{self.path}: its only times are times of day ({self.clock[0]}) and it has '
                    f'no date (no RMC, ZDA): {_GIVE_DATE}')

    def timed(self, roles: dict[str, Source | None]) -> Iterator[Timed]:
        assert self.clock is not None
        clock = Clock(self.clock[0], self.clock[1], self.date_ns)
        # The sentences that matter: the roles', the clock's, and those giving a variation.
        kinds = frozenset({source[0] for source in roles.values() if source is not None}
                          | {self.clock[0], 'RMC', 'HDG'})
        for position, logger_ns, decoded, _ in self._decoded(kinds):
            if decoded is None or decoded.skip is not None or not decoded.records:
                continue
            yield from clock.push(position, logger_ns, decoded)
        yield from clock.finish()
        notes = []
        if clock.rollover:
            notes.append(f'the receiver is past a GPS week rollover: {clock.rollover} times '
                         'read 1024 weeks later')
        if clock.minute_stuck:
            notes.append(f"the clock's minute stuck: {clock.minute_stuck} times read by their "
                         'seconds')
        self.clock_note = '; '.join(notes) or None


def _median(values: list[int]) -> int | None:
    """Return the middle one of ``values`` (the lower of two), None for none."""
    return sorted(values)[(len(values) - 1) // 2] if values else None


def _midnight_ns(date: datetime.date) -> int:
    """Return the UTC midnight that begins ``date`` (ns since the epoch)."""
    return calendar.timegm(date.timetuple()) * _NS


class _Timeline:
    """
    A capture's times on UTC: the day unwrapped (times of day), the GNSS offset added.

    A capture's clock moves forward, give or take the gateway's reordering. A frame stamped more
    than :data:`_STEP_BACK_NS` before the newest time is out of order (a capture's timestamp
    glitch: one real capture holds 0.4 s of frames stamped 13.9 days early) and gets no time,
    unless the frames stay back for :data:`_STAYS_BACK_NS` of their own time: then the clock was
    set back, and the timeline follows it from there. A frame more than :data:`_STEP_BACK_NS`
    ahead of the newest time (or the capture's first) waits: :data:`_CONFIRM_FRAMES`
    consecutive frames agreeing on it make it the newest time, and all get theirs; a frame back
    in line first makes them a glitch, refused. One garbage stamp (year 9999) never becomes the
    time the good frames are measured against. :meth:`push` takes each frame and returns the
    frames it places, :meth:`finish` those still waiting.
    """

    def __init__(self) -> None:
        self.offset_ns = 0
        self._days = 0
        self._last: int | None = None
        self._newest: int | None = None
        self._back_since: int | None = None
        self._ahead: list[tuple[nmea2000.Frame, int]] = []     # waiting: (frame, its time)

    def push(self, frame: nmea2000.Frame) -> list[tuple[nmea2000.Frame, int | None]]:
        """Take the next frame; return the frames placed, each with its time on UTC or None."""
        t = frame.time_ns
        if frame.time_kind == nmea2000.TIME_DAY:        # past midnight from the last placed
            past = self._last is not None and t < self._last - _DAY_NS // 2
            t += (self._days + past) * _DAY_NS
        newest = self._newest
        if newest is None or t > newest + _STEP_BACK_NS:
            out = self._refuse() if self._ahead and abs(t - self._ahead[-1][1]) > (
                _STEP_BACK_NS) else []
            self._ahead.append((frame, t))
            return out + (self._adopt() if len(self._ahead) >= _CONFIRM_FRAMES else [])
        out = self._refuse()                                   # back in line: a glitch
        if t < newest - _STEP_BACK_NS:
            if self._back_since is None:
                self._back_since = t
            if t - self._back_since < _STAYS_BACK_NS:
                return out + [(frame, None)]
            self._newest = t                               # the clock was set back
        elif t > newest:
            self._newest = t
        self._back_since = None
        self._place(frame, t)
        return out + [(frame, t + self.offset_ns)]

    def _place(self, frame: nmea2000.Frame, t: int) -> None:
        """Take a frame's time as placed: a time of day refused never turns the day."""
        if frame.time_kind == nmea2000.TIME_DAY:
            self._last = frame.time_ns
            self._days = (t - frame.time_ns) // _DAY_NS

    def _adopt(self) -> list[tuple[nmea2000.Frame, int | None]]:
        """Take the waiting frames' time as the capture's; return them with their times."""
        self._newest = max(t for _, t in self._ahead)
        self._back_since = None
        self._place(*self._ahead[-1])
        placed: list[tuple[nmea2000.Frame, int | None]] = [
            (frame, t + self.offset_ns) for frame, t in self._ahead]
        self._ahead = []
        return placed

    def _refuse(self) -> list[tuple[nmea2000.Frame, int | None]]:
        """Return the waiting frames without a time (a glitch), and forget them."""
        refused: list[tuple[nmea2000.Frame, int | None]] = [
            (frame, None) for frame, _ in self._ahead]
        self._ahead = []
        return refused

    def finish(self) -> list[tuple[nmea2000.Frame, int | None]]:
        """Return the frames still waiting: timed if the capture has no other time, else not."""
        return self._adopt() if self._newest is None and self._ahead else self._refuse()


class _Nmea2000(_Protocol):
    priorities = nmea2000.PRIORITIES

    def __init__(self, path: Path, fmt: str, date: datetime.date | None) -> None:
        self.path = path
        self.fmt = fmt
        self.date = date
        self.offset_ns = 0
        #: Where a binary capture is damaged (pcap's record lengths).
        self.damaged: list[pcap.Damaged] = []

    def _frames(self) -> Iterator[nmea2000.Frame | str]:
        """Yield each frame of the capture, or why a line or packet is none (a skip reason)."""
        if self.fmt in BINARY_FORMATS:
            for packet in BINARY_FORMATS[self.fmt].frames(self.path):
                if isinstance(packet, pcap.Damaged):
                    self.damaged.append(packet)
                yield packet if isinstance(packet, nmea2000.Frame) else 'not_nmea'
            return
        for line in _lines(self.path):
            if line is None:
                yield 'too_long'
            elif not nmea2000.unwrap(line).startswith(nmea2000.COMMENTS):
                frame = nmea2000.parse_line(self.fmt, line)
                yield 'not_nmea' if frame is None else frame

    def _placed(self, timeline: _Timeline
                ) -> Iterator[tuple[nmea2000.Frame | str, int | None]]:
        """Yield each frame with its time on the timeline (None: refused), or a line skip."""
        for frame in self._frames():
            if isinstance(frame, str):
                yield (frame, None)
            else:
                yield from timeline.push(frame)
        yield from timeline.finish()

    def _decoded(self, timeline: _Timeline
                 ) -> Iterator[tuple[int, Decoded | None, str | None]]:
        """Yield (capture time on the timeline, decoded message, line skip) per line."""
        fast = nmea2000.FastPacket()
        for frame, t in self._placed(timeline):
            if isinstance(frame, str):
                yield (0, None, frame)
                continue
            if t is None:
                yield (0, None, 'time_jump')
                continue
            if frame.pgn not in nmea2000.PGNS:
                yield (t, Decoded(str(frame.pgn), str(frame.source)), None)
                continue
            payload: bytes | None = frame.data
            if frame.pgn in nmea2000.FAST_PGNS and not frame.whole:
                broken = fast.broken
                payload = fast.push(frame)
                for _ in range(fast.broken - broken):
                    yield (t, None, 'fast_packet')
                if payload is None:
                    continue
            assert payload is not None
            yield (t, nmea2000.decode(frame.pgn, payload, frame.source), None)
        for _ in range(fast.finish()):
            yield (0, None, 'fast_packet')

    def survey(self, counts: Counts, survey: Survey) -> None:
        # GNSS UTC - capture time of each 126992 and 129029 with a date a stamp can hold
        offsets: dict[str, list[int]] = {'126992': [], '129029': []}
        impossible = 0
        for t, decoded, skip in self._decoded(_Timeline()):
            counts.lines += 1
            if decoded is None:
                counts.skipped[skip or 'not_nmea'] += 1
                continue
            if decoded.skip is not None:
                counts.skipped[decoded.skip] += 1
                continue
            counts.sentences[decoded.kind] += 1
            survey.add(decoded)
            for record in decoded.records:
                if isinstance(record, ClockTime) and record.utc_ns is not None and (
                        record.fixed):
                    if not _GNSS_EPOCH_NS <= record.utc_ns <= _MAX_STAMP_NS:
                        impossible += 1
                    elif len(offsets[decoded.kind]) < _GNSS_TIMES:
                        offsets[decoded.kind].append(record.utc_ns - t)
        shown = self.damaged[:3] + [d for d in self.damaged[3:] if not d.resumed]   # + the stop
        for damaged in shown:
            counts.notes.append(
                f'the capture is damaged at byte {damaged.offset}: a record {damaged.length} '
                f'bytes long; ' + (f'{damaged.unread} bytes skipped to the next record'
                                   if damaged.resumed else
                                   f'its last {damaged.unread} bytes are not read'))
        if len(self.damaged) > len(shown):
            counts.notes.append(f'the capture is damaged at {len(self.damaged) - len(shown)} '
                                'more records')
        self.damaged = []
        kinds = set(self._time_kinds())
        kind = '126992' if offsets['126992'] else '129029'
        gnss = _median(offsets[kind])
        if impossible:
            counts.notes.append(f'{impossible} GNSS times (PGN 126992, 129029) before 1980 or '
                                'after 2038: not used to date the capture')
        if kinds - {nmea2000.TIME_UTC}:
            if gnss is None and self.date is not None and kinds == {nmea2000.TIME_DAY}:
                self.offset_ns = _midnight_ns(self.date)
                counts.notes.append(f'capture times of day put on {self.date.isoformat()} '
                                    '(the date given)')
                return
            if gnss is None:
                raise MarineLogError(
                    f"{self.path}: the capture's times have no date ({self.fmt}) and it holds "
                    'no GNSS time (PGN 126992 or 129029) to put them on UTC'
                    + (f': {_GIVE_DATE}' if kinds == {nmea2000.TIME_DAY} else ''))
            self.offset_ns = gnss
            counts.notes.append(f'capture times put on UTC by PGN {kind} (the median of '
                                f'{len(offsets[kind])}): {self.offset_ns * 1e-9:+.3f} s')
        elif gnss is not None and abs(gnss) > 2 * _NS:
            counts.notes.append(f'the capture clock is {-gnss * 1e-9:+.1f} s off '
                                "the GNSS time (the stamps are the capture's)")

    def _time_kinds(self) -> Iterable[str]:
        """Return the kinds of time of the capture's first frames."""
        return {frame.time_kind for frame in itertools.islice(self._frames(), _KIND_FRAMES)
                if not isinstance(frame, str)}

    def timed(self, roles: dict[str, Source | None]) -> Iterator[Timed]:
        timeline = _Timeline()
        timeline.offset_ns = self.offset_ns
        for t, decoded, skip in self._decoded(timeline):
            if skip == 'time_jump':                # recounted with each reading, as NMEA 0183's
                yield Timed(Decoded('', ''), 0, 0, skip)
            elif decoded is not None and decoded.skip is None and decoded.records:
                yield Timed(decoded, t, t)


# ---------------------------------------------------------------------------------------------
# The log


#: The topics each source role feeds (a receiver's COG/SOG: the reference and gnss_velocity).
_TOPICS_OF_ROLE = {'fix': (messages.FIX_TOPIC,), 'heading': (messages.IMU_TOPIC,),
                   'speed': (messages.SPEED_TOPIC,),
                   'cog': (messages.COG_SOG_TOPIC, messages.GNSS_VELOCITY_TOPIC)}


@dataclass(frozen=True)
class LogConnection:
    """
    One topic of a marine log, as the replay uses a bag's connection (rosbags' Connection).

    ``ext`` None: recorded with no QoS (``tools.bags.recorded_qos`` gives none); ``owner``
    the log.
    """

    id: int  # noqa: A003 - rosbags' name
    topic: str
    msgtype: str
    msgcount: int = 0
    ext: Any = None
    owner: Any = field(default=None, compare=False, repr=False)


class MarineLog:
    """
    A marine log read as the navigator's input messages, with the surface of rosbags' AnyReader.

    ``connections`` (one per topic of :data:`~vessel_kinematics.marine.messages.TOPICS`),
    ``messages()`` yielding ``(connection, arrival ns, CDR bytes)`` in log order,
    ``deserialize(raw, msgtype)``, ``message_count`` (an upper bound: the survey's usable
    records; untimed lines are dropped later), ``is2`` (CDR, as a rosbag2 bag), ``typestore``,
    ``open()``/``close()`` and use as a context manager. ``counts``: what the log held
    (:class:`Counts`); ``roles``: the source of each role; ``format``: :func:`detect_format`'s.
    """

    is2 = True

    def __init__(self, path: str | Path, *, date: datetime.date | None = None) -> None:
        self.path = Path(path)
        self.format = detect_format(self.path)
        self.date = date
        self.counts = Counts()
        self.roles: dict[str, Source | None] = {}
        self.connections: list[LogConnection] = []
        self._protocol: _Protocol | None = None

    @property
    def protocol(self) -> str:
        """Return ``'nmea0183'`` or ``'nmea2000'``."""
        return self.format.split('/')[0]

    @cached_property
    def typestore(self) -> Any:
        """Return the typestore of the messages (ROS 2 Jazzy)."""
        return messages.typestore()

    def open(self) -> None:  # noqa: A003 - the name of rosbags and files
        """Survey the log; raise :class:`MarineLogError` when it cannot be replayed."""
        if self._protocol is not None:
            return
        if self.protocol == NMEA0183:
            protocol: _Protocol = _Nmea0183(self.path, self.date)
        else:
            protocol = _Nmea2000(self.path, self.format.split('/', 1)[1], self.date)
        counts = Counts()
        survey = Survey()
        try:
            protocol.survey(counts, survey)
        except OSError as error:
            raise MarineLogError(f'cannot read {self.path}: {error.strerror}') from error
        self.roles = survey.roles(protocol.priorities)
        if self.roles['fix'] is None:
            candidates = ', '.join(f'{k} {counts.sentences[k]}'
                                   for k in protocol.priorities['fix'] if counts.sentences[k])
            skipped = ', '.join(f'{k} {n}' for k, n in sorted(counts.skipped.items()))
            raise NoPositionError(
                f'{self.path}: no usable position in {counts.lines} lines ('
                f'{self.format}; position {"sentences" if self.protocol == NMEA0183 else "PGNs"}'
                f': {candidates or "none"}; skipped: {skipped or "none"})')
        if isinstance(protocol, _Nmea0183) and protocol.clock is None:
            raise MarineLogError(f'{self.path}: no time in the log (no RMC, ZDA, GGA, GNS or '
                                 'GLL time): its lines cannot be stamped')
        counts.sources = {topic: self._describe(self.roles.get(role))
                          for role, topics in _TOPICS_OF_ROLE.items() for topic in topics}
        for role in ('attitude', 'rate'):
            if self.roles.get(role) is not None:
                counts.sources[f'{messages.IMU_TOPIC} {role}'] = self._describe(self.roles[role])
        if isinstance(protocol, _Nmea0183) and protocol.clock is not None:
            counts.sources['clock'] = self._describe(protocol.clock)
        for role in ROLES:
            for source, reading in survey.constant(role).items():
                counts.notes.append(
                    f'{role}: {self._describe(source)} read {_reading_text(role, reading)} '
                    'throughout while another source changed: a dead instrument, not used')
        self.counts = counts
        self._survey = survey
        self.connections = [self._connection(i, topic, msgtype)
                            for i, (topic, msgtype) in enumerate(messages.TOPICS.items(), 1)]
        self._by_topic = {c.topic: c for c in self.connections}
        self._protocol = protocol

    def _describe(self, source: Source | None) -> str:
        if source is None:
            return '-'
        kind, talker = source
        if self.protocol == NMEA0183:
            return f'{kind} ({talker})' if talker else kind
        return f'PGN {kind} (source {talker})'

    def _connection(self, cid: int, topic: str, msgtype: str) -> LogConnection:
        return LogConnection(cid, topic, msgtype, owner=self)

    @property
    def message_count(self) -> int:
        """Return the number of messages at most (the survey's usable records of each topic)."""
        total = 0
        for role, topics in _TOPICS_OF_ROLE.items():
            source = self.roles.get(role)
            if source is not None:
                total += self._survey.counts[role][source] * len(topics)
        return total

    def close(self) -> None:
        """Forget the survey (idempotent); the file is open only while reading."""
        self._protocol = None

    def __enter__(self) -> MarineLog:
        """Open the log (:meth:`open`)."""
        self.open()
        return self

    def __exit__(self, *exc: object) -> None:
        """Close the log."""
        self.close()

    def messages(self, connections: Iterable[LogConnection] | None = None
                 ) -> Iterator[tuple[LogConnection, int, bytes]]:
        """
        Yield (connection, arrival ns, CDR bytes) of every message, in log order.

        ``connections``: only those (default all). Each call reads the log anew and recounts
        ``counts.messages``, ``counts.used`` and the timing's skips (``untimed``,
        ``repeated``, ``time_jump``, ``bad_time``).
        """
        if self._protocol is None:
            raise MarineLogError(f'{self.path}: the log is not open')
        wanted = None if connections is None else {c.topic for c in connections}
        counts = self.counts
        for reason in ('untimed', 'repeated', 'time_jump', 'bad_time'):
            counts.skipped.pop(reason, None)
        counts.messages.clear()
        counts.used.clear()
        assembler = Assembler(self.roles)
        for timed in self._protocol.timed(self.roles):
            if timed.skip is not None:
                counts.skipped[timed.skip] += 1
                continue
            if not (0 <= timed.stamp_ns <= _MAX_STAMP_NS and 0 <= timed.arrival_ns
                    <= _MAX_STAMP_NS):
                counts.skipped['bad_time'] += 1
                continue
            made = assembler.feed(timed.stamp_ns, timed.decoded)
            if made:
                counts.used[timed.decoded.kind] += 1
            for topic, msg in made:
                counts.messages[topic] += 1
                if wanted is None or topic in wanted:
                    yield self._by_topic[topic], timed.arrival_ns, bags.serialize(msg)
        note = [n for n in counts.notes if n.startswith(('headings published magnetic',
                                                         "the clock's minute stuck",
                                                         'the receiver is past a GPS week'))]
        for n in note:
            counts.notes.remove(n)
        if self._protocol.clock_note is not None:
            counts.notes.append(self._protocol.clock_note)
        if assembler.magnetic_only:
            counts.notes.append(f'headings published magnetic (no variation in the log): '
                                f"{assembler.magnetic_only}; set the navigator's "
                                'imu.declination')

    def deserialize(self, raw: bytes | memoryview, msgtype: str) -> Any:
        """Return the message (rosbags' dataclass) of CDR bytes."""
        return self.typestore.deserialize_cdr(raw, msgtype)


def open_log(path: str | Path, *, date: datetime.date | None = None) -> MarineLog:
    """
    Return a marine log, surveyed (:meth:`MarineLog.open`), ready for ``messages()``.

    ``date``: the UTC date of a log whose only times are times of day and which has no date of
    its own (NMEA 0183: GGA, GLL without RMC or ZDA; NMEA 2000: a capture of times of day
    without a GNSS time); a log with a date keeps it. Raises :class:`MarineLogError` (one
    line) for a file that is not a marine log or cannot be replayed, :class:`NoPositionError`
    for one without a position.
    """
    log = MarineLog(path, date=date)
    log.open()
    return log
