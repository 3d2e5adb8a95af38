"""
Bag I/O, written once: rosbag2 mcap writers and bag readers over ``rosbags``.

Every tool that touches a bag goes through here (the replay, the simulator, the evaluation,
the demo), so the low-level rosbags calls live in one place:

- :class:`BagWriter` writes a new rosbag2 bag (version 9, mcap) with the message definitions
  of ROS 2 Jazzy; a connection's type and offered QoS default to the interface table's row
  (:mod:`vessel_kinematics.ros.interface`, its QoS profile as rosbags' :func:`offered_qos`);
  :meth:`BagWriter.write` takes CDR bytes and a log time (ns), through rosbags' public
  ``Writer.write``.
- :func:`write_bag` writes a whole sequence of ``(topic, log ns, CDR bytes)`` at once, and
  leaves no half-written bag behind when it fails.
- :func:`reader` makes rosbags' AnyReader (rosbag2 mcap/sqlite3 and ROS 1 bags) for one or
  several bags; :func:`read_topics` reads topics of several bags deserialised,
  :func:`raw_messages` a bag's messages as they are stored, :func:`deserialize` one message's
  CDR (rosbags' dataclasses), :func:`serialize` one message (zero padding: the same message
  gives the same bytes), :func:`header` and :func:`vector3` the common parts to build one.

Problems are :class:`BagError` with a one-line reason (a missing path, an unreadable bag, an
existing output, a message for a topic without connection).
"""

from __future__ import annotations

from contextlib import contextmanager
from functools import cache
from pathlib import Path
import shutil
from typing import Any, Iterable, Iterator, Mapping, Sequence

from rosbags.highlevel import AnyReader, AnyReaderError
from rosbags.interfaces import (Connection, Qos, QosDurability, QosHistory, QosLiveliness,
                                QosReliability, QosTime)
from rosbags.rosbag2 import StoragePlugin, Writer, WriterError
from rosbags.typesys import get_typestore, Stores
from rosbags.typesys.store import Typestore
from vessel_kinematics.core.frames import ns_to_stamp
from vessel_kinematics.ros import interface

__all__ = ['BagError', 'BagWriter', 'cdr_typestore', 'Connection', 'deserialize', 'header',
           'jazzy', 'LATCHED_QOS', 'offered_qos', 'Qos', 'raw_messages', 'read_topics', 'reader',
           'recorded_qos', 'RELIABLE_QOS', 'rosbags_qos', 'serialize', 'vector3', 'VERSION',
           'write_bag']

#: The rosbag2 metadata version written (rosbags' latest).
VERSION = Writer.VERSION_LATEST

_FOREVER = QosTime(2147483647, 4294967295)


def rosbags_qos(profile: interface.QosProfile) -> list[Qos]:
    """Return an interface QoS profile as rosbags' offered profiles (for a connection)."""
    return [Qos(QosHistory.KEEP_LAST, profile.depth,
                QosReliability.RELIABLE if profile.reliable else QosReliability.BEST_EFFORT,
                QosDurability.TRANSIENT_LOCAL if profile.transient_local
                else QosDurability.VOLATILE, _FOREVER, _FOREVER, QosLiveliness.AUTOMATIC,
                _FOREVER, avoid_ros_namespace_conventions=False)]


#: Offered QoS of a latched topic: reliable, transient-local, keep last 1.
LATCHED_QOS: list[Qos] = rosbags_qos(interface.QOS[interface.Qos.LATCHED])
#: Offered QoS of any other topic: reliable, volatile, keep last 10.
RELIABLE_QOS: list[Qos] = rosbags_qos(interface.QOS[interface.Qos.RELIABLE])


class BagError(Exception):
    """A bag that cannot be opened, read or written; the message is one line."""


@cache
def jazzy() -> Typestore:
    """Return rosbags' ROS 2 Jazzy typestore (one shared instance: register nothing in it)."""
    return get_typestore(Stores.ROS2_JAZZY)


def offered_qos(topic: str) -> list[Qos]:
    """Return the offered QoS of a topic of the interface table (latched or reliable)."""
    return LATCHED_QOS if interface.topic(topic).latched else RELIABLE_QOS


def deserialize(data: bytes | memoryview, msgtype: str) -> Any:
    """Return one message of Jazzy's ``msgtype`` from its CDR bytes (rosbags' dataclass)."""
    return jazzy().deserialize_cdr(data, msgtype)


def serialize(msg: Any) -> bytes:
    """Return a rosbags message's CDR bytes, little-endian as rosbag2 stores it, padding zeros."""
    return bytes(jazzy().serialize_cdr(msg, msg.__msgtype__))


