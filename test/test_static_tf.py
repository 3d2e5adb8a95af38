"""
The static transform tree (vessel_kinematics.ros.static_tf) against scipy's Rotation.

Chains through several frames, both directions (a frame above the base, siblings under a
common parent), unknown and disconnected frames, re-publication (the latest per child frame),
loops, and the records tf2 refuses.
"""

from __future__ import annotations

import math

from hypothesis import given, settings, strategies as st
import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from vessel_kinematics.ros.static_tf import IDENTITY, StaticTransform, StaticTree


def record(parent: str, child: str, t, rot: Rotation) -> StaticTransform:
    """Return the record of a transform (pose of child in parent) from a scipy Rotation."""
    return StaticTransform(parent, child, tuple(float(c) for c in t),
                           tuple(float(c) for c in rot.as_quat()))


def pose_of(tree: StaticTree, frame: str, base: str) -> tuple[Rotation, np.ndarray]:
    """Return the tree's answer as (scipy Rotation, translation)."""
    m = tree.lookup(frame, base)
    assert m is not None, (frame, base)
    w, x, y, z = m.q
    assert math.isclose(w * w + x * x + y * y + z * z, 1.0, abs_tol=1e-12)
    return Rotation.from_quat([x, y, z, w]), np.array(m.t)


def reference(poses: dict, frame: str, base: str) -> tuple[Rotation, np.ndarray]:
    """Return the pose of ``frame`` in ``base`` from {child: (parent, R, t)} by scipy."""
    def to_root(f: str) -> tuple[str, Rotation, np.ndarray]:
        rot, t = Rotation.identity(), np.zeros(3)
        while f in poses:
            parent, r_p, t_p = poses[f]
            rot, t = r_p * rot, r_p.apply(t) + t_p
            f = parent
        return f, rot, t
    root_f, r_f, t_f = to_root(frame)
    root_b, r_b, t_b = to_root(base)
    assert root_f == root_b
    return r_b.inv() * r_f, r_b.inv().apply(t_f - t_b)


def check(tree: StaticTree, poses: dict, frame: str, base: str) -> None:
    rot, t = pose_of(tree, frame, base)
    ref_rot, ref_t = reference(poses, frame, base)
    assert (rot.inv() * ref_rot).magnitude() < 1e-12
    np.testing.assert_allclose(t, ref_t, atol=1e-12)


# A URDF-like tree: base_footprint -> base_link -> {imu_link, gnss, mast -> dvl_link}.
POSES = {
    'base_link': ('base_footprint', Rotation.from_euler('xyz', [0.0, 0.0, 0.0]), [0, 0, 0.4]),
    'imu_link': ('base_link', Rotation.from_euler('ZYX', [1.2, -0.3, 0.7]), [0.5, -0.3, 0.52]),
    'gnss': ('base_link', Rotation.identity(), [-3.0, 0.0, 5.0]),
    'mast': ('base_link', Rotation.from_euler('ZYX', [0.4, 0.1, -0.2]), [1.0, 0.2, 1.5]),
    'dvl_link': ('mast', Rotation.from_euler('ZYX', [-2.0, 0.05, math.pi]), [0.3, -0.1, -4.0]),
}


def make_tree(poses=POSES) -> StaticTree:
    tree = StaticTree()
    tree.update(record(p, c, t, r) for c, (p, r, t) in poses.items())
    return tree


def resolved(poses=POSES) -> dict:
    return {c: (p, r, np.asarray(t, dtype=float)) for c, (p, r, t) in poses.items()}


@pytest.mark.parametrize('frame, base', [
    ('imu_link', 'base_link'),          # one hop: the published transform
    ('dvl_link', 'base_link'),          # two hops
    ('dvl_link', 'base_footprint'),     # three hops
    ('base_footprint', 'dvl_link'),     # the inverse direction: up, then inverted
    ('imu_link', 'dvl_link'),           # siblings: through the common ancestor base_link
    ('gnss', 'mast'),
])
def test_chains_and_directions_against_scipy(frame, base) -> None:
    check(make_tree(), resolved(), frame, base)


