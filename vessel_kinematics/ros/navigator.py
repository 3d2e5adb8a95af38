"""
The ``navigator`` rclpy node: NavSatFix + Imu + body velocity in, Odometry and course out.

A thin driver of :class:`~vessel_kinematics.ros.pipeline.Pipeline`, put together from the parts
of :mod:`vessel_kinematics.ros.node`: its parameters (declared from the one table), its inputs
(each message handed to the pipeline with the node clock's time as its arrival), its outputs
(the pipeline's emissions published as the CDR bytes they are) and ``/diagnostics`` once a
second of the steady clock. All conversion and estimation happen in the pipeline, so the
offline replay gives the same outputs. Its services (:mod:`.node.services`): robot_localization's
``fromLL``, ``toLL``, ``datum`` and ``toggle``, and ``~/reset`` and ``~/enable``.

Nothing a peer sends stops the node: every callback and timer is guarded (an exception is
logged, throttled, and counted as ``internal_error/<where>`` in ``/diagnostics``), logging
cannot raise (:mod:`.node.log`), a ``/clock`` rclpy cannot take is counted as
``clock/bad_stamp``, and structural parameters (frames, ``motion``, ``projection``,
``use_sim_time``) are read-only at run time; a legal but harmful change (an origin far from
the vessel, a ``max_gap`` shorter than the inputs' periods: :mod:`.node.checks`) is refused
with its reason. ``velocity.source`` and ``sensor_qos`` may change:
the inputs are subscribed anew, and a message of the old type still queued is refused as
``velocity/unused_input``.

Run it as ``ros2 run vessel_kinematics navigator --ros-args --params-file navigator.yaml``.
Before ``rclpy.init`` (where rcl parses the same arguments in C) :func:`main` reads every
``--params-file`` and ``-p`` with the replay's reader (:mod:`.params_file`): a file beyond its
limits, or a bad value, is one line and exit status 2.
"""

from __future__ import annotations

import math
import os
import sys
import textwrap
import traceback
from typing import Any, Callable, Sequence

import rclpy
from rclpy.clock import Clock, ClockType
from rclpy.executors import Executor, ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.serialization import deserialize_message
from vessel_kinematics.estimation import Level, Reason
from vessel_kinematics.ros import interface
from vessel_kinematics.ros.mountings import oversized
from vessel_kinematics.ros.node.checks import RunTimeChecks
from vessel_kinematics.ros.node.log import NodeLog
from vessel_kinematics.ros.node.parameters import NodeParameters, StartupError
from vessel_kinematics.ros.node.publishers import NodeOutputs
from vessel_kinematics.ros.node.services import NodeServices
from vessel_kinematics.ros.node.subscriptions import INPUT_SILENCE, NodeInputs
from vessel_kinematics.ros.params import declination_problem, NavigatorParams, ParameterError
from vessel_kinematics.ros.params_file import (parse_value, read_params_file, unknown_names_line,
                                               without_removed)
from vessel_kinematics.ros.pipeline import fewer_collections, Pipeline

__all__ = ['check_arguments', 'DIAGNOSTICS_PERIOD', 'main', 'make_executor', 'Navigator',
           'NODE_NAME', 'USAGE']

NODE_NAME = 'navigator'
#: Period of ``/diagnostics`` (s), on the steady clock so that it runs without a ``/clock`` too.
DIAGNOSTICS_PERIOD = 1.0

_OUT = textwrap.fill(', '.join(t.name for t in interface.by_role(
    interface.Role.OUTPUT, interface.Role.AUXILIARY)) + ' out.', 95)
USAGE = f"""\
usage: ros2 run vessel_kinematics navigator [--help] [--ros-args --params-file FILE
           -p NAME:=VALUE -r FROM:=TO ...]
NavSatFix (fix) + Imu (imu) + body velocity (velocity) in;
{_OUT}
Parameters: see config/navigator.yaml (key /**/navigator: matches any namespace);
qos_overrides./<topic>.subscription.<policy> set the inputs' QoS over sensor_qos."""


