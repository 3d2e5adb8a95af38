"""
Tests of the bag I/O module: real bags written, read back and checked, and its errors.

Messages are serialised with rosbags' own Jazzy typestore (an independent serialiser), the
bags written by :mod:`vessel_kinematics.tools.bags` and read back through rosbags' readers.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
from rosbags.interfaces import QosDurability, QosReliability
from rosbags.rosbag1 import Writer as Writer1
from rosbags.typesys import get_typestore, Stores
from vessel_kinematics.tools import bags
import yaml

STORE = get_typestore(Stores.ROS2_JAZZY)
VECTOR3 = 'geometry_msgs/msg/Vector3Stamped'
FIX = 'sensor_msgs/msg/NavSatFix'


def _vector(stamp_ns: int, x: float, store: Any = STORE) -> Any:
    types = store.types
    ros1 = {'seq': 0} if store is not STORE else {}
    header = types['std_msgs/msg/Header'](
        stamp=types['builtin_interfaces/msg/Time'](sec=stamp_ns // 10**9,
                                                   nanosec=stamp_ns % 10**9),
        frame_id='map', **ros1)
    return types[VECTOR3](header=header, vector=types['geometry_msgs/msg/Vector3'](
        x=x, y=-x, z=0.5))


def _cdr(stamp_ns: int, x: float) -> bytes:
    return bytes(STORE.serialize_cdr(_vector(stamp_ns, x), VECTOR3))


def _origin_cdr(stamp_ns: int) -> bytes:
    types = STORE.types
    header = types['std_msgs/msg/Header'](
        stamp=types['builtin_interfaces/msg/Time'](sec=stamp_ns // 10**9, nanosec=0),
        frame_id='map')
    fix = types[FIX](header=header, status=types['sensor_msgs/msg/NavSatStatus'](
        status=0, service=1), latitude=63.4, longitude=10.4, altitude=42.0,
        position_covariance=np.zeros(9), position_covariance_type=0)
    return bytes(STORE.serialize_cdr(fix, FIX))


def _connections(path: Path) -> dict[str, Any]:
    with bags.reader(path) as reader:
        return {c.topic: c for c in reader.connections}


def test_written_messages_read_back_in_log_time_order(tmp_path: Path) -> None:
    path = tmp_path / 'out'
    with bags.BagWriter(path) as writer:
        current = writer.add_connection('/current')          # type from the interface table
        origin = writer.add_connection('/origin')
        for i in (0, 1, 2):
            writer.write(current, 10**9 * (5 + i), _cdr(10**9 * (5 + i), 0.25 * i))
        writer.write(origin, 10**9 * 5, _origin_cdr(10**9 * 5))
    assert (path / 'metadata.yaml').is_file()
    assert [p.suffix for p in path.iterdir() if p.name != 'metadata.yaml'] == ['.mcap']
    connections = _connections(path)
    assert {t: c.msgtype for t, c in connections.items()} == {
        '/current': VECTOR3, '/origin': FIX}
    found = bags.read_topics([path], ['/current', '/origin', '/absent'])
    assert sorted(found) == ['/current', '/origin']
    assert [ns for ns, _ in found['/current']] == [5 * 10**9, 6 * 10**9, 7 * 10**9]
    assert [(m.vector.x, m.vector.y, m.vector.z) for _, m in found['/current']] == \
        [(0.0, -0.0, 0.5), (0.25, -0.25, 0.5), (0.5, -0.5, 0.5)]
    assert found['/current'][1][1].header.stamp.sec == 6
    (ns, fix), = found['/origin']
    assert (ns, fix.latitude, fix.altitude) == (5 * 10**9, 63.4, 42.0)
    raw, types = bags.raw_messages(path)
    assert types == {'/current': VECTOR3, '/origin': FIX}
    assert [(t, ns) for t, ns, _ in raw] == [
        ('/current', 5 * 10**9), ('/origin', 5 * 10**9), ('/current', 6 * 10**9),
        ('/current', 7 * 10**9)]
    stored = {ns: data for t, ns, data in raw if t == '/current'}
    assert stored[6 * 10**9] == _cdr(6 * 10**9, 0.25)      # byte for byte


def test_a_latched_topic_offers_transient_local_depth_1(tmp_path: Path) -> None:
    path = bags.write_bag(tmp_path / 'out', [('/origin', 10**9, _origin_cdr(10**9))],
                          {'/origin': FIX, '/odometry/ned': 'nav_msgs/msg/Odometry',
                           '/not/in/table': VECTOR3})
    connections = _connections(path)
    (latched,) = connections['/origin'].ext.offered_qos_profiles
    assert latched.durability == QosDurability.TRANSIENT_LOCAL
    assert latched.reliability == QosReliability.RELIABLE
    assert latched.depth == 1
    for topic in ('/odometry/ned', '/not/in/table'):     # no message: the connection is there
        (profile,) = connections[topic].ext.offered_qos_profiles
        assert profile.durability == QosDurability.VOLATILE
        assert profile.depth == 10
    assert bags.recorded_qos(connections['/origin']) == bags.LATCHED_QOS
    # As rosbag2 (ros2 bag play) reads it: in metadata.yaml, per topic.
    metadata = yaml.safe_load((path / 'metadata.yaml').read_text())
    offered = {t['topic_metadata']['name']: t['topic_metadata']['offered_qos_profiles']
               for t in metadata['rosbag2_bagfile_information']['topics_with_message_count']}
    assert [(q['durability'], q['reliability'], q['depth']) for q in offered['/origin']] == \
        [('transient_local', 'reliable', 1)]
    assert [q['durability'] for q in offered['/odometry/ned']] == ['volatile']


def test_without_qos_no_profile_is_offered(tmp_path: Path) -> None:
    path = bags.write_bag(tmp_path / 'out', [('/origin', 10**9, _origin_cdr(10**9))],
                          {'/origin': FIX}, qos=False)
    assert list(_connections(path)['/origin'].ext.offered_qos_profiles) == []


def test_read_topics_takes_each_topic_from_the_first_bag_holding_it(tmp_path: Path) -> None:
    first = bags.write_bag(tmp_path / 'a', [('/current', 10**9, _cdr(10**9, 1.0))],
                           {'/current': VECTOR3})
    second = bags.write_bag(tmp_path / 'b', [('/current', 2 * 10**9, _cdr(2 * 10**9, 2.0)),
                                             ('/relative_flow', 3 * 10**9,
                                              _cdr(3 * 10**9, 3.0))],
                            {'/current': VECTOR3, '/relative_flow': VECTOR3})
    found = bags.read_topics([first, second], ['/current', '/relative_flow'])
    assert [(ns, m.vector.x) for ns, m in found['/current']] == [(10**9, 1.0)]
    assert [(ns, m.vector.x) for ns, m in found['/relative_flow']] == [(3 * 10**9, 3.0)]


def test_ros1_bag_reads_and_converts_to_cdr(tmp_path: Path) -> None:
    ros1 = get_typestore(Stores.ROS1_NOETIC)
    path = tmp_path / 'in.bag'
    with Writer1(path) as writer:
        connection = writer.add_connection('/current', 'geometry_msgs/msg/Vector3Stamped',
                                           typestore=ros1)
        writer.write(connection, 10**9, bytes(ros1.serialize_ros1(
            _vector(10**9, 1.5, store=ros1), VECTOR3)))
    (ns, msg), = bags.read_topics([path], ['/current'])['/current']
    assert (ns, msg.vector.x, msg.header.frame_id) == (10**9, 1.5, 'map')
    with bags.reader(path) as reader:
        store = bags.cdr_typestore(reader)
        (c, _, raw), = list(reader.messages())
        cdr = bytes(store.ros1_to_cdr(raw, c.msgtype))
    assert STORE.deserialize_cdr(cdr, VECTOR3).vector.y == -1.5


def test_a_missing_path_is_a_bag_error(tmp_path: Path) -> None:
    missing = tmp_path / 'nowhere'
    with pytest.raises(bags.BagError, match='bag not found: .*nowhere'):
        bags.reader(missing)
    with pytest.raises(bags.BagError, match='bag not found'):
        bags.read_topics([missing], ['/odometry'])
    with pytest.raises(bags.BagError, match='bag not found'):
        bags.raw_messages(missing)
    assert not missing.exists()


def test_what_is_not_a_bag_is_a_bag_error(tmp_path: Path) -> None:
    text = tmp_path / 'notes.txt'
    text.write_text('not a bag\n')
    with pytest.raises(bags.BagError, match='cannot read .*notes.txt as a bag'):
        bags.read_topics([text], ['/odometry'])
    assert text.read_text() == 'not a bag\n'


def test_an_existing_output_is_refused_and_kept(tmp_path: Path) -> None:
    out = tmp_path / 'out'
    out.mkdir()
    (out / 'keep.txt').write_text('mine')
    with pytest.raises(bags.BagError, match='exists already'):
        bags.write_bag(out, [], {'/current': VECTOR3})
    with pytest.raises(bags.BagError, match='exists already'):
        bags.BagWriter(out).open()
    assert [p.name for p in out.iterdir()] == ['keep.txt']


def test_a_failed_write_leaves_no_half_bag(tmp_path: Path) -> None:
    out = tmp_path / 'out'
    messages = [('/current', 10**9, _cdr(10**9, 1.0)), ('/unknown', 2 * 10**9, b'\x00')]
    with pytest.raises(bags.BagError, match='/unknown, which has no connection'):
        bags.write_bag(out, messages, {'/current': VECTOR3})
    assert not out.exists()


def test_connections_need_a_type_off_the_table(tmp_path: Path) -> None:
    with bags.BagWriter(tmp_path / 'out') as writer:
        with pytest.raises(bags.BagError, match='not in the navigator'):
            writer.add_connection('/elsewhere')
        with pytest.raises(bags.BagError, match='velocity source'):
            writer.add_connection('/velocity')
        writer.add_connection('/velocity', 'geometry_msgs/msg/TwistStamped')
        with pytest.raises(bags.BagError, match='/velocity'):
            writer.add_connection('/velocity', 'geometry_msgs/msg/TwistStamped')
    with pytest.raises(bags.BagError, match='not open'):
        bags.BagWriter(tmp_path / 'other').add_connection('/current')


def _write_both_ways(tmp_path: Path, messages: list[tuple[int, int, bytes]]) -> tuple[bytes, ...]:
    """Write ``(connection index, log ns, bytes)`` with BagWriter and with rosbags' Writer."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    topics = ('/current', '/course_sideslip', '/origin')
    mine, theirs = tmp_path / 'mine' / 'bag', tmp_path / 'theirs' / 'bag'   # one name: the
    theirs.parent.mkdir()                                       # metadata holds it
    mine.parent.mkdir()
    with bags.BagWriter(mine) as writer:
        conns = [writer.add_connection(topic) for topic in topics]
        for index, stamp_ns, data in messages:
            writer.write(conns[index], stamp_ns, data)
    reference = Writer(theirs, version=bags.VERSION, storage_plugin=StoragePlugin.MCAP)
    reference.open()
    conns = [reference.add_connection(topic, VECTOR3 if topic != '/origin' else FIX,
                                      typestore=STORE,
                                      offered_qos_profiles=bags.offered_qos(topic))
             for topic in topics]
    for index, stamp_ns, data in messages:
        reference.write(conns[index], stamp_ns, data)
    reference.close()
    return tuple((path / f'{path.name}.mcap').read_bytes() for path in (mine, theirs))


