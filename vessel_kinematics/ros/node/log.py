"""
Logging that cannot fail, throttled per key: a log line must never stop the node.

rclpy refuses a second severity from one call site (its logger remembers each site's severity,
and the next call of another raises ``ValueError``); a log call inside an ``except`` that raises
would take the node down. :class:`NodeLog` logs each severity from a call site of its own and
swallows (and counts) whatever the logger raises.
"""

from __future__ import annotations

import time
from typing import Any

__all__ = ['NodeLog', 'WARN_PERIOD']

#: Minimum time between two lines of the same key (s).
WARN_PERIOD = 5.0


class NodeLog:
    """A node's logger: :meth:`info`, :meth:`warning`, :meth:`error`, :meth:`throttled`."""

    def __init__(self, logger: Any, period: float = WARN_PERIOD) -> None:
        self._logger = logger
        self.period = period
        #: Lines the logger refused (counted, never raised).
        self.failures = 0
        self._last: dict[str, float] = {}
        self._quiet: dict[str, int] = {}

    def info(self, text: str) -> None:
        """Log ``text`` at INFO."""
        try:
            self._logger.info(text)
        except Exception:  # noqa: B902 - a log line must never stop the node
            self.failures += 1

    def warning(self, text: str) -> None:
        """Log ``text`` at WARN."""
        try:
            self._logger.warning(text)
        except Exception:  # noqa: B902 - a log line must never stop the node
            self.failures += 1

    def error(self, text: str) -> None:
        """Log ``text`` at ERROR."""
        try:
            self._logger.error(text)
        except Exception:  # noqa: B902 - a log line must never stop the node
            self.failures += 1

    def throttled(self, key: str, text: str, *, error: bool = False) -> None:
        """Log ``text`` at most every ``period`` s per ``key``, saying how many were quiet."""
        now = time.monotonic()
        last = self._last.get(key)
        if last is not None and now - last < self.period:
            self._quiet[key] = self._quiet.get(key, 0) + 1
            return
        self._last[key] = now
        quiet = self._quiet.pop(key, 0)
        if quiet:
            text += f' ({quiet} more like this in the last {now - (last or now):.0f} s)'
        if error:
            self.error(text)
        else:
            self.warning(text)
