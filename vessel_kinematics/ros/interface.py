"""
The navigator's interface, declared once: every topic, its message type, QoS and role.

The node creates its subscriptions and publishers from this table, the replay reads and
writes bags by it, the simulator writes its inputs and truth by it, the evaluation and the
demo read by it. Adding an output means a row here and its builder
(``ros.outputs.STATE_OUTPUTS``), nothing else. The QoS profiles are here too (:data:`QOS`),
as plain data.

Names are the node's relative topic names (remappable); in a bag, and for the replay, they are
absolute in the root namespace (``'/' + name``). Types are ROS 2 type strings
(``pkg/msg/Name``); :func:`message_class` imports the rclpy class on demand, so this module
itself imports no message package; :func:`type_name` names the type of any message the
pipeline takes (rclpy's, rosbags' or a CDR view).
"""

from __future__ import annotations

from dataclasses import dataclass
import enum
import importlib

__all__ = ['by_role', 'GNSS_VELOCITY_TYPES', 'IMU_TYPES', 'input_names', 'input_qos',
           'message_class', 'output_names', 'QOS', 'Qos',
           'QosProfile', 'Role', 'Topic', 'TOPICS', 'topic', 'type_name', 'types',
           'VELOCITY_TYPES']


class Role(str, enum.Enum):
    """What a topic is to the navigator."""

    #: An input of the pipeline (``fix``, ``imu``, ``velocity``).
    INPUT = 'input'
    #: A per-update output of the pipeline, built from the state (or the origin).
    OUTPUT = 'output'
    #: Published by the drivers beside the outputs: diagnostics, TF.
    AUXILIARY = 'auxiliary'
    #: Written by the simulator for scoring, never read by the navigator.
    TRUTH = 'truth'
    #: A receiver's own solution kept in a recording for comparison (COG/SOG).
    REFERENCE = 'reference'


class Qos(str, enum.Enum):
    """The QoS of a topic, by kind: :data:`QOS` gives each its profile."""

    #: Inputs: best effort (``sensor_qos: sensor_data``) or reliable, a short queue.
    SENSOR = 'sensor'
    #: Reliable, volatile, a short queue: the outputs.
    RELIABLE = 'reliable'
    #: Reliable, transient-local, depth 1: a late subscriber gets the last message.
    LATCHED = 'latched'
    #: tf2's TransformBroadcaster: reliable, volatile, depth 100.
    TF = 'tf'
    #: tf2's StaticTransformBroadcaster: reliable, transient-local, depth 1.
    TF_STATIC = 'tf_static'
    #: tf2's static listener: reliable, transient-local, depth 100 (the latched message of
    #: every broadcaster, a URDF's robot_state_publisher and each static_transform_publisher).
    TF_STATIC_LISTENER = 'tf_static_listener'


@dataclass(frozen=True)
class QosProfile:
    """
    A QoS profile as plain data (keep-last ``depth``), for rclpy and for bags alike.

    The node turns it into an rclpy ``QoSProfile`` (``ros.node.qos``), the bag writer into
    rosbags' offered profile (``tools.bags``): each mapping is written once.
    """

    depth: int
    reliable: bool = True
    transient_local: bool = False


#: The profile of each kind. The inputs' reliability is ``sensor_qos``'s (:func:`input_qos`);
#: their depth is 50 ms of a 400 Hz IMU, so that a short stall drops nothing.
QOS: dict[Qos, QosProfile] = {
    Qos.SENSOR: QosProfile(depth=20, reliable=False),
    Qos.RELIABLE: QosProfile(depth=10),
    Qos.LATCHED: QosProfile(depth=1, transient_local=True),
    Qos.TF: QosProfile(depth=100),
    Qos.TF_STATIC: QosProfile(depth=1, transient_local=True),
    Qos.TF_STATIC_LISTENER: QosProfile(depth=100, transient_local=True),
}


def input_qos(reliable: bool) -> QosProfile:
    """Return the inputs' subscription profile: best effort (sensor data) or reliable."""
    return QosProfile(depth=QOS[Qos.SENSOR].depth, reliable=reliable)