class Navigator(Node):
    """The navigator node: the pipeline between the node's inputs and its outputs."""

    def __init__(self, **node_kwargs: Any) -> None:
        super().__init__(NODE_NAME, **node_kwargs)
        self.log = NodeLog(self.get_logger())
        #: The node's own counts for /diagnostics: internal errors, refused /clock messages.
        self.errors: dict[str, int] = {}
        self.checks = RunTimeChecks()
        self.parameters = NodeParameters(self, self._apply, self._check)
        params = self.parameters.params
        self.pipeline = Pipeline(params)
        self.outputs = NodeOutputs(self, params, self.log)
        self.inputs = NodeInputs(
            self, params, self._on_message,
            self._guard('tf_static', self._on_tf_static) if self.outputs.tf_type else None,
            self._guard, self._on_bad_clock, self.log)
        self.node_services = NodeServices(self, self, self._guard, self.log)
        self._now = self.get_clock().now
        self.outputs.send(self.pipeline.start())
        self._diagnostics_timer = self.create_timer(
            DIAGNOSTICS_PERIOD, self._guard('diagnostics', self._publish_diagnostics),
            clock=Clock(clock_type=ClockType.STEADY_TIME))
        problem = declination_problem(params)
        if problem is not None:
            self.log.warning(problem)
        self.log.info(
            f'navigator ready: inputs {", ".join(self.inputs.names)} ({params.sensor_qos} QoS), '
            f'velocity {params.velocity_source} ({params.velocity_reference} reference), '
            f'frames {params.map_frame}/{params.odom_frame}/{params.base_frame}')

    # --- inputs -----------------------------------------------------------------------------

    def _on_message(self, name: str, msg: Any, source: int = 0) -> None:
        """Hand one input to the pipeline, say what it says, publish what it emits."""
        result = self.pipeline.handle(name, msg, self._now().nanoseconds, source)
        if result.info is not None:
            self.log.info(result.info)
        for event in result.events:
            (self.log.info if event.level is Level.OK else self.log.warning)(
                f'estimator: {event.text}')
        refused = [(name, result.rejected, result.detail)] if result.rejected else []
        for held, reason, detail in refused + list(result.later):
            self.log.throttled(f'{held}/{reason}',
                               f'rejected {held} message ({reason}): {detail or reason}')
        if result.emissions:
            self.outputs.send(result.emissions)
        if name == 'fix' and self.checks.first_fix is None and result.rejected is None:
            self.checks.first_fix = (float(msg.latitude), float(msg.longitude))

    def _on_tf_static(self, raw: bytes) -> None:
        """
        Take a serialised /tf_static message for the mountings; say what the tree refused.

        A message too large is refused from its CDR header, before it is deserialised (which
        costs about 50 us per transform on the executor's thread, the IMU's).
        """
        tree = self.pipeline.mountings.tree
        large = oversized(raw)
        if large is not None:
            tree.refuse(Reason.TOO_LARGE, large[0])
            self.log.throttled('tf_static/too_large', f'/tf_static message refused: {large[1]}')
            return
        refused, full = dict(tree.refused), tree.full
        try:
            msg = deserialize_message(raw, self.inputs.tf_static_type)
        except Exception as error:  # noqa: B902 - rmw's, for a payload a peer got wrong
            tree.refuse(Reason.CDR_ERROR)
            self.log.throttled('tf_static/cdr_error', '/tf_static message refused: not a '
                               f'TFMessage ({str(error).splitlines()[0][:120]})')
            return
        self.pipeline.tf_static(msg)
        if tree.full and not full:
            self.log.warning(f'/tf_static: the static tree holds {len(tree)} frames, its limit; '
                             'new frames are refused (counted as rejected tf_static/too_large)')
        for reason, count in tree.refused.items():
            if reason == Reason.TOO_LARGE.value and tree.full:
                continue
            if count > refused.get(reason, 0):
                self.log.throttled(f'tf_static/{reason}',
                                   f'/tf_static: refused {count - refused.get(reason, 0)} '
                                   f'transform(s) ({reason})')

    def _on_bad_clock(self, error: Exception) -> None:
        self._count('rejected clock/bad_stamp')
        self.log.throttled('clock/bad_stamp', f'/clock message ignored: {error}')

    # --- guards -----------------------------------------------------------------------------

    def _count(self, key: str) -> None:
        self.errors[key] = self.errors.get(key, 0) + 1

    def _guard(self, name: str, function: Callable[..., None]) -> Callable[..., None]:
        """Wrap a callback so that an exception is logged (throttled) and counted, not raised."""
        def guarded(*args: Any) -> None:
            try:
                function(*args)
            except Exception:  # noqa: B902 - one bad message must never stop the node
                self.internal_error(name)
        return guarded

    def internal_error(self, where: str) -> None:
        """Count and log (throttled) the exception being handled, as ``internal_error/where``."""
        self._count(f'internal_error/{where}')
        self.log.throttled(f'internal_error/{where}',
                           f'unexpected error in {where} (dropped):\n{traceback.format_exc()}',
                           error=True)

    # --- parameters and diagnostics ---------------------------------------------------------

    def _check(self, old: NavigatorParams, new: NavigatorParams) -> str | None:
        """Return why a parameter change is harmful now (:mod:`.node.checks`), or None."""
        topics = (new.fix_topics, new.imu_topics, new.imu_source)
        if topics != (old.fix_topics, old.imu_topics, old.imu_source):
            problem = self.inputs.problem(new)
            if problem is not None:
                return problem
        state = self.pipeline.state()
        position = None if state is None else (math.degrees(state.llh[0]),
                                               math.degrees(state.llh[1]))
        return self.checks.problem(old, new, position)

    def _apply(self, new: NavigatorParams, changed: list[str]) -> None:
        """Apply parameters once set: pipeline, subscriptions, TF; publish what follows."""
        try:
            old = self.pipeline.params
            emissions = self.pipeline.set_params(new)
            if _subscribed(new) != _subscribed(old):
                self.inputs.subscribe(new)
            self.outputs.set_params(new)
            self.log.info(f'parameters changed: {", ".join(changed)}')
            self.outputs.send(emissions)
        except Exception:  # noqa: B902 - a bad apply must not take the node down
            self.internal_error('parameters')

    def _publish_diagnostics(self) -> None:
        """Publish the pipeline's /diagnostics with the node's own counts; revive silent inputs."""
        for topic in self.inputs.revive():
            self._count(f'resubscribed {topic}')
            self.log.throttled(f'resubscribed/{topic}',
                               f'{topic}: nothing for {INPUT_SILENCE:g} s while a publisher is '
                               'matched: subscribed anew (a DDS reader wedges on a payload it '
                               'cannot take)')
        extra = {'internal_errors': sum(n for k, n in self.errors.items()
                                        if k.startswith('internal_error/')),
                 **self.errors}
        if self.log.failures:
            extra['log_failures'] = self.log.failures
        est = self.pipeline.estimator
        self.checks.observe(self.pipeline.counts, {'fix': est.last_fix_ns,
                                                   'imu': est.last_imu_ns,
                                                   'velocity': est.last_velocity_ns})
        self.outputs.send([self.pipeline.diagnostics(self._now().nanoseconds, self.get_name(),
                                                     extra)])


