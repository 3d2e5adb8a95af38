"""
The demo's live side: a bridge node playing the voyage over DDS, and the navigator's process.

:class:`Bridge` (an rclpy node on a context of its own) publishes the voyage's inputs and a
``/clock`` and records every output of the navigator as it arrives; :class:`NavigatorProcess`
is the installed navigator, started as ``ros2 run`` starts it; :func:`play` publishes the
inputs with ``/clock`` as fast as the node follows. :mod:`vessel_kinematics.tools.demo` runs
the whole demo with them.

Each input is published at its log time, when it reached the vessel's ROS graph, not at its
header stamp: the simulator logs a GNSS fix 0.1 to 0.5 s after its stamp and the IMU and the
log a few milliseconds after theirs (:mod:`vessel_kinematics.tools.sim`), so the navigator
receives late fixes as it does on board, and has to fuse each at its own stamp
(``history_length``). ``/clock`` follows the log time in steps of at most
:data:`CLOCK_STEP_NS`, so the node's clock at a message's arrival is up to that step before its
log time.
"""

from __future__ import annotations

from dataclasses import dataclass, field
import math
import os
from pathlib import Path
import signal
import struct
import subprocess
import threading
import time
from typing import Any, Sequence

from vessel_kinematics.core import frames
from vessel_kinematics.ros import interface

__all__ = ['Bridge', 'CLOCK_STEP_NS', 'DemoError', 'DIAGNOSTICS_WAIT', 'diagnostics_values',
           'END_WAIT', 'FIX_TOPIC', 'header_stamp_ns', 'HISTORY_MARGIN', 'IMU_TOPIC',
           'INPUT_TOPICS', 'Installation', 'lead_limit', 'MAX_LEAD', 'MAX_WAIT', 'Message',
           'MIN_LEAD', 'NavigatorProcess', 'NUDGE_LIMIT_NS', 'play', 'PlayStats',
           'processed_count', 'read_bag', 'RECORDER_DEPTH', 'Recording', 'say', 'start_clock',
           'tf_available', 'TF_TOPICS']

#: The navigator's inputs in the voyage bag (the node's relative names in the root namespace):
#: those of the default sources (no ``gnss_velocity``).
INPUT_TOPICS = tuple(interface.types(interface.Role.INPUT))
#: Recorded too when tf2_msgs is importable (it is not in the PyPI wheels).
TF_TOPICS: dict[str, str] = {
    t.absolute: t.msg_type for t in interface.by_role(interface.Role.AUXILIARY)
    if t.msg_type is not None and t.qos in (interface.Qos.TF, interface.Qos.TF_STATIC)}
#: The GNSS fix topic: the node's first output waits for its first fix (the origin).
FIX_TOPIC = interface.topic('fix').absolute
#: The IMU topic: it carries the node's state forward; its outputs are the state at the newest
#: IMU sample (an input stamped after it waits for the IMU to reach its stamp).
IMU_TOPIC = interface.topic('imu').absolute
#: How far (s of sim time, by log time) the player may run ahead of the navigator's latest
#: output (the stamp of its last /odometry, its state's time): below the node's input queue
#: depth (20 messages: 0.2 s of the 100 Hz IMU), so that none is dropped. The node must also
#: be able to fuse, at its own stamp, an input handled that far behind the newest one it has
#: taken, plus that input's delivery latency (a fix logged 0.5 s after its stamp): the lead and
#: the latency must fit in its ``history_length`` (:func:`lead_limit` takes the smaller).
MAX_LEAD = 0.18
#: The smallest lead the player runs with (s): two IMU periods.
MIN_LEAD = 0.02
#: What the lead and the inputs' latency leave free of the navigator's ``history_length`` (s): a
#: /clock step, a late output.
HISTORY_MARGIN = 0.1
#: The longest step of /clock between two publications (ns of sim time).
CLOCK_STEP_NS = 50_000_000
#: How far ahead of the inputs /clock may be nudged while waiting for the node (ns).
NUDGE_LIMIT_NS = 200_000_000
#: Give up waiting for the navigator to catch up after this long (s of wall time).
MAX_WAIT = 5.0
#: After the last input, wait at most this long for the outputs (s of wall time).
END_WAIT = 10.0
#: Then at most this long for one more /diagnostics, the final counts (s of wall time).
DIAGNOSTICS_WAIT = 3.0
#: Queue depth of the demo's publishers and recorder (messages): nothing is dropped.
RECORDER_DEPTH = 1000