@dataclass(frozen=True)
class Topic:
    """
    One row of the interface.

    ``name`` relative (``'odometry/local'``); ``msg_type`` the ROS 2 type string (None for
    the inputs whose type a parameter chooses: ``velocity`` :data:`VELOCITY_TYPES`, ``imu``
    :data:`IMU_TYPES`, ``gnss_velocity`` :data:`GNSS_VELOCITY_TYPES`);
    ``water_only``: published only with a water-referenced velocity (the current's outputs).
    """

    name: str
    msg_type: str | None
    role: Role
    qos: Qos
    doc: str
    water_only: bool = False

    @property
    def absolute(self) -> str:
        """Return the topic in the root namespace, as in a bag (``'/odometry'``)."""
        return self.name if self.name.startswith('/') else '/' + self.name

    @property
    def profile(self) -> QosProfile:
        """Return the QoS of the topic's kind (an input's reliability: :func:`input_qos`)."""
        return QOS[self.qos]

    @property
    def latched(self) -> bool:
        """Return True for a transient-local topic (a late subscriber gets the last one)."""
        return QOS[self.qos].transient_local


_VECTOR3 = 'geometry_msgs/msg/Vector3Stamped'
_ODOMETRY = 'nav_msgs/msg/Odometry'
_FIX = 'sensor_msgs/msg/NavSatFix'

#: Every topic, inputs first, then the outputs in the order the pipeline builds them.
TOPICS: tuple[Topic, ...] = (
    Topic('fix', _FIX, Role.INPUT, Qos.SENSOR, 'GNSS fix of the antenna'),
    Topic('imu', None, Role.INPUT, Qos.SENSOR,
          'attitude and body rate (REP-145), or a heading (type per imu.source)'),
    Topic('velocity', None, Role.INPUT, Qos.SENSOR,
          'body velocity, over ground or through the water (type per velocity.source)'),
    Topic('gnss_velocity', None, Role.INPUT, Qos.SENSOR,
          "a receiver's own velocity over ground, ENU (type per gnss_velocity.source)"),
    Topic('odometry', _ODOMETRY, Role.OUTPUT, Qos.RELIABLE, 'fused pose in map (ENU/FLU)'),
    Topic('odometry/local', _ODOMETRY, Role.OUTPUT, Qos.RELIABLE,
          'dead-reckoned pose in odom, never jumps'),
    Topic('odometry/ned', _ODOMETRY, Role.OUTPUT, Qos.RELIABLE,
          "the fused state in Fossen's NED/FRD"),
    Topic('course_sideslip', _VECTOR3, Role.OUTPUT, Qos.RELIABLE,
          'course over ground, sideslip, angle of attack (rad)'),
    Topic('current', _VECTOR3, Role.OUTPUT, Qos.RELIABLE, 'ocean current, ENU (m/s)',
          water_only=True),
    Topic('relative_flow', _VECTOR3, Role.OUTPUT, Qos.RELIABLE,
          'speed, sideslip and angle of attack through the water', water_only=True),
    Topic('fix/filtered', _FIX, Role.OUTPUT, Qos.RELIABLE, 'estimated position of the base'),
    Topic('calibration', _VECTOR3, Role.OUTPUT, Qos.RELIABLE,
          'the calibration in use: log scale, leeway (rad), IMU heading offset (rad)'),
    Topic('origin', _FIX, Role.OUTPUT, Qos.LATCHED, 'the NED/ENU origin in use'),
    Topic('/diagnostics', 'diagnostic_msgs/msg/DiagnosticArray', Role.AUXILIARY,
          Qos.RELIABLE, 'status per input and of the estimate, 1 Hz'),
    Topic('/tf', 'tf2_msgs/msg/TFMessage', Role.AUXILIARY, Qos.TF,
          'map -> odom -> base_link'),
    Topic('/tf_static', 'tf2_msgs/msg/TFMessage', Role.AUXILIARY, Qos.TF_STATIC,
          'earth -> map, map -> map_ned, base_link -> base_link_frd'),
    Topic('/truth/odometry', _ODOMETRY, Role.TRUTH, Qos.RELIABLE,
          'the simulated vessel: map (ENU) / base_link (FLU), twist over ground'),
    Topic('/truth/course_sideslip', _VECTOR3, Role.TRUTH, Qos.RELIABLE,
          'the simulated course, sideslip, angle of attack (rad)'),
    Topic('/truth/current', _VECTOR3, Role.TRUTH, Qos.RELIABLE,
          'the simulated current, ENU (m/s)'),
    Topic('/truth/calibration', _VECTOR3, Role.TRUTH, Qos.RELIABLE,
          'the simulated log scale, leeway (rad), IMU yaw offset (rad)'),
    Topic('/truth/origin', _FIX, Role.TRUTH, Qos.LATCHED, "the origin of the truth's map"),
    Topic('/gnss/cog_sog', _VECTOR3, Role.REFERENCE, Qos.RELIABLE,
          "a receiver's own COG (x, rad from north) and SOG (y, m/s)"),
)