def header(stamp_ns: int, frame_id: str) -> Any:
    """Return a std_msgs/Header stamped ``stamp_ns`` (rosbags' dataclass)."""
    types = jazzy().types
    sec, nanosec = ns_to_stamp(stamp_ns)
    return types['std_msgs/msg/Header'](
        stamp=types['builtin_interfaces/msg/Time'](sec=sec, nanosec=nanosec), frame_id=frame_id)


def vector3(x: float, y: float, z: float) -> Any:
    """Return a geometry_msgs/Vector3 (rosbags' dataclass)."""
    return jazzy().types['geometry_msgs/msg/Vector3'](x=float(x), y=float(y), z=float(z))


def recorded_qos(connection: Connection) -> list[Qos]:
    """
    Return the QoS a bag's connection was recorded with, to copy it into another bag.

    rosbag2's offered profiles as they are; a ROS 1 latching connection :data:`LATCHED_QOS`;
    else none.
    """
    qos: list[Qos] | None = getattr(connection.ext, 'offered_qos_profiles', None)
    if qos is None:
        qos = LATCHED_QOS if getattr(connection.ext, 'latching', 0) else []
    return qos


class BagWriter:
    """
    A new rosbag2 bag (version :data:`VERSION`, mcap) at ``path``, a directory not yet there.

    Use as a context manager, or :meth:`open` and :meth:`close`. Connections carry the message
    definitions of :func:`jazzy` unless given another typestore.
    """

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self._writer: Any = None

    def open(self) -> BagWriter:  # noqa: A003 - the name of rosbags and files
        """Create the bag; raise :class:`BagError` when it exists or cannot be created."""
        if self.path.exists() or self.path.is_symlink():
            raise BagError(f'{self.path} exists already: not writing a bag there')
        try:
            writer = Writer(self.path, version=VERSION, storage_plugin=StoragePlugin.MCAP)
            writer.open()
            self._writer = writer
        except (WriterError, OSError) as error:
            raise BagError(f'cannot write a bag at {self.path}: {error}') from error
        return self

    def __enter__(self) -> BagWriter:
        """Open the bag."""
        return self.open()

    def __exit__(self, *exc: object) -> None:
        """Close the bag (its metadata is written)."""
        self.close()

    def close(self) -> None:
        """Finish the bag: write its summary and ``metadata.yaml`` (idempotent)."""
        writer, self._writer = self._writer, None
        if writer is not None:
            writer.close()

    def add_connection(self, topic: str, msgtype: str | None = None, *,
                       typestore: Typestore | None = None,
                       offered_qos_profiles: Sequence[Qos] | None = None) -> Connection:
        """
        Add a connection (a topic of one type) and return it, for :meth:`write`.

        ``msgtype`` and ``offered_qos_profiles`` default to the interface table's row of
        ``topic`` (:func:`offered_qos`); ``()`` offers no QoS. Raises :class:`BagError` for a
        topic the table lacks when they are not given, or a topic added twice.
        """
        if msgtype is None or offered_qos_profiles is None:
            try:
                row = interface.topic(topic)
            except KeyError as error:
                raise BagError(f'{topic}: give its type and QoS, it is not in the '
                               "navigator's interface") from error
            msgtype = row.msg_type if msgtype is None else msgtype
            if msgtype is None:
                raise BagError(f'{topic}: its type depends on the velocity source: give it')
            if offered_qos_profiles is None:
                offered_qos_profiles = offered_qos(topic)
        if self._writer is None:
            raise BagError(f'{self.path}: the bag is not open')
        try:
            return self._writer.add_connection(
                topic, msgtype, typestore=typestore if typestore is not None else jazzy(),
                offered_qos_profiles=offered_qos_profiles)
        except WriterError as error:
            raise BagError(f'{self.path}: {topic}: {error}') from error

    def write(self, connection: Connection, stamp_ns: int, data: bytes | memoryview) -> None:
        """Write one message: its CDR bytes at log time ``stamp_ns`` (ns)."""
        writer = self._writer
        if writer is None:
            raise BagError(f'{self.path}: the bag is not open')
        try:
            writer.write(connection, stamp_ns, data)
        except WriterError as error:
            raise BagError(f'{self.path}: {error}') from error