def test_writes_give_rosbags_own_bytes(tmp_path: Path) -> None:
    # Out of order, equal stamps, a memoryview, and enough data for several 1 MiB chunks.
    rng = np.random.default_rng(7)
    messages = []
    for i in range(30_000):
        stamp = int(10**9 + rng.integers(0, 10**11))
        index = int(rng.integers(0, 3))
        data = _origin_cdr(stamp) if index == 2 else _cdr(stamp, float(i))
        messages.append((index, stamp, memoryview(data) if i % 5 == 0 else data))
    messages.append((0, messages[-1][1], _cdr(messages[-1][1], -1.0)))
    mine, theirs = _write_both_ways(tmp_path, messages)
    assert len(mine) > 3 * 2**20
    assert mine == theirs
    with bags.reader(tmp_path / 'mine' / 'bag') as reader:
        assert reader.message_count == len(messages)
        assert reader.start_time == min(stamp for _, stamp, _ in messages)
        assert reader.end_time == max(stamp for _, stamp, _ in messages) + 1


def test_a_connection_of_another_bag_is_refused(tmp_path: Path) -> None:
    with bags.BagWriter(tmp_path / 'one') as one, bags.BagWriter(tmp_path / 'two') as two:
        foreign = two.add_connection('/current')
        one.add_connection('/current')
        with pytest.raises(bags.BagError, match='unknown connection'):
            one.write(foreign, 10**9, _cdr(10**9, 1.0))
    with pytest.raises(bags.BagError, match='not open'):
        one.write(foreign, 10**9, _cdr(10**9, 1.0))