class DemoError(RuntimeError):
    """A failure the demo reports in one line and exits 1 on."""


_T0 = time.monotonic()


def start_clock() -> None:
    """Count the seconds :func:`say` prints from now."""
    global _T0
    _T0 = time.monotonic()


def say(text: str) -> None:
    """Print a progress line at once, with the seconds since the demo started."""
    print(f'[demo {time.monotonic() - _T0:5.1f} s] {text}', flush=True)


@dataclass(frozen=True)
class Message:
    """
    One serialised message: topic, log time (ns), CDR bytes.

    An input's log time is when it reached the ROS graph (after its header stamp by its
    delivery latency); a recorded output's is its header stamp.
    """

    topic: str
    log_ns: int
    data: bytes


def read_bag(path: Path) -> tuple[list[Message], dict[str, str]]:
    """Return every message of a rosbag2 bag in log-time order, and its topics' types."""
    from vessel_kinematics.tools import bags

    raw, types = bags.raw_messages(path)
    messages = [Message(*m) for m in raw]
    messages.sort(key=lambda m: m.log_ns)
    return messages, types


def lead_limit(history_length: float, latency: float) -> float:
    """
    Return how far (s) the player may run ahead of the navigator: :data:`MAX_LEAD` at most.

    ``history_length`` (s): how far behind its newest input the navigator still fuses one at
    its own stamp (its parameter); ``latency`` (s): the longest delivery latency of the
    inputs (log time - stamp). The lead, the latency and :data:`HISTORY_MARGIN` must fit in
    the history; DemoError when not even :data:`MIN_LEAD` does (inputs too late for the
    navigator to use).
    """
    room = history_length - latency - HISTORY_MARGIN
    if room < MIN_LEAD:
        raise DemoError(f'inputs delivered up to {latency:g} s after their stamps do not fit '
                        f"in the navigator's history_length of {history_length:g} s (with a "
                        f'lead of {MIN_LEAD:g} s and {HISTORY_MARGIN:g} s to spare): raise '
                        'history_length or lower the latency')
    return min(MAX_LEAD, room)


def header_stamp_ns(data: bytes) -> int | None:
    """
    Return the header stamp (ns) of a CDR message whose first field is a std_msgs/Header.

    The 4-byte encapsulation header says the byte order; the stamp's int32 sec and uint32
    nanosec follow. None when the bytes are too short.
    """
    if len(data) < 12:
        return None
    order = '<' if data[1] == 1 else '>'
    sec, nanosec = struct.unpack_from(order + 'iI', data, 4)
    return frames.stamp_to_ns(sec, nanosec)


# --------------------------------------------------------------------------------------------
# The DDS side: a player of the inputs and /clock, and a recorder of the outputs


@dataclass
class Recording:
    """What the recorder received: messages per output topic (log time: header stamp)."""

    messages: list[Message] = field(default_factory=list)
    counts: dict[str, int] = field(default_factory=dict)
    last_odometry_ns: int = 0
    last_diagnostics: bytes | None = None
    diagnostics_received: int = 0
    processed: int = 0


