"""
The replay's input: a bag opened and checked against the navigator's inputs, in arrival order.

:class:`BagInput` opens rosbag2 (mcap, sqlite3) and ROS 1 bags with rosbags' AnyReader (through
:mod:`vessel_kinematics.tools.bags`) and checks that each input's topic is there with a type the
navigator takes. :meth:`BagInput.decode` turns one of its messages into an :class:`InputMessage`:
rosbags' deserialised dataclass (the fields of the rclpy message the node would receive), the
Imu straight from its CDR (:mod:`~vessel_kinematics.ros.imu_cdr`, as the node reads it), or, for
a payload that does not deserialise, its :class:`~vessel_kinematics.estimation.Rejection`
(``cdr_error``, counted by the pipeline). The replay hands them on in log-time
order, each arriving at its log time, as the node received them live (the estimator fuses a
late one at its stamp); with ``by_stamp``, :class:`StampOrder` merges them by header stamp
through a reorder buffer of :data:`REORDER_WINDOW_NS` of bag time (bounded memory on long
bags), for a bag whose log times say nothing of the arrival.

A marine log (an NMEA 0183 log, an NMEA 2000 capture: :func:`vessel_kinematics.marine.
is_marine_log`, by content) is read the same way through :class:`vessel_kinematics.marine.
MarineLog`, whose topics are the marine bags' (``fix:=/fix imu:=/imu velocity:=/speed_log`` by
default); its stamps are the log's own times, its arrival times too (or the logger's).
"""

from __future__ import annotations

import datetime
import heapq
from pathlib import Path
from typing import Any, Iterator, Mapping, NamedTuple, Sequence

from vessel_kinematics import marine
from vessel_kinematics.core import frames
from vessel_kinematics.estimation import Reason, Rejection
from vessel_kinematics.ros import interface
from vessel_kinematics.ros.imu_cdr import imu_from_cdr
from vessel_kinematics.ros.inputs import stamp_problem
from vessel_kinematics.ros.params import (GnssVelocitySource, NavigatorParams, VelocityReference,
                                          VelocitySource)
from vessel_kinematics.tools import bags
from vessel_kinematics.tools.bags import BagError
from vessel_kinematics.tools.replay.errors import ReplayError

__all__ = ['BagInput', 'DEFAULT_TOPICS', 'input_messages', 'INPUT_TYPES', 'InputMessage',
           'parse_remaps', 'REORDER_WINDOW_NS', 'StampOrder', 'TF_STATIC_TOPIC',
           'TYPE_RENAMES', 'VELOCITY_TYPES']

#: The bag topics the navigator's inputs are read from unless remapped (the interface's names).
DEFAULT_TOPICS: dict[str, str] = {t.name: t.absolute
                                  for t in interface.by_role(interface.Role.INPUT)}
#: The message type each input needs (``velocity``'s depends on ``velocity.source``).
INPUT_TYPES: dict[str, str] = interface.types(interface.Role.INPUT, velocity_source='none',
                                              absolute=False)
#: The ``velocity`` message type of each ``velocity.source``.
VELOCITY_TYPES: dict[str, str] = {source: msg_type for source, msg_type in
                                  interface.VELOCITY_TYPES.items() if msg_type is not None}
#: The static transforms topic: read from the input bag for the sensors' mountings.
TF_STATIC_TOPIC = '/tf_static'
#: The file names of a bag given as one file (rosbags reads them): mcap, sqlite3, ROS 1.
BAG_FILE_SUFFIXES = ('.mcap', '.db3', '.bag')
#: Bag time over which input messages are reordered by header stamp (ns).
REORDER_WINDOW_NS = 10_000_000_000
#: Legacy ROS 1 names that rosbag2 knows under another type.
TYPE_RENAMES = {'tf/msg/tfMessage': 'tf2_msgs/msg/TFMessage'}
_IMU_TYPE = 'sensor_msgs/msg/Imu'
_REFERENCE_TOPICS = frozenset(t.absolute for t in interface.by_role(interface.Role.REFERENCE))


