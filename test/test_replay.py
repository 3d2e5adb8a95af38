"""
The offline replay on small bags written here with rosbags: outputs, frames, TF, remaps, errors.

The voyage: a vessel heading north-east at 2 m/s for 20 s, IMU at 50 Hz, fixes at 5 Hz, body
velocity at 10 Hz, with the fixes logged 0.3 s late (so log-time order is not stamp order).
Expected values come from the construction (pymap3d for the geodesy), not from the code.
"""

from __future__ import annotations

import math
from pathlib import Path
import subprocess
import sys
from typing import Any

import numpy as np
import pymap3d
import pytest
from rosbags.highlevel import AnyReader
from rosbags.rosbag1 import Writer as Writer1
from rosbags.rosbag2 import StoragePlugin, Writer as Writer2
from rosbags.typesys import get_typestore, Stores
from scipy.spatial.transform import Rotation
from vessel_kinematics.ros import imu_cdr, interface
from vessel_kinematics.ros.params import NavigatorParams
from vessel_kinematics.ros.pipeline import Pipeline
from vessel_kinematics.tools import bags, evaluate, plot, replay, sim

LAT0, LON0, H0 = 52.6, 5.3, 10.0
START_NS = 1_700_000_000_000_000_000
SPEED = 2.0
HEADING = math.radians(45.0)  # psi, from north clockwise
DURATION = 20.0