class Bridge:
    """An rclpy node (own context) publishing inputs and /clock and recording the outputs."""

    def __init__(self, output_types: dict[str, str]) -> None:
        import rclpy
        from rclpy.executors import SingleThreadedExecutor
        from rosgraph_msgs.msg import Clock
        from vessel_kinematics.ros.node.qos import qos_profile

        self._rclpy = rclpy
        self.context = rclpy.Context()
        rclpy.init(context=self.context)
        self.node = rclpy.create_node('vessel_kinematics_demo', context=self.context)
        self.recording = Recording()
        self.sim_time_ns = 0
        self._lock = threading.Lock()
        # The interface's profiles, with a recorder's depth: nothing dropped while it writes.
        reliable = qos_profile(interface.QosProfile(depth=RECORDER_DEPTH))
        latched = qos_profile(interface.QosProfile(depth=10, transient_local=True))
        self.clock_msg = Clock()
        self.clock_pub = self.node.create_publisher(Clock, '/clock', 10)
        self.input_pubs = {topic: self.node.create_publisher(
            interface.message_class(msgtype), topic, reliable)
            for topic, msgtype in _input_types().items()}
        self.subscriptions = [
            self.node.create_subscription(
                interface.message_class(msgtype), topic, self._callback(topic),
                latched if interface.topic(topic).latched else reliable, raw=True)
            for topic, msgtype in output_types.items()]
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self._thread = threading.Thread(target=self._spin, daemon=True)
        self._thread.start()

    def _spin(self) -> None:
        from rclpy.executors import ExternalShutdownException
        try:
            self.executor.spin()
        except ExternalShutdownException:
            pass

    def _callback(self, topic: str) -> Any:
        recording = self.recording
        lock = self._lock

        def callback(data: bytes) -> None:
            stamp = header_stamp_ns(data) if topic not in TF_TOPICS else None
            if stamp is None:
                stamp = self.sim_time_ns
            with lock:
                recording.messages.append(Message(topic, stamp, data))
                recording.counts[topic] = recording.counts.get(topic, 0) + 1
                if topic == '/odometry':
                    recording.last_odometry_ns = max(recording.last_odometry_ns, stamp)
                elif topic == '/diagnostics':
                    recording.last_diagnostics = data
                    recording.diagnostics_received += 1
                    recording.processed = processed_count(diagnostics_values(data))
        return callback

    def publish_clock(self, stamp_ns: int) -> None:
        """Publish /clock = stamp_ns (sim time)."""
        self.sim_time_ns = stamp_ns
        sec, nanosec = frames.ns_to_stamp(stamp_ns)
        self.clock_msg.clock.sec = sec
        self.clock_msg.clock.nanosec = nanosec
        self.clock_pub.publish(self.clock_msg)

    def connected(self) -> bool:
        """Return whether the navigator subscribes to every input and /clock, and publishes."""
        if any(p.get_subscription_count() < 1 for p in self.input_pubs.values()):
            return False
        if self.clock_pub.get_subscription_count() < 1:
            return False
        return self.node.count_publishers('/odometry') >= 1 and all(
            s.get_publisher_count() >= 1 for s in self.subscriptions
            if s.topic_name == '/odometry')

    def close(self) -> None:
        """Stop spinning and shut the context down."""
        self.executor.shutdown(timeout_sec=1.0)
        self.node.destroy_node()
        self._rclpy.try_shutdown(context=self.context)
        self._thread.join(timeout=2.0)


def _input_types() -> dict[str, str]:
    from vessel_kinematics.tools.sim import TOPICS
    return {topic: TOPICS[topic] for topic in INPUT_TOPICS}


def tf_available() -> bool:
    try:
        import tf2_msgs.msg  # noqa: F401
    except ImportError:
        return False
    return True


# --------------------------------------------------------------------------------------------
# The navigator process


@dataclass(frozen=True)
class Installation:
    """The navigator executable and the package's share directory, from the ament index."""

    navigator: Path
    share: Path


