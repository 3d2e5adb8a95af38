"""
/tf_static within bounds, and a recovery within the physical ones (issue 25, item 2).

A peer may latch anything on /tf_static: a lever arm of 1e9 m, a message of 50,000 frames, a
new set of frames every message, a mounting that flaps. The static tree, the mountings and the
estimator each keep to their bounds; the cases here drive them with rclpy messages through the
real pipeline (the DDS cases are in test_hostile_peers.py).
"""

from __future__ import annotations

import math

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import TransformStamped
import numpy as np
from rclpy.serialization import deserialize_message, serialize_message
from test_pipeline import decoded, fix_msg, handle, imu_msg, make, T0, vel_msg
from tf2_msgs.msg import TFMessage
from vessel_kinematics.estimation import GnssFix, Mode, Reason
from vessel_kinematics.ros.mountings import (MAX_MOUNTING_LINES, MAX_MOUNTING_STEP,
                                             MAX_TRANSFORMS_PER_MESSAGE, Mountings, oversized)
from vessel_kinematics.ros.params import NavigatorParams
from vessel_kinematics.ros.static_tf import (MAX_FRAME_ID, MAX_LEVER_ARM, MAX_STATIC_FRAMES,
                                             StaticTransform, StaticTree)

IDENTITY_XYZW = (0.0, 0.0, 0.0, 1.0)


def _tf(parent: str, child: str, xyz: tuple[float, float, float]) -> TransformStamped:
    t = TransformStamped()
    t.header.frame_id, t.child_frame_id = parent, child
    t.transform.translation.x, t.transform.translation.y, t.transform.translation.z = xyz
    t.transform.rotation.w = 1.0
    return t


def _frames(n: int, prefix: str = 'f') -> TFMessage:
    return TFMessage(transforms=[_tf('base_link', f'{prefix}{i}', (0.1, 0.0, 0.0))
                                 for i in range(n)])


def test_a_lever_arm_beyond_the_parameters_bound_is_refused() -> None:
    mountings = Mountings(NavigatorParams.from_flat({'origin': [59.9, 10.7, 40.0]}))
    mountings.tree.update([
        StaticTransform('base_link', 'gnss', (1e9, 0.0, 0.0), IDENTITY_XYZW),
        StaticTransform('base_link', 'imu', (MAX_LEVER_ARM, -MAX_LEVER_ARM, 0.0),
                        IDENTITY_XYZW)])
    mounting, line = mountings.of('fix', 'gnss')
    assert mounting is None and line is not None and 'refused' in line, line
    assert mountings.tree.refused == {'implausible_mounting': 1}
    assert mountings.of('imu', 'imu')[0] is not None          # at the bound: taken
    # A chain of transforms each within the bound, beyond it together, is refused at use.
    mountings = Mountings(NavigatorParams.from_flat({'origin': [59.9, 10.7, 40.0]}))
    mountings.tree.update([StaticTransform('base_link', 'mast', (900.0, 0.0, 0.0), IDENTITY_XYZW),
                           StaticTransform('mast', 'gnss', (900.0, 0.0, 0.0), IDENTITY_XYZW)])
    mounting, line = mountings.of('fix', 'gnss')
    assert mounting is None and line is not None and 'refused' in line, line
    assert mountings.counts == {'gnss antenna refused': 1}
    # The tree itself holds any translation (earth -> map is thousands of km).
    tree = StaticTree()
    assert tree.update([StaticTransform('earth', 'map', (3e6, 5e5, 5.5e6), IDENTITY_XYZW)]) == 1


def test_the_tree_holds_a_bounded_number_of_frames() -> None:
    tree = StaticTree()
    records = [StaticTransform('base_link', f'f{i}', (0.0, 0.0, 0.0), IDENTITY_XYZW)
               for i in range(MAX_STATIC_FRAMES + 10)]
    assert tree.update(records) == MAX_STATIC_FRAMES
    assert len(tree) == MAX_STATIC_FRAMES and tree.full
    assert tree.refused == {'too_large': 10}
    # A frame held may still change.
    moved = StaticTransform('base_link', 'f0', (1.0, 0.0, 0.0), IDENTITY_XYZW)
    assert tree.update([moved]) == 1
    assert tree.lookup('f0', 'base_link').t == (1.0, 0.0, 0.0)


def test_a_huge_message_is_refused_from_its_header() -> None:
    raw = serialize_message(_frames(50_000))
    large = oversized(raw)
    assert large is not None and large[0] == 50_000, large
    # The header only: a body that no TFMessage holds is refused just the same.
    garbage = raw[:8] + bytes(len(raw) - 8)
    assert oversized(garbage) == large
    assert oversized(serialize_message(_frames(MAX_TRANSFORMS_PER_MESSAGE))) is None
    assert oversized(b'') is None
    # The pipeline (the replay's path) refuses the same message whole, by the same limit.
    pipe = make()
    assert pipe.tf_static(_frames(MAX_TRANSFORMS_PER_MESSAGE + 1)) == 0
    assert pipe.mountings.tree.refused == {'too_large': MAX_TRANSFORMS_PER_MESSAGE + 1}
    assert len(pipe.mountings.tree) == 0


