"""
Offline replay: a recorded bag through the navigator's pipeline, into a new rosbag2 bag.

``replay INPUT OUTPUT [--params-file FILE] [--remap NAME:=TOPIC ...] [--plot FILE.png]``

The replay is the navigator's second driver (``navigator`` is the first): it reads rosbag2
(mcap, sqlite3) and ROS 1 bags with ``rosbags``' AnyReader, deserialises each input message
with rosbags (CDR, or ROS 1 directly; dataclasses with the fields of the rclpy message the node
would have received, which ``ros_io`` reads alike, about three times faster than
``rclpy.serialization.deserialize_message``; sensor_msgs/Imu, the high-rate input, straight
from its CDR with :func:`~vessel_kinematics.ros.ros_io.imu_from_cdr`), feeds
:meth:`Pipeline.handle` in header-stamp order, and writes every output as the CDR the node's
message serialises to (``ros_io``'s CDR builders, no rclpy message in between) into an mcap
bag (:mod:`vessel_kinematics.tools.bags`, QoS per the interface table): the navigator's topics
(every output of the interface table, :mod:`vessel_kinematics.ros.interface`: ``/odometry``,
``/course_sideslip``, ``/origin`` ...; ``/diagnostics`` at 1 Hz of bag time) and ``/tf``,
``/tf_static`` in the REP-105 tree earth -> map -> odom -> base_link. Every topic of the input
bag is copied across, as its raw bytes (ROS 1 data converted to CDR), unless
``--no-copy-inputs``; of the navigator's own topics, only the input's ``/tf_static``. Where a
process can be forked, a second process builds the outputs and writes the bag while the first
runs the estimator (:func:`_write_in_background`, :mod:`vessel_kinematics.tools.replay_output`;
the same bytes).

Time is the messages' header stamps throughout: a bag's log-time order can differ from the
order in which its sensors sampled, so the messages are merged by header stamp through a
reorder buffer of :data:`REORDER_WINDOW_NS` of bag time (bounded memory on long bags).

Python API: :func:`run` (bag to bag, returns a :class:`Summary`), :func:`replay_in_memory`
(outputs as lists of messages, e.g. for a dead-reckoning-only comparison), and
:func:`input_messages` (the pipeline's input sequence, used by the live-equivalence test).
"""

from __future__ import annotations

import argparse
from collections import Counter
import dataclasses
from dataclasses import dataclass, field
import datetime
import heapq
import importlib
import math
import os
from pathlib import Path
import shutil
import sys
import time
from typing import Any, Callable, Iterable, Iterator, Mapping, Sequence

from rclpy.serialization import deserialize_message, serialize_message
from vessel_kinematics.core import frames
from vessel_kinematics.estimation import Reason
from vessel_kinematics.ros import interface, ros_io
from vessel_kinematics.ros.params import (load_params_file, NavigatorParams, ParameterError,
                                          PARAMETERS)
from vessel_kinematics.ros.pipeline import INPUTS, OUTPUTS, Pipeline
from vessel_kinematics.ros.ros_io import diagnostics_cdr, stamp_problem
from vessel_kinematics.ros.session import Emission, fewer_collections, Session
from vessel_kinematics.tools import bags, evaluate
from vessel_kinematics.tools.bags import BagError
from vessel_kinematics.tools.replay_output import (background_available, BackgroundWriter, Opened,
                                                   OutputBag, WriterFailed)
import yaml

__all__ = ['accuracy_report', 'BAG_FILE_SUFFIXES', 'BAG_FILE_TYPES', 'BagInput', 'BagRow',
           'build_parser', 'check_params_file', 'check_paths', 'check_yaml_text',
           'dead_reckoning_run', 'DEFAULT_TOPICS', 'DIAGNOSTICS_PERIOD_NS', 'error_line',
           'find_bags', 'input_messages', 'INPUT_TYPES', 'is_bag', 'is_bag_directory', 'is_many',
           'LATCHED', 'load_params', 'main', 'MAX_PARAMS_DEPTH', 'MAX_PARAMS_FILE_BYTES',
           'message_class', 'output_name', 'OUTPUT_TYPES', 'parse_param', 'parse_remaps',
           'REASON_CDR_ERROR', 'REORDER_WINDOW_NS', 'replay_in_memory', 'ReplayError',
           'rows_table', 'run', 'run_many', 'staging_path', 'stamp_ns', 'Summary',
           'tf_message_cdr', 'TF_STATIC_TOPIC', 'VELOCITY_TYPES']

try:  # the ROS way to find a message class by name, where rosidl_runtime_py is installed
    from rosidl_runtime_py.utilities import get_message as _ros_get_message
except ImportError:  # pragma: no cover - depends on the installation
    _ros_get_message = None

#: The bag topics the navigator's inputs are read from unless remapped (the interface's names).
DEFAULT_TOPICS: dict[str, str] = {t.name: t.absolute
                                  for t in interface.by_role(interface.Role.INPUT)}

#: The message type each input needs (``velocity`` depends on ``velocity.source``).
INPUT_TYPES: dict[str, str] = interface.types(interface.Role.INPUT, velocity_source='none',
                                              absolute=False)

#: The ``velocity`` message type of each ``velocity.source``.
VELOCITY_TYPES: dict[str, str] = {source: msg_type for source, msg_type in
                                  interface.VELOCITY_TYPES.items() if msg_type is not None}

#: The output bag's topics written by the replay and their types (as the navigator publishes).
OUTPUT_TYPES: dict[str, str] = interface.types(interface.Role.OUTPUT, interface.Role.AUXILIARY)

#: The static transforms topic: read from the input bag for the sensors' mountings.
TF_STATIC_TOPIC = '/tf_static'

#: Latched (transient-local) output topics.
LATCHED = tuple(t.absolute for t in interface.TOPICS if t.latched and t.role in (
    interface.Role.OUTPUT, interface.Role.AUXILIARY))

#: Bag time over which input messages are reordered by header stamp (ns).
REORDER_WINDOW_NS = 10_000_000_000

#: Diagnostics period in bag time (ns): 1 Hz, as the node's timer.
DIAGNOSTICS_PERIOD_NS = 1_000_000_000

#: Largest parameters file read (bytes): a navigator's file is a few kB; the bound keeps a
#: hostile or mistaken file (a log, a bag) from being parsed at all.
MAX_PARAMS_FILE_BYTES = 1 << 20

#: Deepest nesting of mappings and sequences accepted in a parameters file (the navigator's
#: own is 4 deep: node, ros__parameters, gnss, value); deeper YAML would only exhaust the
#: recursive composer.
MAX_PARAMS_DEPTH = 32

#: The counting key of :attr:`Reason.CDR_ERROR <vessel_kinematics.estimation.Reason.CDR_ERROR>`
#: (an input message whose payload cannot be deserialised, garbage CDR), as a plain str.
REASON_CDR_ERROR = Reason.CDR_ERROR.value

#: The files a rosbag2 bag directory may hold, besides ``metadata.yaml``: what ``--overwrite``
#: accepts to remove (mcap, sqlite3 and its journal files, zstd-compressed files).
BAG_FILE_SUFFIXES = ('.mcap', '.db3', '.db3-shm', '.db3-wal', '.db3-journal', '.zstd')

# libyaml's parser where PyYAML was built with it (10x faster on a 1 MiB file).
_YAML_LOADER = getattr(yaml, 'CSafeLoader', yaml.SafeLoader)
# Legacy ROS 1 names that rosbag2 knows under another type.
_TYPE_RENAMES = {'tf/msg/tfMessage': 'tf2_msgs/msg/TFMessage'}
_IMU_TYPE = 'sensor_msgs/msg/Imu'


class ReplayError(Exception):
    """A problem with the replay's input or options, reported as one line and a non-zero exit."""


