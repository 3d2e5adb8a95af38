"""
Benchmark of the navigator node over DDS (prints numbers, asserts nothing).

1. Throughput: a publisher floods ``imu`` (best effort, stamps 2.5 ms apart) for a few seconds;
   the IMU messages per second the installed navigator accepts (from its ``/diagnostics``
   counts) against those a bare rclpy subscriber (same QoS, same executor, empty callback)
   receives from the same flood on the same machine in the same run; their ratio.
2. Latency: 400 Hz IMU + 10 Hz fix + 20 Hz velocity published in real time; the time from each
   message's publish to the arrival of the ``odometry`` with the same header stamp, p50/p99,
   for the navigator, for a bare echo node (subscribes, publishes an Odometry with the same
   stamp for every input) and for a bare echo node answering only the inputs the navigator
   answers at 30 Hz (those whose stamp crosses a period): the differences are the navigator's
   own share, and the second one isolates it from what answering 30 of 430 messages a second
   costs the transport. Each is split by the odometry's DDS timestamps (source and
   received, from the message info) into the answering side (input publish -> the answer
   written), the answer's transit and this process's dispatch.
   ``--latency-only`` runs this part alone; ``--repeat N`` (3) runs N rounds of the three,
   one after the other in each round, prints each round's p99 differences and pools them.
3. CPU: 400 Hz IMU + 20 Hz velocity + 10 Hz fix published in real time for a few seconds,
   every output (and /tf where tf2 is installed) subscribed; the CPU time (user + system,
   /proc) of the navigator process over the stream against a bare rclpy subscriber to the
   same three inputs on the same executor (empty callbacks), fed the same stream; their
   ratio, at the default parameters (``publish_rate`` 30 Hz), with outputs on every update
   (0), and at the defaults with every fix delivered :data:`FIX_DELAY` s after its stamp (a
   GNSS receiver's latency: each is fused at its stamp by re-applying the history). For
   scale, each round also measures the bare subscriber on rclpy's default
   SingleThreadedExecutor (``rclpy.spin``) and prints the navigator's ratio to it.
   ``--repeat N`` rounds of the four, one after the other in each round (the machine may be
   shared: each ratio is of neighbours in time), each round's ratios and their range.
   ``--cpu-only`` runs this part alone.

Run: ``python bench/bench_navigator.py`` with the package built (``make bench``); it uses
VK_INSTALL or the sourced install, else builds one into a temporary directory. The bench needs
only the installed ``navigator`` executable and the interface table, so VK_INSTALL may point at
another version's install for a before/after comparison.
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path
import signal
import subprocess
import sys
import tempfile
import time
from typing import Any

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
sys.path.insert(0, str(REPO / 'test'))
sys.path.append(str(REPO))
os.environ.setdefault('ROS_DOMAIN_ID', str(10 + os.getpid() % 90))
os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
os.environ.setdefault('RMW_IMPLEMENTATION', 'rmw_fastrtps_cpp')

import dds_harness  # noqa: E402
from geometry_msgs.msg import TwistWithCovarianceStamped  # noqa: E402
import numpy as np  # noqa: E402
import rclpy  # noqa: E402
from rclpy.qos import qos_profile_sensor_data, QoSProfile, ReliabilityPolicy  # noqa: E402
from sensor_msgs.msg import Imu, NavSatFix  # noqa: E402
from vessel_kinematics.ros import interface  # noqa: E402

#: The navigator's default input QoS (sensor_data: best effort, depth 20).
INPUT_QOS = QoSProfile(depth=20, reliability=ReliabilityPolicy.BEST_EFFORT)

ORIGIN = [63.4389, 10.3994, 40.0]
T0 = 1000.0
FLOOD_SECONDS = 4.0
LATENCY_SECONDS = 20.0   # about 480 emissions: a p99 of the 5th largest, not the 2nd
CPU_SECONDS = 10.0
#: The late fixes' delivery latency in the CPU comparison (s).
FIX_DELAY = 0.3


# --- helper processes (this file run with --role) ---------------------------------------------

def make_executor(kind: str) -> Any:
    """Return the navigator's executor: the EventsExecutor, or ``single``-threaded."""
    if kind != 'single':
        from rclpy.experimental import EventsExecutor
        return EventsExecutor()
    return rclpy.executors.SingleThreadedExecutor()