class NavigatorProcess:
    """The installed navigator, started as ``ros2 run`` would, its output in a log file."""

    def __init__(self, installation: Installation, params_file: Path, log_path: Path) -> None:
        self.command = [str(installation.navigator), '--ros-args', '--params-file',
                        str(params_file), '-p', 'use_sim_time:=true']
        self.log_path = log_path
        self._log = open(log_path, 'wb')
        self.process = subprocess.Popen(self.command, stdout=self._log,
                                        stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                                        start_new_session=True)

    def alive(self) -> bool:
        """Return whether the node is still running."""
        return self.process.poll() is None

    def log_tail(self, lines: int = 15) -> str:
        """Return the last lines of the node's log."""
        if not self._log.closed:
            self._log.flush()
        try:
            text = self.log_path.read_text(errors='replace').splitlines()
        except OSError:
            return ''
        return '\n'.join('    ' + line for line in text[-lines:])

    def cpu_seconds(self) -> float:
        """Return the node's CPU time so far (user + system, s; NaN where /proc is absent)."""
        try:
            fields = Path(f'/proc/{self.process.pid}/stat').read_text().rsplit(')', 1)[1].split()
            return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')
        except (OSError, IndexError, ValueError):
            return math.nan

    def stop(self, timeout: float = 10.0) -> int:
        """Stop the node with SIGINT (then SIGTERM, SIGKILL); return its exit status."""
        if self.alive():
            self.process.send_signal(signal.SIGINT)
            try:
                self.process.wait(timeout)
            except subprocess.TimeoutExpired:
                self.process.terminate()
                try:
                    self.process.wait(3.0)
                except subprocess.TimeoutExpired:
                    self.process.kill()
                    self.process.wait()
        self._log.close()
        return self.process.returncode


# --------------------------------------------------------------------------------------------
# The run


@dataclass
class PlayStats:
    """Numbers of the live run."""

    published: dict[str, int]
    wall: float
    waits: float
    navigator_cpu: float = math.nan