@dataclass
class Summary:
    """
    What a replay did: the numbers of its closing report.

    Times are bag (header-stamp) times in ns; ``distance_m`` is the horizontal path length of
    ``odometry/local`` (the continuous dead-reckoned track, free of GNSS jumps), m;
    ``final_position`` the last ``fix/filtered`` as (latitude deg, longitude deg, height m).
    """

    input_path: Path
    output_path: Path | None
    start_ns: int = 0
    end_ns: int = 0
    messages_in: Counter = field(default_factory=Counter)
    messages_out: Counter = field(default_factory=Counter)
    messages_copied: int = 0
    rejected: Counter = field(default_factory=Counter)
    out_of_order: int = 0
    distance_m: float = 0.0
    final_position: tuple[float, float, float] | None = None
    wall_time_s: float = 0.0
    topics: dict[str, str] = field(default_factory=dict)
    plot: Path | None = None
    accuracy: str | None = None
    notes: list[str] = field(default_factory=list)
    estimates: dict[str, str] = field(default_factory=dict)

    @property
    def duration_s(self) -> float:
        """Return the bag time spanned by the input messages (s)."""
        return max(0.0, (self.end_ns - self.start_ns) * 1e-9)

    def text(self) -> str:
        """Return the summary as the few lines the command prints."""
        def utc(ns: int) -> str:
            moment = datetime.datetime.fromtimestamp(ns * 1e-9, tz=datetime.timezone.utc)
            return moment.strftime('%Y-%m-%d %H:%M:%S UTC')

        n_in = sum(self.messages_in.values())
        n_out = sum(self.messages_out.values())
        lines = [f'replay {self.input_path} -> {self.output_path or "(memory)"}']
        lines.append(f'  bag time   {self.duration_s:.1f} s from {utc(self.start_ns)}'
                     f' ({self.wall_time_s:.1f} s wall, '
                     f'{n_in / max(self.wall_time_s, 1e-9):.0f} msg/s)')
        per_input = ', '.join(f'{name} {self.messages_in[name]} ({self.topics.get(name, "-")})'
                              for name in INPUTS if name in self.topics)
        lines.append(f'  in         {n_in}: {per_input}')
        outs = ', '.join(f'{t} {n}' for t, n in sorted(self.messages_out.items()))
        lines.append(f'  out        {n_out}: {outs}'
                     + (f'; {self.messages_copied} input messages copied'
                        if self.messages_copied else ''))
        rejected = ', '.join(f'{k} {n}' for k, n in sorted(self.rejected.items())) or 'none'
        lines.append(f'  rejected   {sum(self.rejected.values())}: {rejected}')
        lines.append(f'  distance   {self.distance_m:.1f} m (dead-reckoned path)')
        if self.final_position is not None:
            lat, lon, height = self.final_position
            lines.append(f'  final      {abs(lat):.7f} {"N" if lat >= 0 else "S"}, '
                         f'{abs(lon):.7f} {"E" if lon >= 0 else "W"}, {height:.1f} m')
        else:
            lines.append('  final      no position (no valid fix for the origin)')
        if self.estimates:
            lines.append('  estimated  '
                         + ', '.join(f'{k} {v}' for k, v in self.estimates.items()))
        lines.extend(f'  note       {note}' for note in self.notes)
        if self.accuracy is not None:
            lines.append(self.accuracy)
        if self.plot is not None:
            lines.append(f'  plot       {self.plot}')
        return '\n'.join(lines)


# ---------------------------------------------------------------------------------------------
# Options


def parse_remaps(remaps: Sequence[str] | Mapping[str, str] | None) -> dict[str, str]:
    """
    Return the bag topic of each input from ``NAME:=TOPIC`` remaps over :data:`DEFAULT_TOPICS`.

    ``NAME`` is an input of the navigator (``fix``, ``imu``, ``velocity``; a leading ``/`` or
    ``~/`` is allowed); ``TOPIC`` gets a leading ``/`` when it has none, as rosbag2 names topics.
    """
    topics = dict(DEFAULT_TOPICS)
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
        if key not in INPUTS:
            raise ReplayError(f'remap {name}:={topic}: {name!r} is not an input of the '
                              f'navigator (one of {", ".join(INPUTS)})')
        topic = topic.strip()
        if not topic or topic == '/':
            raise ReplayError(f'remap {name}:=: empty topic name')
        topics[key] = topic if topic.startswith('/') else '/' + topic
    return topics


def parse_param(text: str) -> tuple[str, Any]:
    """Parse ``NAME:=VALUE`` (value in YAML, as ``ros2 run ... -p``) into a name and a value."""
    name, sep, value = text.partition(':=')
    if not sep or not name:
        raise ReplayError(f'parameter {text!r} is not NAME:=VALUE (e.g. gnss.enabled:=false)')
    check_yaml_text(value, f'parameter {name}')
    try:
        parsed = yaml.safe_load(value)
    except yaml.YAMLError as error:
        raise ReplayError(f'parameter {name}: cannot parse {value!r}: {error}') from error
    if isinstance(parsed, str) and parsed.lower() in ('nan', '.nan'):
        parsed = math.nan
    return name, parsed


def _one_line(text: object) -> str:
    """Return ``text`` on one line (YAML and OS errors span several)."""
    return ' '.join(str(text).split())


def check_yaml_text(text: str, where: str) -> None:
    """
    Refuse YAML that would cost more to load than it says: anchors, aliases, deep nesting.

    Scans the parser's events only (nothing is composed or expanded), so a 514-byte alias
    bomb that ``yaml.safe_load`` would expand to 336 MB is refused in microseconds. Raises
    :class:`ReplayError` naming ``where``.
    """
    depth = 0
    try:
        for event in yaml.parse(text, Loader=_YAML_LOADER):
            if isinstance(event, yaml.AliasEvent) or getattr(event, 'anchor', None):
                raise ReplayError(f'{where}: YAML anchors and aliases are not accepted '
                                  f'(line {event.start_mark.line + 1})')
            if isinstance(event, yaml.CollectionStartEvent):
                depth += 1
                if depth > MAX_PARAMS_DEPTH:
                    raise ReplayError(f'{where}: YAML nested deeper than {MAX_PARAMS_DEPTH}')
            elif isinstance(event, yaml.CollectionEndEvent):
                depth -= 1
    except yaml.YAMLError as error:
        raise ReplayError(f'{where} is not valid YAML: {_one_line(error)}') from error


def check_params_file(path: str | Path) -> None:
    """
    Check a parameters file before any parser reads it; raise :class:`ReplayError` if unsafe.

    The file must be readable, at most :data:`MAX_PARAMS_FILE_BYTES`, UTF-8, and YAML without
    anchors, aliases or nesting deeper than :data:`MAX_PARAMS_DEPTH` (:func:`check_yaml_text`).
    """
    path = Path(path)
    try:
        with path.open('rb') as stream:
            data = stream.read(MAX_PARAMS_FILE_BYTES + 1)
    except OSError as error:
        raise ReplayError(f'cannot read params file {path}: {error.strerror}') from error
    if len(data) > MAX_PARAMS_FILE_BYTES:
        raise ReplayError(f'params file {path} is larger than {MAX_PARAMS_FILE_BYTES} bytes')
    try:
        text = data.decode('utf-8')
    except UnicodeDecodeError as error:
        raise ReplayError(f'params file {path} is not UTF-8 text (byte {error.start})') from error
    check_yaml_text(text, f'params file {path}')


