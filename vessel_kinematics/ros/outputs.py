"""
The outputs: one builder per output topic, from a NavState to the message's CDR bytes.

Every output of the interface table (:mod:`.interface`, role OUTPUT) has its builder here,
in :data:`STATE_OUTPUTS` (``origin`` excepted: :func:`origin`, emitted when the origin is set).
The estimator's Fossen frames (NED world, FRD body, scalar-first q_nb) become REP-103/REP-105's
(ENU, FLU, ``xyzw``) through :mod:`vessel_kinematics.core.frames`, the one place of those
conventions; ``odometry/ned`` keeps Fossen's, in the ``_ned``/``_frd`` twins of the frames.
Covariances are row-major: poses [x, y, z, roll, pitch, yaw], twists [linear, angular] in the
child frame. The bytes are laid out by :mod:`.cdr`.
"""

from __future__ import annotations

import math
from typing import Callable, Iterator

import numpy as np
from sensor_msgs.msg import NavSatFix, NavSatStatus
from vessel_kinematics.core import frames
from vessel_kinematics.estimation import Mode, NavState
from vessel_kinematics.ros import cdr, interface
from vessel_kinematics.ros.params import NavigatorParams

__all__ = ['FRD_SUFFIX', 'NED_SUFFIX', 'origin', 'OutputBuilder', 'q_ros', 'state_outputs',
           'STATE_OUTPUTS']

#: Suffixes of the NED/FRD twins of the map and base frames (``odometry/ned``'s frames).
NED_SUFFIX = '_ned'
FRD_SUFFIX = '_frd'


