"""
The navigator's interface, declared once: every topic, its message type, QoS and role.

The node creates its subscriptions and publishers from this table, the replay reads and
writes bags by it, the simulator writes its inputs and truth by it, the evaluation and the
demo read by it. Adding an output means a row here and the code that computes it (a builder in
``ros_io.STATE_OUTPUTS``), nothing else.

Names are the node's relative topic names (remappable); in a bag, and for the replay, they are
absolute in the root namespace (``'/' + name``). Types are ROS 2 type strings
(``pkg/msg/Name``); :func:`message_class` imports the rclpy class on demand, so this module
itself imports no message package.
"""

from __future__ import annotations

from dataclasses import dataclass
import enum
import importlib

__all__ = ['Qos', 'Role', 'Topic', 'TOPICS', 'VELOCITY_TYPES', 'by_role', 'input_names',
           'message_class', 'output_names', 'topic', 'types']


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
    """The QoS a topic is published or subscribed with (the node maps these to profiles)."""

    #: Inputs: ``sensor_data`` (best effort) or reliable, per ``sensor_qos``.
    SENSOR = 'sensor'
    #: Reliable, volatile, a short queue: the outputs.
    RELIABLE = 'reliable'
    #: Reliable, transient-local, depth 1: a late subscriber gets the last message.
    LATCHED = 'latched'
    #: tf2's TransformBroadcaster: reliable, volatile, depth 100.
    TF = 'tf'
    #: tf2's StaticTransformBroadcaster: reliable, transient-local, depth 1.
    TF_STATIC = 'tf_static'


@dataclass(frozen=True)
class Topic:
    """
    One row of the interface.

    ``name`` relative (``'odometry/local'``); ``msg_type`` the ROS 2 type string (None for
    ``velocity``, whose type ``velocity.source`` chooses: :data:`VELOCITY_TYPES`);
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
    def latched(self) -> bool:
        """Return True for a transient-local topic (a late subscriber gets the last one)."""
        return self.qos in (Qos.LATCHED, Qos.TF_STATIC)


_VECTOR3 = 'geometry_msgs/msg/Vector3Stamped'
_ODOMETRY = 'nav_msgs/msg/Odometry'
_FIX = 'sensor_msgs/msg/NavSatFix'

#: Every topic, inputs first, then the outputs in the order the pipeline builds them.
TOPICS: tuple[Topic, ...] = (
    Topic('fix', _FIX, Role.INPUT, Qos.SENSOR, 'GNSS fix of the antenna'),
    Topic('imu', 'sensor_msgs/msg/Imu', Role.INPUT, Qos.SENSOR,
          'attitude and body rate (REP-145)'),
    Topic('velocity', None, Role.INPUT, Qos.SENSOR,
          'body velocity, over ground or through the water (type per velocity.source)'),
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
    """Return the pipeline's input names: ``('fix', 'imu', 'velocity')``."""
    return tuple(t.name for t in by_role(Role.INPUT))


def output_names() -> tuple[str, ...]:
    """Return the pipeline's output names, in the order it builds them."""
    return tuple(t.name for t in by_role(Role.OUTPUT))


def types(*roles: Role, velocity_source: str = 'twist_with_covariance',
          absolute: bool = True) -> dict[str, str]:
    """
    Return ``{topic: type string}`` of the given roles (all when none is given).

    The ``velocity`` input takes the type of ``velocity_source`` (left out for ``none``).
    """
    out: dict[str, str] = {}
    for t in TOPICS:
        if roles and t.role not in roles:
            continue
        msg_type = VELOCITY_TYPES[velocity_source] if t.name == 'velocity' else t.msg_type
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
