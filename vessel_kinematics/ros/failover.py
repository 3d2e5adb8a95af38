"""
Failover between heading sources by priority, as Project11's mru_transform does it.

The ``imu`` topics (``imu.topics``) are in priority order. The source in use is the first whose
last usable message (converted without a rejection) is at most ``imu.failover_timeout`` older,
by header stamp, than the newest heading of any source, and that the estimator has not refused
as faulty (``frozen_input``, a numerical failure) within that timeout. Every other source
stands by: its messages are counted (``standby``) and not fused, so that two compasses'
different biases never mix. A source that comes back (fresh, its fault over) takes over again
from any lower one. Stamps, not a clock: the node and the replay choose alike.
"""

from __future__ import annotations

from typing import Sequence

__all__ = ['FAULTS', 'HeadingFailover']

#: The estimator's refusals that mark a heading source faulty (by their Reason value).
FAULTS = frozenset({'frozen_input', 'numerical', 'implausible_state'})


class HeadingFailover:
    """The heading sources of ``topics`` (priority order) and the one in use."""

    def __init__(self, topics: Sequence[str], timeout_s: float) -> None:
        self.topics = tuple(topics)
        self._timeout = int(round(timeout_s * 1e9))
        self._last_ok: list[int | None] = [None] * len(self.topics)
        self._faulty_until = [0] * len(self.topics)
        self._newest = 0
        #: The index of the source in use (None before any usable heading).
        self.active: int | None = None
        #: How many times the source in use changed.
        self.switches = 0

    @property
    def in_use(self) -> str | None:
        """Return the topic in use, None before any usable heading."""
        return None if self.active is None else self.topics[self.active]

    def offer(self, index: int, stamp_ns: int) -> bool:
        """Take a usable heading of source ``index``; return True when it is the one to fuse."""
        last = self._last_ok[index]
        self._last_ok[index] = stamp_ns if last is None else max(last, stamp_ns)
        self._newest = max(self._newest, stamp_ns)
        chosen = None
        for i, seen in enumerate(self._last_ok):
            if (seen is not None and self._newest - seen <= self._timeout
                    and self._faulty_until[i] <= self._newest):
                chosen = i
                break
        if chosen != self.active and chosen is not None:
            if self.active is not None:
                self.switches += 1
            self.active = chosen
        return chosen == index

    def refused(self, index: int, stamp_ns: int, reason: str) -> None:
        """Mark source ``index`` faulty for the timeout when the estimator refused it so."""
        if reason in FAULTS:
            self._faulty_until[index] = max(self._faulty_until[index], stamp_ns + self._timeout)
