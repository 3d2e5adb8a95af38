"""
From records to messages: which sentence or PGN feeds each topic, and how the IMU is composed.

Both protocols end here. A log usually holds several sources of one thing (RMC, GGA and GLL
all give a position; two talkers may send HDT): :class:`Survey` counts each source's usable
records in a first pass over the log, and :meth:`Survey.roles` picks one per role, so that
each topic has one source and no message is doubled:

* first, a source whose readings never change over the whole log (a speed log reading 0.0 kn
  throughout, a compass stuck on one heading) is a dead instrument: it is chosen only where
  no source of the role reads anything else (a boat at her mooring), and the summary names it
  (:meth:`Survey.constant`). NMEA 2000 buses often carry such a second paddlewheel, unfitted
  or uncalibrated, beside the one that works;
* the best type by the protocol's priority (``nmea0183.PRIORITIES``, ``nmea2000.PRIORITIES``)
  among those with at least half as many usable records as the most plentiful one (a GGA at
  1 Hz beside an RMC at 1 Hz gives the fix, a GGA sent once does not);
* of that type, the talker or source address with the most (of headings, a true one before
  a magnetic one with up to twice as many: NMEA 2000 sends both in PGN 127250, and NMEA 0183
  puts HDT before HDG and HDM alike); but the position comes from the
  receiver that gives the course and speed over ground (the same talker or source address)
  where that one sends at least half as many positions as the most plentiful: one antenna
  for the position and its COG/SOG. Two receivers on one NMEA 2000 bus are common (canboat's
  Furuno captures: a satellite compass at 5 Hz and a second GNSS at 8 Hz whose antenna sits
  elsewhere, 6 m RMS apart, and whose track turns the course 3-4 deg off the compass's COG).

:class:`Assembler` then turns each stamped record of the chosen sources into a message
(:mod:`~vessel_kinematics.marine.messages`):

* ``fix``: each position (a no-fix one as NO_FIX);
* ``heading``: each heading or attitude with a heading is an Imu; roll and pitch are its own
  (an attitude sentence) or the latest of the ``attitude`` source within :data:`MAX_AGE_NS`,
  the rate the latest of the ``rate`` source within :data:`MAX_AGE_NS`; a magnetic heading
  becomes true with its deviation and variation (psi = magnetic + deviation + variation; the
  variation the sentence's own, else the log's latest from RMC, HDG, 127250 or 127258); one
  without any variation is published as it is, and counted;
* ``speed``: each speed through water; ``cog``: each COG/SOG (a magnetic COG made true).
"""

from __future__ import annotations

from collections import Counter
from typing import Any, Mapping, Sequence

from vessel_kinematics.marine import messages
from vessel_kinematics.marine.records import (Attitude, CourseSpeed, Decoded, Heading, Position,
                                              TurnRate, Variation, WaterSpeed, wrap_2pi)

__all__ = ['Assembler', 'MAX_AGE_NS', 'ROLES', 'Source', 'Survey']

#: The roles a source plays (the keys of the protocols' PRIORITIES).
ROLES = ('fix', 'heading', 'attitude', 'rate', 'speed', 'cog')

#: The oldest rate of turn, roll or pitch (ns) combined with a heading into one Imu.
MAX_AGE_NS = 1_500_000_000

#: A source: a sentence type or PGN, and its talker or source address.
Source = tuple[str, str]


def _roles_of(record: Any) -> tuple[str, ...]:
    """Return the roles a record can play (when it is usable)."""
    if isinstance(record, Position):
        return ('fix',) if record.status >= 0 else ()
    if isinstance(record, Heading):
        return ('heading',)
    if isinstance(record, Attitude):
        tilt = ('attitude',) if record.theta is not None or record.phi is not None else ()
        return (('heading',) if record.psi is not None else ()) + tilt
    if isinstance(record, TurnRate):
        return ('rate',)
    if isinstance(record, WaterSpeed):
        return ('speed',)
    if isinstance(record, CourseSpeed):
        return ('cog',)
    return ()


def _reading(record: Any, role: str) -> tuple[float | None, ...]:
    """Return what a record reads in a role: a source that never changes it is dead."""
    if role == 'fix':
        return (record.lat_deg, record.lon_deg)
    if role == 'heading':
        return (record.psi,)
    if role == 'attitude':
        return (record.theta, record.phi)
    if role == 'rate':
        return (record.rate,)
    if role == 'speed':
        return (record.speed,)
    return (record.cog, record.sog)


