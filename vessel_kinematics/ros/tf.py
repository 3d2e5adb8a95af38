"""
The transforms the navigator broadcasts: REP-105's earth -> map -> odom -> base_link.

``tf.publish`` chooses them (:class:`~.params.TfTransform`). :class:`TfOutput` gives, as the
CDR of a tf2_msgs/TFMessage (:mod:`.cdr`):

* for ``/tf``, after each emission of the state: map -> odom (the correction of the fused pose
  over the dead-reckoned one) and odom -> base_link (the dead-reckoned pose), exactly one per
  child frame and stamp, so that a TF buffer never sees TF_REPEATED_DATA (two inputs with one
  stamp emit once);
* for ``/tf_static``, whenever the set changes (the origin was set, a parameter changed), all
  static transforms in one message, as tf2's StaticTransformBroadcaster sends them: earth ->
  map (the origin in ECEF, ENU axes), map -> map_ned and base_link -> base_link_frd (the frames
  of ``odometry/ned``).
"""

from __future__ import annotations

import math

from vessel_kinematics.core import frames, geodesy, quaternion
from vessel_kinematics.estimation import NavState
from vessel_kinematics.ros import cdr
from vessel_kinematics.ros.outputs import FRD_SUFFIX, NED_SUFFIX, q_ros
from vessel_kinematics.ros.params import NavigatorParams, TfTransform

__all__ = ['dynamic_transforms', 'static_transforms', 'TfOutput']

_SQRT_HALF = math.sqrt(0.5)
#: map (ENU) -> map_ned: x_ned = y_enu, y_ned = x_enu, z_ned = -z_enu; 180° about (1, 1, 0)/√2.
_Q_ENU_NED_XYZW = (_SQRT_HALF, _SQRT_HALF, 0.0, 0.0)
#: base (FLU) -> base_frd: 180° about x.
_Q_FLU_FRD_XYZW = (1.0, 0.0, 0.0, 0.0)
_IDENTITY_XYZW = (0.0, 0.0, 0.0, 1.0)
_ZERO = (0.0, 0.0, 0.0)


def dynamic_transforms(s: NavState, params: NavigatorParams) -> list[cdr.Transform]:
    """
    Return map -> odom and odom -> base_link of ``tf.publish``, at the state's stamp.

    odom -> base_link is the local pose; map -> odom = fused pose ∘ (local pose)⁻¹. Both poses
    share the attitude, so map -> odom is the pure translation p_map - p_odom (ENU) (REP-105).
    """
    which = params.tf_set
    out: list[cdr.Transform] = []
    if TfTransform.MAP_ODOM in which:
        out.append((s.stamp_ns, params.map_frame, params.odom_frame,
                    frames.swap_world3(*(s.p - s.p_local).tolist()), _IDENTITY_XYZW))
    if TfTransform.ODOM_BASE in which:
        out.append((s.stamp_ns, params.odom_frame, params.base_frame,
                    frames.swap_world3(*s.p_local.tolist()), q_ros(s)))
    return out


def static_transforms(origin: tuple[float, float, float] | None, stamp_ns: int,
                      params: NavigatorParams) -> list[cdr.Transform]:
    """
    Return the static transforms of ``tf.publish``, all in one list (one /tf_static message).

    earth -> map: the origin's (rad, rad, m) ECEF position and the rotation ENU -> ECEF
    (REP-105), once the origin is known; map -> map_ned and base_link -> base_link_frd.
    """
    which = params.tf_set
    out: list[cdr.Transform] = []
    if TfTransform.EARTH_MAP in which and origin is not None:
        lat, lon, h = origin
        x, y, z = (float(c) for c in geodesy.llh2ecef(lat, lon, h))
        q = quaternion.rot2q(geodesy.rll(lon, lat) @ frames.A_WORLD)
        out.append((stamp_ns, params.earth_frame, params.map_frame, (x, y, z),
                    (float(q[1]), float(q[2]), float(q[3]), float(q[0]))))
    if TfTransform.FRD_NED in which:
        out.append((stamp_ns, params.map_frame, params.map_frame + NED_SUFFIX, _ZERO,
                    _Q_ENU_NED_XYZW))
        out.append((stamp_ns, params.base_frame, params.base_frame + FRD_SUFFIX, _ZERO,
                    _Q_FLU_FRD_XYZW))
    return out


class TfOutput:
    """What to send on /tf and /tf_static, remembering what was sent."""

    def __init__(self) -> None:
        self._sent: dict[str, int] = {}           # child frame -> stamp of its last /tf
        self._static_key: tuple | None = None      # what the last /tf_static held

    def dynamic(self, s: NavState, params: NavigatorParams) -> bytes | None:
        """Return /tf for the state (the transforms not yet sent at its stamp), or None."""
        out = []
        for transform in dynamic_transforms(s, params):
            child = transform[2]
            if self._sent.get(child) != s.stamp_ns:
                self._sent[child] = s.stamp_ns
                out.append(transform)
        return cdr.tf_message(out) if out else None

    def static(self, origin: tuple[float, float, float] | None, stamp_ns: int,
               params: NavigatorParams) -> bytes | None:
        """Return /tf_static when the set of static transforms changed, else None."""
        transforms = static_transforms(origin, stamp_ns, params)
        key = tuple(t[1:] for t in transforms)         # all but the stamp
        if not transforms or key == self._static_key:
            return None
        self._static_key = key
        return cdr.tf_message(transforms)
