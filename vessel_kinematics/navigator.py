"""
The ``navigator`` rclpy node: NavSatFix + Imu + body velocity in, Odometry and course out.

The node is a thin driver around :class:`~vessel_kinematics.pipeline.Pipeline`: it declares the
parameters of :data:`~vessel_kinematics.params.PARAMETERS`, validates them with
:meth:`~vessel_kinematics.params.NavigatorParams.from_flat`, subscribes to the relative topics
``fix``, ``imu`` and ``velocity``, hands every message to :meth:`Pipeline.handle` and publishes
what it returns. All conversion and estimation happen in the pipeline, so the offline replay
gives the same outputs.

Run it as ``ros2 run vessel_kinematics navigator --ros-args --params-file navigator.yaml``.
"""

from __future__ import annotations

import array
import os
import sys
import time
import traceback
from typing import Any, Callable, Sequence

from diagnostic_msgs.msg import DiagnosticArray, KeyValue
from geometry_msgs.msg import Vector3Stamped
from nav_msgs.msg import Odometry
from rcl_interfaces.msg import ParameterDescriptor, ParameterType, SetParametersResult
import rclpy
from rclpy.clock import Clock, ClockType
from rclpy.event_handler import PublisherEventCallbacks
from rclpy.exceptions import InvalidParameterTypeException, InvalidParameterValueException
from rclpy.executors import Executor, ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter as RosParameter
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import Imu, NavSatFix
from vessel_kinematics.params import NavigatorParams, ParameterError, PARAMETERS
from vessel_kinematics.pipeline import Output, Pipeline

NODE_NAME = 'navigator'

#: Message class of each output topic (the pipeline decides what to publish and when).
OUTPUT_TYPES: dict[str, type] = {
    'odometry': Odometry,
    'odometry/local': Odometry,
    'odometry/ned': Odometry,
    'course_sideslip': Vector3Stamped,
    'current': Vector3Stamped,
    'relative_flow': Vector3Stamped,
    'fix/filtered': NavSatFix,
    'origin': NavSatFix,
}

#: Depth of the input queues: 50 ms of a 400 Hz IMU, so a short stall drops nothing.
INPUT_DEPTH = 20
#: Depth of the output queues (reliable).
OUTPUT_DEPTH = 10
#: Minimum time between two warnings of the same rejection reason (s).
WARN_PERIOD = 5.0
#: Longest time (s) between two reads of the outputs' subscription counts (see
#: :meth:`Navigator._listened`); a publisher's ``matched`` event also refreshes them at once.
LISTENED_REFRESH = 0.5
#: Period of ``/diagnostics`` (s), on the steady clock so that it runs without a ``/clock`` too.
DIAGNOSTICS_PERIOD = 1.0

# Names set on the command line or in a params file that are not the navigator's but are fine.
_FOREIGN_PARAMETER_PREFIXES = ('use_sim_time', 'qos_overrides.', 'start_type_description_service')


class StartupError(RuntimeError):
    """The node cannot start: a parameter is invalid. The message says which and why."""


def _descriptor_type(default: Any) -> int:
    """Return the rcl_interfaces ParameterType of a parameter from its default value."""
    if isinstance(default, bool):
        return ParameterType.PARAMETER_BOOL
    if isinstance(default, str):
        return ParameterType.PARAMETER_STRING
    if isinstance(default, int):
        return ParameterType.PARAMETER_INTEGER
    if isinstance(default, float):
        return ParameterType.PARAMETER_DOUBLE
    if isinstance(default, (list, tuple)):
        return ParameterType.PARAMETER_DOUBLE_ARRAY
    raise TypeError(f'no ROS parameter type for the default {default!r}')


def _plain(value: Any) -> Any:
    """Return a ROS parameter value as from_flat expects it (arrays become lists)."""
    if isinstance(value, (array.array, tuple)):
        return list(value)
    return value


def sensor_qos(name: str) -> QoSProfile:
    """Return the input QoS for ``sensor_qos`` (``sensor_data``: best effort; ``reliable``)."""
    reliability = (ReliabilityPolicy.RELIABLE if name == 'reliable'
                   else ReliabilityPolicy.BEST_EFFORT)
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=INPUT_DEPTH,
                      reliability=reliability, durability=DurabilityPolicy.VOLATILE)