def _time(store: Any, ns: int) -> Any:
    return store.types['builtin_interfaces/msg/Time'](sec=ns // 10**9, nanosec=ns % 10**9)


def _header(store: Any, ns: int, frame: str, ros1: bool) -> Any:
    header = store.types['std_msgs/msg/Header']
    if ros1:
        return header(seq=0, stamp=_time(store, ns), frame_id=frame)
    return header(stamp=_time(store, ns), frame_id=frame)


def _vec(store: Any, x: float, y: float, z: float) -> Any:
    return store.types['geometry_msgs/msg/Vector3'](x=x, y=y, z=z)


def truth_ned(t: float) -> tuple[float, float, float]:
    """Return the true NED position (m) at t (s)."""
    return SPEED * t * math.cos(HEADING), SPEED * t * math.sin(HEADING), 0.0


def write_voyage(path: Path, *, fmt: str = 'mcap', topics: dict[str, str] | None = None,
                 velocity: str = 'twist_with_covariance', speed_bias: float = 0.0,
                 truth: bool = False, fix_delay: float = 0.3, cog: bool = False,
                 duration: float = DURATION) -> Path:
    """
    Write the test voyage as a bag: ``fmt`` mcap, sqlite3 or ros1 (``path`` then ends .bag).

    ``topics`` names the bag topics of fix, imu and velocity (default /fix, /imu, /velocity);
    ``velocity`` picks the velocity message type (twist_with_covariance, twist, odometry);
    ``speed_bias`` (m/s) is added to the measured surge; ``truth`` adds /truth/* topics.
    """
    topics = {**replay.DEFAULT_TOPICS, **(topics or {})}
    ros1 = fmt == 'ros1'
    store = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_JAZZY)
    types = store.types
    velocity_type = replay.VELOCITY_TYPES[velocity]
    connection_types = {
        topics['fix']: 'sensor_msgs/msg/NavSatFix',
        topics['imu']: 'sensor_msgs/msg/Imu',
        topics['velocity']: velocity_type,
    }
    if truth:
        connection_types.update({'/truth/odometry': 'nav_msgs/msg/Odometry',
                                 '/truth/course_sideslip': 'geometry_msgs/msg/Vector3Stamped',
                                 '/truth/current': 'geometry_msgs/msg/Vector3Stamped'})
    if cog:
        connection_types['/gnss/cog_sog'] = 'geometry_msgs/msg/Vector3Stamped'
    messages: list[tuple[int, str, Any]] = []
    yaw_enu = math.pi / 2 - HEADING
    q = types['geometry_msgs/msg/Quaternion'](x=0.0, y=0.0, z=math.sin(yaw_enu / 2),
                                              w=math.cos(yaw_enu / 2))
    steps = int(duration * 50) + 1
    for i in range(steps):
        t = i / 50.0
        ns = START_NS + i * 20_000_000
        cov = np.zeros(9)
        cov[0] = cov[4] = cov[8] = 1e-4
        imu = types['sensor_msgs/msg/Imu'](
            header=_header(store, ns, 'imu_link', ros1), orientation=q,
            orientation_covariance=cov, angular_velocity=_vec(store, 0.0, 0.0, 0.0),
            angular_velocity_covariance=cov.copy(),
            linear_acceleration=_vec(store, 0.0, 0.0, 9.81),
            linear_acceleration_covariance=cov.copy())
        messages.append((ns, topics['imu'], imu))
        if i % 5 == 0:
            vcov = np.zeros(36)
            vcov[0] = vcov[7] = vcov[14] = 0.01
            vcov[21] = vcov[28] = vcov[35] = 1e-4
            twist = types['geometry_msgs/msg/Twist'](
                linear=_vec(store, SPEED + speed_bias, 0.0, 0.0),
                angular=_vec(store, 0.0, 0.0, 0.0))
            header = _header(store, ns, 'base_link', ros1)
            if velocity == 'twist':
                msg = types[velocity_type](header=header, twist=twist)
            else:
                with_cov = types['geometry_msgs/msg/TwistWithCovariance'](twist=twist,
                                                                          covariance=vcov)
                if velocity == 'odometry':
                    pose = types['geometry_msgs/msg/PoseWithCovariance'](
                        pose=types['geometry_msgs/msg/Pose'](
                            position=types['geometry_msgs/msg/Point'](x=0.0, y=0.0, z=0.0),
                            orientation=q), covariance=np.zeros(36))
                    msg = types[velocity_type](header=header, child_frame_id='base_link',
                                               pose=pose, twist=with_cov)
                else:
                    msg = types[velocity_type](header=header, twist=with_cov)
            messages.append((ns, topics['velocity'], msg))
        if i % 10 == 0:
            n, e, d = truth_ned(t)
            lat, lon, h = pymap3d.ned2geodetic(n, e, d, LAT0, LON0, H0)
            pcov = np.zeros(9)
            pcov[0] = pcov[4] = 0.25
            pcov[8] = 1.0
            fix = types['sensor_msgs/msg/NavSatFix'](
                header=_header(store, ns, 'gps', ros1),
                status=types['sensor_msgs/msg/NavSatStatus'](status=0, service=1),
                latitude=float(lat), longitude=float(lon), altitude=float(h),
                position_covariance=pcov, position_covariance_type=2)
            messages.append((ns + int(fix_delay * 1e9), topics['fix'], fix))
            if cog:
                msg = types['geometry_msgs/msg/Vector3Stamped'](
                    header=_header(store, ns, 'gps', ros1),
                    vector=_vec(store, HEADING + math.radians(1.0), SPEED, 0.0))
                messages.append((ns, '/gnss/cog_sog', msg))
        if truth and i % 5 == 0:
            n, e, d = truth_ned(t)
            pose = types['geometry_msgs/msg/PoseWithCovariance'](
                pose=types['geometry_msgs/msg/Pose'](
                    position=types['geometry_msgs/msg/Point'](x=e, y=n, z=-d),
                    orientation=q), covariance=np.zeros(36))
            twist = types['geometry_msgs/msg/TwistWithCovariance'](
                twist=types['geometry_msgs/msg/Twist'](linear=_vec(store, SPEED, 0.0, 0.0),
                                                       angular=_vec(store, 0.0, 0.0, 0.0)),
                covariance=np.zeros(36))
            messages.append((ns, '/truth/odometry', types['nav_msgs/msg/Odometry'](
                header=_header(store, ns, 'map', ros1), child_frame_id='base_link', pose=pose,
                twist=twist)))
            messages.append((ns, '/truth/course_sideslip', types[
                'geometry_msgs/msg/Vector3Stamped'](header=_header(store, ns, 'map', ros1),
                                                    vector=_vec(store, HEADING, 0.0, 0.0))))
            messages.append((ns, '/truth/current', types['geometry_msgs/msg/Vector3Stamped'](
                header=_header(store, ns, 'map', ros1), vector=_vec(store, 0.0, 0.0, 0.0))))
    messages.sort(key=lambda m: m[0])
    if ros1:
        writer = Writer1(path)
        serialize = store.serialize_ros1
    else:
        plugin = StoragePlugin.MCAP if fmt == 'mcap' else StoragePlugin.SQLITE3
        writer = Writer2(path, version=9, storage_plugin=plugin)
        serialize = store.serialize_cdr
    with writer:
        connections = {topic: writer.add_connection(topic, msgtype, typestore=store)
                       for topic, msgtype in connection_types.items()}
        for ns, topic, msg in messages:
            writer.write(connections[topic], ns, serialize(msg, connection_types[topic]))
    return path