class InputMessage(NamedTuple):
    """
    One input message: its input ``name``, header ``stamp_ns``, ``arrival_ns`` and ``msg``.

    ``arrival_ns`` is the bag's log time; ``stamp_ns`` is -1 for a message without a usable
    stamp (passed on at once, for the pipeline to refuse). ``msg`` is what the pipeline takes
    (a message, or the Rejection of a payload that does not deserialise); ``raw`` its CDR.
    """

    name: str
    stamp_ns: int
    arrival_ns: int
    msg: Any
    raw: bytes
    #: The index of its topic in ``fix.topics`` / ``imu.topics`` (0 for the other inputs).
    source: int = 0


def parse_remaps(remaps: Sequence[str] | Mapping[str, str] | None,
                 defaults: Mapping[str, str] | None = None) -> dict[str, str]:
    """
    Return the bag topic of each input from ``NAME:=TOPIC`` remaps over :data:`DEFAULT_TOPICS`.

    ``NAME`` is an input of the navigator (``fix``, ``imu``, ``velocity``; a leading ``/`` or
    ``~/`` is allowed); ``TOPIC`` gets a leading ``/`` when it has none, as rosbag2 names topics.
    ``defaults``: topics over :data:`DEFAULT_TOPICS` (a marine log's, ``velocity:=/speed_log``).
    """
    topics = {**DEFAULT_TOPICS, **(defaults or {})}
    if remaps is None:
        return topics
    pairs: list[tuple[str, str]] = []
    if isinstance(remaps, Mapping):
        pairs = list(remaps.items())
    else:
        for remap in remaps:
            name, sep, topic = remap.partition(':=')
            if not sep:
                raise ReplayError(f'remap {remap!r} is not NAME:=TOPIC (e.g. fix:=/gps/fix)')
            pairs.append((name, topic))
    for name, topic in pairs:
        key = name.strip().removeprefix('~').lstrip('/')
        if key not in DEFAULT_TOPICS:
            raise ReplayError(f'remap {name}:={topic}: {name!r} is not an input of the '
                              f'navigator (one of {", ".join(DEFAULT_TOPICS)})')
        topic = topic.strip()
        if not topic or topic == '/':
            raise ReplayError(f'remap {name}:=: empty topic name')
        topics[key] = topic if topic.startswith('/') else '/' + topic
    return topics


def _first_line(error: BaseException) -> str:
    """Return an error's first line (its type's name when it has no text)."""
    text = str(error).strip()
    return text.splitlines()[0] if text else type(error).__name__


def _absolute(topic: str) -> str:
    """Return a relative topic name in the root namespace (``gps2/fix``: ``/gps2/fix``)."""
    return '/' + topic.removeprefix('~/').lstrip('/')


