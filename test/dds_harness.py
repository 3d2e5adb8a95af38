"""
A small harness for tests that run the installed navigator over DDS.

* :func:`colcon_build` builds the package as ``ros.ament_python`` into a directory of its own;
  :func:`sourced_env` is the environment after ``source <install>/setup.bash``;
  :func:`resolve_executable` finds ``lib/<package>/<executable>`` through the ament index,
  exactly as ``ros2 run`` does.
* :class:`NodeProcess` starts that executable as a subprocess with ``--ros-args`` (what
  ``ros2 run vessel_kinematics navigator --ros-args ...`` executes), logs its output to a file
  and stops it with SIGINT (then SIGKILL if it does not exit).
* :class:`DdsTester` is an rclpy node on a context of its own: publishers, collecting
  subscriptions, parameter-service calls and spinning until a condition holds.
* ``make_fix``, ``make_imu``, ``make_twist`` build input messages with explicit stamps.

Everything here is rclpy, subprocess and the standard library; numpy is not needed.
"""

from __future__ import annotations

import math
import os
from pathlib import Path
import signal
import subprocess
import time
from typing import Any, Callable, Iterable, Sequence

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import TwistWithCovarianceStamped
from rcl_interfaces.msg import Parameter as ParameterMsg
from rcl_interfaces.srv import GetParameters, SetParameters
import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions
from sensor_msgs.msg import Imu, NavSatFix, NavSatStatus

PACKAGE = 'vessel_kinematics'

#: Seconds a service request may go unanswered before it is sent again (:meth:`DdsTester._call`).
RESEND = 3.0

#: Reliable, volatile, deep: what the tests publish and subscribe with for determinism.
RELIABLE = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1000,
                      reliability=ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.VOLATILE)
#: Reliable transient-local depth 1: a late subscriber to a latched topic (``origin``).
LATCHED = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                     reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL)


# --- build and environment ------------------------------------------------------------------

def colcon_build(source: Path, base: Path, env: dict[str, str] | None = None) -> Path:
    """
    Build the package at ``source`` with colcon into ``base``/{build,install,log}.

    Return the install space. Raise RuntimeError with colcon's output when the build fails.
    """
    base.mkdir(parents=True, exist_ok=True)
    command = ['colcon', '--log-base', str(base / 'log'), 'build',
               '--base-paths', str(source), '--build-base', str(base / 'build'),
               '--install-base', str(base / 'install'), '--event-handlers', 'console_direct-']
    done = subprocess.run(command, cwd=base, env=env, capture_output=True, text=True,
                          timeout=600, check=False)
    if done.returncode != 0:
        raise RuntimeError(f'colcon build failed ({done.returncode}):\n{done.stdout}\n'
                           f'{done.stderr}')
    return base / 'install'


def sourced_env(install: Path, base: dict[str, str] | None = None) -> dict[str, str]:
    """Return the environment after ``source <install>/setup.bash`` (as a user's shell has)."""
    base = dict(os.environ if base is None else base)
    script = install / 'setup.bash'
    if not script.exists():
        script = install / 'local_setup.bash'
    done = subprocess.run(['bash', '-c', f'source "{script}" && env -0'], env=base,
                          capture_output=True, check=True, timeout=60)
    env = {}
    for entry in done.stdout.split(b'\0'):
        if b'=' in entry:
            key, _, value = entry.decode().partition('=')
            env[key] = value
    return env


def package_prefix(env: dict[str, str], package: str = PACKAGE) -> Path:
    """Return the prefix of ``package`` in AMENT_PREFIX_PATH, as ament_index_python does."""
    for prefix in env.get('AMENT_PREFIX_PATH', '').split(os.pathsep):
        marker = Path(prefix, 'share', 'ament_index', 'resource_index', 'packages', package)
        if prefix and marker.is_file():
            return Path(prefix)
    raise LookupError(f'package {package!r} not found in the ament index '
                      f'(AMENT_PREFIX_PATH={env.get("AMENT_PREFIX_PATH")!r})')


def resolve_executable(env: dict[str, str], executable: str,
                       package: str = PACKAGE) -> Path:
    """Return ``<prefix>/lib/<package>/<executable>``: the file ``ros2 run`` executes."""
    path = package_prefix(env, package) / 'lib' / package / executable
    if not (path.is_file() and os.access(path, os.X_OK)):
        raise LookupError(f'no executable {executable!r} in package {package!r} ({path})')
    return path


def share_directory(env: dict[str, str], package: str = PACKAGE) -> Path:
    """Return ``<prefix>/share/<package>`` (ament_index_python's package share directory)."""
    return package_prefix(env, package) / 'share' / package


