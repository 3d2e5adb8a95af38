"""
The interface packages the navigator uses besides the wheels': tf2_msgs, geographic_msgs, r_l.

In the development venv, ``make build`` generates tf2_msgs, geographic_msgs (its point and pose
messages) and robot_localization's service types from the definitions in .ci/interfaces; on a
real ROS install they are apt's. Either way these tests hold:

* the three import (a failure here is a failure, not a skip: the services need them);
* their type hashes (RIHS01, what DDS discovery compares in Jazzy) are those of a real Jazzy
  install, so a peer built against apt's packages matches ours;
* a service of each robot_localization type, and tf2_msgs' FrameGraph, is served by another
  process and called over DDS, and TFMessage and GeoPoseStamped cross as topics;
* a ROS workspace holding the repository sees only vessel_kinematics (colcon and rosdep skip
  .ci/), and the package installs none of the interfaces: a real install is never shadowed.
"""

from __future__ import annotations

from argparse import ArgumentParser
import json
import math
import os
from pathlib import Path
import sys

from ament_index_python.packages import get_package_share_directory
import dds_harness
from geographic_msgs.msg import GeoPoint, GeoPose, GeoPoseStamped
from geometry_msgs.msg import Point
import pytest
from robot_localization.srv import FromLL, SetDatum, ToggleFilterProcessing, ToLL
from tf2_msgs.msg import TFMessage
from tf2_msgs.srv import FrameGraph

REPO = Path(__file__).resolve().parents[1]
PEER = Path(__file__).resolve().parent / 'interfaces_peer.py'
INTERFACES = ('tf2_msgs', 'geographic_msgs', 'robot_localization')

#: Type hashes of Jazzy's packages. TFMessage's is also computed by rosbags from its own copy of
#: the Jazzy definitions (below); GeoPoint, GeoPose, FromLL and SetDatum are those that
#: rosidl_generator_c wrote into published builds of upstream's packages (*__description.c);
#: ToLL and ToggleFilterProcessing (no published build found) are this build's, of upstream's
#: unchanged definitions, kept so that an edit to them fails here.
JAZZY_HASHES = {
    'tf2_msgs/msg/TFMessage':
        'RIHS01_e369d0f05a23ae52508854b66f6aa0437f3449d652e8cbf22d5abe85d020f087',
    'geographic_msgs/msg/GeoPoint':
        'RIHS01_602c647cf87bbe95a0231b459b5ac30051875d07c0c740b31ad7a8c4662b971e',
    'geographic_msgs/msg/GeoPose':
        'RIHS01_8052786d7663e225e38926f7d05716046c931572c25e557d4f70dca55b972626',
    'robot_localization/srv/FromLL':
        'RIHS01_db39e47b5738d4c5ba6c5907d334ada35899262fba4bd415aa06eefb4733840e',
    'robot_localization/srv/SetDatum':
        'RIHS01_dbb26d6fa555491d14d1de3fd0308f10bc139801b80ccb71511425ffc336c573',
    'robot_localization/srv/ToLL':
        'RIHS01_ea9806b70e690a6727aa5e360606e4e569d33ae0a8bdf62f66fcbdc8ea1945ce',
    'robot_localization/srv/ToggleFilterProcessing':
        'RIHS01_a394a6db1a2413cb92e931ebe59da85398909e7f8a317e7cd4c8aaa3d736517e',
}


def _installed_hash(type_name: str) -> str:
    """Return the RIHS01 hash that the installed package's type description records."""
    package, kind, name = type_name.split('/')
    path = Path(get_package_share_directory(package), kind, f'{name}.json')
    hashes = json.loads(path.read_text())['type_hashes']
    return next(h['hash_string'] for h in hashes if h['type_name'] == type_name)


@pytest.mark.parametrize('type_name', sorted(JAZZY_HASHES))
def test_type_hashes_are_those_of_a_jazzy_install(type_name: str) -> None:
    assert _installed_hash(type_name) == JAZZY_HASHES[type_name]


def test_tf_message_hash_agrees_with_rosbags_jazzy_definitions() -> None:
    from rosbags.typesys import get_typestore, Stores
    store = get_typestore(Stores.ROS2_JAZZY)
    assert store.hash_rihs01('tf2_msgs/msg/TFMessage') == JAZZY_HASHES['tf2_msgs/msg/TFMessage']


@pytest.fixture
def peer(tmp_path: Path):
    """Start interfaces_peer.py in a process of its own; stop it (by its PID) afterwards."""
    process = dds_harness.NodeProcess(Path(sys.executable), [str(PEER)], dict(os.environ),
                                      tmp_path / 'peer.log')
    yield process
    process.stop(timeout=5.0)


