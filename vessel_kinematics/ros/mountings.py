"""
Where each sensor sits on the vessel: its mounting from /tf_static, else from the parameters.

A sensor message names its frame (``header.frame_id``; an Odometry's twist its
``child_frame_id``). :class:`Mountings` looks that frame up in the static transform tree of
``/tf_static`` (:class:`~vessel_kinematics.ros.static_tf.StaticTree`, what a URDF's
robot_state_publisher or a static_transform_publisher latches) and returns its pose in the base
frame; the base frame itself, no frame id, or a frame the tree does not connect to the base
frame take the parameters (``gnss.antenna_position``, ``imu.mounting_rpy``,
``velocity.mounting_rpy`` and ``velocity.sensor_position``; identity by default). Each change of
source is said once, as a line for the log, and the source in use per input is kept for
``/diagnostics``.

A peer may send anything on ``/tf_static``, so it is taken within bounds: a message of more
than :data:`MAX_TRANSFORMS_PER_MESSAGE` transforms (or, read raw by the node,
:data:`MAX_TF_STATIC_BYTES`; :func:`oversized` reads its CDR header only) is refused whole as
``too_large``; the tree refuses lever arms beyond the parameters' bound and holds a bounded
number of frames. A mounting change is checked against the one in use: a lever arm beyond
:data:`~vessel_kinematics.ros.static_tf.MAX_LEVER_ARM` after chaining, or moved by more than
:data:`MAX_MOUNTING_STEP` from a /tf_static mounting in use, is refused (the one in use is kept)
as ``implausible_mounting``. Changes and refusals are counted per input (:attr:`Mountings.counts`,
in ``/diagnostics``).
"""

from __future__ import annotations

import math
import struct
from typing import Any

from vessel_kinematics.estimation import Reason
from vessel_kinematics.ros.params import NavigatorParams
from vessel_kinematics.ros.static_tf import (MAX_FRAME_ID, MAX_LEVER_ARM, Mounting,
                                             StaticTransform, StaticTree, strip_frame)

__all__ = ['LABELS', 'MAX_MOUNTING_STEP', 'MAX_MOUNTINGS', 'MAX_TF_STATIC_BYTES',
           'MAX_TRANSFORMS_PER_MESSAGE', 'Mountings', 'oversized', 'static_transforms_from_msg']

#: What each input's mounting is called in the log and in ``/diagnostics``.
LABELS = {'fix': 'gnss antenna', 'imu': 'imu mounting', 'velocity': 'velocity mounting',
          'gnss_velocity': 'gnss velocity antenna'}
#: Most (input, frame id) mountings remembered (frame ids come from messages: bounded).
MAX_MOUNTINGS = 64
#: Most transforms in one /tf_static message (a URDF's fixed joints are tens). Deserialising one
#: costs about 50 us in rclpy: this bounds a message to a few IMU periods of the node's time.
MAX_TRANSFORMS_PER_MESSAGE = 256
#: Largest serialised /tf_static message (bytes) the node deserialises.
MAX_TF_STATIC_BYTES = 256 * 1024
#: Fewest bytes of one serialised TransformStamped: a stamp, two 1-byte strings, 7 doubles.
MIN_TRANSFORM_BYTES = 8 + 2 * 5 + 7 * 8
#: Largest move (m) of a lever arm from a /tf_static mounting in use that is taken as a change:
#: a sensor does not move by more on a hull; a larger jump is a broken or hostile publisher.
MAX_MOUNTING_STEP = 100.0
#: Lines said per input about its mounting; a mounting that keeps changing (a flapping
#: publisher) is then counted only, with one line saying so.
MAX_MOUNTING_LINES = 5


