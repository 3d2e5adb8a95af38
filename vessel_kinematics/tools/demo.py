"""
The README's first command: the navigator, for real, on a simulated voyage with ground truth.

``python -m vessel_kinematics.tools.demo --output demo_out`` (what ``make demo`` runs, after
``source install/setup.bash``):

1. simulates a voyage with :mod:`vessel_kinematics.tools.sim` (inputs and truth in a bag);
2. starts the installed ``navigator`` exactly as ``ros2 run vessel_kinematics navigator`` would,
   found through the ament index, with ``--params-file <share>/config/demo.yaml -p
   use_sim_time:=true``;
3. publishes the voyage's ``/fix``, ``/imu`` and ``/velocity`` over DDS (reliable QoS) with a
   ``/clock`` running ``--rate`` times faster than real time, and records every output of the
   node (those of the interface table, :mod:`vessel_kinematics.ros.interface`, and
   ``/diagnostics``; ``/tf`` and ``/tf_static`` where tf2_msgs exists) as it arrives;
4. stops the node with SIGINT, writes one mcap bag with the inputs, the truth and the outputs;
5. scores the outputs against truth beside a dead-reckoning-only replay
   (:mod:`vessel_kinematics.tools.evaluate`), draws the figure
   (:mod:`vessel_kinematics.tools.plot`), and prints the paths of the bag, the PNG and the
   summary.

The DDS domain is the environment's ``ROS_DOMAIN_ID`` (the Makefile picks one per run). The exit
status is 0 on success and 1 with a one-line reason on failure (e.g. the navigator is not
installed: run ``make build`` first).
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass, field
import math
import os
from pathlib import Path
import shutil
import signal
import struct
import subprocess
import sys
import threading
import time
from typing import Any, Sequence

from vessel_kinematics.core import frames
from vessel_kinematics.ros import interface

__all__ = ['Bridge', 'CLOCK_STEP_NS', 'DemoError', 'diagnostics_values', 'ESTIMATES',
           'find_installation', 'header_stamp_ns', 'INPUT_TOPICS', 'Installation', 'main',
           'MAX_LEAD', 'MAX_WAIT', 'Message', 'NavigatorProcess', 'NUDGE_LIMIT_NS',
           'OUTPUT_TOPICS', 'PACKAGE', 'play', 'PlayStats', 'processed_count', 'read_bag',
           'Recording', 'run', 'say', 'TF_TOPICS', 'VOYAGE_ERRORS', 'write_run_bag']

PACKAGE = 'vessel_kinematics'
#: The navigator's inputs in the voyage bag (the node's relative names in the root namespace).
INPUT_TOPICS = tuple(t.absolute for t in interface.by_role(interface.Role.INPUT))
#: The demo voyage's sensor errors: a speed log (surge only, through the water) reading 10 %
#: low and a 3 deg leeway, which the navigator estimates with the current (sim.VoyageConfig).
VOYAGE_ERRORS: dict[str, Any] = {'log_scale': 0.9, 'log_surge_only': True,
                                 'leeway': math.radians(3.0)}
#: The /diagnostics values the demo's summary quotes.
ESTIMATES = ('log scale', 'leeway (deg)', 'turn drift (m/rad)', 'current set (deg)',
             'current drift (kn)')
#: Recorded too when tf2_msgs is importable (it is not in the PyPI wheels).
TF_TOPICS: dict[str, str] = {
    t.absolute: t.msg_type for t in interface.by_role(interface.Role.AUXILIARY)
    if t.msg_type is not None and t.qos in (interface.Qos.TF, interface.Qos.TF_STATIC)}
#: Every other output of the navigator the demo records, with its type (as the replay writes).
OUTPUT_TOPICS: dict[str, str] = {
    topic: msg_type for topic, msg_type in interface.types(
        interface.Role.OUTPUT, interface.Role.AUXILIARY).items() if topic not in TF_TOPICS}
#: How far (s of sim time) the player may run ahead of the navigator's latest output: below the
#: ``reorder_window`` of config/demo.yaml (0.25 s), so that messages of different topics taken
#: from their queues out of stamp order are still used, and below the node's input queue depth
#: (20 messages: 0.2 s of the 100 Hz IMU), so that none is dropped.
MAX_LEAD = 0.18
#: The longest step of /clock between two publications (ns of sim time).
CLOCK_STEP_NS = 50_000_000
#: How far ahead of the inputs /clock may be nudged while waiting for the node (ns).
NUDGE_LIMIT_NS = 200_000_000
#: Give up waiting for the navigator to catch up after this long (s of wall time).
MAX_WAIT = 5.0


class DemoError(RuntimeError):
    """A failure the demo reports in one line and exits 1 on."""


_T0 = time.monotonic()


def say(text: str) -> None:
    """Print a progress line at once, with the seconds since the demo started."""
    print(f'[demo {time.monotonic() - _T0:5.1f} s] {text}', flush=True)


# --------------------------------------------------------------------------------------------
# Locating the installed navigator


@dataclass(frozen=True)
class Installation:
    """The navigator executable and the package's share directory, from the ament index."""

    navigator: Path
    share: Path


