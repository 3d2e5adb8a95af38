"""
A sensor_msgs/Imu read straight from its CDR bytes: the 100-400 Hz input, without a message.

Both drivers read the Imu so: the node subscribes to it raw (:func:`imu_from_raw`), the replay
reads the bag's bytes (:func:`imu_from_cdr`), one struct call per block. The view costs
about a tenth of an rclpy Imu (docs/performance.md), at the highest-rate input. The view
(:class:`ImuCdr`) has the message's attributes, with the values rosbags' ``deserialize_cdr``
gives (the same bytes read as int32/float64; covariances as tuples): the tests compare the two
on every Imu of the simulated and the real bags and on random messages, and
:func:`~vessel_kinematics.ros.inputs.imu_from_msg` reads both alike. Anything but the exact
layout of a little-endian Imu is left to a generic deserialiser (None), which decides what is
garbage: :func:`message_from_raw`, which the node also reads its other inputs with.
"""

from __future__ import annotations

import struct
from typing import Any, NamedTuple

from rclpy.serialization import deserialize_message
from sensor_msgs.msg import Imu
from vessel_kinematics.estimation import Reason, Rejection
from vessel_kinematics.ros.cdr import CDR_LE

__all__ = ['CdrHeader', 'CdrQuaternion', 'CdrStamp', 'CdrVector3', 'imu_from_cdr',
           'imu_from_raw', 'ImuCdr', 'message_from_raw']


class CdrStamp(NamedTuple):
    """builtin_interfaces/Time of a CDR view."""

    sec: int
    nanosec: int


class CdrHeader(NamedTuple):
    """std_msgs/Header of a CDR view."""

    stamp: CdrStamp
    frame_id: str


class CdrQuaternion(NamedTuple):
    """geometry_msgs/Quaternion of a CDR view, ``xyzw`` as in the message."""

    x: float
    y: float
    z: float
    w: float


class CdrVector3(NamedTuple):
    """geometry_msgs/Vector3 of a CDR view."""

    x: float
    y: float
    z: float


class ImuCdr:
    """
    A sensor_msgs/Imu read from its CDR (:func:`imu_from_cdr`), with the message's attributes.

    ``values``: the 37 float64 after the header in message order: orientation ``xyzw`` (0:4),
    its covariance (4:13), ω (13:16), its covariance (16:25), the acceleration (25:28), its
    covariance (28:37). The vectors are made when asked for; :func:`imu_from_msg` reads
    ``values`` directly.
    """

    __slots__ = ('header', 'values')
    #: The type it stands for (:func:`~vessel_kinematics.ros.interface.type_name`).
    __msgtype__ = 'sensor_msgs/msg/Imu'

    def __init__(self, header: CdrHeader, values: tuple[float, ...]) -> None:
        self.header = header
        self.values = values

    #: The orientation (``xyzw``), its covariance (9 float64, row-major), the angular velocity
    #: (rad/s) and the linear acceleration (m/s²) with theirs, as the message's fields.
    orientation = property(lambda self: CdrQuaternion(*self.values[0:4]))
    orientation_covariance = property(lambda self: self.values[4:13])
    angular_velocity = property(lambda self: CdrVector3(*self.values[13:16]))
    angular_velocity_covariance = property(lambda self: self.values[16:25])
    linear_acceleration = property(lambda self: CdrVector3(*self.values[25:28]))
    linear_acceleration_covariance = property(lambda self: self.values[28:37])


_HEADER_CDR = struct.Struct('<iiII')    # encapsulation, sec, nanosec, frame_id's length
#: Imu after its header: orientation (4), its covariance (9), ω (3), its covariance (9),
#: acceleration (3), its covariance (9), float64 each.
_IMU_BODY = struct.Struct('<37d')
_IMU_ENCAPSULATION = int.from_bytes(CDR_LE, 'little', signed=True)


def imu_from_cdr(raw: bytes | memoryview) -> ImuCdr | None:
    """
    Return a sensor_msgs/Imu's fields from its little-endian CDR, or None.

    None for anything but a plain little-endian Imu of exactly its size (another
    encapsulation, a truncated or longer payload, a frame_id that is not NUL-terminated UTF-8):
    the caller then deserialises generically and learns what is wrong.
    """
    size = len(raw)
    if size < 16 + _IMU_BODY.size:
        return None
    encapsulation, sec, nanosec, length = _HEADER_CDR.unpack_from(raw, 0)
    end = 16 + length                     # the string and its NUL
    body = end + (-(end - 4) % 8)         # float64 alignment counts from after encapsulation
    if (encapsulation != _IMU_ENCAPSULATION or length == 0 or body + _IMU_BODY.size != size
            or raw[end - 1] != 0):
        return None
    try:
        frame_id = bytes(raw[16:end - 1]).decode()
    except UnicodeDecodeError:
        return None
    return ImuCdr(CdrHeader(CdrStamp(sec, nanosec), frame_id), _IMU_BODY.unpack_from(raw, body))


def imu_from_raw(raw: bytes | memoryview) -> ImuCdr | Any | Rejection:
    """
    Return a serialised sensor_msgs/Imu (a raw subscription's payload) for :func:`imu_from_msg`.

    Its plain little-endian CDR is read directly (:func:`imu_from_cdr`, the replay's reader);
    anything else is left to :func:`message_from_raw`.
    """
    msg = imu_from_cdr(raw)
    return msg if msg is not None else message_from_raw(raw, Imu)


def message_from_raw(raw: bytes | memoryview, msg_class: type) -> Any | Rejection:
    """
    Return the rclpy message of class ``msg_class`` a raw subscription's payload holds.

    A payload that does not deserialise is ``Rejection(CDR_ERROR)``, never an exception: the
    node takes every input raw so that such a payload is counted, as the replay counts it,
    rather than dropped unseen by the middleware.
    """
    try:
        return deserialize_message(bytes(raw), msg_class)
    except Exception as error:  # noqa: B902 (rclpy raises RMWError for a garbage payload)
        first = str(error).splitlines()[0] if str(error) else type(error).__name__
        return Rejection(Reason.CDR_ERROR, f'{msg_class.__name__} payload of {len(raw)} bytes '
                                           f'does not deserialise: {first}')
