"""
The serialised form of every message the navigator sends: CDR bytes laid out with ``struct``.

The node publishes these bytes as they are (a raw publish), the replay writes them into its
bag: one serialisation for both drivers, and no message object built on the way. The layout is
XCDR1 little-endian, as rmw_fastrtps and rosbags write it: a 4-byte encapsulation header, then
each field aligned to its size counted from after that header; strings are a uint32 length
(with the NUL), the bytes and the NUL. Padding bytes are zeros, so the same values give the
same bytes in both drivers (Fast CDR leaves its padding unwritten). Tests deserialise every
output with ``rclpy.serialization.deserialize_message`` and with rosbags and compare the fields.

Hand-laid rather than rosbags' generic ``serialize_cdr``: building the rosbags message objects
and serialising them costs about six times as much per emission (docs/performance.md), a cost
the node pays at every output on small boards. A header's frame strings and the padding after
them depend only on the frame names, so they are laid out once per name (``lru_cache``).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
import struct
from typing import Sequence

import numpy as np
from vessel_kinematics.core.frames import NS_PER_S

__all__ = ['CDR_LE', 'diagnostic_array', 'nav_sat_fix', 'odometry', 'Status', 'tf_message',
           'Transform', 'vector3_stamped']

#: CDR encapsulation header: little-endian plain CDR, no options.
CDR_LE = b'\x00\x01\x00\x00'
_U32 = struct.Struct('<I')
_TIME = struct.Struct('<iI')
_D3 = struct.Struct('<3d')
_D6 = struct.Struct('<6d')
_D7 = struct.Struct('<7d')

#: One transform: (stamp ns, parent frame, child frame, translation x y z (m), rotation x y z
#: w), as geometry_msgs/TransformStamped holds it.
Transform = tuple[int, str, str, tuple[float, float, float], tuple[float, float, float, float]]


@dataclass(frozen=True)
class Status:
    """One diagnostic_msgs/DiagnosticStatus: level (0 OK, 1 WARN, 2 ERROR), name, values."""

    level: int
    name: str
    message: str
    values: tuple[tuple[str, str], ...]
    hardware_id: str = 'vessel_kinematics'


def _strings(offset: int, names: Sequence[str], align: int) -> bytes:
    """Return CDR strings ``names`` starting at ``offset``, padded to ``align`` after them."""
    out = bytearray()
    for name in names:
        out += bytes(-(offset + len(out)) % 4)
        data = name.encode() + b'\x00'
        out += _U32.pack(len(data)) + data
    out += bytes(-(offset + len(out)) % align)
    return bytes(out)


@lru_cache(maxsize=64)
def _after_stamp(names: tuple[str, ...]) -> bytes:
    """Return the frame strings after a Header's stamp, padded for the float64 that follows."""
    return _strings(8, names, 8)


@lru_cache(maxsize=16)
def _fix_middle(frame_id: str, status: int, service: int) -> bytes:
    """Return a NavSatFix's frame_id and NavSatStatus (int8, uint16), padded to float64."""
    strings = _strings(8, (frame_id,), 1)
    at = 8 + len(strings)
    status_cdr = struct.pack('<b', status) + bytes((at + 1) % 2) + struct.pack('<H', service)
    at += len(status_cdr)
    return strings + status_cdr + bytes(-at % 8)


@lru_cache(maxsize=64)
def _tf_strings(offset: int, parent: str, child: str) -> bytes:
    """Return a TransformStamped's frame strings after its stamp, padded to float64."""
    return _strings(offset, (parent, child), 8)


def _stamp(ns: int) -> bytes:
    """Return a builtin_interfaces/Time; ValueError for a time its int32 seconds cannot hold."""
    try:
        return _TIME.pack(*divmod(int(ns), NS_PER_S))
    except struct.error:
        raise ValueError(f'time {int(ns)} ns is not a ROS time stamp (int32 seconds, '
                         'up to 2038-01-19)') from None


def odometry(ns: int, frame_id: str, child: str, position: Sequence[float],
             q_xyzw: Sequence[float], pose_cov: np.ndarray, linear: Sequence[float],
             angular: Sequence[float], twist_cov: np.ndarray) -> bytes:
    """Return a nav_msgs/Odometry (covariances: 36 float64 each, row-major)."""
    return b''.join((CDR_LE, _stamp(ns), _after_stamp((frame_id, child)),
                     _D7.pack(*position, *q_xyzw), np.asarray(pose_cov, dtype='<f8').tobytes(),
                     _D6.pack(*linear, *angular),
                     np.asarray(twist_cov, dtype='<f8').tobytes()))


def vector3_stamped(ns: int, frame_id: str, x: float, y: float, z: float) -> bytes:
    """Return a geometry_msgs/Vector3Stamped."""
    return b''.join((CDR_LE, _stamp(ns), _after_stamp((frame_id,)), _D3.pack(x, y, z)))


def nav_sat_fix(ns: int, frame_id: str, status: int, lat: float, lon: float, alt: float,
                cov: np.ndarray, cov_type: int) -> bytes:
    """Return a sensor_msgs/NavSatFix (service 0; ``cov`` 9 float64, row-major)."""
    return b''.join((CDR_LE, _stamp(ns), _fix_middle(frame_id, status, 0),
                     _D3.pack(lat, lon, alt), np.asarray(cov, dtype='<f8').tobytes(),
                     bytes((cov_type,))))


def tf_message(transforms: Sequence[Transform]) -> bytes:
    """Return a tf2_msgs/TFMessage holding ``transforms`` (geometry_msgs/TransformStamped)."""
    body = bytearray(_U32.pack(len(transforms)))
    for stamp_ns, parent, child, t, q in transforms:
        body += _stamp(stamp_ns)        # at a multiple of 4 (the previous ends on 8)
        body += _tf_strings(len(body), parent, child)
        body += _D7.pack(*t, *q)
    return CDR_LE + bytes(body)


def diagnostic_array(ns: int, statuses: Sequence[Status], frame_id: str = '') -> bytes:
    """Return a diagnostic_msgs/DiagnosticArray of ``statuses``."""
    out = bytearray(_stamp(ns))

    def string(text: str) -> None:
        out.extend(bytes(-len(out) % 4))
        data = text.encode() + b'\x00'
        out.extend(_U32.pack(len(data)))
        out.extend(data)

    def count(n: int) -> None:
        out.extend(bytes(-len(out) % 4))
        out.extend(_U32.pack(n))

    string(frame_id)
    count(len(statuses))
    for status in statuses:
        out.append(status.level)
        for text in (status.name, status.message, status.hardware_id):
            string(text)
        count(len(status.values))
        for key, value in status.values:
            string(key)
            string(value)
    return CDR_LE + bytes(out)