def write_bag(path: str | Path, messages: Iterable[tuple[str, int, bytes]],
              types: Mapping[str, str], *, qos: bool = True) -> Path:
    """
    Write a new bag at ``path`` of ``(topic, log ns, CDR bytes)``; return its path.

    A connection per entry of ``types`` (``{topic: type string}``, in that order, with or
    without messages), offering the interface table's QoS (:func:`offered_qos`, reliable for a
    topic not in the table) or, with ``qos=False``, none. A message on a topic not in ``types``
    is a :class:`BagError`. On any failure no bag is left at ``path``.
    """
    path = Path(path)
    writer = BagWriter(path).open()
    try:
        connections = {
            topic: writer.add_connection(
                topic, msgtype, offered_qos_profiles=(
                    () if not qos else
                    offered_qos(topic) if _in_interface(topic) else RELIABLE_QOS))
            for topic, msgtype in types.items()}
        for topic, stamp_ns, data in messages:
            connection = connections.get(topic)
            if connection is None:
                raise BagError(f'{path}: a message on {topic}, which has no connection '
                               f'(types: {", ".join(types) or "none"})')
            writer.write(connection, stamp_ns, data)
        writer.close()
    except BaseException:
        try:
            writer.close()
        finally:
            shutil.rmtree(path, ignore_errors=True)
        raise
    return path


def _in_interface(topic: str) -> bool:
    try:
        interface.topic(topic)
    except KeyError:
        return False
    return True


def reader(paths: str | Path | Sequence[str | Path], *,
           typestore: Typestore | None = None) -> AnyReader:
    """
    Return rosbags' AnyReader over one or several bags, not yet open.

    ``typestore`` deserialises what a bag holds no definitions for (default :func:`jazzy`).
    Raises :class:`BagError` for a missing path or what is not a bag.
    """
    given = [paths] if isinstance(paths, (str, Path)) else list(paths)
    bags = [Path(p) for p in given]
    for path in bags:
        if not path.exists():
            raise BagError(f'bag not found: {path}')
    try:
        return AnyReader(bags, default_typestore=typestore if typestore is not None else jazzy())
    except (AnyReaderError, OSError, ValueError) as error:
        where = bags[0] if len(bags) == 1 else ', '.join(map(str, bags))
        raise BagError(f'cannot read {where} as a bag: {error}') from error


@contextmanager
def _opened(path: Path) -> Iterator[AnyReader]:
    """Open one bag for reading, as a context manager; :class:`BagError` when unreadable."""
    bag = reader(path)
    try:
        bag.open()
    except Exception as error:  # noqa: B902 - any failure here means an unreadable bag
        raise BagError(f'cannot read {path} as a bag: {error}') from error
    try:
        yield bag
    finally:
        bag.close()


def cdr_typestore(bag: AnyReader) -> Typestore:
    """
    Return the typestore that writes an open bag's messages as CDR.

    A rosbag2 bag's own; for a ROS 1 bag its definitions with ROS 2's ``std_msgs/Header``
    (for :meth:`Typestore.ros1_to_cdr`).
    """
    if bag.is2:
        return bag.typestore
    store = get_typestore(Stores.EMPTY)
    store.register({**bag.typestore.fielddefs,
                    'std_msgs/msg/Header': jazzy().fielddefs['std_msgs/msg/Header']})
    return store


def read_topics(bags: Sequence[str | Path], topics: Iterable[str]) -> dict[str, list[Any]]:
    """
    Return ``{topic: [(log ns, message)]}`` of ``topics``, deserialised (rosbags' dataclasses).

    Each topic comes from the first of ``bags`` that holds it, in log-time order; a topic no
    bag holds is left out. Raises :class:`BagError` for a missing or unreadable bag.
    """
    wanted = set(topics)
    found: dict[str, list[Any]] = {}
    for given in bags:
        path = Path(given)
        with _opened(path) as bag:
            connections = [c for c in bag.connections
                           if c.topic in wanted and c.topic not in found]
            if not connections:
                continue
            for connection in connections:
                found[connection.topic] = []
            for connection, log_ns, raw in bag.messages(connections=connections):
                found[connection.topic].append(
                    (log_ns, bag.deserialize(raw, connection.msgtype)))
    return found


def raw_messages(path: str | Path) -> tuple[list[tuple[str, int, bytes]], dict[str, str]]:
    """
    Return a bag's messages as stored, ``[(topic, log ns, bytes)]`` in log-time order.

    And ``{topic: type string}`` of its connections. Raises :class:`BagError` for a missing or
    unreadable bag.
    """
    with _opened(Path(path)) as bag:
        types = {c.topic: c.msgtype for c in bag.connections}
        messages = [(c.topic, log_ns, bytes(raw)) for c, log_ns, raw in bag.messages()]
    return messages, types