def _subscribed(params: NavigatorParams) -> tuple:
    """Return what the input subscriptions depend on: QoS, topics and message types."""
    return (params.sensor_qos, params.velocity_source, params.imu_source,
            params.gnss_velocity_source, params.fix_topics, params.imu_topics)


def make_executor() -> Executor:
    """
    Return the executor: rclpy's EventsExecutor where it exists, else SingleThreadedExecutor.

    The EventsExecutor dispatches a message in a fraction of the SingleThreadedExecutor's time
    (it does not rebuild a wait set per callback), which is most of the node's latency at
    400 Hz. ``VK_NAVIGATOR_EXECUTOR=single`` selects the SingleThreadedExecutor.
    """
    if os.environ.get('VK_NAVIGATOR_EXECUTOR', 'events') != 'single':
        try:
            from rclpy.experimental import EventsExecutor
        except ImportError:
            pass
        else:
            return EventsExecutor()
    return SingleThreadedExecutor()


def _ros_arguments(argv: Sequence[str]) -> tuple[list[str], list[tuple[str, str]]]:
    """Return the user's arguments, and the (flag, value) pairs inside ``--ros-args``."""
    user, ros, in_ros = [], [], False
    args = list(argv[1:])
    i = 0
    while i < len(args):
        arg = args[i]
        if arg == '--ros-args':
            in_ros = True
        elif in_ros and arg == '--':
            in_ros = False
        elif in_ros and arg in _VALUED and i + 1 < len(args):
            ros.append((_VALUED[arg], args[i + 1]))
            i += 1
        elif not in_ros:
            user.append(arg)
        i += 1
    return user, ros