def oversized(raw: bytes | memoryview) -> tuple[int, str] | None:
    """
    Return (transforms, why) when a serialised tf2_msgs/TFMessage is too large to take, or None.

    Reads its size and the transform count of its CDR header (encapsulation, then the
    sequence length) only: a huge message costs nothing before it is refused. The count is
    at most what its bytes can hold (a garbage header claims billions).
    """
    count = 0
    if len(raw) >= 8:
        (count,) = struct.unpack_from('<I' if bytes(raw[1:2]) == b'\x01' else '>I', raw, 4)
        count = min(count, len(raw) // MIN_TRANSFORM_BYTES)
    if len(raw) > MAX_TF_STATIC_BYTES:
        return max(count, 1), f'{len(raw)} bytes, more than {MAX_TF_STATIC_BYTES}'
    if count > MAX_TRANSFORMS_PER_MESSAGE:
        return count, f'{count} transforms, more than {MAX_TRANSFORMS_PER_MESSAGE}'
    return None


def static_transforms_from_msg(msg: Any) -> list[StaticTransform]:
    """
    Return the transforms of a tf2_msgs/TFMessage (``/tf_static``) as static-tree records.

    Each geometry_msgs/TransformStamped: parent ``header.frame_id``, ``child_frame_id``,
    translation (m) and rotation ``xyzw`` as published (checked by the tree). rclpy messages
    and rosbags' dataclasses alike.
    """
    out = []
    for t in msg.transforms:
        tr, rot = t.transform.translation, t.transform.rotation
        out.append(StaticTransform(str(t.header.frame_id), str(t.child_frame_id),
                                   (float(tr.x), float(tr.y), float(tr.z)),
                                   (float(rot.x), float(rot.y), float(rot.z), float(rot.w))))
    return out


class Mountings:
    """The inputs' mountings: the static tree, resolved per (input, frame id) and tree version."""

    def __init__(self, params: NavigatorParams) -> None:
        self.params = params
        self.tree = StaticTree()
        #: The source in use per input: ``'tf_static <frame>'`` or ``'parameters'``.
        self.sources: dict[str, str] = {}
        self._resolved: dict[tuple[str, str], Mounting | None] = {}
        self._version = 0
        self._said: dict[tuple[str, str], str] = {}
        #: The mounting in use per input (None: the parameters').
        self._in_use: dict[str, Mounting | None] = {}
        #: For /diagnostics: ``'<label> changes'`` and ``'<label> refused'`` per input.
        self.counts: dict[str, int] = {}
        self._lines: dict[str, int] = {}

    def set_params(self, params: NavigatorParams) -> None:
        """Take new parameters (the base frame and the parameters' mountings may change)."""
        self.params = params
        self._resolved.clear()

    def take(self, msg: Any) -> int:
        """
        Take one ``/tf_static`` message (tf2_msgs/TFMessage) into the tree.

        The latest transform per child frame is kept (several latched broadcasters each re-send
        their own). A message of more than :data:`MAX_TRANSFORMS_PER_MESSAGE` is refused whole
        (``too_large``). Return the number of transforms that changed.
        """
        count = len(msg.transforms)
        if count > MAX_TRANSFORMS_PER_MESSAGE:
            self.tree.refuse(Reason.TOO_LARGE, count)
            return 0
        return self.tree.update(static_transforms_from_msg(msg))

    def _count(self, key: str) -> None:
        self.counts[key] = self.counts.get(key, 0) + 1

    def _implausible(self, name: str, mounting: Mounting) -> str | None:
        """Return why ``mounting`` cannot replace input ``name``'s mounting in use, or None."""
        if max(abs(c) for c in mounting.t) > MAX_LEVER_ARM:
            return f'lever arm beyond {MAX_LEVER_ARM:.0f} m'
        held = self._in_use.get(name)
        if held is not None and math.dist(held.t, mounting.t) > MAX_MOUNTING_STEP:
            return (f'lever arm moved {math.dist(held.t, mounting.t):.3g} m from the one in '
                    f'use, more than {MAX_MOUNTING_STEP:.0f} m')
        return None

    def of(self, name: str, frame: str) -> tuple[Mounting | None, str | None]:
        """
        Return the mounting of input ``name``'s ``frame`` (None: the parameters) and a log line.

        The line says where the mounting comes from, once per change (else None). A name longer
        than any the tree holds is cut to :data:`~.static_tf.MAX_FRAME_ID`: it is in no tree,
        and its caches and lines stay small.
        """
        frame = frame[:MAX_FRAME_ID]
        key = (name, frame)
        if self._version == self.tree.version:
            try:
                return self._resolved[key], None
            except KeyError:
                pass
        else:
            self._resolved.clear()
            self._version = self.tree.version
        if len(self._resolved) >= MAX_MOUNTINGS:
            self._resolved.clear()
        stripped = strip_frame(frame)
        base = self.params.base_frame
        mounting = None
        if not stripped or stripped == base:
            why = 'no frame_id' if not stripped else f'frame {stripped} is the base frame'
        else:
            mounting = self.tree.lookup(stripped, base)
            why = (f'frame {stripped} not in /tf_static' if stripped not in self.tree
                   else f'frame {stripped} not connected to {base} in /tf_static')
        label = LABELS[name]
        why_not = self._implausible(name, mounting) if mounting is not None else None
        if mounting is not None and why_not is not None:
            self.tree.refuse(Reason.IMPLAUSIBLE_MOUNTING)
            self._count(f'{label} refused')
            kept = self._in_use.get(name)
            self._resolved[key] = kept
            return kept, self._say(name, f'{label} from /tf_static refused: frame {stripped} '
                                         f'({mounting.describe()}): {why_not}; the one in use '
                                         'is kept')
        if name in self._in_use and self._in_use[name] != mounting:
            self._count(f'{label} changes')
        self._in_use[name] = mounting
        if mounting is not None:
            self.sources[name] = f'tf_static {stripped}'
            line = f'{label} from /tf_static: frame {stripped} ({mounting.describe()})'
        else:
            self.sources[name] = 'parameters'
            line = f'{label} from parameters ({self._parameter_text(name)}) ({why})'
        self._resolved[key] = mounting
        if self._said.get(key) == line:
            return mounting, None
        if len(self._said) >= MAX_MOUNTINGS:
            self._said.clear()
        self._said[key] = line
        return mounting, self._say(name, line)

    def _say(self, name: str, line: str) -> str | None:
        """Return ``line`` for the log while input ``name`` has lines left, else None."""
        said = self._lines.get(name, 0)
        self._lines[name] = said + 1
        if said < MAX_MOUNTING_LINES:
            return line
        if said == MAX_MOUNTING_LINES:
            return (f'{LABELS[name]} keeps changing: further changes are counted in '
                    f'/diagnostics, not logged')
        return None

    def _parameter_text(self, name: str) -> str:
        """Return the parameters that give the mounting of input ``name``, with values."""
        p = self.params
        if name in ('fix', 'gnss_velocity'):
            return f'gnss.antenna_position {list(p.gnss_antenna_position)}'
        if name == 'imu':
            return f'imu.mounting_rpy {list(p.imu_mounting_rpy)}'
        return (f'velocity.mounting_rpy {list(p.velocity_mounting_rpy)}, '
                f'velocity.sensor_position {list(p.velocity_sensor_position)}')