class BagInput:
    """
    An input bag opened for the replay, checked against the navigator's inputs.

    Use as a context manager. Raises :class:`ReplayError` with a one-line reason for a missing
    path, an unreadable bag, an input topic the bag does not hold, or a topic whose message type
    the navigator cannot use on that input. ``date``: the date of a marine log of times of day
    without one (:func:`~vessel_kinematics.marine.open_log`).
    """

    def __init__(self, path: str | Path, params: NavigatorParams,
                 remaps: Sequence[str] | Mapping[str, str] | None = None, *,
                 date: datetime.date | None = None) -> None:
        self.path = Path(path)
        self.params = params
        #: A marine log (NMEA 0183, NMEA 2000) read as a bag, its own default topics.
        self.marine = self.path.is_file() and marine.is_marine_log(self.path)
        self.topics = parse_remaps(remaps, marine.INPUT_TOPICS if self.marine else None)
        #: /tf_static messages whose payload could not be deserialised.
        self.tf_static_errors = 0
        #: What the input changed of the parameters (a marine log's, :meth:`_marine_params`).
        self.notes: list[str] = []
        if params.velocity_source is VelocitySource.NONE:
            self.topics.pop('velocity')
        if params.gnss_velocity_source is GnssVelocitySource.NONE:
            self.topics.pop('gnss_velocity')
        #: The topics of several fixes or headings (``fix.topics``, ``imu.topics``), as the
        #: node in the root namespace reads them: {bag topic: (input, index)}. One topic
        #: (the default) is the remappable input's.
        self.extra: dict[str, tuple[str, int]] = {}
        for name, names in (('fix', params.fix_topics), ('imu', params.imu_topics)):
            if len(names) > 1:
                self.topics[name] = _absolute(names[0])
                self.extra.update((_absolute(n), (name, i)) for i, n in enumerate(names) if i)
        if not self.path.exists():
            raise ReplayError(f'input bag not found: {self.path}')
        self.reader: Any
        if self.marine:
            self.reader = marine.MarineLog(self.path, date=date)
        elif self.path.is_file() and self.path.suffix.lower() not in BAG_FILE_SUFFIXES:
            try:
                marine.detect_format(self.path)
            except marine.MarineLogError as error:   # neither: say what the content is not
                raise ReplayError(f'{error}; nor is it a bag (a rosbag2 directory, '
                                  f"{', '.join(BAG_FILE_SUFFIXES)})") from error
        if not self.marine:
            try:
                self.reader = bags.reader(self.path)
            except BagError as error:
                raise ReplayError(str(error)) from error
        self._open = False

    def __enter__(self) -> BagInput:
        """Open the bag and check the input topics and their types."""
        try:
            self.reader.open()
        except marine.MarineLogError as error:      # no position, no time: one line
            raise ReplayError(str(error)) from error
        except Exception as error:  # noqa: B902 - any failure here means an unreadable bag
            raise ReplayError(f'cannot read {self.path} as a bag: {_first_line(error)}') \
                from error
        self._open = True
        try:
            if self.marine:
                self._marine_params()
            self._check()
        except BaseException:
            self.close()
            raise
        return self

    def __exit__(self, *exc: object) -> None:
        """Close the bag."""
        self.close()

    def close(self) -> None:
        """Close the bag (idempotent)."""
        if self._open:
            self._open = False
            self.reader.close()

    def _marine_params(self) -> None:
        """
        Set the parameters a marine log needs, with a note for each change (:attr:`notes`).

        Its speed log (``/speed_log``: VHW, VBW, PGN 128259) measures through the water: when
        the velocity input reads it, ``velocity.reference`` is ``water`` whatever was given. A
        log without a heading cannot say where that speed goes (the current would take the
        vessel's whole course): the speed log is not used. With no speed log, or none used,
        ``velocity.source`` is ``none`` and the fixes give the speed (a log held missing for
        the whole run would be an error in /diagnostics throughout). With no speed log used,
        the receiver's own COG/SOG (RMC, VTG, PGN 129026: ``/vel``) is ``gnss_velocity``
        unless that input is set already: its Doppler velocity is better than the fixes'
        differences (docs/validation.md: on 32 yacht logs, course within 4° of the COG in
        30 instead of 22). With a speed log it is not: a receiver's velocity taken as white
        noise then moves the log's scale and the current apart on a straight leg.
        """
        p = self.params
        flat = p.to_flat()
        name = self.path.name
        roles = self.reader.roles
        reads_log = (p.velocity_source is not VelocitySource.NONE
                     and self.topics.get('velocity') == marine.messages.SPEED_TOPIC)
        if reads_log and (roles.get('speed') is None or roles.get('heading') is None):
            reads_log = False
            flat['velocity.source'] = VelocitySource.NONE.value
            self.topics.pop('velocity')
            self.notes.append(
                f'{name} has no speed log (velocity.source none): the fixes give the speed'
                if roles.get('speed') is None else
                f'{name} has no heading: its speed log is not used (velocity.source none), '
                'the fixes alone give course and speed')
        elif reads_log and p.velocity_reference is not VelocityReference.WATER:
            flat['velocity.reference'] = marine.VELOCITY_REFERENCE
            self.notes.append(f'{name} is a marine log: its speed log is through the water, '
                              'velocity.reference water')
        if (not reads_log and roles.get('cog') is not None
                and p.gnss_velocity_source is GnssVelocitySource.NONE):
            flat['gnss_velocity.source'] = GnssVelocitySource.TWIST.value
            topic = self.topics['gnss_velocity'] = marine.messages.GNSS_VELOCITY_TOPIC
            self.notes.append(f"{name}: no speed log used, the receiver's own COG/SOG is the "
                              f'receiver velocity (gnss_velocity.source twist, {topic})')
        self.params = NavigatorParams.from_flat(flat)

    def _check(self) -> None:
        bag_topics = {c.topic: c.msgtype for c in self.reader.connections}
        available = ', '.join(f'{t} ({m})' for t, m in sorted(bag_topics.items())) or 'none'
        p = self.params
        expected = interface.types(interface.Role.INPUT, absolute=False,
                                   velocity_source=p.velocity_source, imu_source=p.imu_source,
                                   gnss_velocity_source=p.gnss_velocity_source)
        for name, topic in [*self.topics.items(),
                            *((name, topic) for topic, (name, _) in self.extra.items())]:
            if topic not in bag_topics:
                raise ReplayError(f'input {name!r} reads topic {topic}, which is not in '
                                  f'{self.path} (topics: {available}); '
                                  f'use --remap {name}:=TOPIC')
            msgtype = TYPE_RENAMES.get(bag_topics[topic], bag_topics[topic])
            if msgtype != expected[name]:
                hint = ''
                if name == 'velocity':
                    sources = [s for s, t in VELOCITY_TYPES.items() if t == msgtype]
                    hint = (f'; set velocity.source: {sources[0]}' if sources else
                            '; the velocity input takes TwistWithCovarianceStamped, '
                            'TwistStamped or Odometry')
                raise ReplayError(f'topic {topic} ({name}) is {msgtype}, but the navigator '
                                  f'needs {expected[name]} there{hint}')
        #: {bag topic: input name}
        self.by_topic = {topic: name for name, topic in self.topics.items()}
        #: {bag topic: its index in fix.topics / imu.topics}, for the second topic on
        self.source_of = {topic: index for topic, (_, index) in self.extra.items()}
        self.by_topic.update((topic, name) for topic, (name, _) in self.extra.items())
        self.tf_static_connections = [
            c for c in self.reader.connections if c.topic == TF_STATIC_TOPIC
            and TYPE_RENAMES.get(c.msgtype, c.msgtype) == 'tf2_msgs/msg/TFMessage']
        # ROS 1 data is converted to CDR with the bag's own definitions and ROS 2's Header.
        self.is_ros1 = not self.reader.is2
        self.cdr_store = bags.cdr_typestore(self.reader)

    @property
    def message_count(self) -> int:
        """Return the number of messages in the bag (all topics)."""
        return self.reader.message_count

    @property
    def has_reference(self) -> bool:
        """Return True when the input holds a receiver's COG/SOG (``/gnss/cog_sog``)."""
        return any(c.topic in _REFERENCE_TOPICS for c in self.reader.connections)

    @property
    def has_truth(self) -> bool:
        """Return True when the bag holds the simulator's truth (``/truth/odometry``)."""
        return any(c.topic == '/truth/odometry' for c in self.reader.connections)

    def messages(self, connections: Sequence[Any] | None = None) -> Iterator[Any]:
        """
        Yield the reader's (connection, log time, raw) in log-time order.

        A bag found corrupt on the way (a bit flip, a bad chunk) raises :class:`ReplayError`,
        ``cannot read <file> as a bag: <cause>``, as one found so at :meth:`__enter__`.
        """
        found = (self.reader.messages() if connections is None
                 else self.reader.messages(connections=connections))
        while True:
            try:
                item = next(found)
            except StopIteration:
                return
            except marine.MarineLogError as error:
                raise ReplayError(str(error)) from error
            except Exception as error:  # noqa: B902 - any failure here means an unreadable bag
                what = '' if self.marine else ' as a bag'
                raise ReplayError(f'cannot read {self.path}{what}: '
                                  f'{_first_line(error)}') from error
            yield item

    def to_cdr(self, raw: bytes | memoryview, msgtype: str) -> bytes:
        """Return a message's CDR bytes (converting ROS 1 serialisation)."""
        if self.is_ros1:
            return bytes(self.cdr_store.ros1_to_cdr(raw, msgtype))
        return bytes(raw)

    def tf_static(self) -> Iterator[Any]:
        """
        Yield every /tf_static message of the bag (rosbags' TFMessage), in log-time order.

        Static transforms are latched (transient-local): a listener holds them from when they
        arrive, whatever their stamps. The replay takes them all before the first input, as
        a node started after the URDF's publishers has them on subscription. A payload that
        cannot be deserialised is counted in ``tf_static_errors`` and skipped.
        """
        if not self.tf_static_connections:
            return
        for connection, _, raw in self.messages(self.tf_static_connections):
            try:
                yield self.reader.deserialize(raw, connection.msgtype)
            except Exception:  # noqa: B902 - any decoding failure is a garbage payload
                self.tf_static_errors += 1

    def decode(self, name: str, connection: Any, log_ns: int,
               raw: bytes | memoryview) -> InputMessage:
        """Return the input message of one of the bag's messages on input ``name``'s topic."""
        item = self._decode(name, connection, log_ns, raw)
        source = self.source_of.get(connection.topic)
        return item if source is None else item._replace(source=source)

    def _decode(self, name: str, connection: Any, log_ns: int,
                raw: bytes | memoryview) -> InputMessage:
        msgtype = connection.msgtype
        try:
            msg: Any = None
            if msgtype == _IMU_TYPE and not self.is_ros1:
                msg = imu_from_cdr(raw)
            if msg is None:
                msg = self.reader.deserialize(raw, msgtype)
            stamp = msg.header.stamp
            sec, nanosec = stamp.sec, stamp.nanosec
            data = self.to_cdr(raw, msgtype)
        except Exception as error:  # noqa: B902 - any decoding failure is a garbage payload
            first = str(error).splitlines()[0] if str(error) else type(error).__name__
            refused = Rejection(Reason.CDR_ERROR, f'{msgtype} payload of {len(raw)} bytes '
                                                  f'does not deserialise: {first[:80]}')
            return InputMessage(name, -1, log_ns, refused, bytes(raw))
        if stamp_problem(sec, nanosec) is not None:
            return InputMessage(name, -1, log_ns, msg, data)
        return InputMessage(name, frames.stamp_to_ns(sec, nanosec), log_ns, msg, data)