class Survey:
    """The usable records of each role, per source, counted over a whole log."""

    def __init__(self) -> None:
        self.counts: dict[str, Counter] = {role: Counter() for role in ROLES}
        #: Each source's first reading in each role ...
        self._first: dict[tuple[str, Source], tuple[float | None, ...]] = {}
        #: ... and the sources whose reading has changed since.
        self._varied: set[tuple[str, Source]] = set()
        #: The heading sources that sent a magnetic heading.
        self._magnetic: set[Source] = set()

    def add(self, decoded: Decoded) -> None:
        """Count one decoded sentence or PGN."""
        if decoded.skip is not None:
            return
        key = (decoded.kind, decoded.source)
        for record in decoded.records:
            for role in _roles_of(record):
                self.counts[role][key] += 1
                if role == 'heading' and isinstance(record, Heading) and record.magnetic:
                    self._magnetic.add(key)
                entry = (role, key)
                if entry not in self._varied:
                    reading = _reading(record, role)
                    if self._first.setdefault(entry, reading) != reading:
                        self._varied.add(entry)

    def constant(self, role: str) -> dict[Source, tuple[float | None, ...]]:
        """
        Return the sources of a role left out as dead, with the one reading each gave.

        A source is dead when its reading never changed over the log while another source of
        the role's did change.
        """
        live = [key for key in self.counts[role] if (role, key) in self._varied]
        if not live:
            return {}
        return {key: self._first[(role, key)] for key in self.counts[role]
                if (role, key) not in self._varied}

    def _true_first(self, of_kind: dict[Source, int]) -> dict[Source, int]:
        """Return the true headings of a kind when they are plenty, else all of them."""
        true = {key: n for key, n in of_kind.items() if key not in self._magnetic}
        if true and 2 * max(true.values()) >= max(of_kind.values()):
            return true
        return of_kind

    def roles(self, priorities: Mapping[str, Sequence[str]]) -> dict[str, Source | None]:
        """Return the source of each role (None when the log has none)."""
        chosen: dict[str, Source | None] = {}
        for role in ROLES:
            dead = self.constant(role)
            counts = Counter({key: n for key, n in self.counts[role].items()
                              if key not in dead})
            chosen[role] = None
            if not counts:
                continue
            most = max(counts.values())
            for kind in priorities.get(role, ()):
                of_kind = {key: n for key, n in counts.items() if key[0] == kind}
                if of_kind and 2 * max(of_kind.values()) >= most:
                    if role == 'heading':
                        of_kind = self._true_first(of_kind)
                    chosen[role] = max(of_kind, key=lambda key: (of_kind[key], key[1]))
                    break
        fix, cog = chosen['fix'], chosen['cog']
        if fix is not None and cog is not None and fix[1] != cog[1]:
            of_kind = self.counts['fix']
            receiver = (fix[0], cog[1])        # the COG/SOG's receiver, the position's type
            if receiver not in self.constant('fix') and 2 * of_kind[receiver] >= of_kind[fix]:
                chosen['fix'] = receiver
        return chosen


class Assembler:
    """
    The navigator's messages of a log's stamped records, for the sources chosen per role.

    :meth:`feed` takes each decoded sentence or PGN with its stamp, in log order, and returns
    the (topic, message) pairs it makes. ``magnetic_only`` counts the headings published
    magnetic for want of a variation.
    """

    def __init__(self, roles: Mapping[str, Source | None]) -> None:
        self.roles = dict(roles)
        self._variation: float | None = None
        self._rate: tuple[int, float] | None = None
        self._tilt: tuple[int, Attitude] | None = None
        #: Headings published magnetic: no variation was known.
        self.magnetic_only = 0

    def _fresh(self, entry: tuple[int, Any] | None, stamp_ns: int) -> Any:
        if entry is None or abs(stamp_ns - entry[0]) > MAX_AGE_NS:
            return None
        return entry[1]

    def _true(self, angle: float, variation: float | None, deviation: float | None = None
              ) -> float:
        if variation is None:
            variation = self._variation
        if variation is None:
            self.magnetic_only += 1
            variation = 0.0
        return wrap_2pi(angle + (deviation or 0.0) + variation)

    def feed(self, stamp_ns: int, decoded: Decoded) -> list[tuple[str, Any]]:
        """Return the messages of one decoded sentence or PGN stamped ``stamp_ns``."""
        if decoded.skip is not None or not decoded.records:
            return []
        key = (decoded.kind, decoded.source)
        roles = self.roles
        out: list[tuple[str, Any]] = []
        heading_records = []
        for record in decoded.records:
            if isinstance(record, Variation):
                self._variation = record.variation
            elif isinstance(record, Heading) and record.variation is not None:
                self._variation = record.variation
            if key == roles['rate'] and isinstance(record, TurnRate):
                self._rate = (stamp_ns, record.rate)
            if key == roles['attitude'] and isinstance(record, Attitude) and (
                    record.theta is not None or record.phi is not None):
                self._tilt = (stamp_ns, record)
            if key == roles['heading'] and (isinstance(record, Heading) or (
                    isinstance(record, Attitude) and record.psi is not None)):
                heading_records.append(record)
            if key == roles['fix'] and isinstance(record, Position):
                out.append((messages.FIX_TOPIC, messages.fix_msg(stamp_ns, record)))
            elif key == roles['speed'] and isinstance(record, WaterSpeed):
                out.append((messages.SPEED_TOPIC, messages.speed_msg(stamp_ns, record.speed)))
            elif key == roles['cog'] and isinstance(record, CourseSpeed):
                cog = self._true(record.cog, None) if record.magnetic else record.cog
                out.append((messages.COG_SOG_TOPIC,
                            messages.cog_sog_msg(stamp_ns, cog, record.sog)))
                out.append((messages.GNSS_VELOCITY_TOPIC,
                            messages.gnss_velocity_msg(stamp_ns, cog, record.sog)))
        for record in heading_records:
            out.append((messages.IMU_TOPIC, self._imu(stamp_ns, record)))
        return out

    def _imu(self, stamp_ns: int, record: Heading | Attitude) -> Any:
        rate = self._fresh(self._rate, stamp_ns)
        if isinstance(record, Heading):
            psi = (self._true(record.psi, record.variation, record.deviation)
                   if record.magnetic else record.psi)
            tilt = self._fresh(self._tilt, stamp_ns)
            var_psi = record.variance
        else:
            assert record.psi is not None
            psi, var_psi = record.psi, record.var_psi
            tilt = record if record.theta is not None or record.phi is not None else (
                self._fresh(self._tilt, stamp_ns))
        if tilt is None:
            return messages.imu_msg(stamp_ns, psi, rate=rate, var_psi=var_psi)
        return messages.imu_msg(stamp_ns, psi, tilt.theta, tilt.phi, rate, var_psi,
                                tilt.var_theta, tilt.var_phi)