def _spin_until_shutdown(node: Any) -> None:
    """Spin ``node`` on the navigator's choice of executor until SIGINT/SIGTERM."""
    executor = make_executor(os.environ.get('VK_NAVIGATOR_EXECUTOR', 'events'))
    executor.add_node(node)
    try:
        while rclpy.ok():
            executor.spin_once(timeout_sec=0.2)
    except (KeyboardInterrupt, rclpy.executors.ExternalShutdownException):
        pass


def _role_flood(seconds: float) -> None:
    """Publish IMU messages as fast as possible for ``seconds``; print how many."""
    rclpy.init()
    node = rclpy.create_node('vk_bench_flood')
    publisher = node.create_publisher(Imu, 'imu', qos_profile_sensor_data)
    time.sleep(1.0)                      # discovery
    msg = dds_harness.make_imu(T0, (0.0, 0.0, 0.7071067811865476, 0.7071067811865476))
    sent, end, t = 0, time.monotonic() + seconds, T0
    while time.monotonic() < end:
        t += 0.0025
        msg.header.stamp = dds_harness.stamp(t)
        publisher.publish(msg)
        sent += 1
    print(f'sent {sent} {sent / seconds:.0f}', flush=True)
    node.destroy_node()
    rclpy.try_shutdown()


def _role_bare_subscriber(executor_kind: str) -> None:
    """Count IMU messages until SIGINT; print count and the span first..last (s)."""
    os.environ['VK_NAVIGATOR_EXECUTOR'] = executor_kind
    rclpy.init()
    node = rclpy.create_node('vk_bench_bare')
    times: list[float] = []
    # The navigator's default input QoS (sensor_data: best effort, depth 20).
    node.create_subscription(Imu, 'imu', lambda msg: times.append(time.monotonic()),
                             INPUT_QOS)
    _spin_until_shutdown(node)
    span = times[-1] - times[0] if len(times) > 1 else 0.0
    print(f'received {len(times)} {span:.6f}', flush=True)
    node.destroy_node()
    rclpy.try_shutdown()


def _role_bare_inputs(executor_kind: str) -> None:
    """Subscribe to fix, imu and velocity as the navigator does (empty callbacks), until SIGINT."""
    os.environ['VK_NAVIGATOR_EXECUTOR'] = executor_kind
    rclpy.init()
    node = rclpy.create_node('vk_bench_bare_inputs')
    counts = {'fix': 0, 'imu': 0, 'velocity': 0}

    def count(topic: str) -> Any:
        def callback(msg: Any) -> None:
            counts[topic] += 1
        return callback
    for topic, msg_type in (('fix', NavSatFix), ('imu', Imu),
                            ('velocity', TwistWithCovarianceStamped)):
        node.create_subscription(msg_type, topic, count(topic), INPUT_QOS)
    _spin_until_shutdown(node)
    print('received', counts['fix'], counts['imu'], counts['velocity'], flush=True)
    node.destroy_node()
    rclpy.try_shutdown()