def find_installation() -> Installation:
    """Return the installed navigator as ``ros2 run`` finds it, or raise DemoError."""
    hint = 'run `make build` first (or `source install/setup.bash` in this shell)'
    try:
        from ament_index_python.packages import (get_package_prefix,
                                                 get_package_share_directory,
                                                 PackageNotFoundError)
    except ImportError as error:
        raise DemoError(f'ament_index_python is not importable ({error}): {hint}') from error
    try:
        prefix = Path(get_package_prefix(PACKAGE))
        share = Path(get_package_share_directory(PACKAGE))
    except PackageNotFoundError as error:
        raise DemoError(f'the {PACKAGE} package is not installed in AMENT_PREFIX_PATH='
                        f'{os.environ.get("AMENT_PREFIX_PATH", "")!r}: {hint}') from error
    navigator = prefix / 'lib' / PACKAGE / 'navigator'
    if not os.access(navigator, os.X_OK):
        raise DemoError(f'{navigator} is missing or not executable: {hint}')
    return Installation(navigator=navigator, share=share)


# --------------------------------------------------------------------------------------------
# The voyage's messages


@dataclass(frozen=True)
class Message:
    """One serialised message: topic, log time = header stamp (ns), CDR bytes."""

    topic: str
    stamp_ns: int
    data: bytes