@pytest.mark.dds
def test_each_service_type_is_called_over_dds(dds, peer) -> None:
    dds.wait_for_node('vk_interfaces_peer', peer)
    base = '/vk_interfaces_peer/'
    datum = GeoPose(position=GeoPoint(latitude=52.6, longitude=5.3, altitude=-1.5))
    datum.orientation.z, datum.orientation.w = math.sin(0.25), math.cos(0.25)
    assert isinstance(dds._call(SetDatum, base + 'datum', SetDatum.Request(geo_pose=datum),
                                10.0), SetDatum.Response)

    point = GeoPoint(latitude=52.75, longitude=5.125, altitude=3.0)
    map_point = dds._call(FromLL, base + 'fromLL', FromLL.Request(ll_point=point),
                          10.0).map_point
    assert (map_point.x, map_point.y, map_point.z) == (5.125 - 5.3, 52.75 - 52.6, 4.5)
    back = dds._call(ToLL, base + 'toLL', ToLL.Request(map_point=Point(x=1.0, y=-2.0, z=0.5)),
                     10.0).ll_point
    expected = (-2.0 + 52.6, 1.0 + 5.3, 0.5 - 1.5)   # the datum plus the map point
    assert (back.latitude, back.longitude, back.altitude) == expected

    for on in (False, True):
        answer = dds._call(ToggleFilterProcessing, base + 'toggle',
                           ToggleFilterProcessing.Request(on=on), 10.0)
        assert answer.status is on
    frames = dds._call(FrameGraph, base + 'tf2_frames', FrameGraph.Request(), 10.0)
    assert frames.frame_yaml == 'map: {parent: earth}\n'

    # The topics: the datum set above comes back whole, and the hashes that DDS discovery
    # advertises are the Jazzy ones.
    transforms = dds.collect('/interfaces_tf', TFMessage)
    datums = dds.collect('/interfaces_datum', GeoPoseStamped)
    assert dds.spin_until(lambda: transforms and datums, 10.0), peer.output()
    assert [t.child_frame_id for t in transforms[-1].transforms] == ['map']
    assert datums[-1].pose == datum
    [info] = dds.node.get_publishers_info_by_topic('/interfaces_tf')
    assert str(info.topic_type_hash) == JAZZY_HASHES['tf2_msgs/msg/TFMessage']
    assert peer.stop() == 0, peer.output()
    assert 'Traceback' not in peer.output()


def _colcon_finds(base_paths: list[Path]) -> dict[str, str]:
    """Return {name: type} of the packages colcon's discovery finds under ``base_paths``."""
    from colcon_core.package_discovery import (add_package_discovery_arguments,
                                               discover_packages)
    from colcon_core.package_identification import get_package_identification_extensions
    parser = ArgumentParser()
    add_package_discovery_arguments(parser)
    args = parser.parse_args(['--base-paths', *map(str, base_paths)])
    found = discover_packages(args, get_package_identification_extensions())
    return {d.name: d.type for d in found}


def test_a_ros_workspace_sees_only_the_package(tmp_path: Path) -> None:
    # The repository cloned into a workspace's src/ (a link here), as a ROS user has it.
    source = tmp_path / 'ws' / 'src'
    source.mkdir(parents=True)
    (source / 'vessel_kinematics').symlink_to(REPO, target_is_directory=True)
    assert _colcon_finds([source]) == {'vessel_kinematics': 'ros.ament_python'}
    # rosdep install --from-paths src reads the workspace with catkin_pkg.
    from catkin_pkg.packages import find_packages
    assert [p.name for p in find_packages(str(source)).values()] == ['vessel_kinematics']
    # ...while `make build` names .ci/interfaces, and colcon finds the three there.
    found = _colcon_finds([REPO, REPO / '.ci' / 'interfaces'])
    assert found == {'vessel_kinematics': 'ros.ament_python',
                     **dict.fromkeys(INTERFACES, 'ros.ament_cmake')}


@pytest.mark.slow
def test_the_package_installs_no_interface(colcon_install: Path) -> None:
    # The package built alone (the colcon_install fixture builds the repository as a
    # workspace would): nothing of the interfaces in its install tree.
    prefix = colcon_install / 'vessel_kinematics'
    installed = [p for p in prefix.rglob('*') if set(p.parts) & set(INTERFACES)]
    assert installed == []
    assert sorted(p.name for p in colcon_install.iterdir() if p.is_dir()) == ['vessel_kinematics']