def _role_echo(rate: float = 0.0) -> None:
    """
    Republish fix/imu/velocity as an Odometry with the same stamp, until SIGINT.

    ``rate`` > 0: answer only the inputs whose stamp crosses a period of ``rate`` Hz, as the
    navigator's pipeline does (the same inputs as the navigator's ``odometry``).
    """
    from nav_msgs.msg import Odometry
    rclpy.init()
    node = rclpy.create_node('vk_bench_echo')
    publisher = node.create_publisher(Odometry, 'odometry', 10)
    qos = QoSProfile(depth=20)
    period = int(1e9 / rate) if rate > 0.0 else 0
    due = [0]

    def echo(msg: Any) -> None:
        if period:
            stamp = msg.header.stamp.sec * 10 ** 9 + msg.header.stamp.nanosec
            if stamp < due[0]:
                return
            due[0] = (stamp // period + 1) * period
        out = Odometry()
        out.header = msg.header
        publisher.publish(out)
    for topic, msg_type in (('fix', NavSatFix), ('imu', Imu),
                            ('velocity', TwistWithCovarianceStamped)):
        node.create_subscription(msg_type, topic, echo, qos)
    _spin_until_shutdown(node)
    node.destroy_node()
    rclpy.try_shutdown()


def _self(role: str, *args: str) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, __file__, '--role', role, *args],
                            stdout=subprocess.PIPE, text=True)


def _stop(process: subprocess.Popen) -> str:
    if process.poll() is None:
        process.send_signal(signal.SIGINT)
    try:
        out, _ = process.communicate(timeout=10)
    except subprocess.TimeoutExpired:
        process.kill()
        out, _ = process.communicate()
    return out or ''


# --- the measurements -------------------------------------------------------------------------

def _navigator(env: dict[str, str], log: Path, **params: Any) -> dds_harness.NodeProcess:
    executable = dds_harness.resolve_executable(env, 'navigator')
    args = dds_harness.ros_args({'origin': ORIGIN, **params})
    return dds_harness.NodeProcess(executable, args, env, log)


def bare_throughput(executor_kind: str) -> float:
    """Return the IMU messages/s a bare rclpy subscriber receives from a flood."""
    bare = _self('bare-subscriber', '--executor', executor_kind)
    time.sleep(1.5)
    flood = _self('flood', str(FLOOD_SECONDS))
    flood_out = flood.communicate(timeout=FLOOD_SECONDS + 60)[0]
    count, span = _stop(bare).split()[1:3]
    print(f'  flood publisher: {flood_out.split()[2]} msg/s for {FLOOD_SECONDS} s; bare '
          f'subscriber ({executor_kind} executor) received {count} in {float(span):.2f} s')
    return int(count) / FLOOD_SECONDS


def throughput(env: dict[str, str], workdir: Path) -> tuple[float, float]:
    """Return (navigator, bare) IMU messages/s under a flood."""
    from diagnostic_msgs.msg import DiagnosticArray
    from nav_msgs.msg import Odometry

    bare_rate = bare_throughput(os.environ.get('VK_NAVIGATOR_EXECUTOR', 'events'))

    # Navigator (a fix first so that every IMU message produces the full outputs).
    tester = dds_harness.DdsTester('vk_bench')
    process = _navigator(env, workdir / 'throughput.log')
    try:
        diagnostics = tester.collect('/diagnostics', DiagnosticArray)
        # A consumer of odometry, as an autopilot would be (unsubscribed outputs are skipped).
        tester.collect('odometry', Odometry, QoSProfile(depth=10))
        tester.wait_for_node('navigator', process)
        tester.publisher('fix', NavSatFix)
        tester.wait_for_match(['fix', 'odometry'])
        # Several fixes: a best-effort reader may miss the first message after discovery.
        for k in range(5):
            tester.publish('fix', dds_harness.make_fix(T0 - 0.5 + 0.1 * k, *ORIGIN))
            tester.spin_for(0.1)

        def accepted() -> int:
            count = len(diagnostics)
            tester.spin_until(lambda: len(diagnostics) > count, 10.0)
            values = dds_harness.diagnostic_values(diagnostics[-1])
            print(f'  navigator: mode {values.get("mode")}, accepted imu '
                  f'{values.get("accepted imu")}')
            return int(values.get('accepted imu', 0))
        before = accepted()
        flood = _self('flood', str(FLOOD_SECONDS))
        while flood.poll() is None:
            tester.spin_for(0.05)
        flood.communicate(timeout=10)
        tester.spin_for(1.0)                 # the queue drains
        # /diagnostics may come late under the flood (its timer waits behind the messages),
        # so the rate is the count over the flood's duration, as for the bare subscriber.
        nav_rate = (accepted() - before) / FLOOD_SECONDS
    finally:
        process.stop()
        tester.close()
    return nav_rate, bare_rate