def load_params(params_file: str | Path | None = None,
                overrides: Mapping[str, Any] | None = None,
                node_fqn: str = '/navigator') -> NavigatorParams:
    """
    Return validated parameters from a ROS 2 parameters file and ``name: value`` overrides.

    The file is read as the node reads it (:func:`~vessel_kinematics.ros.params.load_params_file`:
    rclpy's parser, rcl's wildcard keys for ``node_fqn``); names that are not the navigator's
    are ignored with a warning, as the node does (``qos_overrides.*`` and ``use_sim_time``
    silently: they concern DDS and the clock, not the replay).
    """
    values: dict[str, Any] = {}
    if params_file is not None:
        check_params_file(params_file)
        known = {p.name for p in PARAMETERS}
        from_file = load_params_file(params_file, node_fqn)
        if not from_file:
            print(f'replay: warning: {params_file} sets no parameter of {node_fqn} '
                  '(keys: /**, /**/navigator, /ns/navigator or navigator)', file=sys.stderr)
        for name, value in from_file.items():
            if name in known:
                values[name] = value
            else:
                print(f'replay: warning: parameter {name!r} is not a navigator parameter: '
                      'ignored (a typo?)', file=sys.stderr)
    if overrides:
        values.update(overrides)
    return NavigatorParams.from_flat(values)


def _type_name(cls: type) -> str:
    """Return ``pkg/msg/Name`` for an rclpy message class."""
    return f'{cls.__module__.split(".")[0]}/msg/{cls.__name__}'


_CLASSES: dict[str, type] = {}


def message_class(msgtype: str) -> type:
    """Return the rclpy message class of a ``pkg/msg/Name`` type."""
    cls = _CLASSES.get(msgtype)
    if cls is None:
        if _ros_get_message is not None:
            cls = _ros_get_message(msgtype)
        else:
            package, kind, name = msgtype.split('/')
            cls = getattr(importlib.import_module(f'{package}.{kind}'), name)
        _CLASSES[msgtype] = cls
    return cls


def stamp_ns(msg: Any) -> int:
    """Return a stamped message's header stamp in ns."""
    stamp = msg.header.stamp
    return frames.stamp_to_ns(stamp.sec, stamp.nanosec)


# ---------------------------------------------------------------------------------------------
# Reading


class BagInput:
    """
    An input bag opened for the replay, checked against the navigator's inputs.

    Use as a context manager. Raises :class:`ReplayError` with a one-line reason for a missing
    path, an unreadable bag, an input topic the bag does not hold, or a topic whose message type
    the navigator cannot use on that input.
    """

    def __init__(self, path: str | Path, params: NavigatorParams,
                 remaps: Sequence[str] | Mapping[str, str] | None = None) -> None:
        self.path = Path(path)
        self.params = params
        self.topics = parse_remaps(remaps)
        #: Input messages whose payload could not be deserialised, by input name.
        self.cdr_errors: Counter = Counter()
        #: /tf_static messages whose payload could not be deserialised.
        self.tf_static_errors = 0
        if params.velocity_source == 'none':
            self.topics.pop('velocity')
        if not self.path.exists():
            raise ReplayError(f'input bag not found: {self.path}')
        self.jazzy = bags.jazzy()
        try:
            self.reader = bags.reader(self.path, typestore=self.jazzy)
        except BagError as error:
            raise ReplayError(str(error)) from error
        self._open = False

    def __enter__(self) -> BagInput:
        """Open the bag and check the input topics and their types."""
        try:
            self.reader.open()
        except Exception as error:  # noqa: B902 - any failure here means an unreadable bag
            raise ReplayError(f'cannot read {self.path} as a bag: {error}') from error
        self._open = True
        try:
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

    def _check(self) -> None:
        bag_topics = {c.topic: c.msgtype for c in self.reader.connections}
        available = ', '.join(f'{t} ({m})' for t, m in sorted(bag_topics.items())) or 'none'
        expected = dict(INPUT_TYPES)
        if 'velocity' in self.topics:
            expected['velocity'] = VELOCITY_TYPES[self.params.velocity_source]
        for name, topic in self.topics.items():
            if topic not in bag_topics:
                raise ReplayError(f'input {name!r} reads topic {topic}, which is not in '
                                  f'{self.path} (topics: {available}); '
                                  f'use --remap {name}:=TOPIC')
            msgtype = _TYPE_RENAMES.get(bag_topics[topic], bag_topics[topic])
            if msgtype != expected[name]:
                hint = ''
                if name == 'velocity':
                    sources = [s for s, t in VELOCITY_TYPES.items() if t == msgtype]
                    hint = (f'; set velocity.source: {sources[0]}' if sources else
                            '; the velocity input takes TwistWithCovarianceStamped, '
                            'TwistStamped or Odometry')
                raise ReplayError(f'topic {topic} ({name}) is {msgtype}, but the navigator '
                                  f'needs {expected[name]} there{hint}')
        self.by_topic = {topic: name for name, topic in self.topics.items()}
        #: The bag's /tf_static connections (the sensors' mountings, see :meth:`tf_static`).
        self.tf_static_connections = [
            c for c in self.reader.connections if c.topic == TF_STATIC_TOPIC
            and _TYPE_RENAMES.get(c.msgtype, c.msgtype) == OUTPUT_TYPES[TF_STATIC_TOPIC]]
        # ROS 1 data is converted to CDR with the bag's own definitions and ROS 2's Header.
        self.is_ros1 = not self.reader.is2
        self.cdr_store = bags.cdr_typestore(self.reader)

    @property
    def message_count(self) -> int:
        """Return the number of messages in the bag (all topics)."""
        return self.reader.message_count

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
        for connection, _, raw in self.reader.messages(connections=self.tf_static_connections):
            try:
                yield self.reader.deserialize(raw, connection.msgtype)
            except Exception:  # noqa: B902 - any decoding failure is a garbage payload
                self.tf_static_errors += 1

    def raw_messages(self) -> Iterator[tuple[Any, int, bytes]]:
        """Yield (connection, log time ns, CDR bytes) of every message in log-time order."""
        for connection, log_ns, raw in self.reader.messages():
            yield connection, log_ns, self.to_cdr(raw, connection.msgtype)


def _merge_by_stamp(items: Iterator[tuple[str, int, Any] | None],
                    window_ns: int = REORDER_WINDOW_NS) -> Iterator[tuple[str, int, Any]]:
    """
    Reorder (name, stamp ns, msg) items by stamp through a heap spanning ``window_ns``.

    ``None`` items (messages that are not inputs) pass through as ticks, so the caller's
    per-message work (copying, progress) stays in step. Equal stamps keep their bag order.
    A negative stamp (an invalid one, see :func:`_decoded`) passes straight through.
    """
    heap: list[tuple[int, int, str, Any]] = []
    newest = -(2 ** 63)
    sequence = 0
    for item in items:
        if item is None:
            continue
        name, stamp, msg = item
        if stamp < 0:
            yield item
            continue
        heapq.heappush(heap, (stamp, sequence, name, msg))
        sequence += 1
        newest = max(newest, stamp)
        while heap and newest - heap[0][0] > window_ns:
            stamp, _, name, msg = heapq.heappop(heap)
            yield name, stamp, msg
    while heap:
        stamp, _, name, msg = heapq.heappop(heap)
        yield name, stamp, msg


def input_messages(path: str | Path, params: NavigatorParams,
                   remaps: Sequence[str] | Mapping[str, str] | None = None, *,
                   rclpy_messages: bool = True) -> Iterator[tuple[str, int, Any]]:
    """
    Yield the pipeline's input sequence of a bag: (input name, header stamp ns, message).

    In header-stamp order, exactly as :func:`run` feeds :meth:`Pipeline.handle`. The messages
    are rclpy message instances (what the node receives over DDS, ready to publish), or with
    ``rclpy_messages=False`` what :func:`run` feeds the pipeline: rosbags' deserialised
    dataclasses, and for sensor_msgs/Imu in ROS 2 bags :class:`~vessel_kinematics.ros.ros_io.
    ImuCdr` read straight from the CDR (the same fields and values, deserialised about three
    and twelve times faster; ``ros_io``'s inbound conversions take all of them).
    """
    with BagInput(path, params, remaps) as bag:
        yield from _merge_by_stamp(_decoded(bag, None, rclpy_messages))