def read_bag(path: Path) -> tuple[dict[str, str], dict[str, list[tuple[int, Any]]]]:
    """Return {topic: type} and {topic: [(log ns, message)]} of a bag."""
    with AnyReader([path]) as reader:
        types = {c.topic: c.msgtype for c in reader.connections}
        messages: dict[str, list[tuple[int, Any]]] = {t: [] for t in types}
        for connection, ns, raw in reader.messages():
            messages[connection.topic].append((ns, reader.deserialize(raw, connection.msgtype)))
    return types, messages


@pytest.fixture(scope='module')
def voyage(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Return the default voyage bag (mcap)."""
    return write_voyage(tmp_path_factory.mktemp('voyage') / 'in')


@pytest.fixture(scope='module')
def replayed(voyage: Path, tmp_path_factory: pytest.TempPathFactory,
             ) -> tuple[replay.Summary, dict[str, str], dict[str, list]]:
    """Replay the voyage with default parameters and read the output bag back."""
    out = tmp_path_factory.mktemp('replayed') / 'out'
    summary = replay.run(voyage, out, progress=False)
    types, messages = read_bag(out)
    return summary, types, messages


def test_outputs_have_the_navigators_topics_and_types(replayed: Any) -> None:
    summary, types, messages = replayed
    for topic, msgtype in replay.OUTPUT_TYPES.items():
        assert types[topic] == msgtype
    for topic in ('/odometry', '/odometry/local', '/odometry/ned', '/course_sideslip',
                  '/fix/filtered', '/origin', '/diagnostics', '/tf', '/tf_static'):
        assert messages[topic], topic
    # Copied inputs, untouched.
    assert {'/fix', '/imu', '/velocity'} <= set(types)
    assert len(messages['/imu']) == int(DURATION * 50) + 1
    assert summary.messages_in['imu'] == len(messages['/imu'])
    assert summary.messages_in['fix'] == len(messages['/fix'])
    assert summary.messages_copied == sum(len(messages[t]) for t in ('/fix', '/imu',
                                                                     '/velocity'))
    assert not summary.rejected
    assert summary.out_of_order == 0
    # Diagnostics at 1 Hz of bag time (plus one at the end).
    assert abs(len(messages['/diagnostics']) - (DURATION + 1)) <= 1


def test_outputs_have_the_frames_and_the_motion(replayed: Any) -> None:
    _, _, messages = replayed
    odometry = messages['/odometry'][-1][1]
    assert (odometry.header.frame_id, odometry.child_frame_id) == ('map', 'base_link')
    local = messages['/odometry/local'][-1][1]
    assert (local.header.frame_id, local.child_frame_id) == ('odom', 'base_link')
    ned = messages['/odometry/ned'][-1][1]
    assert (ned.header.frame_id, ned.child_frame_id) == ('map_ned', 'base_link_frd')
    n, e, _ = truth_ned(DURATION)
    p = odometry.pose.pose.position
    assert p.x == pytest.approx(e, abs=0.5) and p.y == pytest.approx(n, abs=0.5)
    assert ned.pose.pose.position.x == pytest.approx(n, abs=0.5)
    assert ned.pose.pose.position.y == pytest.approx(e, abs=0.5)
    course = messages['/course_sideslip'][-1][1].vector
    assert course.x == pytest.approx(HEADING, abs=0.02)
    assert course.y == pytest.approx(0.0, abs=0.02)
    origin = messages['/origin'][0][1]
    assert (origin.latitude, origin.longitude) == pytest.approx((LAT0, LON0), abs=1e-9)
    last_fix = messages['/fix/filtered'][-1][1]
    lat, lon, _ = pymap3d.ned2geodetic(n, e, 0.0, LAT0, LON0, H0)
    assert last_fix.latitude == pytest.approx(lat, abs=5e-6)
    assert last_fix.longitude == pytest.approx(lon, abs=5e-6)
    # Every output is stamped with bag time and written at that time.
    for topic in ('/odometry', '/course_sideslip', '/fix/filtered'):
        for log_ns, msg in messages[topic]:
            assert log_ns == msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec


def test_summary_numbers(replayed: Any) -> None:
    summary, _, _ = replayed
    assert summary.distance_m == pytest.approx(SPEED * DURATION, rel=0.02)
    n, e, _ = truth_ned(DURATION)
    lat, lon, _ = pymap3d.ned2geodetic(n, e, 0.0, LAT0, LON0, H0)
    assert summary.final_position[:2] == pytest.approx((lat, lon), abs=5e-6)
    # Log time: the last fix is delivered up to 0.5 s after its stamp.
    assert DURATION <= summary.duration_s <= DURATION + 0.5
    text = summary.text()
    assert 'rejected   0: none' in text
    assert f'{abs(lat):.7f} N' in text and f'{abs(lon):.7f} E' in text


def test_tf_tree_is_rep105(replayed: Any) -> None:
    _, _, messages = replayed
    # Latched: the last /tf_static holds them all (the first, before the origin, had two).
    static = messages['/tf_static'][-1][1].transforms
    assert [(t.header.frame_id, t.child_frame_id) for t in static] == [
        ('earth', 'map'), ('map', 'map_ned'), ('base_link', 'base_link_frd')]
    x, y, z = pymap3d.geodetic2ecef(LAT0, LON0, H0)
    tr = static[0].transform.translation
    assert (tr.x, tr.y, tr.z) == pytest.approx((x, y, z), abs=1e-3)
    pairs = {(t.header.frame_id, t.child_frame_id)
             for _, m in messages['/tf'] for t in m.transforms}
    assert pairs == {('map', 'odom'), ('odom', 'base_link')}
    # map->odom composed with odom->base_link is the fused pose (translations, planar motion).
    _, last = messages['/tf'][-1]
    by_pair = {(t.header.frame_id, t.child_frame_id): t for t in last.transforms}
    stamp = by_pair[('odom', 'base_link')].header.stamp
    # One transform per stamp: TF carries the first pose of a stamp that two inputs share.
    fused = {(m.header.stamp.sec, m.header.stamp.nanosec): m
             for _, m in reversed(messages['/odometry'])}[(stamp.sec, stamp.nanosec)]
    map_odom = by_pair[('map', 'odom')].transform
    odom_base = by_pair[('odom', 'base_link')].transform
    q = map_odom.rotation
    rot = Rotation.from_quat([q.x, q.y, q.z, q.w]).as_matrix()
    composed = np.array([map_odom.translation.x, map_odom.translation.y,
                         map_odom.translation.z]) + rot @ np.array(
        [odom_base.translation.x, odom_base.translation.y, odom_base.translation.z])
    p = fused.pose.pose.position
    assert composed == pytest.approx([p.x, p.y, p.z], abs=1e-6)


def test_arrival_order_is_the_log_order(voyage: Path) -> None:
    items = list(replay.input_messages(voyage, NavigatorParams()))
    with AnyReader([voyage]) as reader:
        logged = [(c.topic, log_ns) for c, log_ns, _ in reader.messages()
                  if c.topic in replay.DEFAULT_TOPICS.values()]
    # Each message arrives at its log time, in the bag's order, as the node received it live.
    assert [(replay.DEFAULT_TOPICS[item.name], item.arrival_ns) for item in items] == logged
    stamps = [item.stamp_ns for item in items]
    assert stamps != sorted(stamps)          # the fixes come after IMU samples newer than them
    late = [item for item in items if item.name == 'fix']
    assert all(item.arrival_ns - item.stamp_ns >= 100_000_000 for item in late)


@pytest.mark.parametrize('fmt, velocity', [('mcap', 'twist_with_covariance'),
                                           ('sqlite3', 'twist'), ('ros1', 'odometry')])
def test_rosbags_and_rclpy_messages_give_the_same_outputs(fmt: str, velocity: str,
                                                          tmp_path: Path) -> None:
    """The replay feeds rosbags' dataclasses, the node rclpy messages: the same bytes come out."""
    from rclpy.serialization import deserialize_message
    source = write_voyage(tmp_path / ('in.bag' if fmt == 'ros1' else 'in'), fmt=fmt,
                          velocity=velocity, duration=5.0)
    params = NavigatorParams.from_flat({'velocity.source': velocity, 'publish_rate': 0.0})
    types = interface.types(interface.Role.INPUT, velocity_source=velocity, absolute=False)
    ours, nodes = Pipeline(params), Pipeline(params)
    runs: dict[str, list] = {'replay': [], 'node': []}
    for item in replay.input_messages(source, params):
        # Not rclpy's: rosbags' dataclasses, and on ROS 2 bags the Imu CDR view.
        direct = type(item.msg) is imu_cdr.ImuCdr
        assert direct == (item.name == 'imu' and fmt != 'ros1')
        assert type(item.msg).__module__.startswith('rosbags') != direct
        as_node = deserialize_message(item.raw, interface.message_class(types[item.name]))
        for label, pipeline, msg in (('replay', ours, item.msg), ('node', nodes, as_node)):
            result = pipeline.handle(item.name, msg, item.arrival_ns)
            runs[label].append((item.name, item.stamp_ns, result.rejected,
                                [(e.topic, e.cdr) for e in result.emissions]))
    counts = ours.counts
    assert counts['velocity'] > 0 and counts['fix'] > 0 and counts['imu'] > 0, counts
    assert sum(len(emitted) for *_, emitted in runs['node']) > 100
    assert runs['replay'] == runs['node'] and ours.counts == nodes.counts


def test_no_copy_inputs(voyage: Path, tmp_path: Path) -> None:
    replay.run(voyage, tmp_path / 'out', copy_inputs=False, progress=False)
    types, _ = read_bag(tmp_path / 'out')
    assert set(types) == set(replay.OUTPUT_TYPES)


@pytest.mark.parametrize('fmt, copy_inputs', [('mcap', True), ('mcap', False), ('ros1', True)])
def test_a_replay_writes_the_same_bytes_every_time(fmt: str, copy_inputs: bool,
                                                   tmp_path: Path) -> None:
    """Two replays of one bag give the same bag, byte for byte (zero padding, one process)."""
    source = write_voyage(tmp_path / ('in.bag' if fmt == 'ros1' else 'in'), fmt=fmt,
                          duration=20.0)
    files = []
    for run in (1, 2):
        out = tmp_path / str(run) / 'out'      # one name: the metadata holds it
        out.parent.mkdir()
        summary = replay.run(source, out, copy_inputs=copy_inputs, progress=False)
        files.append((summary.messages_copied, summary.notes, summary.messages_out,
                      summary.distance_m, summary.final_position, summary.estimates,
                      (out / 'metadata.yaml').read_bytes(), (out / 'out.mcap').read_bytes()))
    assert (files[0][0] > 1000) == copy_inputs
    assert files[0][2]['/odometry'] > 500 and files[0][3] > 10.0
    assert files[0] == files[1]


def test_collecting_less_gives_the_callers_thresholds_back(voyage: Path, tmp_path: Path) -> None:
    """
    The caller's garbage collector thresholds come back after a replay, and after a failure.

    The drivers run with the young-generation threshold ``pipeline.GC_THRESHOLD``.
    """
    import gc
    from vessel_kinematics.ros.pipeline import fewer_collections, GC_THRESHOLD
    before = gc.get_threshold()
    assert before[0] != GC_THRESHOLD
    replay.run(voyage, tmp_path / 'out', progress=False, accuracy=False)
    assert gc.get_threshold() == before
    with pytest.raises(RuntimeError):
        with fewer_collections():
            assert gc.get_threshold() == (GC_THRESHOLD, *before[1:])
            raise RuntimeError
    assert gc.get_threshold() == before


@pytest.mark.parametrize('fmt', ['sqlite3', 'ros1'])
def test_other_formats_give_the_same_outputs(fmt: str, replayed: Any, tmp_path: Path) -> None:
    source = write_voyage(tmp_path / ('in.bag' if fmt == 'ros1' else 'in'), fmt=fmt)
    outputs, summary = replay.replay_in_memory(source)
    _, _, messages = replayed
    assert summary.messages_in == replayed[0].messages_in
    for topic in ('/odometry', '/course_sideslip', '/fix/filtered'):
        ours = [(m.pose.pose.position.x, m.pose.pose.position.y) if topic == '/odometry'
                else (m.vector.x, m.vector.y) if topic == '/course_sideslip'
                else (m.latitude, m.longitude) for _, m in outputs[topic]]
        theirs = [(m.pose.pose.position.x, m.pose.pose.position.y) if topic == '/odometry'
                  else (m.vector.x, m.vector.y) if topic == '/course_sideslip'
                  else (m.latitude, m.longitude) for _, m in messages[topic]]
        assert ours == theirs


def test_remaps_and_velocity_types(tmp_path: Path) -> None:
    topics = {'fix': '/gps/fix', 'imu': '/imu/data', 'velocity': '/wheel/odom'}
    source = write_voyage(tmp_path / 'in', topics=topics, velocity='odometry')
    params = NavigatorParams.from_flat({'velocity.source': 'odometry'})
    summary = replay.run(source, tmp_path / 'out', params,
                         ['fix:=/gps/fix', 'imu:=imu/data', 'velocity:=/wheel/odom'],
                         progress=False)
    assert summary.topics == topics
    assert summary.messages_in['velocity'] == int(DURATION * 10) + 1
    assert not summary.rejected
    assert summary.distance_m == pytest.approx(SPEED * DURATION, rel=0.02)


def test_params_file_sections(voyage: Path, tmp_path: Path) -> None:
    for i, section in enumerate(('navigator', '/**')):
        params_file = tmp_path / f'p{i}.yaml'
        params_file.write_text(f"'{section}':\n  ros__parameters:\n    map_frame: world\n"
                               '    gnss:\n      enabled: false\n')
        rc = replay.main([str(voyage), str(tmp_path / f'out{i}'), '--params-file',
                          str(params_file), '--no-progress'])
        assert rc == 0
        _, messages = read_bag(tmp_path / f'out{i}')
        assert messages['/odometry'][-1][1].header.frame_id == 'world'


def test_param_override_on_the_command_line(voyage: Path, tmp_path: Path) -> None:
    rc = replay.main([str(voyage), str(tmp_path / 'out'), '-p', 'base_frame:=hull',
                      '--no-progress', '--no-copy-inputs'])
    assert rc == 0
    _, messages = read_bag(tmp_path / 'out')
    assert messages['/odometry'][0][1].child_frame_id == 'hull'


def _fails(argv: list[str], capsys: pytest.CaptureFixture, *needles: str) -> None:
    rc = replay.main(argv + ['--no-progress'])
    err = capsys.readouterr().err.strip()
    assert rc != 0
    assert err.startswith('replay: error:') and '\n' not in err, err
    for needle in needles:
        assert needle in err, err


def test_error_missing_file(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    _fails([str(tmp_path / 'nope.bag'), str(tmp_path / 'out')], capsys, 'not found')
    assert not (tmp_path / 'out').exists()


def test_error_unreadable_bag(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    junk = tmp_path / 'junk.bag'
    junk.write_bytes(b'this is not a bag\n' * 10)
    _fails([str(junk), str(tmp_path / 'out')], capsys, 'cannot read')
    folder = tmp_path / 'folder'
    folder.mkdir()
    (folder / 'metadata.yaml').write_text('rosbag2_bagfile_information: {version: 99}\n')
    _fails([str(folder), str(tmp_path / 'out')], capsys, 'cannot read')
    assert not (tmp_path / 'out').exists()


def test_error_missing_topic(voyage: Path, tmp_path: Path,
                             capsys: pytest.CaptureFixture) -> None:
    _fails([str(voyage), str(tmp_path / 'out'), '--remap', 'fix:=/gps/fix'], capsys,
           '/gps/fix', 'not in')
    _fails([str(voyage), str(tmp_path / 'out'), '--remap', 'gps:=/fix'], capsys,
           "'gps' is not an input")
    assert not (tmp_path / 'out').exists()


def test_error_wrong_type(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    source = write_voyage(tmp_path / 'in', velocity='twist', duration=2.0)
    _fails([str(source), str(tmp_path / 'out')], capsys,
           'geometry_msgs/msg/TwistStamped', 'velocity.source: twist')
    _fails([str(source), str(tmp_path / 'out'), '--remap', 'imu:=/fix'], capsys,
           'sensor_msgs/msg/NavSatFix', 'sensor_msgs/msg/Imu')
    assert replay.main([str(source), str(tmp_path / 'out'), '-p', 'velocity.source:=twist',
                        '--no-progress']) == 0


def test_error_bad_parameter_and_existing_output(voyage: Path, tmp_path: Path,
                                                 capsys: pytest.CaptureFixture) -> None:
    _fails([str(voyage), str(tmp_path / 'out'), '-p', 'projection:=mercator'], capsys,
           'projection')
    (tmp_path / 'out').mkdir()
    _fails([str(voyage), str(tmp_path / 'out')], capsys, 'exists')


def test_command_line_module(voyage: Path, tmp_path: Path) -> None:
    done = subprocess.run([sys.executable, '-m', 'vessel_kinematics.tools.replay', str(voyage),
                           str(tmp_path / 'out'), '--plot', str(tmp_path / 'run.png')],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert 'distance' in done.stdout and str(tmp_path / 'run.png') in done.stdout
    assert (tmp_path / 'run.png').read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'
    assert done.stderr == ''  # no progress bar when not on a terminal
    done = subprocess.run([sys.executable, '-m', 'vessel_kinematics.tools.replay',
                           str(tmp_path / 'missing'), str(tmp_path / 'out2')],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 1 and 'not found' in done.stderr


def test_accuracy_against_truth_with_dead_reckoning_beside(tmp_path: Path) -> None:
    # The speed log reads 5 % high: dead reckoning drifts 0.1 m/s, the fixes hold the fusion.
    source = write_voyage(tmp_path / 'in', truth=True, speed_bias=0.1, fix_delay=0.0)
    summary = replay.run(source, tmp_path / 'out', progress=False,
                         plot=tmp_path / 'run.png')
    assert summary.accuracy is not None and 'dead-reckoning' in summary.accuracy
    fused = evaluate.accuracy(evaluate.load_run(tmp_path / 'out'))
    dr = evaluate.accuracy(replay.dead_reckoning_run(source))
    assert dr['position'].maximum == pytest.approx(0.1 * DURATION, rel=0.1)
    assert fused['position'].rms < 0.5 * dr['position'].rms
    assert fused['heading'].maximum < math.radians(0.5)
    assert fused['course'].rms < math.radians(2.0)
    assert dr['course'].maximum < math.radians(0.5)  # straight ahead: the bias is along track
    assert (tmp_path / 'run.png').stat().st_size > 10_000


def _value_sigma(text: str) -> tuple[float, float]:
    """Return (value, sigma) of an estimate as the summary prints it: ``'0.801 ± 0.004'``."""
    value, sigma = text.split(' ± ')
    return float(value), float(sigma)


def test_calibration_output_against_the_simulators_truth(tmp_path: Path) -> None:
    """
    The ``calibration`` output is what the filter learnt, against ``/truth/calibration``.

    The simulator's default 300 s voyage with a surge-only log reading 20 % low and an IMU
    whose yaw is 30 deg off, replayed through the water with the heading offset estimated.
    """
    config = sim.VoyageConfig(log_scale=0.8, log_surge_only=True,
                              imu_yaw_offset=math.radians(30.0))
    sim.generate(tmp_path / 'in', config)
    params = NavigatorParams.from_flat({'velocity.reference': 'water',
                                        'imu.estimate_yaw_offset': True,
                                        'gnss.antenna_position': list(config.antenna)})
    summary = replay.run(tmp_path / 'in', tmp_path / 'out', params, progress=False,
                         accuracy=False)
    types, messages = read_bag(tmp_path / 'out')
    assert types['/calibration'] == 'geometry_msgs/msg/Vector3Stamped'
    truth = messages['/truth/calibration'][-1][1].vector          # copied from the input
    assert (truth.x, truth.y, truth.z) == pytest.approx((0.8, 0.0, math.radians(30.0)))
    calibration = [msg for _, msg in messages['/calibration']]
    assert len(calibration) == len(messages['/odometry'])        # one per state, as the others
    assert all(msg.header.frame_id == 'base_link' for msg in calibration)
    first, last = calibration[0].vector, calibration[-1].vector
    # At the start: the log's prior scale, and no heading offset before the vessel moved 20 m.
    assert first.x == pytest.approx(1.0, abs=0.05) and first.z == 0.0
    # At the end: the values in use (the summary's, rounded), each within 3 sigma of the truth.
    scale, scale_sigma = _value_sigma(summary.estimates['log scale'])
    assert last.x == pytest.approx(scale, abs=5e-4)
    assert abs(last.x - truth.x) < 3.0 * scale_sigma + 1e-3
    assert last.x == pytest.approx(0.8, rel=0.02)
    offset, offset_sigma = _value_sigma(summary.estimates['heading offset (deg)'])
    # (the summary's one decimal, and what the messages after the last output moved it)
    assert math.degrees(last.z) == pytest.approx(offset, abs=0.1)
    error_deg = math.degrees(math.remainder(last.z - truth.z, 2.0 * math.pi))
    # (σ 1.9°: 1.15° off, just under 1° before the log's steady reading; docs/validation.md)
    assert abs(error_deg) < 3.0 * offset_sigma + 0.05 and abs(error_deg) < 1.5
    # With the heading offset estimated the leeway is not (the offset takes it all): 0.
    assert 'leeway (deg)' not in summary.estimates
    assert all(msg.vector.y == 0.0 for msg in calibration)


def test_course_against_a_reference_cog(tmp_path: Path) -> None:
    source = write_voyage(tmp_path / 'in', cog=True, fix_delay=0.0)
    outputs, _ = replay.replay_in_memory(source)
    extra = bags.read_topics([source], ['/gnss/cog_sog', '/fix'])
    comparison = evaluate.course_vs_reference(
        evaluate.run_from_messages({**outputs, **extra}))
    # The reference COG is 1 degree to starboard of the true course, by construction.
    assert comparison['mean'] == pytest.approx(-1.0, abs=0.3)
    assert comparison['cog_minus_heading'] == pytest.approx(1.0, abs=0.3)
    assert comparison['n'] >= DURATION * 5 - 5


def test_break_at_wraps_splits_lines_only_where_the_angle_wraps() -> None:
    t = np.arange(0.0, 60.0, 0.5)
    angle = np.radians(170.0) + 0.12 * t * np.sin(0.1 * t)   # sweeps through ±180 deg both ways
    angle[40] = angle[39] + np.radians(150.0)                 # a fast turn that does not wrap
    t_out, out = plot.break_at_wraps(t, angle)
    wrapped = (angle + np.pi) % (2 * np.pi) - np.pi
    # Independently: np.unwrap adds a turn exactly where a neighbour is more than π away.
    expected = np.flatnonzero(np.abs(np.diff(np.unwrap(wrapped) - wrapped)) > 1.0) + 1
    assert len(expected) >= 2
    gaps = np.flatnonzero(np.isnan(out))
    assert list(gaps - np.arange(len(gaps))) == list(expected)
    kept = ~np.isnan(out)
    np.testing.assert_array_equal(t_out[kept], t)
    np.testing.assert_allclose(out[kept], wrapped, atol=1e-12)
    assert np.all(np.diff(t_out) > 0.0)
    steps = np.abs(np.diff(out))
    assert np.all(steps[~np.isnan(steps)] <= np.pi)   # no drawn segment crosses the axis
    t_same, same = plot.break_at_wraps(t[:30], np.zeros(30))
    assert not np.isnan(same).any() and len(t_same) == 30


@pytest.mark.parametrize('flat', [{}, {'publish_rate': 0.0, 'velocity.reference': 'water'}])
def test_the_bag_holds_the_in_memory_replays_messages(flat: dict, voyage: Path,
                                                      tmp_path: Path) -> None:
    """
    The bag and the in-memory replay: one loop, two sinks; the same messages, at the same times.

    Each message written deserialises (rosbags) to the in-memory one and re-serialises to the
    written bytes; the summaries agree.
    """
    params = NavigatorParams.from_flat(flat)
    summary = replay.run(voyage, tmp_path / 'out', params, copy_inputs=False, progress=False)
    memory, memory_summary = replay.replay_in_memory(voyage, params,
                                                     topics=list(replay.OUTPUT_TYPES))
    written: dict[str, list[tuple[int, bytes]]] = {}
    with AnyReader([tmp_path / 'out']) as reader:
        for connection, ns, raw in reader.messages():
            written.setdefault(connection.topic, []).append((ns, bytes(raw)))
    assert set(written) == {t for t, m in memory.items() if m}
    store = bags.jazzy()
    with AnyReader([voyage]) as reader:
        start = reader.start_time          # nothing is logged before the input's start
    for topic, messages in memory.items():
        assert [(max(ns, start), bytes(store.serialize_cdr(m, replay.OUTPUT_TYPES[topic])))
                for ns, m in messages] == written.get(topic, []), topic
    assert len(written['/odometry']) > 10
    if 'velocity.reference' in flat:
        assert len(written['/relative_flow']) == len(written['/odometry'])
    for key in ('messages_out', 'distance_m', 'final_position', 'rejected'):
        assert getattr(summary, key) == getattr(memory_summary, key), key