def output_qos(topic: str) -> QoSProfile:
    """Return the output QoS: reliable; ``origin`` transient-local depth 1 (latched)."""
    if topic == 'origin':
        return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                          reliability=ReliabilityPolicy.RELIABLE,
                          durability=DurabilityPolicy.TRANSIENT_LOCAL)
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=OUTPUT_DEPTH,
                      reliability=ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.VOLATILE)


def _tf_broadcasters(node: Node) -> tuple[Any, Any] | None:
    """Return (TransformBroadcaster, StaticTransformBroadcaster) or None without tf2_ros."""
    try:
        from tf2_ros import StaticTransformBroadcaster, TransformBroadcaster
    except ImportError:
        return None
    return TransformBroadcaster(node), StaticTransformBroadcaster(node)


class Navigator(Node):
    """
    The navigator node: parameters, QoS, subscriptions, publishers, diagnostics and TF.

    Each input callback is ``pipeline.handle(name, msg)`` followed by one ``publish`` per
    returned :class:`~vessel_kinematics.pipeline.Output`; a rejection is counted by the
    pipeline and warned about at most every :data:`WARN_PERIOD` seconds per reason; an
    unexpected exception is logged and counted (``internal_error/<input>``), never fatal.
    """

    def __init__(self, **node_kwargs: Any) -> None:
        super().__init__(NODE_NAME, **node_kwargs)
        self._declare_parameters()
        self.params = self._read_params()
        self.pipeline = Pipeline(self.params)

        # The outputs somebody listens to ('origin' always: it is latched), refreshed at most
        # every LISTENED_REFRESH s or on a publisher's matched event: the pipeline builds
        # only these.
        self._listened_topics: frozenset[str] = frozenset({'origin'})
        self._listened_due = 0.0
        self._publishers_by_topic = {
            topic: self.create_publisher(msg_type, topic, output_qos(topic),
                                         event_callbacks=self._matched_callbacks())
            for topic, msg_type in OUTPUT_TYPES.items()}
        self._diagnostics_pub = self.create_publisher(
            DiagnosticArray, '/diagnostics', OUTPUT_QOS_DIAGNOSTICS)
        self._subscriptions_by_input: dict[str, Any] = {}
        self._subscribe()

        self._errors: dict[str, int] = {}
        self._last_warning: dict[str, float] = {}
        self._suppressed: dict[str, int] = {}

        self._tf = _tf_broadcasters(self) if self.params.publish_tf else None
        if self.params.publish_tf and self._tf is None:
            self.get_logger().info('tf2_ros is not available: no TF is broadcast '
                                   '(the odometry topics carry the same poses)')

        self._snapshot_timer = None
        self._make_snapshot_timer()
        self._steady_clock = Clock(clock_type=ClockType.STEADY_TIME)
        self._diagnostics_timer = self.create_timer(
            DIAGNOSTICS_PERIOD, self._guarded('diagnostics', self._publish_diagnostics),
            clock=self._steady_clock)

        self._pending: NavigatorParams | None = None
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self.add_post_set_parameters_callback(self._after_set_parameters)
        self.get_logger().info(
            f'navigator ready: inputs {", ".join(sorted(self._subscriptions_by_input))} '
            f'({self.params.sensor_qos} QoS), velocity {self.params.velocity_source} '
            f'({self.params.velocity_reference} reference), '
            f'frames {self.params.map_frame}/{self.params.odom_frame}/{self.params.base_frame}')

    # --- parameters -------------------------------------------------------------------------

    def _declare_parameters(self) -> None:
        """Declare every navigator parameter, typed, with its description."""
        for parameter in PARAMETERS:
            descriptor = ParameterDescriptor(
                name=parameter.name, type=_descriptor_type(parameter.default),
                description=parameter.description)
            try:
                self.declare_parameter(parameter.name, parameter.default, descriptor)
            except (InvalidParameterTypeException, InvalidParameterValueException) as error:
                expected = RosParameter.Type(descriptor.type).name.lower().replace('_', ' ')
                raise StartupError(
                    f'parameter {parameter.name!r}: must be a {expected} '
                    f'(e.g. {parameter.default!r}); {error}') from error
        overrides = getattr(self, '_parameter_overrides', {})
        known = {p.name for p in PARAMETERS}
        for name in sorted(overrides):
            if name not in known and not name.startswith(_FOREIGN_PARAMETER_PREFIXES):
                self.get_logger().warning(
                    f'parameter {name!r} is not a navigator parameter: ignored (a typo?)')

    def _current_values(self) -> dict[str, Any]:
        """Return the navigator's parameter values by ROS name."""
        return {p.name: _plain(self.get_parameter(p.name).value) for p in PARAMETERS}

    def _read_params(self) -> NavigatorParams:
        """Validate the declared values; raise StartupError with the reason."""
        try:
            return NavigatorParams.from_flat(self._current_values())
        except ParameterError as error:
            raise StartupError(str(error)) from error

    def _on_set_parameters(self, parameters: list[RosParameter]) -> SetParametersResult:
        """Validate a ``param set`` against the other current values; refuse with the reason."""
        values = self._current_values()
        for parameter in parameters:
            if parameter.name in values:
                values[parameter.name] = _plain(parameter.value)
        try:
            self._pending = NavigatorParams.from_flat(values)
        except ParameterError as error:
            self._pending = None
            return SetParametersResult(successful=False, reason=str(error))
        return SetParametersResult(successful=True)

    def _after_set_parameters(self, parameters: list[RosParameter]) -> None:
        """Apply parameters once set: pipeline, subscriptions, timer; publish its outputs."""
        new, self._pending = self._pending, None
        if new is None or new == self.params:
            return
        try:
            self._apply(new)
        except Exception:  # noqa: B902 (a bad apply must not take the node down)
            self._count_error('parameters')
            self.get_logger().error(
                f'applying parameters failed:\n{traceback.format_exc()}')

    def _apply(self, new: NavigatorParams) -> None:
        old, self.params = self.params, new
        outputs = self.pipeline.set_params(new)
        if (new.sensor_qos, new.velocity_source) != (old.sensor_qos, old.velocity_source):
            self._subscribe()
        if new.publish_rate != old.publish_rate:
            self._make_snapshot_timer()
        if new.publish_tf and self._tf is None:
            self._tf = _tf_broadcasters(self)
        changed = sorted(k for k, v in new.to_flat().items() if old.to_flat()[k] != v)
        self.get_logger().info(f'parameters changed: {", ".join(changed)}')
        self._publish(outputs)

    # --- inputs -----------------------------------------------------------------------------

    def _subscribe(self) -> None:
        """(Re)create the input subscriptions for the current QoS and velocity source."""
        for subscription in self._subscriptions_by_input.values():
            self.destroy_subscription(subscription)
        self._subscriptions_by_input = {}
        qos = sensor_qos(self.params.sensor_qos)
        types: dict[str, type | None] = {
            'fix': NavSatFix, 'imu': Imu, 'velocity': self.pipeline.velocity_type()}
        for name, msg_type in types.items():
            if msg_type is None:
                continue
            self._subscriptions_by_input[name] = self.create_subscription(
                msg_type, name, self._input_callback(name), qos)

    def _matched_callbacks(self) -> PublisherEventCallbacks:
        """Return publisher event callbacks: a (un)matched subscriber refreshes the listened."""
        def matched(_status: Any) -> None:
            self._listened_due = 0.0
        return PublisherEventCallbacks(matched=matched)

    def _listened(self) -> frozenset[str]:
        """
        Return the outputs with a subscriber, plus ``origin`` (a frozenset: same object if same).

        ``get_subscription_count`` is asked at most every :data:`LISTENED_REFRESH` s (and at
        the next message after a publisher's matched event), not per message.
        """
        now = time.monotonic()
        if now < self._listened_due:
            return self._listened_topics
        self._listened_due = now + LISTENED_REFRESH
        listened = frozenset(
            [topic for topic, publisher in self._publishers_by_topic.items()
             if topic == 'origin' or publisher.get_subscription_count() > 0])
        if listened != self._listened_topics:
            self._listened_topics = listened
        return self._listened_topics

    def _input_callback(self, name: str) -> Callable[[Any], None]:
        """Return the callback of input ``name``: handle, warn on rejection, publish."""
        handle = self.pipeline.handle
        publish = self._publish
        listened = self._listened

        def callback(msg: Any) -> None:
            try:
                result = handle(name, msg, listened())
                if result.rejected is not None:
                    self._warn_rejected(name, result.rejected, result.detail)
                if result.outputs:
                    publish(result.outputs)
                elif (self._tf is not None and result.rejected is None
                      and self.params.publish_rate <= 0.0):
                    publish(result.outputs, tf=True)   # TF though no topic is listened to
            except Exception:  # noqa: B902 (one bad message must never stop the node)
                self._count_error(name)
                self._warn_throttled(
                    f'internal_error/{name}',
                    f'unexpected error on {name!r} (message dropped):\n{traceback.format_exc()}',
                    error=True)
        return callback

    def _guarded(self, name: str, function: Callable[[], None]) -> Callable[[], None]:
        """Wrap a timer callback so that an exception is logged and counted, not fatal."""
        def callback() -> None:
            try:
                function()
            except Exception:  # noqa: B902 (a timer must never stop the node)
                self._count_error(name)
                self._warn_throttled(f'internal_error/{name}',
                                     f'unexpected error in {name}:\n{traceback.format_exc()}',
                                     error=True)
        return callback

    def _count_error(self, name: str) -> None:
        key = f'internal_error/{name}'
        self._errors[key] = self._errors.get(key, 0) + 1

    def _warn_rejected(self, name: str, reason: str, detail: str | None) -> None:
        self._warn_throttled(f'{name}/{reason}',
                             f'rejected {name} message ({reason}): {detail or reason}')

    def _warn_throttled(self, key: str, text: str, *, error: bool = False) -> None:
        """Log ``text`` at most every WARN_PERIOD s per ``key``, saying how many were quiet."""
        now = time.monotonic()
        last = self._last_warning.get(key)
        if last is not None and now - last < WARN_PERIOD:
            self._suppressed[key] = self._suppressed.get(key, 0) + 1
            return
        self._last_warning[key] = now
        quiet = self._suppressed.pop(key, 0)
        if quiet:
            text += f' ({quiet} more like this in the last {now - last:.0f} s)'
        logger = self.get_logger()
        (logger.error if error else logger.warning)(text)

    # --- outputs ----------------------------------------------------------------------------

    def _publish(self, outputs: Sequence[Output], tf: bool = False) -> None:
        """
        Publish the pipeline's outputs (and TF when broadcasting, or when ``tf``).

        The pipeline built only the listened outputs (:meth:`_listened`), so each is published
        without asking for subscribers per message; ``origin`` is latched, always published.
        """
        publishers = self._publishers_by_topic
        origin_changed = False
        for output in outputs:
            if output.topic == 'origin':
                origin_changed = True
            publishers[output.topic].publish(output.msg)
        if self._tf is not None and self.params.publish_tf and (outputs or tf):
            broadcaster, static_broadcaster = self._tf
            transforms = self.pipeline.transforms()
            if transforms:
                broadcaster.sendTransform(transforms)
            if origin_changed:
                static_broadcaster.sendTransform(self.pipeline.static_transforms())

    def _make_snapshot_timer(self) -> None:
        """(Re)create the publish_rate timer on the node clock (follows /clock in sim time)."""
        if self._snapshot_timer is not None:
            self.destroy_timer(self._snapshot_timer)
            self._snapshot_timer = None
        if self.params.publish_rate > 0.0:
            self._snapshot_timer = self.create_timer(
                1.0 / self.params.publish_rate,
                self._guarded('snapshot', lambda: self._publish(
                    self.pipeline.snapshot(self._listened()), tf=True)))

    def _publish_diagnostics(self) -> None:
        """Publish the pipeline's DiagnosticArray, with the node's own error counts added."""
        diagnostics = self.pipeline.diagnostics(self.get_clock().now().nanoseconds)
        if diagnostics is None:
            return
        if diagnostics.status:
            values = diagnostics.status[0].values
            values.append(KeyValue(key='internal_errors',
                                   value=str(sum(self._errors.values()))))
            for key, count in sorted(self._errors.items()):
                values.append(KeyValue(key=key, value=str(count)))
        self._diagnostics_pub.publish(diagnostics)


OUTPUT_QOS_DIAGNOSTICS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=OUTPUT_DEPTH,
                                    reliability=ReliabilityPolicy.RELIABLE,
                                    durability=DurabilityPolicy.VOLATILE)


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


def main(args: Sequence[str] | None = None) -> int:
    """Run the navigator until SIGINT/SIGTERM; return 1 when a parameter is invalid."""
    rclpy.init(args=args)
    node: Navigator | None = None
    try:
        try:
            node = Navigator()
        except StartupError as error:
            rclpy.logging.get_logger(NODE_NAME).fatal(f'cannot start: {error}')
            return 1
        executor = make_executor()
        executor.add_node(node)
        # spin_once in a loop rather than spin(): the EventsExecutor's spin() does not return
        # when rclpy's signal handler shuts the context down; this loop notices within 0.2 s.
        while rclpy.ok():
            executor.spin_once(timeout_sec=0.2)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main())
