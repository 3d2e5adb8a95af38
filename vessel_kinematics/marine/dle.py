"""
NMEA 2000 logged as a raw NGT-1 stream: Yacht Devices' ``.dle`` files (YDNU-02 USB gateway).

The gateway's serial framing of :mod:`vessel_kinematics.marine.ebl` without EBL's time headers:
``DLE STX <command> <length> <payload> <checksum> DLE ETX``, only ``DLE`` escaped (doubled).
A message received (``0x93``) carries the gateway's ms counter, its one time: since the gateway
started, put on UTC by the capture's GNSS time (:mod:`~vessel_kinematics.marine.log`). A file
may start in the middle of a message (a ``DLE ETX`` first): that part is skipped.
"""

from __future__ import annotations

from pathlib import Path
from typing import Iterable, Iterator

from vessel_kinematics.marine import ebl
from vessel_kinematics.marine.nmea2000 import Frame

__all__ = ['frames', 'is_capture', 'packets']

_START = bytes((ebl.DLE, ebl.STX))


def is_capture(head: bytes) -> bool:
    """Return True when a file starting with ``head`` is a raw NGT-1 stream (DLE STX first)."""
    return head[:2] == _START or head[2:4] == _START and head[:2] == bytes((ebl.DLE, ebl.ETX))


def frames(path: str | Path) -> Iterator[Frame | None]:
    """Yield the frame of each message of the stream (None: no NMEA 2000 message)."""
    return ebl.read_ngt1(path, headers=False)


def packets(captured: Iterable[Frame]) -> Iterator[bytes]:
    """Yield the raw stream of ``captured`` whole messages, the counter from the first one."""
    first: int | None = None
    for frame in captured:
        first = frame.time_ns if first is None else first
        yield ebl.received(frame, (frame.time_ns - first) // 1_000_000, (ebl.DLE,))