def ros_value(value: Any) -> str:
    """Format a Python value for ``-p name:=value`` (YAML, as the rcl argument parser reads)."""
    if isinstance(value, bool):
        return 'true' if value else 'false'
    if isinstance(value, float):
        return '.nan' if math.isnan(value) else repr(value)
    if isinstance(value, (list, tuple)):
        return '[' + ','.join(ros_value(v) for v in value) + ']'
    return str(value)


def ros_args(params: dict[str, Any] | None = None, remaps: dict[str, str] | None = None,
             params_file: Path | None = None) -> list[str]:
    """Return ``--ros-args`` with ``--params-file``, ``-p name:=value`` and ``-r from:=to``."""
    args = ['--ros-args']
    if params_file is not None:
        args += ['--params-file', str(params_file)]
    for name, value in (params or {}).items():
        args += ['-p', f'{name}:={ros_value(value)}']
    for old, new in (remaps or {}).items():
        args += ['-r', f'{old}:={new}']
    return args


# --- the node under test ----------------------------------------------------------------------

class NodeProcess:
    """An installed ROS executable run as a subprocess, output to a log file."""

    def __init__(self, executable: Path, args: Sequence[str], env: dict[str, str],
                 log_path: Path) -> None:
        self.executable = executable
        self.args = list(args)
        self.log_path = log_path
        self._log = open(log_path, 'wb')  # closed in stop()
        self.process = subprocess.Popen(
            [str(executable), *self.args], env=env, cwd=log_path.parent,
            stdin=subprocess.DEVNULL, stdout=self._log, stderr=subprocess.STDOUT,
            start_new_session=True)

    @property
    def pid(self) -> int:
        """Return the process id."""
        return self.process.pid

    def alive(self) -> bool:
        """Return True while the process runs."""
        return self.process.poll() is None

    def output(self) -> str:
        """Return everything the process printed so far."""
        if not self._log.closed:
            self._log.flush()
        return self.log_path.read_text(errors='replace')

    def wait(self, timeout: float) -> int | None:
        """Wait up to ``timeout`` s for the process to exit; return its code or None."""
        try:
            return self.process.wait(timeout)
        except subprocess.TimeoutExpired:
            return None

    def stop(self, sig: int = signal.SIGINT, timeout: float = 10.0) -> int:
        """Send ``sig`` and wait; SIGKILL after ``timeout`` s. Return the exit code."""
        if self.alive():
            self.process.send_signal(sig)
            if self.wait(timeout) is None:
                self.kill()
        code = self.process.wait()
        if not self._log.closed:
            self._log.close()
        return code

    def kill(self) -> None:
        """Kill the process (and anything it started in its session) at once."""
        if self.alive():
            try:
                os.killpg(self.process.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
        self.process.wait()


# --- the test node ----------------------------------------------------------------------------

class DdsTester:
    """
    An rclpy node on a context of its own that publishes inputs and collects outputs.

    ``collect(topic, type)`` returns a list that fills as messages arrive while the tester
    spins (``spin_for``, ``spin_until`` or any of the waiting helpers).
    """

    def __init__(self, name: str = 'vk_tester', namespace: str = '/') -> None:
        self.context = Context()
        rclpy.init(context=self.context, signal_handler_options=SignalHandlerOptions.NO)
        self.node = Node(name, namespace=namespace, context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self._publishers: dict[str, Any] = {}
        self.received: dict[str, list[Any]] = {}
        self.arrival: dict[str, list[float]] = {}

    def close(self) -> None:
        """Destroy the node and shut the context down."""
        self.executor.shutdown(timeout_sec=1.0)
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)

    # publishing

    def publisher(self, topic: str, msg_type: type, qos: QoSProfile = RELIABLE) -> Any:
        """Return (creating once) a publisher on ``topic``."""
        if topic not in self._publishers:
            self._publishers[topic] = self.node.create_publisher(msg_type, topic, qos)
        return self._publishers[topic]

    def publish(self, topic: str, msg: Any) -> None:
        """Publish ``msg`` on ``topic`` (a publisher of its type is created the first time)."""
        self.publisher(topic, type(msg)).publish(msg)

    def play(self, events: Sequence[tuple[str, Any]], pace: float = 0.0005,
             sync: list[Any] | None = None, sync_every: int = 5,
             sync_timeout: float = 0.5) -> int:
        """
        Publish ``(topic, msg)`` events in order, spinning ``pace`` s after each.

        With ``sync`` (a list from :meth:`collect` of stamped outputs), wait until an output
        stamped at or after the event's stamp has arrived (at most ``sync_timeout`` s) after
        every ``sync_every`` events and before the topic changes: few messages are in flight
        (the node's input depth is 20), and the node receives them in stamp order (DDS keeps
        the order within a topic, not across topics). Return how many waits timed out.
        """
        timeouts = 0
        for index, (topic, msg) in enumerate(events):
            self.publish(topic, msg)
            if sync is None:
                self.spin_for(pace)
                continue
            following = events[index + 1][0] if index + 1 < len(events) else None
            if (index + 1) % sync_every and following == topic:
                self.executor.spin_once(timeout_sec=0.0)
                continue
            t = seconds(msg.header.stamp)

            def caught_up() -> bool:
                return bool(sync) and seconds(sync[-1].header.stamp) >= t - 1e-9
            if not self.spin_until(caught_up, sync_timeout):
                timeouts += 1
        return timeouts

    # collecting

    def collect(self, topic: str, msg_type: type, qos: QoSProfile = RELIABLE) -> list[Any]:
        """Subscribe to ``topic`` and return the list its messages are appended to."""
        messages: list[Any] = self.received.setdefault(topic, [])
        arrivals = self.arrival.setdefault(topic, [])

        def store(msg: Any) -> None:
            messages.append(msg)
            arrivals.append(time.monotonic())
        self.node.create_subscription(msg_type, topic, store, qos)
        return messages

    # spinning

    def spin_for(self, seconds: float) -> None:
        """Process callbacks for ``seconds``."""
        end = time.monotonic() + seconds
        while True:
            left = end - time.monotonic()
            if left <= 0:
                break
            self.executor.spin_once(timeout_sec=min(left, 0.05))

    def spin_until(self, condition: Callable[[], bool], timeout: float) -> bool:
        """Process callbacks until ``condition()`` holds; return False on timeout."""
        end = time.monotonic() + timeout
        while not condition():
            if time.monotonic() > end:
                return False
            self.executor.spin_once(timeout_sec=0.02)
        return True

    def wait_for_node(self, name: str, process: NodeProcess | None = None,
                      timeout: float = 15.0) -> None:
        """Wait until node ``name`` is on the graph; fail early if ``process`` exits."""
        def seen() -> bool:
            if process is not None and not process.alive():
                raise RuntimeError(f'{process.executable.name} exited with '
                                   f'{process.process.returncode}:\n{process.output()}')
            return name in self.node.get_node_names()
        if not self.spin_until(seen, timeout):
            raise TimeoutError(f'node {name!r} did not appear in {timeout} s'
                               + (f':\n{process.output()}' if process else ''))

    def wait_for_match(self, topics: Iterable[str], timeout: float = 10.0) -> None:
        """Wait until the publishers on ``topics`` and collectors are matched with the node."""
        publishers = [self._publishers[t] for t in topics if t in self._publishers]
        subscriptions = [s for s in self.node.subscriptions
                         if s.topic_name.lstrip('/') in {t.lstrip('/') for t in topics}]

        def matched() -> bool:
            return (all(p.get_subscription_count() > 0 for p in publishers)
                    and all(s.get_publisher_count() > 0 for s in subscriptions))
        if not self.spin_until(matched, timeout):
            raise TimeoutError(f'topics {sorted(topics)} not matched in {timeout} s')

    # parameters

    def set_parameters(self, node: str, values: dict[str, Any],
                       timeout: float = 10.0) -> list[Any]:
        """Call ``<node>/set_parameters``; return the SetParametersResult of each value."""
        request = SetParameters.Request()
        request.parameters = [Parameter(name, value=value).to_parameter_msg()
                              for name, value in values.items()]
        return self._call(SetParameters, f'{node}/set_parameters', request, timeout).results

    def get_parameters(self, node: str, names: Sequence[str],
                       timeout: float = 10.0) -> dict[str, Any]:
        """Call ``<node>/get_parameters``; return the values by name."""
        request = GetParameters.Request(names=list(names))
        response = self._call(GetParameters, f'{node}/get_parameters', request, timeout)
        values = {}
        for name, value in zip(names, response.values):
            values[name] = Parameter.from_parameter_msg(ParameterMsg(name=name, value=value)).value
        return values

    def _call(self, srv_type: type, service: str, request: Any, timeout: float) -> Any:
        """
        Call ``service`` and return its response; TimeoutError if none comes in ``timeout`` s.

        A request sent while discovery is still matching the reply path can go unanswered
        (the server's reply finds no matched reader and is dropped; seen once, in a CI run's
        test_params_files): the parameter calls here are idempotent, so a request unanswered
        for :data:`RESEND` s is sent again, and the first answer to either is taken.
        """
        client = self.node.create_client(srv_type, service)
        try:
            if not client.wait_for_service(timeout_sec=timeout):
                raise TimeoutError(f'service {service} not available in {timeout} s')
            end = time.monotonic() + timeout
            futures: list[Any] = []
            while (left := end - time.monotonic()) > 0.0:
                futures.append(client.call_async(request))
                if self.spin_until(lambda: any(f.done() for f in futures), min(RESEND, left)):
                    return next(f for f in futures if f.done()).result()
            raise TimeoutError(f'service {service} did not answer in {timeout} s '
                               f'({len(futures)} requests)')
        finally:
            self.node.destroy_client(client)


# --- messages ---------------------------------------------------------------------------------

def stamp(seconds: float) -> Time:
    """Return a builtin_interfaces/Time for ``seconds`` (>= 0)."""
    nanoseconds = round(seconds * 1e9)
    return Time(sec=nanoseconds // 1_000_000_000, nanosec=nanoseconds % 1_000_000_000)


def seconds(time_msg: Time) -> float:
    """Return a builtin_interfaces/Time in seconds."""
    return time_msg.sec + time_msg.nanosec * 1e-9


def make_fix(t: float, lat: float, lon: float, height: float, sigma: float = 0.5,
             status: int = NavSatStatus.STATUS_FIX, frame_id: str = 'gnss',
             covariance_type: int = NavSatFix.COVARIANCE_TYPE_DIAGONAL_KNOWN) -> NavSatFix:
    """Return a NavSatFix at ``t`` s with a diagonal covariance of ``sigma`` m per axis."""
    msg = NavSatFix()
    msg.header.stamp = stamp(t)
    msg.header.frame_id = frame_id
    msg.status.status = status
    msg.status.service = NavSatStatus.SERVICE_GPS
    msg.latitude, msg.longitude, msg.altitude = float(lat), float(lon), float(height)
    msg.position_covariance = [sigma ** 2, 0.0, 0.0, 0.0, sigma ** 2, 0.0, 0.0, 0.0, sigma ** 2]
    msg.position_covariance_type = covariance_type
    return msg


def make_imu(t: float, q_xyzw: Sequence[float], omega_flu: Sequence[float] = (0.0, 0.0, 0.0),
             accel_flu: Sequence[float] = (0.0, 0.0, 9.81), frame_id: str = 'imu_link',
             orientation_sigma: float = 0.01, rate_sigma: float = 0.001) -> Imu:
    """Return an Imu at ``t`` s: orientation ENU world xyzw, angular rate FLU (rad/s)."""
    msg = Imu()
    msg.header.stamp = stamp(t)
    msg.header.frame_id = frame_id
    (msg.orientation.x, msg.orientation.y, msg.orientation.z,
     msg.orientation.w) = (float(v) for v in q_xyzw)
    msg.orientation_covariance = _diagonal(orientation_sigma ** 2)
    (msg.angular_velocity.x, msg.angular_velocity.y,
     msg.angular_velocity.z) = (float(v) for v in omega_flu)
    msg.angular_velocity_covariance = _diagonal(rate_sigma ** 2)
    (msg.linear_acceleration.x, msg.linear_acceleration.y,
     msg.linear_acceleration.z) = (float(v) for v in accel_flu)
    msg.linear_acceleration_covariance = _diagonal(0.01)
    return msg


def make_twist(t: float, v_flu: Sequence[float], sigma: float = 0.05,
               frame_id: str = 'base_link') -> TwistWithCovarianceStamped:
    """Return a body velocity (FLU, m/s) at ``t`` s with ``sigma`` m/s per linear axis."""
    msg = TwistWithCovarianceStamped()
    msg.header.stamp = stamp(t)
    msg.header.frame_id = frame_id
    (msg.twist.twist.linear.x, msg.twist.twist.linear.y,
     msg.twist.twist.linear.z) = (float(v) for v in v_flu)
    covariance = [0.0] * 36
    for i in range(3):
        covariance[7 * i] = sigma ** 2
    for i in range(3, 6):
        covariance[7 * i] = 0.01
    msg.twist.covariance = covariance
    return msg


def _diagonal(variance: float) -> list[float]:
    return [variance, 0.0, 0.0, 0.0, variance, 0.0, 0.0, 0.0, variance]


def diagnostic_values(msg: DiagnosticArray) -> dict[str, str]:
    """Return every key/value of every status of a DiagnosticArray (later statuses win)."""
    values = {}
    for status in msg.status:
        for item in status.values:
            values[item.key] = item.value
    return values