def latency(env: dict[str, str], workdir: Path, echo: bool,
            rate: float = 0.0) -> dict[str, np.ndarray]:
    """
    Return publish-to-odometry latencies (s) at 400/10/20 Hz (echo: answering at ``rate``).

    ``'total'``: from the input's publish to the odometry's callback here; split by the
    odometry's DDS timestamps (the message info's, CLOCK_REALTIME in every process) into
    ``'answer'`` (input publish -> the answer written: the input's transport, the answering
    node's dispatch and work), ``'transit'`` (written -> received here) and ``'dispatch'``
    (received -> the callback here).
    """
    from nav_msgs.msg import Odometry
    tester = dds_harness.DdsTester('vk_bench')
    process = None
    helper = None
    received: list[tuple[int, float, int, int, int]] = []

    def store(msg: Any, info: Any) -> None:
        received.append((msg.header.stamp.sec * 10 ** 9 + msg.header.stamp.nanosec,
                         time.monotonic(), time.time_ns(), info['source_timestamp'],
                         info['received_timestamp']))
    try:
        tester.node.create_subscription(Odometry, 'odometry', store, QoSProfile(depth=100))
        if echo:
            helper = _self('echo', '--rate', str(rate))
            tester.spin_until(lambda: 'vk_bench_echo' in tester.node.get_node_names(), 15.0)
        else:
            process = _navigator(env, workdir / 'latency.log', sensor_qos='reliable')
            tester.wait_for_node('navigator', process)
        qos = QoSProfile(depth=20)
        for topic, msg_type in (('fix', NavSatFix), ('imu', Imu),
                                ('velocity', TwistWithCovarianceStamped)):
            tester.publisher(topic, msg_type, qos)
        tester.wait_for_match(['fix', 'imu', 'velocity', 'odometry'])
        events = _schedule(LATENCY_SECONDS)
        sent: dict[int, tuple[float, int]] = {}
        start = time.monotonic() + 0.2
        for due, topic, msg in events:
            while True:
                left = start + due - time.monotonic()
                if left <= 0:
                    break
                tester.executor.spin_once(timeout_sec=min(left, 0.001))
            tester.publisher(topic, type(msg)).publish(msg)
            sent[msg.header.stamp.sec * 10 ** 9 + msg.header.stamp.nanosec] = (
                time.monotonic(), time.time_ns())
        tester.spin_for(0.5)
        rows = []
        for key, arrived, arrived_ns, source_ns, received_ns in received:
            if key in sent:
                sent_at, sent_ns = sent.pop(key)
                rows.append((arrived - sent_at, (source_ns - sent_ns) * 1e-9,
                             (received_ns - source_ns) * 1e-9, (arrived_ns - received_ns) * 1e-9))
        print(f'  {"echo" if echo else "navigator"}: {len(rows)} of {len(events)} '
              f'messages matched')
        parts = np.array(rows[50:]).reshape(-1, 4)   # skip the start-up (first fix, warm-up)
        return dict(zip(('total', 'answer', 'transit', 'dispatch'), parts.T))
    finally:
        if process is not None:
            process.stop()
        if helper is not None:
            _stop(helper)
        tester.close()


def _cpu_seconds(pid: int) -> float:
    """Return the CPU time (user + system, s) the process ``pid`` has used so far."""
    fields = Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')


def _stream(tester: Any, seconds: float, fix_delay: float = 0.0) -> None:
    """Publish 400 Hz IMU + 20 Hz velocity + 10 Hz fix (``fix_delay`` s late) in real time."""
    for topic, msg_type in (('fix', NavSatFix), ('imu', Imu),
                            ('velocity', TwistWithCovarianceStamped)):
        tester.publisher(topic, msg_type, qos_profile_sensor_data)
    start = time.monotonic() + 0.2
    for due, topic, msg in _schedule(seconds, fix_delay=fix_delay):
        while True:
            left = start + due - time.monotonic()
            if left <= 0:
                break
            tester.executor.spin_once(timeout_sec=min(left, 0.001))
        tester.publisher(topic, type(msg)).publish(msg)


