"""
Late measurements fused at their own stamps: a state history with re-application.

Fossen's kinematics (ch. 2) integrate forward in time; the inputs do not arrive in stamp
order. A GNSS receiver delivers its fix 0.1–0.5 s after the instant it measured, while the IMU
arrives within milliseconds. :class:`Timeline` keeps every measurement of the last
``history_length`` seconds and a copy of the estimator's state every
:data:`SNAPSHOT_INTERVAL` s of stamp time. A measurement stamped before the newest one goes
back to the last copy before its stamp and applies everything from there again, in stamp
order: the state is the one it would have been had the inputs arrived in order, to the bit
(robot_localization's ``history_length`` and ``smooth_lagged_data``, for the same reason).

The pace input (the IMU: the one that carries the state forward, many times a second) is
applied at once. Any other measurement stamped more than one pace period after the newest
pace sample (so that pace samples stamped before it are still to come) waits for the pace to
reach its stamp, and is then applied in order, so that a sensor whose clock runs a little
ahead of the IMU's never makes every IMU sample late (which would re-apply the history
hundreds of times a second). Within one period it is applied at once: the next pace sample
will be newer. It waits only while the pace flows: while its newest stamp is within
:data:`PACE_SILENT` s of the newest stamp handed in. Everything here goes by stamps
and the order of arrival, never by the arrival's time, so the node and the replay agree.

The order is the key (stamp ns, input rank, topic index): equal stamps of different inputs go
in a fixed order, so any arrival order within ``history_length`` gives the same state. A
second message with the key of one already held (a sensor whose stamps froze) is refused as
``repeated_stamp``; one stamped more than ``history_length`` before the newest, as
``too_late``. Neither moves the state.
"""

from __future__ import annotations

import bisect
import heapq
import pickle
from typing import Any, Callable, Mapping, NamedTuple

from vessel_kinematics.estimation.records import Reason, Rejection

__all__ = ['Outcome', 'PACE_SILENT', 'SNAPSHOT_INTERVAL', 'Timeline']

#: Stamp time (s) between two copies of the state (the re-application starts at the last copy
#: before a late message's stamp: at most this much more work per late message).
SNAPSHOT_INTERVAL = 0.1
#: The pace input is silent (nothing waits for it) when its newest stamp is this far (s)
#: behind the newest stamp handed in: a 2 Hz IMU still paces, a dead one does not.
PACE_SILENT = 0.5
#: The estimator's parts that never change after set-up: shared by the copies, not copied.
_SHARED = ('config', 'layout', 'table')

Key = tuple[int, int, int]


class Outcome(NamedTuple):
    """What became of ``measurement`` of input ``name``: None (taken) or its rejection."""

    name: str
    rejection: Rejection | None
    measurement: Any


class _Entry(NamedTuple):
    """One measurement: its order ``key`` (stamp ns, rank, topic), input ``name``, and it."""

    key: Key
    name: str
    measurement: Any


class _Snapshot(NamedTuple):
    """The estimator's state (pickled) after every entry up to ``key`` was applied."""

    key: Key
    state: bytes


_BEFORE_ALL: Key = (-1, -1, -1)