def play(bridge: Bridge, inputs: Sequence[Message], rate: float,
         navigator: NavigatorProcess, publish_period: float,
         max_lead: float = MAX_LEAD) -> PlayStats:
    """
    Publish ``inputs`` with /clock at up to ``rate`` x real time, as fast as the node follows.

    Each input at its log time (its arrival on the vessel, after its header stamp by its
    delivery latency), in log-time order. /clock advances with the inputs in steps of one output
    period (at most :data:`CLOCK_STEP_NS`), published before the first message past each step.
    The player never runs more than ``max_lead`` s (:func:`lead_limit`) of sim time ahead of
    the last ``/odometry`` stamp it received (the node's state time; before the first, the
    first fix's log time: the node waits for its origin) while that is before the newest IMU
    stamp sent (the state goes no further): when it would, it waits, nudging
    /clock forward (at most :data:`NUDGE_LIMIT_NS` ahead) so that the node's ``publish_rate``
    timer fires and reports its progress, until the node's output catches up or its
    ``/diagnostics`` (1 Hz, steady clock) count every message sent as handled. A node slower
    than ``rate`` thus slows the demo down instead of dropping inputs from its queues. A node
    whose output stands still though it handled every message sent, or for :data:`MAX_WAIT` s
    (e.g. one refusing every fix, without an origin), is played on to at ``rate`` until its
    output moves again.
    """
    start_ns = inputs[0].log_ns
    end_ns = inputs[-1].log_ns
    duration = (end_ns - start_ns) * 1e-9
    # Before its first output the node waits for its first fix: that fix's arrival stands in.
    first_ns = max(start_ns, next((m.log_ns for m in inputs if m.topic == FIX_TOPIC), start_ns))
    published = dict.fromkeys(INPUT_TOPICS, 0)
    pubs = bridge.input_pubs
    recording = bridge.recording
    lead_ns = int(max_lead * 1e9)
    stalled_at: int | None = None   # the last /odometry stamp when a wait gave up
    newest_ns = 0   # the newest IMU stamp sent: the node's state does not go past it
    period_ns = max(int(publish_period * 1e9), 10_000_000)
    # /clock once per output period of sim time (not per message): fewer callbacks in the node.
    clock_step_ns = min(period_ns, CLOCK_STEP_NS)
    wall0 = time.monotonic()
    waited = 0.0
    next_report = 0.1

    def behind(log_ns: int) -> bool:
        # Ahead of the node's output by more than the lead, and the node has not output the
        # newest IMU stamp sent yet (a fix arriving after the last IMU message is not behind).
        odometry = recording.last_odometry_ns
        return log_ns - max(odometry, first_ns) > lead_ns and odometry < newest_ns

    for message in inputs:
        arrival = message.log_ns
        delay = wall0 + waited + (arrival - start_ns) * 1e-9 / rate - time.monotonic()
        if delay > 0.0:
            time.sleep(delay)
        if stalled_at is not None and recording.last_odometry_ns != stalled_at:
            stalled_at = None   # the node's output moves again: follow it again
        if stalled_at is None and behind(arrival):
            t_wait = time.monotonic()
            next_nudge = t_wait + 0.01
            sent = sum(published.values())
            while behind(arrival):
                now = time.monotonic()
                if recording.processed >= sent:
                    # /diagnostics: the node has handled everything sent: not behind, its
                    # output stands still (no origin yet): go on until it moves.
                    stalled_at = recording.last_odometry_ns
                    break
                if now - t_wait > MAX_WAIT:
                    if navigator.alive():
                        say(f'    the navigator is still behind after {MAX_WAIT:.0f} s: going '
                            'on until its output moves')
                    stalled_at = recording.last_odometry_ns
                    break
                if now >= next_nudge:
                    nudged = min(bridge.sim_time_ns + period_ns, arrival + NUDGE_LIMIT_NS)
                    if nudged > bridge.sim_time_ns:
                        bridge.publish_clock(nudged)
                    next_nudge = now + 0.01
                time.sleep(0.0005)
            waited += time.monotonic() - t_wait
        if arrival >= bridge.sim_time_ns + clock_step_ns or not any(published.values()):
            bridge.publish_clock(arrival)
        pubs[message.topic].publish(message.data)
        if message.topic == IMU_TOPIC:
            newest_ns = max(newest_ns, header_stamp_ns(message.data) or 0)
        published[message.topic] += 1
        progress = (arrival - start_ns) * 1e-9 / max(duration, 1e-9)
        if progress >= next_report - 1e-9:
            if not navigator.alive():
                raise DemoError('the navigator exited during the voyage; its log:\n'
                                + navigator.log_tail())
            # The node's state behind the newest IMU stamp sent (not the arrival of a late fix).
            lag = (newest_ns - recording.last_odometry_ns) * 1e-9 \
                if recording.last_odometry_ns else math.nan
            say(f'  {progress:4.0%}  sim {(arrival - start_ns) * 1e-9:6.1f} s  '
                f'wall {time.monotonic() - wall0:5.1f} s  navigator lag {lag:5.2f} s')
            next_report += 0.1
    # Let the node's publish_rate timer fire past the last input, then wait for its outputs, up
    # to the last IMU stamp (the last input to arrive, a late fix, is stamped before it).
    deadline = time.monotonic() + END_WAIT
    while time.monotonic() < deadline:
        if (recording.last_odometry_ns >= newest_ns
                and bridge.sim_time_ns >= end_ns + period_ns):
            break
        bridge.publish_clock(max(bridge.sim_time_ns, end_ns) + 10_000_000)
        time.sleep(0.01 / rate)
    # One more /diagnostics (1 Hz, steady clock) after the last input: the final counts.
    seen = recording.diagnostics_received
    deadline = time.monotonic() + DIAGNOSTICS_WAIT
    while recording.diagnostics_received == seen and time.monotonic() < deadline:
        time.sleep(0.05)
    return PlayStats(published=published, wall=time.monotonic() - wall0, waits=waited)


def diagnostics_values(data: bytes | None) -> dict[str, str]:
    """Return the key/values of the navigator's last DiagnosticArray (empty if none)."""
    if data is None:
        return {}
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.serialization import deserialize_message

    array = deserialize_message(data, DiagnosticArray)
    values: dict[str, str] = {}
    for status in array.status:
        values['message'] = status.message
        values.update({kv.key: kv.value for kv in status.values})
    return values


def processed_count(values: dict[str, str]) -> int:
    """Return how many inputs the node has handled (accepted and rejected), from diagnostics."""
    total = 0
    for key, value in values.items():
        if key.startswith('rejected ') or key in ('accepted fix', 'accepted imu',
                                                  'accepted velocity'):
            try:
                total += int(value)
            except ValueError:
                pass
    return total