def _bare_cpu(executor_kind: str, seconds: float) -> float:
    """Return the CPU time (s) of a bare subscriber to the three inputs over the stream."""
    tester = dds_harness.DdsTester('vk_bench')
    bare = _self('bare-inputs', '--executor', executor_kind)
    try:
        tester.spin_until(lambda: 'vk_bench_bare_inputs' in tester.node.get_node_names(), 15.0)
        tester.spin_for(1.0)
        before = _cpu_seconds(bare.pid)
        _stream(tester, seconds)
        tester.spin_for(0.2)
        return _cpu_seconds(bare.pid) - before
    finally:
        _stop(bare)
        tester.close()


def _navigator_cpu(env: dict[str, str], workdir: Path, rate: float,
                   seconds: float, fix_delay: float = 0.0) -> tuple[float, int]:
    """Return the navigator's CPU time (s) over the stream, every output subscribed."""
    try:  # /tf only where tf2_msgs is installed
        from tf2_msgs.msg import TFMessage
    except ImportError:
        TFMessage = None
    tester = dds_harness.DdsTester('vk_bench')
    process = _navigator(env, workdir / f'cpu_{rate:g}.log', publish_rate=rate)
    try:
        received = {topic: tester.collect(topic, interface.message_class(msg_type),
                                          QoSProfile(depth=10))
                    for topic, msg_type in interface.types(interface.Role.OUTPUT,
                                                           absolute=False).items()}
        if TFMessage is not None:
            tester.collect('/tf', TFMessage, QoSProfile(depth=100))
        tester.wait_for_node('navigator', process)
        tester.spin_for(1.0)
        pid = process.process.pid
        before = _cpu_seconds(pid)
        _stream(tester, seconds, fix_delay)
        tester.spin_for(0.2)
        return _cpu_seconds(pid) - before, len(received['odometry'])
    finally:
        process.stop()
        tester.close()


def cpu(env: dict[str, str], workdir: Path, repeat: int, seconds: float = CPU_SECONDS) -> None:
    """Print the navigator's CPU time over the stream against a bare subscriber's, per round."""
    executor_kind = os.environ.get('VK_NAVIGATOR_EXECUTOR', 'events')
    # (publish_rate Hz, fix delivery delay s): the default; every update; fixes 0.3 s late.
    ratios: dict[tuple[float, float], list[float]] = {(30.0, 0.0): [], (0.0, 0.0): [],
                                                      (30.0, FIX_DELAY): []}
    # For scale, not the guard: the same bare subscriber on rclpy's default executor
    # (rclpy.spin's SingleThreadedExecutor), what most rclpy nodes run on.
    single: dict[tuple[float, float], list[float]] = {key: [] for key in ratios}
    for round_ in range(repeat):
        bare = _bare_cpu(executor_kind, seconds)
        bare_single = _bare_cpu('single', seconds) if executor_kind != 'single' else bare
        line = [f'  round {round_ + 1}: bare subscriber ({executor_kind} executor) '
                f'{bare:.2f} s CPU in {seconds:.0f} s (single-threaded executor '
                f'{bare_single:.2f} s)']
        for rate, delay in ratios:
            nav, n_odometry = _navigator_cpu(env, workdir, rate, seconds, delay)
            ratios[rate, delay].append(nav / bare)
            single[rate, delay].append(nav / bare_single)
            line.append(f'navigator at {rate:g} Hz, fixes {delay:g} s late {nav:.2f} s '
                        f'({n_odometry} odometry), ratio {nav / bare:.2f}')
        print('; '.join(line), flush=True)
    for (rate, delay), values in ratios.items():
        label = ('publish_rate 0 (every update)' if not rate else
                 f'default, fixes {delay:g} s late' if delay else 'default, publish_rate 30 Hz')
        print(f'  navigator / bare subscriber, {label}: median {np.median(values):.2f}, '
              f'range {min(values):.2f}-{max(values):.2f} over {repeat} rounds'
              + (' (guard <= 1.5)' if rate else '')
              + f'; / the bare subscriber on the single-threaded executor: median '
              f'{np.median(single[rate, delay]):.2f}')