#: The ``--ros-args`` flags read before rclpy.init, by their long name.
_VALUED = {'--params-file': '--params-file', '-p': '--param', '--param': '--param',
           '-r': '--remap', '--remap': '--remap'}


def _node_name(ros: list[tuple[str, str]]) -> str:
    """Return the node's fully qualified name under ``__ns``/``__node`` remaps (rcl's rules)."""
    namespace, name = '', NODE_NAME
    for flag, value in ros:
        if flag != '--remap':
            continue
        key, _, target = value.partition(':=')
        if key == '__ns':
            namespace = target.rstrip('/')
        elif key == '__node':
            name = target
    if namespace and not namespace.startswith('/'):
        namespace = '/' + namespace
    return f'{namespace}/{name}'


def check_arguments(argv: Sequence[str], log: Callable[[str], None]) -> str | None:
    """
    Read the ``--params-file`` and ``-p`` arguments as the replay does; return why not, or None.

    Every file and value goes through the one reader's limits and checks (before rcl's C parser
    meets them), for the node's name under its ``__ns`` and ``__node`` remaps; names that are
    not the navigator's get one warning line (``log``).
    """
    values: dict[str, Any] = {}
    ros = _ros_arguments(argv)[1]
    fqn = _node_name(ros)
    try:
        for flag, value in ros:
            if flag == '--remap':
                continue
            if flag == '--params-file':
                read = read_params_file(value, fqn)
                if read.unknown:
                    log(unknown_names_line(read.unknown, value))
                for line in read.ignored:
                    log(line)
                values.update(read.values)
                continue
            name, sep, text = value.partition(':=')
            if not sep:
                continue                      # rcl says what is wrong with it
            parsed = parse_value(text, name)
            if name.startswith(('use_sim_time', 'qos_overrides.')):
                continue
            kept, ignored = without_removed({name: parsed}, '-p')
            for line in ignored:
                log(line)
            values.update(kept)
        NavigatorParams.from_flat(values)
    except ParameterError as error:
        return str(error)
    return None


def main(args: Sequence[str] | None = None) -> int:
    """Run the navigator until SIGINT/SIGTERM; return 2 when an argument is unusable."""
    argv = list(sys.argv if args is None else args)
    if {'-h', '--help'} & set(_ros_arguments(argv)[0]):
        print(USAGE)
        return 0
    problem = check_arguments(argv, lambda line: print(f'navigator: warning: {line}',
                                                       file=sys.stderr))
    if problem is not None:
        print(f'navigator: error: {problem}', file=sys.stderr)
        return 2
    try:
        rclpy.init(args=None if args is None else list(args))
    except Exception as error:  # noqa: B902 (rcl's RCLError: bad --ros-args, one line)
        text = str(error).splitlines()[0] if str(error) else type(error).__name__
        print(f'navigator: error: invalid command line ({type(error).__name__}): {text}',
              file=sys.stderr)
        return 2
    node: Navigator | None = None
    try:
        try:
            node = Navigator()
        except StartupError as error:
            print(f'navigator: error: {error}', file=sys.stderr)
            return 2
        executor = make_executor()
        executor.add_node(node)
        # spin_once in a loop rather than spin(): the EventsExecutor's spin() does not return
        # when rclpy's signal handler shuts the context down; this loop notices within 0.2 s.
        with fewer_collections():
            while rclpy.ok():
                try:
                    executor.spin_once(timeout_sec=0.2)
                except (KeyboardInterrupt, ExternalShutdownException):
                    raise
                except Exception:  # noqa: B902 - a callback of rclpy's own that raised
                    node.internal_error('executor')
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main())