class Timeline:
    """
    The estimator's recent history: measurements applied in stamp order, whatever their arrival.

    ``estimator``: the :class:`~.estimator.Estimator` (its state is copied and restored in
    place, so its bound methods stay valid); ``updates``: the update of each input name, in
    the order of equal stamps; ``history_length`` (s): how far back a late measurement is
    still fused at its stamp; ``pace``: the input that carries the state forward.
    """

    def __init__(self, estimator: Any, updates: Mapping[str, Callable[[Any], Any]],
                 history_length: float, pace: str = 'imu') -> None:
        self.estimator = estimator
        self.updates = dict(updates)
        self._rank = {name: i for i, name in enumerate(self.updates)}
        self.pace = pace
        self.history_ns = int(round(history_length * 1e9))
        self._silent_ns = int(PACE_SILENT * 1e9)
        self._interval_ns = int(SNAPSHOT_INTERVAL * 1e9)
        #: Late measurements re-applied at their stamps, and the updates that took in all.
        self.late = 0
        self.reapplied = 0
        self.clear()

    def reconfigure(self, config: Any) -> None:
        """
        Apply a new :class:`~.config.FilterConfig` to the estimator, keeping what still holds.

        What waits for the pace input stays. The history stays unless the state itself changed
        kind (:meth:`~.config.FilterConfig.structure`): the copies hold the state, not the
        configuration, so a late measurement re-applied from one is taken as the new
        configuration takes it. Otherwise the history starts at the state as it is now.
        """
        old = self.estimator.config
        self.estimator.set_config(config)
        self.history_ns = int(round(config.history_length * 1e9))
        if config.structure() != old.structure():
            self._start_history()

    def clear(self) -> None:
        """Forget the history and what waits (after a reset): the next message starts anew."""
        self._start_history()
        # (key, arrival number, entry): equal keys (a sensor repeating a stamp) leave in
        # arrival order, and the heap never compares two measurements.
        self._waiting: list[tuple[Key, int, _Entry]] = []
        self._arrivals = 0
        self._pace_key: Key | None = None
        self._pace_period = 0
        self._newest_seen = 0

    def _start_history(self) -> None:
        """Start the history at the estimator's state as it is now."""
        self._entries: list[_Entry] = []
        self._keys: list[Key] = []
        self._snapshots: list[_Snapshot] = [_Snapshot(_BEFORE_ALL, self._copy())]

    @property
    def newest_ns(self) -> int | None:
        """Return the newest stamp applied (ns), None when nothing is."""
        return self._keys[-1][0] if self._keys else None

    @property
    def waiting(self) -> int:
        """Return how many measurements wait for the pace input to reach their stamps."""
        return len(self._waiting)

    def waiting_by_input(self) -> dict[str, int]:
        """Return how many measurements of each input wait (inputs with none left out)."""
        counts: dict[str, int] = {}
        for _, _, entry in self._waiting:
            counts[entry.name] = counts.get(entry.name, 0) + 1
        return counts

    def apply(self, name: str, measurement: Any, topic: int = 0) -> list[Outcome]:
        """
        Take ``measurement`` of input ``name``; say what was applied.

        The outcomes of every measurement applied now, in order: waiting ones whose time came,
        and this one unless it waits (then it is not among them). ``topic``: the index of its
        topic among the input's topics.
        """
        stamp = measurement.stamp_ns
        if stamp <= 0:                      # the estimator's own answer (zero_stamp)
            return [Outcome(name, self.updates[name](measurement), measurement)]
        entry = _Entry((stamp, self._rank[name], topic), name, measurement)
        self._newest_seen = max(self._newest_seen, stamp)
        pace = name == self.pace
        if pace and (self._pace_key is None or entry.key > self._pace_key):
            if self._pace_key is not None:
                self._pace_period = min(stamp - self._pace_key[0], self._silent_ns)
            self._pace_key = entry.key
        out = self._release(entry.key if pace else None)
        if (not pace and self.pace_flowing
                and stamp > self._pace_key[0] + self._pace_period):  # type: ignore[index]
            self._arrivals += 1
            heapq.heappush(self._waiting, (entry.key, self._arrivals, entry))
            return out
        out.append(Outcome(name, self._apply(entry), measurement))
        return out

    def flush(self) -> list[Outcome]:
        """Apply every waiting measurement (the end of a replay); say what became of them."""
        return [Outcome(e.name, self._apply(e), e.measurement)
                for e in (heapq.heappop(self._waiting)[2] for _ in range(len(self._waiting)))]

    @property
    def pace_flowing(self) -> bool:
        """Return True when the pace's newest stamp is within PACE_SILENT of the newest."""
        return (self._pace_key is not None
                and self._newest_seen - self._pace_key[0] <= self._silent_ns)

    def _release(self, before: Key | None) -> list[Outcome]:
        """Apply, in order, what waits for a pace sample at ``before``, all if it is silent."""
        out = []
        flowing = self.pace_flowing
        while self._waiting:
            key, _, entry = self._waiting[0]
            if flowing and (before is None or key >= before):
                break
            heapq.heappop(self._waiting)
            out.append(Outcome(entry.name, self._apply(entry), entry.measurement))
        return out

    def _apply(self, entry: _Entry) -> Rejection | None:
        """Apply ``entry`` at its stamp: at the end, or by re-applying what came after it."""
        key = entry.key
        if not self._keys or key > self._keys[-1]:
            rejection = self.updates[entry.name](entry.measurement)
            self._entries.append(entry)
            self._keys.append(key)
            self._snapshot_if_due(key)
            self._prune()
            return rejection
        at = bisect.bisect_left(self._keys, key)
        if at < len(self._keys) and self._keys[at] == key:
            return Rejection(Reason.REPEATED_STAMP,
                             f'stamp {key[0] * 1e-9:.9f} s repeats one already taken')
        newest = self._keys[-1][0]
        if newest - key[0] > self.history_ns:
            return Rejection(Reason.TOO_LATE,
                             f'stamp {(newest - key[0]) * 1e-9:.3f} s older than the newest, '
                             f'beyond history_length {self.history_ns * 1e-9:g} s')
        return self._insert(at, entry)

    def _insert(self, at: int, entry: _Entry) -> Rejection | None:
        """Go back to the last copy before ``entry`` and apply it and all after it again."""
        s = bisect.bisect_left(self._snapshots, entry.key, key=lambda snap: snap.key) - 1
        if s < 0:                           # older than the oldest copy kept
            return Rejection(Reason.TOO_LATE, 'stamp older than the history kept')
        est = self.estimator
        origin, origin_event = est.origin, est._origin_event
        del self._snapshots[s + 1:]
        self._restore(self._snapshots[s].state)
        self._entries.insert(at, entry)
        self._keys.insert(at, entry.key)
        first = bisect.bisect_right(self._keys, self._snapshots[s].key)
        rejection, events = None, []
        for i in range(first, len(self._entries)):
            e = self._entries[i]
            result = self.updates[e.name](e.measurement)
            if e is entry:
                rejection = result
                events = est.pop_events()   # the new measurement's, said once
            else:
                est.pop_events()            # said already when it arrived
            self._snapshot_if_due(e.key)
        est._events = events
        est._origin_event = origin_event or est.origin != origin
        self.late += 1
        self.reapplied += len(self._entries) - first
        return rejection

    def _snapshot_if_due(self, key: Key) -> None:
        last = self._snapshots[-1].key[0]
        if last < 0 or key[0] - last >= self._interval_ns:
            self._snapshots.append(_Snapshot(key, self._copy()))

    def _prune(self) -> None:
        """Drop what is older than ``history_length``, keeping the last copy before it."""
        horizon = self._keys[-1][0] - self.history_ns
        snaps = self._snapshots
        drop = 0
        while drop + 1 < len(snaps) and snaps[drop + 1].key[0] < horizon:
            drop += 1
        if drop:
            del snaps[:drop]
            n = bisect.bisect_right(self._keys, snaps[0].key)
            del self._entries[:n]
            del self._keys[:n]

    def _copy(self) -> bytes:
        """
        Return the estimator's state, its events left out, as pickled bytes.

        Pickle rather than ``copy.deepcopy``: the same copy in a fifth of the time (about
        60 us against 300 us for the surface estimator), which a replay pays ten times a second
        of its bag.
        """
        state = {name: value for name, value in self.estimator.__dict__.items()
                 if name not in _SHARED}
        state['_events'] = []
        state['_origin_event'] = False
        return pickle.dumps(state, protocol=pickle.HIGHEST_PROTOCOL)

    def _restore(self, snap: bytes) -> None:
        """Set the estimator's state to the copy ``snap`` (the copy stays for later)."""
        state = self.estimator.__dict__
        shared = {name: state[name] for name in _SHARED if name in state}
        state.clear()
        state.update(shared)
        state.update(pickle.loads(snap))