def _schedule(duration: float, after: float = 0.0,
              fix_delay: float = 0.0) -> list[tuple[float, str, Any]]:
    """
    Return (due s, topic, msg): 400 Hz IMU, 20 Hz velocity, 10 Hz fix, unique stamps.

    ``after``: the stream from ``after`` s on (stamps and positions continue; due from 0);
    ``fix_delay``: each fix is due that long after its stamp (a receiver's latency).
    """
    import math
    events: list[tuple[float, str, Any]] = []
    q = (0.0, 0.0, math.sin(math.pi / 4), math.cos(math.pi / 4))   # heading north
    for k in range(int(duration * 400)):
        t = k / 400
        events.append((t, 'imu', dds_harness.make_imu(T0 + after + t, q)))
    for k in range(int(duration * 20)):
        t = k / 20 + 0.0007
        events.append((t, 'velocity', dds_harness.make_twist(T0 + after + t, (2.0, 0.0, 0.0))))
    for k in range(int(duration * 10)):
        t = k / 10 + 0.0003
        lat = ORIGIN[0] + 2.0 * (after + t) / 111_300.0
        events.append((t + fix_delay, 'fix', dds_harness.make_fix(T0 + after + t, lat,
                                                                  ORIGIN[1], ORIGIN[2])))
    events.sort(key=lambda e: e[0])
    return events


def _p99_minus(run: dict[str, np.ndarray], peer: dict[str, np.ndarray]) -> float:
    """Return the p99 of ``run``'s total latency minus ``peer``'s (ms)."""
    return float(np.percentile(run['total'], 99) - np.percentile(peer['total'], 99)) * 1e3


def _percentiles(label: str, seconds: np.ndarray) -> str:
    if seconds.size == 0:
        return f'  {label}: no samples'
    p50, p99 = np.percentile(seconds * 1e3, [50, 99])
    return (f'  {label}: p50 {p50:.3f} ms, p99 {p99:.3f} ms, max {seconds.max() * 1e3:.3f} ms '
            f'(n={seconds.size})')


def _install_env(workdir: Path) -> dict[str, str]:
    if 'VK_INSTALL' in os.environ:
        return dds_harness.sourced_env(Path(os.environ['VK_INSTALL']))
    try:
        dds_harness.resolve_executable(dict(os.environ), 'navigator')
        return dict(os.environ)
    except LookupError:
        print('building the package into', workdir)
        return dds_harness.sourced_env(dds_harness.colcon_build(REPO, workdir / 'colcon'))