#: The ``velocity`` input's type per ``velocity.source`` (None: no velocity input).
VELOCITY_TYPES: dict[str, str | None] = {
    'twist_with_covariance': 'geometry_msgs/msg/TwistWithCovarianceStamped',
    'twist': 'geometry_msgs/msg/TwistStamped',
    'odometry': _ODOMETRY,
    'none': None,
}

#: The ``imu`` inputs' type per ``imu.source``.
IMU_TYPES: dict[str, str] = {
    'imu': 'sensor_msgs/msg/Imu',
    'quaternion': 'geometry_msgs/msg/QuaternionStamped',
}

#: The ``gnss_velocity`` input's type per ``gnss_velocity.source`` (None: no such input).
GNSS_VELOCITY_TYPES: dict[str, str | None] = {
    'none': None,
    'twist': 'geometry_msgs/msg/TwistStamped',
    'twist_with_covariance': 'geometry_msgs/msg/TwistWithCovarianceStamped',
}

_BY_NAME = {t.name: t for t in TOPICS}


def topic(name: str) -> Topic:
    """Return the row of a topic by its name, relative (``'odometry'``) or absolute."""
    try:
        return _BY_NAME[name]
    except KeyError:
        pass
    try:
        return _BY_NAME[name[1:]] if name.startswith('/') else _BY_NAME['/' + name]
    except KeyError:
        raise KeyError(f"{name!r} is not a topic of the navigator's interface") from None


def by_role(*roles: Role) -> tuple[Topic, ...]:
    """Return the topics of the given roles, in table order."""
    return tuple(t for t in TOPICS if t.role in roles)


def input_names() -> tuple[str, ...]:
    """Return the pipeline's input names: ``('fix', 'imu', 'velocity', 'gnss_velocity')``."""
    return tuple(t.name for t in by_role(Role.INPUT))


def output_names() -> tuple[str, ...]:
    """Return the pipeline's output names, in the order it builds them."""
    return tuple(t.name for t in by_role(Role.OUTPUT))


def types(*roles: Role, velocity_source: str = 'twist_with_covariance',
          absolute: bool = True, imu_source: str = 'imu',
          gnss_velocity_source: str = 'none') -> dict[str, str]:
    """
    Return ``{topic: type string}`` of the given roles (all when none is given).

    The ``velocity`` input takes the type of ``velocity_source`` (left out for ``none``),
    ``imu`` that of ``imu_source``, ``gnss_velocity`` that of ``gnss_velocity_source`` (left
    out for ``none``).
    """
    chosen = {'velocity': VELOCITY_TYPES[velocity_source], 'imu': IMU_TYPES[imu_source],
              'gnss_velocity': GNSS_VELOCITY_TYPES[gnss_velocity_source]}
    out: dict[str, str] = {}
    for t in TOPICS:
        if roles and t.role not in roles:
            continue
        msg_type = chosen[t.name] if t.name in chosen else t.msg_type
        if msg_type is not None:
            out[t.absolute if absolute else t.name] = msg_type
    return out


_CLASSES: dict[str, type] = {}


def message_class(msg_type: str) -> type:
    """Return the rclpy message class of a type string (``'nav_msgs/msg/Odometry'``)."""
    cls = _CLASSES.get(msg_type)
    if cls is None:
        package, kind, name = msg_type.split('/')
        cls = getattr(importlib.import_module(f'{package}.{kind}'), name)
        _CLASSES[msg_type] = cls
    return cls


def type_name(msg: object) -> str:
    """
    Return the ROS 2 type string of a message: an rclpy one, rosbags' dataclass or a CDR view.

    rosbags' classes and the CDR views carry ``__msgtype__``; an rclpy class is named by its
    package and class (``sensor_msgs.msg._imu.Imu`` is ``sensor_msgs/msg/Imu``).
    """
    cls = type(msg)
    name = getattr(cls, '__msgtype__', None)
    if isinstance(name, str):
        return name
    return f'{cls.__module__.split(".")[0]}/msg/{cls.__name__}'