def _block(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Return the 6x6 block diagonal of two 3x3 blocks (a pose's or a twist's covariance)."""
    out = np.zeros((6, 6))
    out[0:3, 0:3] = a
    out[3:6, 3:6] = b
    return out


def _twist_flu(s: NavState) -> np.ndarray:
    """Return the twist's covariance in the base frame (FLU), row-major."""
    return frames.cov6_frd_to_flu(_block(s.cov_nu, s.cov_omega)).ravel()


def q_ros(s: NavState) -> tuple[float, float, float, float]:
    """Return q_enu_flu of the state (the attitude swap of :mod:`~.core.frames`), x, y, z, w."""
    w, x, y, z = s.q.tolist()
    qw, qx, qy, qz = frames.swap_attitude4(w, x, y, z)
    return qx, qy, qz, qw


def _enu_flu(s: NavState, frame: str, child: str, p_ned: np.ndarray, cov_p: np.ndarray) -> bytes:
    """Return an Odometry in REP-103 frames: the pose ``p_ned`` (cov_p) in ``frame`` (ENU)."""
    return cdr.odometry(s.stamp_ns, frame, child, frames.swap_world3(*p_ned.tolist()), q_ros(s),
                        frames.cov6_pose_to_ros(_block(cov_p, s.cov_att)).ravel(),
                        frames.flip_body3(*s.nu.tolist()), frames.flip_body3(*s.omega.tolist()),
                        _twist_flu(s))


def _odometry(s: NavState, p: NavigatorParams) -> bytes:
    """Return ``odometry``: the fused pose in map (ENU) of base (FLU), the twist in base."""
    return _enu_flu(s, p.map_frame, p.base_frame, s.p, s.cov_p)


def _odometry_local(s: NavState, p: NavigatorParams) -> bytes:
    """Return ``odometry/local``: the dead-reckoned pose in odom (ENU), never corrected."""
    return _enu_flu(s, p.odom_frame, p.base_frame, s.p_local, s.cov_p_local)


def _odometry_ned(s: NavState, p: NavigatorParams) -> bytes:
    """Return ``odometry/ned``: the fused state in Fossen's frames, map_ned / base_frd."""
    w, x, y, z = s.q.tolist()
    return cdr.odometry(s.stamp_ns, p.map_frame + NED_SUFFIX, p.base_frame + FRD_SUFFIX,
                        s.p.tolist(), (x, y, z, w), _block(s.cov_p, s.cov_att).ravel(),
                        s.nu.tolist(), s.omega.tolist(), _block(s.cov_nu, s.cov_omega).ravel())


def _course_sideslip(s: NavState, p: NavigatorParams) -> bytes:
    """Return ``course_sideslip``: x = course χ, y = sideslip β, z = angle of attack α, rad."""
    return cdr.vector3_stamped(s.stamp_ns, p.base_frame, s.course, s.sideslip,
                               s.angle_of_attack)


def _current(s: NavState, p: NavigatorParams) -> bytes:
    """Return ``current``: the estimated current, ENU in map, m/s; zero when not estimated."""
    east, north, up = (0.0, 0.0, 0.0) if s.current is None else frames.swap_world3(
        *s.current.tolist())
    return cdr.vector3_stamped(s.stamp_ns, p.map_frame, east, north, up)


def _relative_flow(s: NavState, p: NavigatorParams) -> bytes:
    """
    Return ``relative_flow``: x = U_r (m/s), y = β_r, z = α_r (rad), in base; else zero.

    Fossen 2.4.2: the speed, sideslip (leeway and turning drift) and angle of attack of the body
    velocity through the water ν_r = ν − ν_c.
    """
    f = s.relative_flow
    values = (0.0, 0.0, 0.0) if f is None else (f.speed, f.sideslip, f.angle_of_attack)
    return cdr.vector3_stamped(s.stamp_ns, p.base_frame, *values)


def _fix_filtered(s: NavState, p: NavigatorParams) -> bytes:
    """
    Return ``fix/filtered``: the estimated base position (deg, m; covariance ENU, KNOWN).

    A position from dead reckoning alone is no GNSS fix: STATUS_NO_FIX, so that nobody
    (navsat_transform, a logger, a second filter) takes it for one, with its honest (growing)
    covariance kept; STATUS_FIX while fixes are fused.
    """
    lat, lon, h = s.llh
    status = NavSatStatus.STATUS_FIX if s.mode is Mode.FUSED else NavSatStatus.STATUS_NO_FIX
    return cdr.nav_sat_fix(s.stamp_ns, p.base_frame, status, math.degrees(lat),
                           math.degrees(lon), float(h), frames.cov3_ned_to_enu(s.cov_p).ravel(),
                           NavSatFix.COVARIANCE_TYPE_KNOWN)


def _calibration(s: NavState, p: NavigatorParams) -> bytes:
    """
    Return ``calibration``: the log scale k, the leeway λ and the IMU heading offset δψ.

    x = k (the log reads k times the speed through the water), y = λ (rad), z = δψ (rad, added
    to the IMU heading, NED: the IMU's published minus true yaw, ENU), in base_frame; 1, 0, 0
    where not estimated. The layout of the simulator's ``/truth/calibration``.
    """
    c = s.calibration
    return cdr.vector3_stamped(
        s.stamp_ns, p.base_frame, 1.0 if c.log_scale is None else c.log_scale.value,
        0.0 if c.leeway is None else c.leeway.value,
        0.0 if c.heading_offset is None else c.heading_offset.value)


#: An output's builder: (state, parameters) -> its CDR bytes.
OutputBuilder = Callable[[NavState, NavigatorParams], bytes]

#: The builder of each output made from the state, by its name in the interface table.
STATE_OUTPUTS: dict[str, OutputBuilder] = {
    'odometry': _odometry,
    'odometry/local': _odometry_local,
    'odometry/ned': _odometry_ned,
    'course_sideslip': _course_sideslip,
    'current': _current,
    'relative_flow': _relative_flow,
    'fix/filtered': _fix_filtered,
    'calibration': _calibration,
}

#: (name, water_only, builder) of every state output, in the interface table's order.
_ROWS: tuple[tuple[str, bool, OutputBuilder], ...] = tuple(
    (t.name, t.water_only, STATE_OUTPUTS[t.name])
    for t in interface.by_role(interface.Role.OUTPUT) if t.name in STATE_OUTPUTS)
if len(_ROWS) != len(STATE_OUTPUTS):     # a builder without a row: a mistake, said at once
    raise RuntimeError(f'outputs.STATE_OUTPUTS {sorted(STATE_OUTPUTS)}: not all are outputs '
                       'of the interface table')


def state_outputs(s: NavState, params: NavigatorParams) -> Iterator[tuple[str, bytes]]:
    """
    Yield (output name, CDR bytes) of every output of the state, in the interface's order.

    The ``water_only`` ones (``current``, ``relative_flow``) only with a water-referenced
    velocity (:attr:`~.params.NavigatorParams.water`).
    """
    water = params.water
    for name, water_only, build in _ROWS:
        if water or not water_only:
            yield name, build(s, params)


def origin(llh: tuple[float, float, float], stamp_ns: int, params: NavigatorParams) -> bytes:
    """Return the ``origin`` output: the origin in rad, rad, m as a NavSatFix in degrees."""
    return cdr.nav_sat_fix(stamp_ns, params.map_frame, NavSatStatus.STATUS_FIX,
                           math.degrees(llh[0]), math.degrees(llh[1]), float(llh[2]),
                           np.zeros(9), NavSatFix.COVARIANCE_TYPE_UNKNOWN)