def read_bag(path: Path) -> tuple[list[Message], dict[str, str]]:
    """Return every message of a rosbag2 bag in log-time order, and its topics' types."""
    from vessel_kinematics.tools import bags

    raw, types = bags.raw_messages(path)
    messages = [Message(*m) for m in raw]
    messages.sort(key=lambda m: m.stamp_ns)
    return messages, types


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
    """What the recorder received: messages per output topic (log time = header stamp)."""

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
        from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
        from rosgraph_msgs.msg import Clock

        self._rclpy = rclpy
        self.context = rclpy.Context()
        rclpy.init(context=self.context)
        self.node = rclpy.create_node('vessel_kinematics_demo', context=self.context)
        self.recording = Recording()
        self.sim_time_ns = 0
        self._lock = threading.Lock()
        reliable = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1000,
                              reliability=ReliabilityPolicy.RELIABLE,
                              durability=DurabilityPolicy.VOLATILE)
        latched = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=10,
                             reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self.clock_msg = Clock()
        self.clock_pub = self.node.create_publisher(Clock, '/clock', 10)
        self.input_pubs = {topic: self.node.create_publisher(_msg_class(msgtype), topic, reliable)
                           for topic, msgtype in _input_types().items()}
        self.subscriptions = [
            self.node.create_subscription(
                _msg_class(msgtype), topic, self._callback(topic),
                latched if topic in ('/origin', '/tf_static') else reliable, raw=True)
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


def _msg_class(msgtype: str) -> type:
    """Return the rclpy message class of 'pkg/msg/Name'."""
    import importlib

    package, _, name = msgtype.split('/')
    return getattr(importlib.import_module(f'{package}.msg'), name)


def _tf_available() -> bool:
    try:
        import tf2_msgs.msg  # noqa: F401
    except ImportError:
        return False
    return True


# --------------------------------------------------------------------------------------------
# The navigator process


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
         navigator: NavigatorProcess, publish_period: float) -> PlayStats:
    """
    Publish ``inputs`` with /clock at up to ``rate`` x real time, as fast as the node follows.

    /clock advances with the inputs in steps of one output period (at most
    :data:`CLOCK_STEP_NS`), published before the first message past each step. The player
    never runs more than :data:`MAX_LEAD` s of sim time ahead of the last ``/odometry`` stamp
    it received (the node's state time): when it would, it waits, nudging /clock forward (at
    most :data:`NUDGE_LIMIT_NS` ahead) so that the node's ``publish_rate`` timer fires and
    reports its progress, until the node's output catches up or its ``/diagnostics`` (1 Hz,
    steady clock) count every message sent as handled. A node slower than ``rate`` thus slows
    the demo down instead of dropping inputs from its queues.
    """
    start_ns = inputs[0].stamp_ns
    end_ns = inputs[-1].stamp_ns
    duration = (end_ns - start_ns) * 1e-9
    published = dict.fromkeys(INPUT_TOPICS, 0)
    pubs = bridge.input_pubs
    recording = bridge.recording
    lead_ns = int(MAX_LEAD * 1e9)
    period_ns = max(int(publish_period * 1e9), 10_000_000)
    # /clock once per output period of sim time (not per message): fewer callbacks in the node.
    clock_step_ns = min(period_ns, CLOCK_STEP_NS)
    wall0 = time.monotonic()
    waited = 0.0
    next_report = 0.1
    for message in inputs:
        stamp = message.stamp_ns
        delay = wall0 + waited + (stamp - start_ns) * 1e-9 / rate - time.monotonic()
        if delay > 0.0:
            time.sleep(delay)
        # Before the first output (the node waits for its origin) the first stamp stands in.
        if stamp - max(recording.last_odometry_ns, start_ns) > lead_ns:
            t_wait = time.monotonic()
            next_nudge = t_wait + 0.01
            sent = sum(published.values())
            while stamp - max(recording.last_odometry_ns, start_ns) > lead_ns:
                now = time.monotonic()
                if recording.processed >= sent:
                    break   # /diagnostics: the node has handled everything sent: not behind
                if now - t_wait > MAX_WAIT:
                    if navigator.alive():
                        say(f'    the navigator is still behind after {MAX_WAIT:.0f} s: going on')
                    break
                if now >= next_nudge:
                    nudged = min(bridge.sim_time_ns + period_ns, stamp + NUDGE_LIMIT_NS)
                    if nudged > bridge.sim_time_ns:
                        bridge.publish_clock(nudged)
                    next_nudge = now + 0.01
                time.sleep(0.0005)
            waited += time.monotonic() - t_wait
        if stamp >= bridge.sim_time_ns + clock_step_ns:
            bridge.publish_clock(stamp)
        pubs[message.topic].publish(message.data)
        published[message.topic] += 1
        progress = (stamp - start_ns) * 1e-9 / max(duration, 1e-9)
        if progress >= next_report - 1e-9:
            if not navigator.alive():
                raise DemoError('the navigator exited during the voyage; its log:\n'
                                + navigator.log_tail())
            lag = (stamp - recording.last_odometry_ns) * 1e-9 if recording.last_odometry_ns \
                else math.nan
            say(f'  {progress:4.0%}  sim {(stamp - start_ns) * 1e-9:6.1f} s  '
                f'wall {time.monotonic() - wall0:5.1f} s  navigator lag {lag:5.2f} s')
            next_report += 0.1
    # Let the node's publish_rate timer fire past the last input, then wait for its outputs.
    deadline = time.monotonic() + 10.0
    while time.monotonic() < deadline:
        if recording.last_odometry_ns >= end_ns and bridge.sim_time_ns >= end_ns + period_ns:
            break
        bridge.publish_clock(max(bridge.sim_time_ns, end_ns) + 10_000_000)
        time.sleep(0.01 / rate)
    # One more /diagnostics (1 Hz, steady clock) after the last input: the final counts.
    seen = recording.diagnostics_received
    deadline = time.monotonic() + 3.0
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


def write_run_bag(path: Path, messages: Sequence[Message], types: dict[str, str]) -> Path:
    """
    Write all messages (sorted by log time) to a new rosbag2 mcap bag.

    Each connection offers the interface table's QoS (latched ``/origin``, ``/truth/origin``
    and ``/tf_static``: transient-local, keep last 1), as the replay's output does.
    """
    from vessel_kinematics.tools import bags

    ordered = sorted(messages, key=lambda m: m.stamp_ns)
    present = {m.topic for m in ordered}
    return bags.write_bag(path, ((m.topic, m.stamp_ns, m.data) for m in ordered),
                          {t: ty for t, ty in types.items() if t in present})


