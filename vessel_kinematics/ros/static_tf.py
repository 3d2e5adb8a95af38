"""
A small static transform tree: the sensor mountings of a URDF or static_transform_publisher.

What tf2's static listener keeps of ``/tf_static``, without ROS: records ``(parent, child,
translation, rotation xyzw)`` (:class:`StaticTransform`, made from
geometry_msgs/TransformStamped by ``mountings.static_transforms_from_msg``), chained to answer
"where is frame F in the base frame" (:meth:`StaticTree.lookup`, a :class:`Mounting`).

Each transform is the pose of ``child`` in ``parent``: a point p_c in the child frame is
p_p = R(q) p_c + t in the parent frame (REP-103 frames, metres, ``q`` a unit quaternion). Two
poses compose as T_ac = T_ab ∘ T_bc: q_ac = q_ab ⊗ q_bc, t_ac = R(q_ab) t_bc + t_ab (Fossen eq.
2.72 for R(q), his Hamilton product); the inverse is (q*, −R(q)ᵀ t).

Re-publication as tf2 handles it: ``/tf_static`` is latched by several broadcasters, each of
whose messages replaces its own transforms; a transform is identified by its child frame
(every frame has one parent in a tf tree), so the latest transform per child frame is kept.
Unusable records (an empty or equal frame pair, non-finite numbers, a quaternion whose squared
norm is off 1 by 1e-2 or more, tf2's tolerance) are refused and counted; smaller deviations
are normalised. Frame ids lose a leading ``/`` as in tf2. numpy and the core only; no ROS.

Bounds, as a hostile peer may publish anything: the tree holds at most
:data:`MAX_STATIC_FRAMES` child frames (a new frame beyond that is refused as ``too_large``;
frames held may still change), so that memory stays bounded whatever is sent. Translations are
not bounded here (``earth -> map`` is thousands of km); a sensor's mounting is, where it is
used (:data:`MAX_LEVER_ARM`, :mod:`~vessel_kinematics.ros.mountings`).
"""

from __future__ import annotations

from dataclasses import dataclass
import math
from typing import Iterable

from vessel_kinematics.core import quaternion
from vessel_kinematics.estimation import Reason
from vessel_kinematics.ros.param_types import MAX_ANTENNA_OFFSET

__all__ = ['IDENTITY', 'MAX_FRAME_ID', 'MAX_LEVER_ARM', 'MAX_STATIC_FRAMES', 'Mounting',
           'StaticTransform', 'StaticTree', 'strip_frame']

#: tf2's tolerance on |q|² − 1 for a transform's rotation (TF_DENORMALIZED_QUATERNION).
QUATERNION_TOLERANCE = 1e-2

#: Largest lever arm (m, per axis) of a sensor mounting: the mounting parameters' bound.
MAX_LEVER_ARM = MAX_ANTENNA_OFFSET

#: Most child frames the tree holds (a URDF has tens; a peer sending more is refused).
MAX_STATIC_FRAMES = 1024
#: Longest frame name (characters) the tree holds or a mounting is looked up by: a URDF's are
#: tens; a peer's megabyte names would make every held or cached frame a megabyte.
MAX_FRAME_ID = 256

#: Longest chain followed from a frame to its root (a deeper one is taken as a loop).
MAX_DEPTH = 256


def strip_frame(frame_id: str) -> str:
    """Return a frame id as tf2 stores it: without a leading slash."""
    return frame_id[1:] if frame_id.startswith('/') else frame_id


@dataclass(frozen=True)
class StaticTransform:
    """The pose of ``child`` in ``parent``: translation (x, y, z) m, rotation (x, y, z, w)."""

    parent: str
    child: str
    translation: tuple[float, float, float]
    rotation_xyzw: tuple[float, float, float, float]


@dataclass(frozen=True)
class Mounting:
    """
    A sensor frame in the base frame (both FLU, REP-103): rotation q and translation t.

    ``q`` scalar-first unit quaternion rotating vectors of the sensor frame into the base frame
    (v_base = R(q) v_sensor); ``t`` the sensor frame's origin in the base frame (m): the lever
    arm. ``source``: ``'tf_static'`` or ``'parameters'``.
    """

    q: tuple[float, float, float, float]
    t: tuple[float, float, float]
    source: str = 'tf_static'

    @property
    def rpy(self) -> tuple[float, float, float]:
        """Return the rotation as roll, pitch, yaw (rad), R = Rz(yaw) Ry(pitch) Rx(roll)."""
        return tuple(float(a) for a in quaternion.q2euler(self.q))  # type: ignore[return-value]

    def describe(self) -> str:
        """Return 'rpy (r, p, y), xyz (x, y, z)' (rad, m) for a log line."""
        r, p, y = (a + 0.0 for a in self.rpy)      # + 0.0: no '-0' in the log
        x, yy, z = (a + 0.0 for a in self.t)
        return f'rpy ({r:.6g}, {p:.6g}, {y:.6g}) rad, xyz ({x:.6g}, {yy:.6g}, {z:.6g}) m'


#: The base frame in itself.
IDENTITY = Mounting((1.0, 0.0, 0.0, 0.0), (0.0, 0.0, 0.0))

# A pose: (q scalar-first, t) as tuples of floats.
_Pose = tuple[tuple[float, float, float, float], tuple[float, float, float]]
_ORIGIN: _Pose = ((1.0, 0.0, 0.0, 0.0), (0.0, 0.0, 0.0))


def _rotate(q: tuple, v: tuple) -> tuple[float, float, float]:
    """Return R(q) v (q a unit quaternion, scalar first)."""
    r = quaternion.rquat9(*q)
    x, y, z = v
    return (r[0] * x + r[1] * y + r[2] * z, r[3] * x + r[4] * y + r[5] * z,
            r[6] * x + r[7] * y + r[8] * z)