def test_one_hop_is_the_published_transform_exactly() -> None:
    tree = make_tree()
    m = tree.lookup('imu_link', 'base_link')
    x, y, z, w = POSES['imu_link'][1].as_quat()
    assert m.q == pytest.approx((w, x, y, z), abs=1e-15) and m.t == (0.5, -0.3, 0.52)


def test_unknown_and_disconnected_frames() -> None:
    tree = make_tree()
    assert tree.lookup('camera', 'base_link') is None
    assert tree.lookup('imu_link', 'map') is None
    tree.update([record('map', 'map_ned', (0, 0, 0), Rotation.from_rotvec([math.pi, 0, 0]))])
    assert tree.lookup('map_ned', 'base_link') is None        # two trees, not connected
    assert tree.lookup('base_link', 'base_link') == IDENTITY
    assert 'map' in tree and 'imu_link' in tree and 'camera' not in tree
    assert '/imu_link' in tree                                  # tf2 strips a leading slash
    assert tree.lookup('/imu_link', '/base_link') == tree.lookup('imu_link', 'base_link')


def test_latest_per_child_frame_and_version() -> None:
    tree = make_tree()
    version = tree.version
    # Re-publication of the same transform (another latched copy) changes nothing.
    p, r, t = POSES['gnss']
    assert tree.update([record(p, 'gnss', t, r)]) == 0 and tree.version == version
    # A new transform for a child replaces the old one, even under another parent.
    assert tree.update([record('mast', 'gnss', (0.0, 0.0, 2.0), Rotation.identity())]) == 1
    assert tree.version == version + 1
    poses = resolved()
    poses['gnss'] = ('mast', Rotation.identity(), np.array([0.0, 0.0, 2.0]))
    check(tree, poses, 'gnss', 'base_link')
    assert len(tree) == len(POSES)


def test_refused_records_and_loops() -> None:
    tree = StaticTree()
    bad = [
        StaticTransform('', 'a', (0, 0, 0), (0, 0, 0, 1)),
        StaticTransform('a', 'a', (0, 0, 0), (0, 0, 0, 1)),
        StaticTransform('a', 'b', (float('nan'), 0, 0), (0, 0, 0, 1)),
        StaticTransform('a', 'c', (0, 0, 0), (0, 0, 0, 0)),
        StaticTransform('a', 'd', (0, 0, 0), (0, 0, 0, 1.1)),
    ]
    assert tree.update(bad) == 0 and len(tree) == 0
    assert tree.refused == {'no_frame_id': 1, 'self_transform': 1, 'nan_field': 1,
                            'non_unit_quaternion': 2}
    # Within tf2's tolerance a quaternion is normalised.
    tree.update([StaticTransform('a', 'e', (0, 0, 0), (0, 0, 0, 1.001))])
    assert tree.lookup('e', 'a').q == (1.0, 0.0, 0.0, 0.0)
    # A loop a -> x -> y -> x answers None instead of spinning.
    tree.update([StaticTransform('x', 'y', (0, 0, 0), (0, 0, 0, 1)),
                 StaticTransform('y', 'x', (0, 0, 0), (0, 0, 0, 1))])
    assert tree.lookup('y', 'a') is None and tree.lookup('a', 'x') is None


_angles = st.floats(-math.pi, math.pi, allow_nan=False)
_offsets = st.floats(-50.0, 50.0, allow_nan=False)


@settings(max_examples=30, deadline=None)
@given(st.lists(st.tuples(_angles, _angles, _angles, _offsets, _offsets, _offsets),
                min_size=5, max_size=5))
def test_random_trees_against_scipy(values) -> None:
    """Random rotations and offsets on the fixed URDF-like shape, every pair of frames."""
    poses = {}
    for (child, (parent, _, _)), (a, b, c, x, y, z) in zip(POSES.items(), values):
        poses[child] = (parent, Rotation.from_euler('ZYX', [a, b, c]), np.array([x, y, z]))
    tree = make_tree(poses)
    frames = ['base_footprint', *poses]
    for frame in frames:
        for base in frames:
            if frame != base:
                rot, t = pose_of(tree, frame, base)
                ref_rot, ref_t = reference(poses, frame, base)
                assert (rot.inv() * ref_rot).magnitude() < 1e-9
                np.testing.assert_allclose(t, ref_t, atol=1e-9)