def run(args: argparse.Namespace) -> dict[str, Any]:
    """Run the whole demo; return the paths and numbers (raises DemoError on failure)."""
    from vessel_kinematics.ros.params import load_params_file, NavigatorParams, ParameterError
    from vessel_kinematics.tools import plot, replay, sim

    global _T0
    _T0 = t_start = time.monotonic()
    installation = find_installation()
    params_file = args.params_file or installation.share / 'config' / 'demo.yaml'
    try:
        params = NavigatorParams.from_flat(load_params_file(params_file))
    except ParameterError as error:
        raise DemoError(str(error)) from error
    out = Path(args.output)
    out.mkdir(parents=True, exist_ok=True)
    voyage_bag = out / 'voyage'
    run_bag = out / 'navigator_run'
    png = out / 'demo_voyage.png'
    summary_path = out / 'summary.txt'
    log_path = out / 'navigator.log'
    for stale in (voyage_bag, run_bag):
        if stale.exists():
            shutil.rmtree(stale)
    domain = os.environ.get('ROS_DOMAIN_ID', '0')
    say(f'navigator: {installation.navigator}')
    say(f'parameters: {params_file}; DDS domain {domain}')

    say(f'1/5 simulating a {args.duration:.0f} s voyage (seed {args.seed}) -> {voyage_bag}')
    config = sim.VoyageConfig(duration=args.duration, seed=args.seed,
                              reference=params.velocity_reference, **VOYAGE_ERRORS)
    voyage = sim.generate(voyage_bag, config)
    messages, types = read_bag(voyage_bag)
    inputs = [m for m in messages if m.topic in INPUT_TOPICS]
    counts = ', '.join(f'{t} {n}' for t, n in voyage['messages'].items())
    say(f'    {voyage["distance"]:.0f} m over ground; {counts}')

    output_types = dict(OUTPUT_TOPICS)
    if _tf_available():
        output_types.update(TF_TOPICS)
    say('2/5 starting the navigator (use_sim_time) and connecting over DDS')
    bridge = Bridge(output_types)
    navigator = NavigatorProcess(installation, params_file, log_path)
    return_code = None
    try:
        bridge.publish_clock(inputs[0].stamp_ns)
        deadline = time.monotonic() + args.connect_timeout
        while not bridge.connected():
            if not navigator.alive():
                raise DemoError('the navigator exited at start-up; its log:\n'
                                + navigator.log_tail())
            if time.monotonic() > deadline:
                raise DemoError(f'the navigator did not connect within {args.connect_timeout} '
                                f's (DDS domain {domain}); its log:\n' + navigator.log_tail())
            bridge.publish_clock(inputs[0].stamp_ns)
            time.sleep(0.1)
        time.sleep(0.3)
        say(f'3/5 publishing {len(inputs)} messages with /clock at {args.rate:g}x real time')
        period = 1.0 / params.publish_rate if params.publish_rate > 0 else 0.0
        stats = play(bridge, inputs, args.rate, navigator, period)
        stats.navigator_cpu = navigator.cpu_seconds()
    finally:
        return_code = navigator.stop()
        bridge.close()
    if return_code != 0:
        say(f'    warning: the navigator exited with status {return_code} on SIGINT')
    recording = bridge.recording
    if not recording.counts.get('/odometry'):
        raise DemoError('no /odometry received from the navigator; its log:\n'
                        + navigator.log_tail())
    diag = diagnostics_values(recording.last_diagnostics)
    say(f'    played in {stats.wall:.1f} s wall; navigator stopped (exit {return_code}); '
        f'outputs: ' + ', '.join(f'{t} {n}' for t, n in sorted(recording.counts.items())))

    say(f'4/5 writing {run_bag}')
    write_run_bag(run_bag, messages + recording.messages, {**types, **output_types})

    say('5/5 scoring against truth (and a dead-reckoning-only replay) and plotting')
    text, fused_run, dr_run = replay.accuracy_report(run_bag, params)
    title = (f'vessel_kinematics navigator (live over DDS, {args.rate:g}x) on a simulated '
             f'{args.duration:.0f} s voyage')
    plot.plot(fused_run, png, dead_reckoning=dr_run, title=title)

    accepted = {name: diag.get(f'accepted {name}', '?') for name in ('fix', 'imu', 'velocity')}
    rejected = {k[len('rejected '):]: v for k, v in diag.items() if k.startswith('rejected ')}
    lines = [
        f'vessel_kinematics demo: {args.duration:.0f} s simulated voyage (seed {args.seed}, '
        f'speed log through the water reading {config.log_scale:g} x, leeway '
        f'{math.degrees(config.leeway):g} deg, GNSS outage '
        + ('{:.0f}-{:.0f} s'.format(*voyage['outage']) if voyage['outage'] else 'none') + ')',
        f'  navigator    {installation.navigator} (live, use_sim_time, /clock at '
        f'{args.rate:g}x: {stats.wall:.1f} s wall, node CPU {stats.navigator_cpu:.1f} s)',
        '  published    ' + ', '.join(f'{t} {n}' for t, n in stats.published.items()),
        '  accepted     ' + ', '.join(f'{k} {v}' for k, v in accepted.items())
        + ('; rejected ' + ', '.join(f'{k} {v}' for k, v in rejected.items())
           if rejected else ''),
        '  outputs      ' + ', '.join(f'{t} {n}' for t, n in sorted(recording.counts.items())),
        f'  final mode   {diag.get("mode", "?")}',
        '  estimated    ' + ', '.join(f'{k} {diag[k]}' for k in ESTIMATES if k in diag)
        + f' (truth: log scale {config.log_scale:g}, leeway {math.degrees(config.leeway):g} deg)',
        '',
        text,
        '',
        '  dead reckoning = the same inputs replayed with gnss.enabled: false (the first fix only '
        'sets the origin)' + (';\n  a log through the water cannot observe the current, '
                              'so it drifts with it' if config.reference == 'water' else ''),
    ]
    summary = '\n'.join(lines) + '\n'
    summary_path.write_text(summary)
    return {'bag': run_bag, 'png': png, 'summary': summary_path, 'text': summary,
            'voyage': voyage_bag, 'log': log_path, 'seconds': time.monotonic() - t_start}