def _compose(a: _Pose, b: _Pose) -> _Pose:
    """Return T_a ∘ T_b: q_a ⊗ q_b, R(q_a) t_b + t_a."""
    (qa, ta), (qb, tb) = a, b
    rt = _rotate(qa, tb)
    return (quaternion.mul4(qa, qb),
            (rt[0] + ta[0], rt[1] + ta[1], rt[2] + ta[2]))


def _inverse(a: _Pose) -> _Pose:
    """Return T⁻¹: q*, −R(q)ᵀ t = −R(q*) t."""
    q, t = a
    qc = (q[0], -q[1], -q[2], -q[3])
    x, y, z = _rotate(qc, t)
    return qc, (-x, -y, -z)


class StaticTree:
    """
    The latest static transform per child frame, chained on request.

    :meth:`update` takes records (one ``/tf_static`` message or several); :meth:`lookup`
    answers the pose of a frame in another, None when either is unknown or they are not
    connected. ``version`` counts the changes (a cache of lookups is valid while it stays).
    """

    def __init__(self) -> None:
        self._by_child: dict[str, tuple[str, _Pose]] = {}
        self.version = 0
        #: Records refused by :meth:`update`, by reason.
        self.refused: dict[str, int] = {}
        #: True once a new frame was refused because the tree holds :data:`MAX_STATIC_FRAMES`.
        self.full = False

    def __len__(self) -> int:
        """Return the number of transforms (child frames) held."""
        return len(self._by_child)

    def __contains__(self, frame: object) -> bool:
        """Return True when ``frame`` is a parent or child of a held transform."""
        if not isinstance(frame, str):
            return False
        frame = strip_frame(frame)
        return frame in self._by_child or any(
            parent == frame for parent, _ in self._by_child.values())

    def _refuse(self, reason: Reason, count: int = 1) -> None:
        self.refused[reason.value] = self.refused.get(reason.value, 0) + count

    def refuse(self, reason: Reason, count: int = 1) -> None:
        """Count ``count`` records refused before they reached the tree (a message too large)."""
        self._refuse(reason, count)

    def update(self, transforms: Iterable[StaticTransform]) -> int:
        """
        Take static transforms, each replacing the one of its child frame; return changes.

        Unusable records are refused and counted in :attr:`refused` by the :class:`Reason`'s
        value (``'no_frame_id'``, ``'self_transform'``, ``'nan_field'``,
        ``'non_unit_quaternion'``, ``'too_large'``: a new frame once the tree is full, or a
        name longer than :data:`MAX_FRAME_ID`); the others are kept.
        """
        changed = 0
        for tr in transforms:
            parent, child = strip_frame(tr.parent), strip_frame(tr.child)
            if not parent or not child:
                self._refuse(Reason.NO_FRAME_ID)
                continue
            if parent == child:
                self._refuse(Reason.SELF_TRANSFORM)
                continue
            if len(parent) > MAX_FRAME_ID or len(child) > MAX_FRAME_ID:
                self._refuse(Reason.TOO_LARGE)
                continue
            x, y, z, w = (float(c) for c in tr.rotation_xyzw)
            t = tuple(float(c) for c in tr.translation)
            if not all(math.isfinite(c) for c in (x, y, z, w, *t)):
                self._refuse(Reason.NAN_FIELD)
                continue
            n2 = w * w + x * x + y * y + z * z
            if abs(n2 - 1.0) >= QUATERNION_TOLERANCE:
                self._refuse(Reason.NON_UNIT_QUATERNION)
                continue
            n = math.sqrt(n2)
            entry: tuple[str, _Pose] = (parent, ((w / n, x / n, y / n, z / n),
                                                 (t[0], t[1], t[2])))
            held = self._by_child.get(child)
            if held is None and len(self._by_child) >= MAX_STATIC_FRAMES:
                self.full = True
                self._refuse(Reason.TOO_LARGE)
                continue
            if held != entry:
                self._by_child[child] = entry
                changed += 1
        if changed:
            self.version += 1
        return changed

    def _chain(self, frame: str) -> list[tuple[str, _Pose]] | None:
        """Return [(frame, pose in its parent), ...] up to the root (last: (root, origin))."""
        chain: list[tuple[str, _Pose]] = []
        seen = set()
        while frame in self._by_child:
            if frame in seen or len(chain) > MAX_DEPTH:
                return None   # a loop: no tree
            seen.add(frame)
            parent, pose = self._by_child[frame]
            chain.append((frame, pose))
            frame = parent
        chain.append((frame, _ORIGIN))
        return chain

    def lookup(self, frame: str, base: str) -> Mounting | None:
        """
        Return the pose of ``frame`` in ``base`` (a :class:`Mounting`), None if not connected.

        Both walk up to their lowest common ancestor A: T_base_frame = T_A_base⁻¹ ∘ T_A_frame
        (exactly the published transform when ``base`` is the parent of ``frame``).
        """
        frame, base = strip_frame(frame), strip_frame(base)
        if frame == base:
            return IDENTITY
        up_frame, up_base = self._chain(frame), self._chain(base)
        if up_frame is None or up_base is None:
            return None
        base_index = {name: i for i, (name, _) in enumerate(up_base)}
        for i, (name, _) in enumerate(up_frame):
            if name in base_index:
                j = base_index[name]
                break
        else:
            return None
        a_frame = _ORIGIN
        for _, pose in reversed(up_frame[:i]):
            a_frame = _compose(a_frame, pose)
        a_base = _ORIGIN
        for _, pose in reversed(up_base[:j]):
            a_base = _compose(a_base, pose)
        q, t = a_frame if j == 0 else _compose(_inverse(a_base), a_frame)
        return Mounting(q, t)