def _decoded(bag: BagInput, on_raw: Callable[[Any, int, Any], None] | None,
             rclpy_messages: bool = False) -> Iterator[tuple[str, int, Any] | None]:
    """
    Yield (name, stamp, msg) for input messages and ``None`` for the others.

    ``on_raw(connection, log ns, raw)`` sees every message first, in the bag's own
    serialisation (:meth:`BagInput.to_cdr` turns ROS 1 data into CDR).

    A message whose payload cannot be deserialised is counted in ``bag.cdr_errors`` (by input
    name) and yields ``None``; one whose stamp is invalid (:func:`ros_io.stamp_problem`)
    yields the stamp -1, which :func:`_merge_by_stamp` passes on at once for the pipeline to
    reject (so it cannot flush or stall the reorder buffer).
    """
    by_topic = bag.by_topic
    deserialize = bag.reader.deserialize
    # Imu, the high-rate input, is read straight from its CDR (ros_io.imu_from_cdr: the same
    # values, a fifth of the time); anything else, or an Imu it does not take, generically.
    direct = not rclpy_messages and not bag.is_ros1
    for connection, log_ns, raw in bag.reader.messages():
        if on_raw is not None:
            on_raw(connection, log_ns, raw)
        name = by_topic.get(connection.topic)
        if name is None:
            yield None
            continue
        msgtype = connection.msgtype
        try:
            if rclpy_messages:
                msg = deserialize_message(bag.to_cdr(raw, msgtype),
                                          message_class(_TYPE_RENAMES.get(msgtype, msgtype)))
            elif direct and msgtype == _IMU_TYPE:
                msg = ros_io.imu_from_cdr(raw) or deserialize(raw, msgtype)
            else:
                msg = deserialize(raw, msgtype)
            stamp = msg.header.stamp
            sec, nanosec = stamp.sec, stamp.nanosec
        except Exception:  # noqa: B902 - any decoding failure is a garbage payload
            bag.cdr_errors[name] += 1
            yield None
            continue
        if stamp_problem(sec, nanosec) is None:
            yield name, frames.stamp_to_ns(sec, nanosec), msg
        else:
            yield name, -1, msg


# ---------------------------------------------------------------------------------------------
# The replay loop


class _Progress:
    """A one-line progress bar on stderr, only when stderr is a terminal."""

    def __init__(self, total: int, enabled: bool | None = None) -> None:
        self.total = max(total, 1)
        self.enabled = sys.stderr.isatty() if enabled is None else enabled
        self.done = 0
        self.last = 0.0
        self.start = time.monotonic()

    def update(self, n: int = 1) -> None:
        self.done += n
        if not self.enabled:
            return
        now = time.monotonic()
        if now - self.last < 0.2 and self.done < self.total:
            return
        self.last = now
        fraction = min(self.done / self.total, 1.0)
        width = 30
        filled = int(round(width * fraction))
        rate = self.done / max(now - self.start, 1e-9)
        sys.stderr.write(f'\rreplay [{"#" * filled}{"." * (width - filled)}] '
                         f'{100 * fraction:5.1f}% {self.done}/{self.total} msg {rate:.0f} msg/s')
        sys.stderr.flush()

    def close(self) -> None:
        if self.enabled:
            self.update(0)
            sys.stderr.write('\n')
            sys.stderr.flush()


class _Sender:
    """
    Send the session's emissions to ``emit`` and keep what the summary learns from them.

    That is the messages per topic, the distance along ``odometry/local`` and the last
    ``fix/filtered``; :meth:`report` gives them and :meth:`add_to` adds them to a summary (the
    sender may run in the writer process, see :func:`_write_in_background`).
    """

    def __init__(self, pipeline: Pipeline, emit: Callable[[str, int, Any], None]) -> None:
        self.pipeline = pipeline
        self.emit = emit
        self.messages_out: Counter = Counter()
        self.distance_m = 0.0
        self.final_position: tuple[float, float, float] | None = None
        self._last_local: tuple[float, float] | None = None

    def __call__(self, emissions: Iterable[Emission]) -> None:
        """Send each emission as it is built."""
        cdr = self.pipeline.cdr
        for emission in emissions:
            msg = emission.payload
            self.emit(emission.topic, emission.stamp_ns, msg)
            self.messages_out[emission.topic] += 1
            if emission.topic == '/odometry/local':
                # x, y of odometry/local: east and north of the local position (CDR outputs
                # are bytes: read the pose they were built from)
                if cdr:
                    pose = self.pipeline.pose()
                    assert pose is not None
                    x, y, _ = frames.swap_world3(*pose.p_local.tolist())
                else:
                    p = msg.pose.pose.position
                    x, y = p.x, p.y
                if self._last_local is not None:
                    self.distance_m += math.hypot(x - self._last_local[0],
                                                  y - self._last_local[1])
                self._last_local = (x, y)
            elif emission.topic == '/fix/filtered':
                if cdr:
                    state = self.pipeline.state()
                    assert state is not None
                    lat, lon, height = state.llh
                    self.final_position = (math.degrees(lat), math.degrees(lon),
                                           float(height))
                else:
                    self.final_position = (msg.latitude, msg.longitude, msg.altitude)

    def report(self) -> tuple[dict[str, int], float, tuple[float, float, float] | None]:
        """Return (messages per topic, distance m, final position): picklable."""
        return dict(self.messages_out), self.distance_m, self.final_position

    @staticmethod
    def add_to(summary: Summary,
               report: tuple[dict[str, int], float, tuple[float, float, float] | None]) -> None:
        """Add a :meth:`report` to ``summary``."""
        messages_out, distance_m, final_position = report
        summary.messages_out.update(messages_out)
        summary.distance_m += distance_m
        if final_position is not None:
            summary.final_position = final_position