def test_many_messages_of_new_frames_keep_the_tree_bounded() -> None:
    pipe = make()
    for k in range(200):
        pipe.tf_static(_frames(100, prefix=f'm{k}_'))
    assert len(pipe.mountings.tree) == MAX_STATIC_FRAMES
    assert pipe.mountings.tree.refused['too_large'] == 200 * 100 - MAX_STATIC_FRAMES


def _fed(pipe, t_end: float, t_start: float = 0.0) -> list:
    out = []
    for k in range(int(t_start * 10), int(t_end * 10)):
        t = k / 10.0
        for name, msg in (('imu', imu_msg(t, 0.0, 0.0)), ('velocity', vel_msg(t, 2.0, 0.0)),
                          *((('fix', _gnss(fix_msg(t, (2.0 * t, 0.0, 0.0)))),) if k % 5 == 0
                            else ())):
            out.append(handle(pipe, name, msg))
    return out


def _gnss(msg):
    msg.header.frame_id = 'gnss'
    return msg


def test_a_mounting_change_is_checked_against_the_one_in_use() -> None:
    pipe = make()
    pipe.tf_static(TFMessage(transforms=[_tf('base_link', 'gnss', (1.0, 0.0, 2.0))]))
    _fed(pipe, 2.0)
    assert pipe.mountings.sources['fix'] == 'tf_static gnss'
    # A jump beyond MAX_MOUNTING_STEP: refused, the one in use kept, counted, said.
    pipe.tf_static(TFMessage(transforms=[_tf('base_link', 'gnss',
                                             (MAX_MOUNTING_STEP + 5.0, 0.0, 2.0))]))
    lines = [r.info for r in _fed(pipe, 4.0, 2.0) if r.info]
    assert any('refused' in line and 'the one in use is kept' in line for line in lines), lines
    assert pipe.mountings.counts.get('gnss antenna refused') == 1
    position = decoded(_fed(pipe, 4.2, 4.0)[-2].emissions)['odometry'].pose.pose.position
    assert abs(position.x - 0.0) < 5.0 and abs(position.y - 8.0) < 5.0, position  # ENU
    status = deserialize_message(pipe.diagnostics(int((T0 + 5.0) * 1e9)).cdr,
                                 DiagnosticArray).status[0]
    values = {kv.key: kv.value for kv in status.values}
    assert values['gnss antenna refused'] == '1', values


def test_a_flapping_mounting_is_said_a_bounded_number_of_times() -> None:
    pipe = make()
    lines = []
    for k in range(200):
        pipe.tf_static(TFMessage(transforms=[_tf('base_link', 'gnss', (0.1 * (k % 2), 0.0, 0.0))]))
        lines += [r.info for r in _fed(pipe, (k + 1) * 0.1, k * 0.1) if r.info]
    lines = [line for line in lines if line.startswith('gnss antenna')]
    assert len(lines) == MAX_MOUNTING_LINES + 1, lines
    assert 'keeps changing' in lines[-1]
    assert pipe.mountings.counts['gnss antenna changes'] >= 30       # one per fix (2 Hz)


def test_a_recovery_never_reinitialises_beyond_the_physical_bounds() -> None:
    """A 1e9 m lever arm reaching the estimator: refused, never taken, never 'fused'."""
    pipe = make()
    _fed(pipe, 10.0)
    est = pipe.estimator
    assert est.mode is Mode.FUSED
    before = est.x[est.layout.p].copy()
    lat, lon = math.radians(59.9), math.radians(10.7)
    reasons = set()
    t0 = est.t
    for k in range(1, 60):
        stamp = t0 + int(k * 0.2e9)
        rejection = est.fix(GnssFix(stamp, lat, lon, 40.0, np.eye(3) * 0.09,
                                    lever_b=(1e9, 0.0, 0.0)))
        assert rejection is not None
        reasons.add(rejection.reason)
    assert Reason.IMPLAUSIBLE_STATE in reasons, reasons
    assert float(np.abs(est.x[est.layout.p]).max()) < 1e3, est.x[est.layout.p]
    assert np.allclose(est.x[est.layout.p][:2], before[:2], atol=100.0)
    assert est.mode is not Mode.FUSED


def test_frame_names_longer_than_any_urdf_s_stay_small() -> None:
    """A megabyte frame_id: refused by the tree, cut in the mountings' caches and lines."""
    tree = StaticTree()
    huge = 'f' * (MAX_FRAME_ID + 1)
    assert tree.update([StaticTransform('base_link', huge, (0.0, 0.0, 0.0), IDENTITY_XYZW),
                        StaticTransform(huge, 'imu_link', (0.0, 0.0, 0.0), IDENTITY_XYZW)]) == 0
    assert tree.refused == {'too_large': 2}
    pipe = make()
    lines = [pipe.mountings.of('imu', f'{k}' + 'x' * 1_000_000)[1] for k in range(100)]
    assert all(line is None or len(line) < 2 * MAX_FRAME_ID + 200 for line in lines)
    assert all(len(frame) <= MAX_FRAME_ID for _, frame in pipe.mountings._resolved)