def main() -> None:
    """Run the benchmarks and print the numbers."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument('--role', choices=['flood', 'bare-subscriber', 'bare-inputs', 'echo'])
    parser.add_argument('--cpu-only', action='store_true', help='only the CPU comparison')
    parser.add_argument('--latency-only', action='store_true',
                        help='only the latency comparison and the in-process callback times')
    parser.add_argument('--repeat', type=int, default=3,
                        help='rounds of the peer and the navigator, interleaved (CPU, latency)')
    parser.add_argument('seconds', nargs='?', type=float, default=FLOOD_SECONDS)
    parser.add_argument('--rate', type=float, default=0.0, help=argparse.SUPPRESS)
    parser.add_argument('--executor', default='events', choices=['events', 'single'])
    arguments = parser.parse_args()
    if arguments.role == 'flood':
        return _role_flood(arguments.seconds)
    if arguments.role == 'bare-subscriber':
        return _role_bare_subscriber(arguments.executor)
    if arguments.role == 'echo':
        return _role_echo(arguments.rate)
    if arguments.role == 'bare-inputs':
        return _role_bare_inputs(arguments.executor)

    with tempfile.TemporaryDirectory(prefix='vk_bench_') as tmp:
        workdir = Path(tmp)
        env = _install_env(workdir)
        print(f'navigator: {dds_harness.resolve_executable(env, "navigator")}')
        print(f'load average before: {os.getloadavg()}')
        if not arguments.latency_only:
            print(f'CPU, {CPU_SECONDS:.0f} s of 400 Hz IMU + 20 Hz velocity + 10 Hz fix, '
                  'every output subscribed:')
            cpu(env, workdir, arguments.repeat)
            if arguments.cpu_only:
                return None
            print('throughput (IMU flood, best effort):')
            nav_rate, bare_rate = throughput(env, workdir)
            ratio = nav_rate / bare_rate if bare_rate else float('nan')
            print(f'  navigator {nav_rate:.0f} msg/s, bare rclpy subscriber {bare_rate:.0f} '
                  f'msg/s, ratio {ratio:.2f} (aim >= 0.8)')
            if os.environ.get('VK_NAVIGATOR_EXECUTOR', 'events') != 'single':
                single = bare_throughput('single')
                print(f'  (for reference: a bare subscriber on the SingleThreadedExecutor: '
                      f'{single:.0f} msg/s; navigator / that = {nav_rate / single:.2f})')
        print('latency, publish -> matching odometry arrival (400 Hz IMU + 10 Hz fix + '
              '20 Hz velocity, reliable):')
        runs: dict[str, list[dict[str, np.ndarray]]] = {
            'navigator': [], 'bare echo node': [],
            'bare echo node answering the same inputs (30 Hz)': []}
        for _ in range(arguments.repeat):      # interleaved: each round meets the same machine
            for (label, measured), echo, rate in zip(runs.items(), (False, True, True),
                                                     (0.0, 0.0, 30.0)):
                measured.append(latency(env, workdir, echo=echo, rate=rate))
        if arguments.repeat > 1:
            print(f"  each of the {arguments.repeat} rounds, p99 minus the echo's, the same "
                  "inputs' echo (ms): " + ', '.join(
                      f'{_p99_minus(nav, bare):.3f}/{_p99_minus(nav, same):.3f}'
                      for nav, bare, same in zip(*runs.values())))
            print(f'  pooled over the {arguments.repeat} rounds:')
        runs = {label: {key: np.concatenate([r[key] for r in measured]) for key in measured[0]}
                for label, measured in runs.items()}
        for label, parts in runs.items():
            print(_percentiles(label, parts['total']))
        print('  where it goes, p50 (ms; DDS timestamps): input publish -> answer written, '
              '-> received here, -> callback here')
        for label, parts in runs.items():
            print(f'    {label}: ' + ', '.join(
                f'{np.percentile(parts[k], 50) * 1e3:.3f}' if parts[k].size else '-'
                for k in ('answer', 'transit', 'dispatch')))
        nav, bare, same = (parts['total'] for parts in runs.values())
        if nav.size and bare.size:
            print(f'  navigator minus echo: p50 '
                  f'{(np.percentile(nav, 50) - np.percentile(bare, 50)) * 1e3:.3f} ms, p99 '
                  f'{(np.percentile(nav, 99) - np.percentile(bare, 99)) * 1e3:.3f} ms '
                  f'(guard p99 <= 2 ms)')
        if nav.size and same.size:
            print(f'  navigator minus the echo of the same inputs: p50 '
                  f'{(np.percentile(nav, 50) - np.percentile(same, 50)) * 1e3:.3f} ms, p99 '
                  f'{(np.percentile(nav, 99) - np.percentile(same, 99)) * 1e3:.3f} ms')
        print(f'load average after: {os.getloadavg()}')


if __name__ == '__main__':
    main()