def _drive(bag: BagInput, session: Session, summary: Summary,
           emit: Callable[[str, int, Any], None],
           on_raw: Callable[[Any, int, bytes], None] | None,
           progress: _Progress | None,
           defer: Callable[[bytes | None], None] | None = None) -> None:
    """
    Feed the bag's inputs to the pipeline in stamp order and emit what the session emits.

    The output policy is :class:`~vessel_kinematics.ros.session.Session`'s, the node's own:
    ``emit(topic, stamp_ns, msg)`` receives the navigator's outputs (absolute topic names),
    ``/tf`` (a list of TransformStamped) after each emission of the state and ``/tf_static``
    (a list) whenever the static transforms change; and ``/diagnostics`` once per second of
    bag time.

    ``defer``: the emissions are built elsewhere, by a copy of ``session`` made before this
    call. ``defer(None)`` stands for its first :meth:`~vessel_kinematics.ros.session.Session.
    statics`, ``defer(frozen)`` for each emission, with the pipeline's :meth:`~vessel_kinematics.
    ros.pipeline.Pipeline.hand_off`; only ``/diagnostics`` goes to ``emit``.
    """
    pipeline = session.pipeline
    next_diagnostics: int | None = None

    def ticks() -> Iterator[tuple[str, int, Any] | None]:
        for item in _decoded(bag, on_raw):
            if progress is not None:
                progress.update()
            yield item

    send = _Sender(pipeline, emit)
    if defer is None:
        send(session.statics())
    else:
        defer(None)
    # The bag's static transforms first (latched: in force from the start; see
    # BagInput.tf_static), so the inputs' mountings come from them where their frames are.
    n_static = sum(pipeline.tf_static(msg) >= 0 for msg in bag.tf_static())
    if n_static:
        summary.notes.append(f'{TF_STATIC_TOPIC}: {n_static} messages read before the inputs, '
                             f'{len(pipeline.static_tree)} static transforms')
    if bag.tf_static_errors:
        summary.notes.append(f'{TF_STATIC_TOPIC}: {bag.tf_static_errors} messages not '
                             'readable (skipped)')
    last_stamp: int | None = None
    for name, stamp, msg in _merge_by_stamp(ticks()):
        summary.messages_in[name] += 1
        if defer is None:
            result, emissions = session.handle(name, msg)
            if emissions:
                send(emissions)
        else:
            result, due = session.step(name, msg)
            if due:
                defer(pipeline.hand_off())
        if result.rejected is not None:
            summary.rejected[f'{name}/{result.rejected}'] += 1
        if result.info is not None:
            summary.notes.append(result.info)
        if stamp < 0:  # an invalid stamp (rejected): not a time of the bag
            continue
        if last_stamp is None:
            summary.start_ns = stamp
            next_diagnostics = stamp + DIAGNOSTICS_PERIOD_NS
        elif stamp < last_stamp:
            summary.out_of_order += 1
        last_stamp = stamp if last_stamp is None else max(last_stamp, stamp)
        summary.end_ns = max(summary.end_ns, stamp)
        assert next_diagnostics is not None
        if stamp >= next_diagnostics:
            emit('/diagnostics', stamp, pipeline.diagnostics(stamp))
            summary.messages_out['/diagnostics'] += 1
            next_diagnostics += DIAGNOSTICS_PERIOD_NS * (
                (stamp - next_diagnostics) // DIAGNOSTICS_PERIOD_NS + 1)
    if last_stamp is not None:
        emit('/diagnostics', last_stamp, pipeline.diagnostics(last_stamp))
        summary.messages_out['/diagnostics'] += 1
    send.add_to(summary, send.report())
    summary.estimates = pipeline.estimates()
    for name, count in bag.cdr_errors.items():
        summary.messages_in[name] += count
        summary.rejected[f'{name}/{REASON_CDR_ERROR}'] += count


def tf_message_cdr(transforms: Sequence[Any]) -> bytes:
    """
    Return the CDR (little-endian) of a tf2_msgs/TFMessage holding ``transforms``.

    tf2_msgs has no rclpy bindings here, so the message is laid out by hand
    (:func:`~vessel_kinematics.ros.ros_io.tf_cdr`), as rosbags' ``serialize_cdr`` would (the
    tests compare the two): ``transforms`` are geometry_msgs/TransformStamped messages.
    """
    return ros_io.tf_cdr([ros_io.parts_of(t) for t in transforms])


def check_paths(inputs: Sequence[str | Path], output: str | Path,
                plot: str | Path | None = None) -> None:
    """
    Refuse an output (or plot) that would overwrite or nest with an input; before any I/O.

    Paths are compared as real paths (symlinks resolved, also through a not yet existing
    tail): the output must not be an input, lie inside one, or contain one. Raises
    :class:`ReplayError`.
    """
    out = Path(os.path.realpath(output))
    figure = None if plot is None else Path(os.path.realpath(plot))
    for given in inputs:
        source = Path(os.path.realpath(given))
        if out == source:
            raise ReplayError(f'output {output} is the input {given}: refusing to touch it')
        if source in out.parents:
            raise ReplayError(f'output {output} is inside the input {given}: refusing')
        if out in source.parents:
            raise ReplayError(f'output {output} contains the input {given}: refusing')
        if figure is not None and (figure == source or source in figure.parents):
            raise ReplayError(f'plot {plot} would write into the input {given}: refusing')


def is_bag_directory(path: Path) -> bool:
    """
    Return True for a rosbag2 bag directory: ``metadata.yaml`` and only bag files in it.

    Bag files are regular files named with :data:`BAG_FILE_SUFFIXES`; a symlink (to the
    directory or in it) or any other entry makes it something else, which ``--overwrite``
    does not remove.
    """
    if path.is_symlink() or not path.is_dir():
        return False
    names = set()
    for entry in path.iterdir():
        if entry.is_symlink() or not entry.is_file():
            return False
        if entry.name != 'metadata.yaml' and not entry.name.endswith(BAG_FILE_SUFFIXES):
            return False
        names.add(entry.name)
    return 'metadata.yaml' in names


def _prepare_output(output: Path, overwrite: bool) -> bool:
    """Check that ``output`` can be written; return True when a previous output is replaced."""
    if output.exists() or output.is_symlink():
        if not overwrite:
            raise ReplayError(f'output {output} exists already (use --overwrite to replace it)')
        if not is_bag_directory(output):
            raise ReplayError(f'output {output} exists and is not a rosbag2 bag (metadata.yaml '
                              'and bag files only): not replacing it')
        return True
    parent = output.parent
    if not parent.is_dir():
        raise ReplayError(f'output directory {parent} does not exist')
    if not os.access(parent, os.W_OK | os.X_OK):
        raise ReplayError(f'output directory {parent} is not writable')
    return False


def staging_path(output: Path) -> Path:
    """Return the hidden sibling directory a replay writes ``output`` in before moving it."""
    return output.parent / f'.{output.name}.replay-{os.getpid()}'


def _place(written: Path, output: Path, replace: bool) -> None:
    """Move the finished bag ``written`` to ``output`` (replacing a previous output)."""
    if not replace:
        if output.exists() or output.is_symlink():
            raise ReplayError(f'output {output} appeared during the replay: not replacing it')
        os.rename(written, output)
        return
    if not is_bag_directory(output):
        raise ReplayError(f'output {output} changed during the replay: not replacing it')
    previous = output.parent / f'.{output.name}.replaced-{os.getpid()}'
    os.rename(output, previous)
    try:
        os.rename(written, output)
    except BaseException:
        os.rename(previous, output)
        raise
    shutil.rmtree(previous)


def _check_usable(summary: Summary, pipeline: Pipeline, bag: BagInput) -> None:
    """Raise :class:`ReplayError` when the run had no input message, or no usable one."""
    n_in = sum(summary.messages_in.values())
    if n_in == 0:
        raise ReplayError(f'no messages on the input topics ({", ".join(bag.topics.values())})'
                          f' of {bag.path}: nothing to replay')
    counts = pipeline.counts
    if not any(counts.get(name, 0) for name in INPUTS):
        reasons = ', '.join(f'{k} {n}' for k, n in sorted(summary.rejected.items()))
        raise ReplayError(f'no usable input message: all {n_in} were rejected ({reasons})')


def run(input_path: str | Path, output_path: str | Path,
        params: NavigatorParams | None = None,
        remaps: Sequence[str] | Mapping[str, str] | None = None, *,
        copy_inputs: bool = True, plot: str | Path | None = None,
        progress: bool | None = None, overwrite: bool = False,
        accuracy: bool = True, background: bool | None = None) -> Summary:
    """
    Replay the bag ``input_path`` through the navigator's pipeline into ``output_path`` (mcap).

    ``params`` default to the navigator's defaults; ``remaps`` map input names to bag topics
    (``['fix:=/gps/fix']`` or ``{'fix': '/gps/fix'}``). ``plot`` writes a figure of the run
    (:func:`vessel_kinematics.tools.plot.plot`). ``progress`` None = a bar when stderr is a
    terminal. When the input holds simulator truth (``/truth/odometry``) and ``accuracy`` is
    true, the summary carries the accuracy table of
    :func:`vessel_kinematics.tools.evaluate.accuracy`,
    fused beside a dead-reckoning-only replay (made in memory). ``background``: write the
    output bag in a second process while this one runs the pipeline (the same bytes; None: where
    a process can be forked, see :func:`_write`). Raises :class:`ReplayError` for unusable
    input or options.

    Nothing is lost or half-written: an output that is, contains or lies inside the input is
    refused before anything is opened (:func:`check_paths`); ``overwrite`` replaces only a
    rosbag2 bag directory (:func:`is_bag_directory`); the bag is written in a hidden sibling
    directory (:func:`staging_path`) and renamed into place only once complete and usable,
    so any failure or interrupt leaves no output and any previous output untouched. A run
    without input messages, or whose every input was rejected, is an error.
    """
    params = params if params is not None else NavigatorParams()
    check_paths([input_path], output_path, plot)
    wall_start = time.monotonic()
    summary = Summary(input_path=Path(input_path), output_path=Path(output_path))
    # Absolute (symlinks kept), so that '.' or 'x/..' have a name and a parent to stage in.
    output = Path(os.path.abspath(output_path))
    with BagInput(input_path, params, remaps) as bag:
        replace = _prepare_output(output, overwrite)
        summary.topics = dict(bag.topics)
        has_truth = any(c.topic == '/truth/odometry' for c in bag.reader.connections)
        pipeline = Pipeline(params, cdr=True)  # outputs as CDR bytes: no rclpy messages
        staging = staging_path(output)
        try:
            staging.mkdir()
        except OSError as error:
            raise ReplayError(f'cannot write in {output.parent}: {error.strerror}') from error
        try:
            written = staging / output.name
            _write(bag, pipeline, summary, written, copy_inputs, progress, background)
            _check_usable(summary, pipeline, bag)
            _place(written, output, replace)
        finally:
            shutil.rmtree(staging, ignore_errors=True)
    summary.wall_time_s = time.monotonic() - wall_start
    if plot is None and not (accuracy and has_truth):
        return summary
    inputs_bag = None if copy_inputs else Path(input_path)
    dr_run = None
    if accuracy and has_truth:
        summary.accuracy, run_, dr_run = accuracy_report(
            output, params, remaps, inputs_bag=Path(input_path) if inputs_bag else None)
    if plot is not None:
        source: Any = output
        if accuracy and has_truth:
            source = run_
        from vessel_kinematics.tools import plot as figure   # matplotlib, only when drawing
        summary.plot = figure.plot(source, plot, fix_topic=summary.topics['fix'],
                                   fixes_bag=inputs_bag, dead_reckoning=dr_run)
    return summary


def _write(bag: BagInput, pipeline: Pipeline, summary: Summary, output: Path,
           copy_inputs: bool, progress: bool | None, background: bool | None = None) -> None:
    """
    Write the replay of ``bag`` as a new mcap bag at ``output`` (which must not exist).

    ``background``: write the bag in a second process (:class:`~vessel_kinematics.tools.
    replay_output.BackgroundWriter`: the same bytes); None where one can be forked
    (:func:`~vessel_kinematics.tools.replay_output.background_available`).
    """
    inputs, skipped = _copied_inputs(bag) if copy_inputs else ([], set())
    if skipped:
        summary.notes.append('not copied (the replay writes them): '
                             + ', '.join(sorted(skipped)))
    if background is None:
        background = background_available()
    bar = _Progress(bag.message_count, progress)
    try:
        with fewer_collections():     # in both processes: the writer is forked in here
            if background:
                copied, uncopied = _write_in_background(bag, pipeline, summary, output, inputs,
                                                        bar)
            else:
                out = _open_output(bag, output, inputs)
                try:
                    _drive(bag, Session(pipeline), summary, _writing_to(out),
                           out.copy if out.copies else None, bar)
                finally:
                    out.close()
                copied, uncopied = out.copied, out.uncopied
    except WriterFailed as error:
        raise ReplayError(f'cannot write {output}: {error}') from error
    finally:
        bar.close()
    summary.messages_copied += copied
    if uncopied:
        summary.notes.append('not copied (ROS 1 payload not convertible to CDR): '
                             + ', '.join(f'{t} {n}' for t, n in sorted(uncopied.items())))


def _open_output(bag: BagInput, output: Path, inputs: list[tuple[Any, str, Any]]) -> OutputBag:
    """Open the replay's output bag at ``output``, copying ``inputs`` (ROS 1 ones as CDR)."""
    return OutputBag(output, OUTPUT_TYPES, inputs, bag.jazzy, bag.to_cdr if bag.is_ros1 else None)


def _writing_to(out: OutputBag | BackgroundWriter) -> Callable[[str, int, Any], None]:
    """Return the ``emit`` of :func:`_drive` that writes each emission's bytes into ``out``."""
    return lambda topic, at_ns, msg: out.write(topic, at_ns, *_output_bytes(topic, msg))


def _write_in_background(bag: BagInput, pipeline: Pipeline, summary: Summary, output: Path,
                         inputs: list[tuple[Any, str, Any]],
                         bar: _Progress) -> tuple[int, Counter]:
    """
    Run the estimator here; build the outputs and write the bag in a second process.

    The second process builds each emission with its copy of the session (forked before the
    first input), given the estimator of the moment (:meth:`~vessel_kinematics.ros.pipeline.
    Pipeline.hand_off`): the same code on the same state as :func:`_drive` in one process, so
    the same bytes, with the outputs' state and messages off this process. Returns the copy
    counts (inputs copied, not copied by topic).
    """
    session = Session(pipeline)

    def open_bag() -> Opened:
        # In the second process, with its copies of this process's objects.
        return _open_output(bag, output, inputs), _Emitter(session)

    writer = BackgroundWriter(open_bag, [c.id for c, _, _ in inputs])
    try:
        _drive(bag, session, summary, _writing_to(writer), writer.copy if inputs else None,
               bar, writer.defer)
        copied, uncopied, report = writer.finish()
    except BaseException:
        writer.abort()
        raise
    _Sender.add_to(summary, report)
    return copied, uncopied


class _Emitter:
    """The :class:`~vessel_kinematics.tools.replay_output.Builder` of the replay's emissions."""

    def __init__(self, session: Session) -> None:
        self.session = session
        self.bag: OutputBag | None = None
        self.send = _Sender(session.pipeline, self._write)

    def _write(self, topic: str, at_ns: int, msg: Any) -> None:
        assert self.bag is not None
        self.bag.write(topic, at_ns, *_output_bytes(topic, msg))

    def build(self, payload: bytes | None, out: OutputBag) -> None:
        """Write the first static transforms (None) or the emission of a hand-off."""
        self.bag = out
        if payload is None:
            self.send(self.session.statics())
            return
        self.session.pipeline.take_over(payload)
        self.send(self.session.emissions())

    def report(self) -> tuple[dict[str, int], float, tuple[float, float, float] | None]:
        """Return the sender's report."""
        return self.send.report()


def _copied_inputs(bag: BagInput) -> tuple[list[tuple[Any, str, Any]], set[str]]:
    """
    Return the input connections to copy (connection, type, typestore) and the topics not.

    The navigator's own outputs are not copied (the replay writes them anew), but the input's
    static transforms are: they come from other publishers (a URDF's robot_state_publisher), and
    a tf2 listener merges every /tf_static message.
    """
    inputs, skipped = [], set()
    for c in bag.reader.connections:
        if c.topic in OUTPUT_TYPES and c.topic != TF_STATIC_TOPIC:
            skipped.add(c.topic)
            continue
        msgtype = _TYPE_RENAMES.get(c.msgtype, c.msgtype)
        store = bag.cdr_store if msgtype in bag.cdr_store.fielddefs else bag.jazzy
        inputs.append((c, msgtype, store))
    return inputs, skipped


def _output_bytes(topic: str, msg: Any) -> tuple[bytes, str | None]:
    """
    Return an emission's CDR bytes, and its type when it is a message (not yet a connection).

    The pipeline's outputs come as CDR bytes; TF as lists of TransformStamped (the session's
    emissions, the node's own), diagnostics as a message, any other output as an rclpy message.
    """
    if isinstance(msg, bytes):
        return msg, None
    if isinstance(msg, list):
        return tf_message_cdr(msg), None
    if topic == '/diagnostics':
        return diagnostics_cdr(msg), None
    return serialize_message(msg), _type_name(type(msg))


def replay_in_memory(input_path: str | Path, params: NavigatorParams | None = None,
                     remaps: Sequence[str] | Mapping[str, str] | None = None,
                     topics: Sequence[str] | None = None,
                     ) -> tuple[dict[str, list[tuple[int, Any]]], Summary]:
    """
    Replay a bag without writing one: return {topic: [(stamp ns, rclpy message)]} and a summary.

    ``topics`` limits what is kept (default: the navigator's outputs and ``/diagnostics``;
    ``/tf`` entries are lists of TransformStamped).
    """
    params = params if params is not None else NavigatorParams()
    keep = set(topics) if topics is not None else {'/' + t for t in OUTPUTS} | {'/diagnostics'}
    out: dict[str, list[tuple[int, Any]]] = {t: [] for t in keep}
    summary = Summary(input_path=Path(input_path), output_path=None)
    wall_start = time.monotonic()

    def emit(topic: str, at_ns: int, msg: Any) -> None:
        if topic in keep:
            out[topic].append((at_ns, msg))

    with BagInput(input_path, params, remaps) as bag:
        summary.topics = dict(bag.topics)
        with fewer_collections():
            _drive(bag, Session(Pipeline(params)), summary, emit, None, None)
    summary.wall_time_s = time.monotonic() - wall_start
    return out, summary


# ---------------------------------------------------------------------------------------------
# Many bags

#: Files taken as bags in a directory of bags (each rosbag2 bag directory is taken too).
BAG_FILE_TYPES = ('.bag', '.mcap')


def is_bag(path: Path) -> bool:
    """Return True for one bag: a rosbag2 directory (``metadata.yaml``) or a bag file."""
    if path.is_dir():
        return (path / 'metadata.yaml').is_file()
    return path.is_file()


def is_many(inputs: Sequence[str | Path]) -> bool:
    """Return True when ``inputs`` are several, or one directory of bags (not a bag itself)."""
    return len(inputs) > 1 or (Path(inputs[0]).is_dir() and not is_bag(Path(inputs[0])))


def find_bags(inputs: Sequence[str | Path]) -> list[Path]:
    """
    Return the bags of ``inputs``, in order: each bag, and the bags in each directory of bags.

    In a directory that is not a bag itself, every rosbag2 bag directory and every
    :data:`BAG_FILE_TYPES` file directly in it is a bag (sorted by name; hidden entries, such as
    a replay's staging directories, are skipped). A path that does not exist stays in the list,
    for its row to say so. Raises :class:`ReplayError` for a directory without bags.
    """
    bags: list[Path] = []
    for given in map(Path, inputs):
        if not given.is_dir() or is_bag(given):
            bags.append(given)
            continue
        found = [entry for entry in sorted(given.iterdir())
                 if not entry.name.startswith('.')
                 and (entry.is_dir() and is_bag(entry)
                      or entry.is_file() and entry.suffix in BAG_FILE_TYPES)]
        if not found:
            raise ReplayError(f'{given} is neither a bag nor a directory of bags (rosbag2 '
                              f'directories, {", ".join(BAG_FILE_TYPES)} files)')
        bags.extend(found)
    return bags


def output_name(bag: Path) -> str:
    """Return the name of a bag's output in the output directory: its name without suffix."""
    return bag.name if bag.is_dir() else bag.stem


@dataclass
class BagRow:
    """One row of the table of a many-bag replay: a bag's numbers, or its error."""

    name: str
    input_path: Path
    output_path: Path
    duration_s: float = 0.0
    messages_in: int = 0
    messages_out: int = 0
    rejected: int = 0
    distance_m: float = 0.0
    wall_time_s: float = 0.0
    error: str | None = None

    @property
    def ok(self) -> bool:
        """Return True when the bag was replayed."""
        return self.error is None


def _replay_one(task: tuple[str, Path, Path, NavigatorParams, Any, bool, bool, bool]
                ) -> BagRow:
    """
    Replay one bag of a many-bag run (in a worker process); never raises but interrupts.

    With several workers the bag is written in the worker itself: the cores are busy already.
    """
    name, source, target, params, remaps, copy_inputs, overwrite, alone = task
    row = BagRow(name, source, target)
    start = time.monotonic()
    try:
        summary = run(source, target, params, remaps, copy_inputs=copy_inputs, progress=False,
                      overwrite=overwrite, accuracy=False, background=None if alone else False)
    except Exception as error:  # noqa: B902 - one bag's failure is its row, never the run's
        row.error = error_line(error)
    else:
        row.duration_s = summary.duration_s
        row.messages_in = sum(summary.messages_in.values())
        row.messages_out = sum(summary.messages_out.values())
        row.rejected = sum(summary.rejected.values())
        row.distance_m = summary.distance_m
    row.wall_time_s = time.monotonic() - start
    return row


def run_many(inputs: Sequence[str | Path], output: str | Path,
             params: NavigatorParams | None = None,
             remaps: Sequence[str] | Mapping[str, str] | None = None, *, jobs: int = 1,
             copy_inputs: bool = True, overwrite: bool = False) -> list[BagRow]:
    """
    Replay every bag of ``inputs`` (:func:`find_bags`) into ``output``/<name> (:func:`run`).

    ``output`` is a directory (made if missing; it must not be, lie inside or contain an
    input); each bag's output follows :func:`run`'s rules (refused if it exists unless
    ``overwrite``, written in a hidden sibling and renamed when complete). ``jobs`` > 1 replays
    that many bags at a time in separate processes (spawned: nothing of this process is
    shared). A bag that fails is a row with its one-line error; the others go on. Returns the
    rows in input order. Raises :class:`ReplayError` before any replay for unusable
    ``inputs``/``output``: no bags, two bags of one output name, an output that is a file.
    """
    params = params if params is not None else NavigatorParams()
    bags = find_bags(inputs)
    names = [output_name(bag) for bag in bags]
    seen: dict[str, Path] = {}
    for name, bag in zip(names, bags):
        if name in seen:
            raise ReplayError(f'{seen[name]} and {bag} would both write {Path(output) / name}')
        seen[name] = bag
    check_paths([*inputs, *bags], output)
    out = Path(os.path.abspath(output))
    if out.is_symlink() or (out.exists() and not out.is_dir()):
        raise ReplayError(f'output {output} exists and is not a directory')
    try:
        out.mkdir(exist_ok=True)
    except OSError as error:
        raise ReplayError(f'cannot make the output directory {output}: '
                          f'{error.strerror}') from error
    alone = jobs <= 1 or len(bags) == 1
    tasks = [(name, bag, out / name, params, remaps, copy_inputs, overwrite, alone)
             for name, bag in zip(names, bags)]
    if jobs <= 1 or len(tasks) == 1:
        return [_replay_one(task) for task in tasks]
    import concurrent.futures
    import multiprocessing
    context = multiprocessing.get_context('spawn')
    rows: list[BagRow | None] = [None] * len(tasks)
    with concurrent.futures.ProcessPoolExecutor(min(jobs, len(tasks)),
                                                mp_context=context) as pool:
        futures = {pool.submit(_replay_one, task): i for i, task in enumerate(tasks)}
        for future in concurrent.futures.as_completed(futures):
            i = futures[future]
            try:
                rows[i] = future.result()
            except Exception as error:  # noqa: B902 - e.g. a worker process that died
                name, source, target = tasks[i][:3]
                rows[i] = BagRow(name, source, target, error=error_line(error))
    return [row for row in rows if row is not None]


def rows_table(rows: Sequence[BagRow]) -> str:
    """Return the summary table of a many-bag replay: one row per bag, then the totals."""
    header = ('bag', 'bag time s', 'in', 'out', 'rejected', 'distance m', 'wall s', 'status')
    lines = [[row.name, f'{row.duration_s:.1f}', str(row.messages_in), str(row.messages_out),
              str(row.rejected), f'{row.distance_m:.1f}', f'{row.wall_time_s:.1f}',
              'ok' if row.ok else f'error: {row.error}'] for row in rows]
    failed = sum(not row.ok for row in rows)
    lines.append(['total', f'{sum(r.duration_s for r in rows):.1f}',
                  str(sum(r.messages_in for r in rows)), str(sum(r.messages_out for r in rows)),
                  str(sum(r.rejected for r in rows)), f'{sum(r.distance_m for r in rows):.1f}',
                  f'{sum(r.wall_time_s for r in rows):.1f}',
                  f'{len(rows) - failed} ok, {failed} failed'])
    widths = [max(len(cells[i]) for cells in [list(header), *lines[:-1], lines[-1]])
              for i in range(len(header) - 1)]

    def fmt(cells: Sequence[str]) -> str:
        left = cells[0].ljust(widths[0])
        middle = '  '.join(c.rjust(w) for c, w in zip(cells[1:-1], widths[1:]))
        return f'{left}  {middle}  {cells[-1]}'

    return '\n'.join([fmt(header)] + [fmt(cells) for cells in lines])


# ---------------------------------------------------------------------------------------------
# Command line


# ---------------------------------------------------------------------------------------------
# Scoring against truth (a second, dead-reckoning-only replay)


def dead_reckoning_run(inputs_bag: str | Path, params: NavigatorParams | None = None,
                       remaps: Sequence[str] | Mapping[str, str] | None = None,
                       ) -> evaluate.Run:
    """
    Replay a bag's inputs in memory with ``gnss.enabled: false``: the dead-reckoning-only run.

    The fixes then only set the origin (the first fix, as in the fused run, unless ``origin`` is
    a parameter); the truth and reference topics are taken from the same bag.
    """
    params = params if params is not None else NavigatorParams()
    topics_map = parse_remaps(remaps)
    outputs, _ = replay_in_memory(inputs_bag, dataclasses.replace(params, gnss_enabled=False),
                                  remaps)
    extra = bags.read_topics([inputs_bag], set(evaluate.TRUTH_TOPICS)
                             | {evaluate.COG_SOG_TOPIC, topics_map['fix']})
    return evaluate.run_from_messages({**outputs, **extra}, fix_topic=topics_map['fix'],
                                      label='dead reckoning')


def accuracy_report(bag: str | Path, params: NavigatorParams | None = None,
                    remaps: Sequence[str] | Mapping[str, str] | None = None,
                    inputs_bag: str | Path | None = None,
                    dead_reckoning: bool = True,
                    ) -> tuple[str, evaluate.Run, evaluate.Run | None]:
    """
    Score the outputs in ``bag`` against its truth, with a dead-reckoning-only replay beside.

    ``inputs_bag`` holds the navigator's inputs and truth when ``bag`` does not (default:
    ``bag`` itself, as the replay copies its inputs). Return (text, fused run, DR run or None);
    the text says so when there is no truth.
    """
    fix_topic = parse_remaps(remaps)['fix']
    run = evaluate.load_run(bag, fix_topic=fix_topic, fixes_bag=inputs_bag)
    scores = evaluate.accuracy(run)
    if scores is None:
        return 'no truth topics in the bag: accuracy not scored', run, None
    dr_run = None
    dr_scores = None
    if dead_reckoning:
        dr_run = dead_reckoning_run(inputs_bag if inputs_bag is not None else bag, params,
                                    remaps)
        dr_scores = evaluate.accuracy(dr_run)
    return evaluate.format_accuracy(scores, dr_scores), run, dr_run


def build_parser() -> argparse.ArgumentParser:
    """Return the command line parser of ``replay``."""
    names = ', '.join(p.name for p in PARAMETERS)
    parser = argparse.ArgumentParser(
        prog='replay',
        description='Replay a recorded bag (rosbag2 mcap/sqlite3 or ROS 1) through the '
                    "vessel_kinematics navigator's estimator and write its outputs, TF and the "
                    'copied inputs to a rosbag2 mcap bag.',
        epilog='example: replay run.bag out --params-file config/navigator.yaml '
               '--remap fix:=/gps/fix imu:=/imu/data velocity:=/wheel/odom --plot run.png; '
               'replay archive/ out_dir --jobs 2. '
               f'Parameters: {names}.')
    parser.add_argument('paths', nargs='+', metavar='INPUT [INPUT ...] OUTPUT',
                        help='input bags: rosbag2 directories (mcap, sqlite3), ROS 1 .bag or '
                             '.mcap files, or directories of them; then the output rosbag2 '
                             'directory (mcap), which must not exist. With several inputs (or '
                             'a directory of bags) OUTPUT is a directory holding one output '
                             'per input, OUTPUT/<input name>, and a table is printed')
    parser.add_argument('--params-file', metavar='FILE',
                        help='ROS 2 parameters file (navigator: ros__parameters: or /**)')
    parser.add_argument('-p', '--param', action='append', default=[], metavar='NAME:=VALUE',
                        help='set one parameter over the file, e.g. -p gnss.enabled:=false')
    parser.add_argument('-r', '--remap', nargs='+', action='extend', default=[],
                        metavar='NAME:=TOPIC',
                        help='read input NAME (fix, imu, velocity) from bag topic TOPIC; '
                             'defaults fix:=/fix imu:=/imu velocity:=/velocity')
    parser.add_argument('--plot', metavar='FILE.png', help='write a figure of the run')
    parser.add_argument('--no-copy-inputs', action='store_true',
                        help="do not copy the input bag's topics into the output")
    parser.add_argument('--overwrite', action='store_true',
                        help='replace OUTPUT if it is an existing rosbag2 bag')
    parser.add_argument('--no-progress', action='store_true', help='no progress bar')
    parser.add_argument('-j', '--jobs', type=int, default=1, metavar='N',
                        help='with several inputs, replay N bags at a time in separate '
                             'processes (default 1)')
    return parser


def error_line(error: BaseException) -> str:
    """Return the one line ``replay`` prints for ``error`` (without the ``replay: error:``)."""
    if isinstance(error, (ReplayError, ParameterError, BagError)):
        return _one_line(error)
    if isinstance(error, OSError):
        where = f' ({error.filename})' if error.filename else ''
        return f'{_one_line(error.strerror or error)}{where}'
    return f'unexpected {type(error).__name__}: {_one_line(error)}'


def main(argv: Sequence[str] | None = None) -> int:
    """Run the ``replay`` command; return the exit status (0 ok, 1 error, 2 usage)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    *inputs, output = args.paths
    if not inputs:
        parser.error('the following arguments are required: output')
    try:
        overrides = dict(parse_param(p) for p in args.param)
        params = load_params(args.params_file, overrides)
        if args.jobs < 1:
            raise ReplayError(f'--jobs {args.jobs}: must be at least 1')
        if is_many(inputs):
            if args.plot is not None:
                raise ReplayError('--plot takes one input bag (several inputs print a table)')
            rows = run_many(inputs, output, params, args.remap, jobs=args.jobs,
                            copy_inputs=not args.no_copy_inputs, overwrite=args.overwrite)
            print(rows_table(rows))
            return 0 if all(row.ok for row in rows) else 1
        summary = run(inputs[0], output, params, args.remap,
                      copy_inputs=not args.no_copy_inputs, plot=args.plot,
                      progress=False if args.no_progress else None,
                      overwrite=args.overwrite)
    except KeyboardInterrupt:
        print('replay: error: interrupted; no output written', file=sys.stderr)
        return 130
    except Exception as error:  # noqa: B902 - the promise: one line, never a traceback
        if os.environ.get('VK_REPLAY_TRACEBACK') and not isinstance(
                error, (ReplayError, ParameterError, BagError, OSError)):
            raise
        line = error_line(error)
        if not isinstance(error, (ReplayError, ParameterError, BagError, OSError)):
            line += ' (VK_REPLAY_TRACEBACK=1 shows the traceback)'
        print(f'replay: error: {line}', file=sys.stderr)
        return 1
    print(summary.text())
    return 0


if __name__ == '__main__':
    sys.exit(main())