def _parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        prog='python -m vessel_kinematics.tools.demo',
        description='Simulate a voyage, run the installed navigator on it over DDS at an '
                    'accelerated /clock, record its outputs, score them against truth and '
                    'plot them. Needs `source install/setup.bash` (make demo does it).')
    parser.add_argument('--output', type=Path, default=Path('demo_out'),
                        help='directory for the bags, the figure and the summary '
                             '(default %(default)s)')
    parser.add_argument('--duration', type=float, default=300.0,
                        help='voyage length in s of sim time (default %(default)s)')
    parser.add_argument('--seed', type=int, default=1, help='simulation seed (default 1)')
    parser.add_argument('--rate', type=float, default=10.0,
                        help='speed of the /clock relative to real time (default %(default)s)')
    parser.add_argument('--params-file', type=Path, default=None,
                        help='navigator parameters (default: the installed config/demo.yaml)')
    parser.add_argument('--connect-timeout', type=float, default=30.0,
                        help='seconds to wait for the navigator on DDS (default %(default)s)')
    args = parser.parse_args(argv)
    if not 0.1 <= args.rate <= 100.0:
        parser.error(f'--rate must be between 0.1 and 100, got {args.rate}')
    if not 1.0 <= args.duration <= 3600.0:
        parser.error(f'--duration must be between 1 and 3600 s, got {args.duration}')
    return args


def _terminate(signum: int, frame: Any) -> None:
    raise KeyboardInterrupt(f'signal {signum}')


def main(argv: Sequence[str] | None = None) -> int:
    """Run the demo; print the paths of the bag, the figure and the summary; return 0 or 1."""
    args = _parse_args(argv)
    # SIGTERM (e.g. timeout) stops the navigator as Ctrl-C does: it runs in its own session.
    signal.signal(signal.SIGTERM, _terminate)
    try:
        result = run(args)
    except DemoError as error:
        print(f'[demo] error: {error}', file=sys.stderr, flush=True)
        return 1
    except KeyboardInterrupt:
        print('[demo] interrupted', file=sys.stderr, flush=True)
        return 130
    print()
    print(result['text'])
    say(f'done in {result["seconds"]:.0f} s')
    print(f'  bag:     {result["bag"]}')
    print(f'  plot:    {result["png"]}')
    print(f'  summary: {result["summary"]}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