class StampOrder:
    """
    A reorder buffer: input messages in, the same messages out by header stamp.

    A message leaves once one ``window_ns`` newer has come in (:meth:`push`), the rest at
    :meth:`flush`. Equal stamps keep their bag order; a message without a usable stamp (-1)
    passes straight through, so that it cannot flush or stall the buffer.
    """

    def __init__(self, window_ns: int = REORDER_WINDOW_NS) -> None:
        self.window_ns = window_ns
        self._heap: list[tuple[int, int, InputMessage]] = []
        self._newest = -(2 ** 63)
        self._sequence = 0
        #: Messages that came in with a stamp older than one already handed on.
        self.out_of_order = 0
        self._last_out: int | None = None

    def push(self, item: InputMessage) -> list[InputMessage]:
        """Take one message; return those now due, in stamp order."""
        if item.stamp_ns < 0:
            return [item]
        heapq.heappush(self._heap, (item.stamp_ns, self._sequence, item))
        self._sequence += 1
        self._newest = max(self._newest, item.stamp_ns)
        out = []
        while self._heap and self._newest - self._heap[0][0] > self.window_ns:
            out.append(self._pop())
        return out

    def flush(self) -> list[InputMessage]:
        """Return every message still held, in stamp order."""
        return [self._pop() for _ in range(len(self._heap))]

    def _pop(self) -> InputMessage:
        stamp, _, item = heapq.heappop(self._heap)
        if self._last_out is not None and stamp < self._last_out:
            self.out_of_order += 1
        self._last_out = stamp if self._last_out is None else max(self._last_out, stamp)
        return item


def input_messages(path: str | Path, params: NavigatorParams,
                   remaps: Sequence[str] | Mapping[str, str] | None = None, *,
                   date: datetime.date | None = None) -> Iterator[InputMessage]:
    """Yield a bag's input messages in the order the replay hands them to the pipeline."""
    with BagInput(path, params, remaps, date=date) as bag:
        for connection, log_ns, raw in bag.messages():
            name = bag.by_topic.get(connection.topic)
            if name is not None:
                yield bag.decode(name, connection, log_ns, raw)
