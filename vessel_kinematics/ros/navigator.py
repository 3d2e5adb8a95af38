"""
The ``navigator`` rclpy node: NavSatFix + Imu + body velocity in, Odometry and course out.

The node is a thin driver around :class:`~vessel_kinematics.ros.pipeline.Pipeline`: it declares the
parameters of :data:`~vessel_kinematics.ros.params.PARAMETERS`, validates them with
:meth:`~vessel_kinematics.ros.params.NavigatorParams.from_flat`, subscribes to the relative topics
``fix``, ``imu`` and ``velocity``, hands every message to :meth:`Pipeline.handle` and publishes
what it returns. All conversion and estimation happen in the pipeline, so the offline replay
gives the same outputs. The outputs come as the CDR bytes of their messages (``ros_io``'s
builders, checked against rclpy's serialisation in test_ros_io) and are published as they are
(``Publisher.publish`` of bytes): the very bytes the replay writes, and no rclpy message built
or serialised per output (a fifth of the node's CPU at 30 Hz, a third of an emitting callback).
Inbound, the 400 Hz ``imu`` is taken raw and read straight from its CDR, as the replay reads it
(:data:`RAW_INPUTS`); a payload that does not deserialise is counted as ``imu/cdr_error``.

Run it as ``ros2 run vessel_kinematics navigator --ros-args --params-file navigator.yaml``.
"""

from __future__ import annotations

import array
import os
import sys
import textwrap
import time
import traceback
from typing import Any, Callable, Iterable, Sequence

from diagnostic_msgs.msg import DiagnosticArray, KeyValue
from rcl_interfaces.msg import (FloatingPointRange, ParameterDescriptor, ParameterType,
                                SetParametersResult)
import rclpy
from rclpy.clock import Clock, ClockType
from rclpy.event_handler import PublisherEventCallbacks
from rclpy.exceptions import InvalidParameterTypeException, InvalidParameterValueException
from rclpy.executors import Executor, ExternalShutdownException, SingleThreadedExecutor
from rclpy.impl.implementation_singleton import rclpy_implementation
from rclpy.node import Node
from rclpy.parameter import Parameter as RosParameter
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.qos_overriding_options import QoSOverridingOptions
from vessel_kinematics.ros import interface, ros_io
from vessel_kinematics.ros.params import (FOREIGN_PARAMETER_PREFIXES, NavigatorParams,
                                          ParameterError, PARAMETERS)
from vessel_kinematics.ros.pipeline import Pipeline
from vessel_kinematics.ros.session import (Emission, fewer_collections, Session, TF,
                                           TF_STATIC)
import yaml

__all__ = ['DIAGNOSTICS_PERIOD', 'INPUT_DEPTH', 'LISTENED_REFRESH', 'main', 'make_executor',
           'Navigator', 'NODE_NAME', 'OUTPUT_DEPTH', 'output_qos', 'OUTPUT_QOS_DIAGNOSTICS',
           'OUTPUT_TYPES', 'RCLError', 'RESUBSCRIBE_ATTEMPTS', 'RESUBSCRIBE_PERIOD', 'sensor_qos',
           'StartupError', 'TF_QOS', 'TF_STATIC_LISTENER_QOS', 'TF_STATIC_QOS', 'USAGE',
           'WARN_PERIOD']

NODE_NAME = 'navigator'
#: What rcl raises when the middleware refuses an entity.
RCLError = rclpy_implementation.RCLError

#: Message class of each output topic (the interface table; the pipeline decides what to
#: publish and when).
OUTPUT_TYPES: dict[str, type] = {
    t.name: interface.message_class(t.msg_type) for t in interface.by_role(interface.Role.OUTPUT)
    if t.msg_type is not None}

#: Inputs subscribed raw (their serialised payload) and read here: the 400 Hz Imu straight
#: from its CDR, as the replay reads it (:func:`ros_io.imu_from_raw`: rclpy builds no message,
#: about 4 us against 50 us).
RAW_INPUTS: dict[str, Callable[[Any], Any]] = {'imu': ros_io.imu_from_raw}
#: Depth of the input queues: 50 ms of a 400 Hz IMU, so a short stall drops nothing.
INPUT_DEPTH = 20
#: Depth of the output queues (reliable).
OUTPUT_DEPTH = 10
#: Minimum time between two warnings of the same rejection reason (s).
WARN_PERIOD = 5.0
#: Longest time (s) between two reads of the outputs' subscription counts (see
#: :meth:`Navigator._listened`); a publisher's ``matched`` event also refreshes them at once.
LISTENED_REFRESH = 0.5
#: A subscription the middleware refused (the old one of another type not finalised yet) is
#: retried this often (s, steady clock), at most this many times.
RESUBSCRIBE_PERIOD = 0.05
RESUBSCRIBE_ATTEMPTS = 200
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
    if isinstance(default, (list, tuple)) and default and isinstance(default[0], str):
        return ParameterType.PARAMETER_STRING_ARRAY
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
    """Return the output QoS: reliable; a latched one (``origin``) transient-local depth 1."""
    if interface.topic(topic).latched:
        return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                          reliability=ReliabilityPolicy.RELIABLE,
                          durability=DurabilityPolicy.TRANSIENT_LOCAL)
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=OUTPUT_DEPTH,
                      reliability=ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.VOLATILE)


#: /tf as tf2's TransformBroadcaster offers it: reliable, volatile, keep last 100.
TF_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=100,
                    reliability=ReliabilityPolicy.RELIABLE,
                    durability=DurabilityPolicy.VOLATILE)
#: /tf_static as tf2's StaticTransformBroadcaster offers it: reliable, transient-local, keep
#: last 1 (every static transform in that one message).
TF_STATIC_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                           reliability=ReliabilityPolicy.RELIABLE,
                           durability=DurabilityPolicy.TRANSIENT_LOCAL)
#: /tf_static as tf2's static listener subscribes: reliable, transient-local, keep last 100
#: (the latched message of every broadcaster, a URDF's robot_state_publisher and each
#: static_transform_publisher, arrives on subscription).
TF_STATIC_LISTENER_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=100,
                                    reliability=ReliabilityPolicy.RELIABLE,
                                    durability=DurabilityPolicy.TRANSIENT_LOCAL)


def _tf_message_type() -> type | None:
    """Return tf2_msgs/TFMessage, or None where tf2_msgs is not installed."""
    try:
        from tf2_msgs.msg import TFMessage
    except ImportError:
        return None
    return TFMessage


class Navigator(Node):
    """
    The navigator node: parameters, QoS, subscriptions, publishers, diagnostics and TF.

    Each input callback is :meth:`~vessel_kinematics.ros.session.Session.handle` (the output
    policy the replay runs too) followed by a ``publish`` per emission; a rejection is
    counted by the pipeline and warned about at most every :data:`WARN_PERIOD` seconds per
    reason; an unexpected exception is logged and counted (``internal_error/<input>``), never
    fatal.
    """

    def __init__(self, **node_kwargs: Any) -> None:
        super().__init__(NODE_NAME, **node_kwargs)
        self._declare_parameters()
        self.params = self._read_params()
        # Outputs as the CDR bytes of their messages (the ros_io builders the replay writes),
        # published as they are (rclpy's publish_raw): no rclpy message built or serialised.
        self.pipeline = Pipeline(self.params, cdr=True)
        self.session = Session(self.pipeline)

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
        self._unsubscribed: dict[str, type] = {}
        self._resubscribe_timer: Any = None
        self._resubscribe_attempts = 0
        self._steady_clock = Clock(clock_type=ClockType.STEADY_TIME)
        self._subscribe()

        self._errors: dict[str, int] = {}
        self._last_warning: dict[str, float] = {}
        self._suppressed: dict[str, int] = {}

        # TF: plain publishers of tf2_msgs/TFMessage on /tf and /tf_static (all that tf2's
        # broadcasters do), created once tf.publish chooses a transform.
        self._tf_type: Any = _tf_message_type()
        self._tf_pub: Any = None
        self._tf_static_pub: Any = None
        self._setup_tf()
        # The sensors' mountings: a static-transform listener on /tf_static (the pipeline
        # keeps the tree; no tf2 buffer is needed for static frames).
        self._tf_static_sub: Any = None
        if self._tf_type is not None:
            self._tf_static_sub = self.create_subscription(
                self._tf_type, '/tf_static', self._guarded_msg('tf_static', self._on_tf_static),
                TF_STATIC_LISTENER_QOS)
        else:
            self.get_logger().warning(
                'tf2_msgs is not installed: /tf_static is not read, the mountings come from '
                'the parameters')

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
        coerce = []
        for parameter in PARAMETERS:
            kind = _descriptor_type(parameter.default)
            # Doubles take integers too (users write max_gap: 2, origin: [59, 10, 0]): typed
            # dynamically, then validated by NavigatorParams.from_flat and stored as doubles.
            numeric = kind in (ParameterType.PARAMETER_DOUBLE,
                               ParameterType.PARAMETER_DOUBLE_ARRAY)
            descriptor = ParameterDescriptor(
                name=parameter.name, type=kind, description=parameter.description,
                dynamic_typing=numeric, read_only=bool(getattr(parameter, 'read_only', False)))
            low, high = getattr(parameter, 'low', None), getattr(parameter, 'high', None)
            if kind == ParameterType.PARAMETER_DOUBLE and low is not None and high is not None:
                descriptor.floating_point_range = [
                    FloatingPointRange(from_value=float(low), to_value=float(high))]
            try:
                self.declare_parameter(parameter.name, parameter.default, descriptor)
            except (InvalidParameterTypeException, InvalidParameterValueException) as error:
                expected = RosParameter.Type(descriptor.type).name.lower().replace('_', ' ')
                raise StartupError(
                    f'parameter {parameter.name!r}: must be a {expected} '
                    f'(e.g. {parameter.default!r}); {error}') from error
            if numeric:
                coerce.append((parameter.name, kind))
        self._coerce_numbers(coerce)
        overrides = getattr(self, '_parameter_overrides', {})
        known = {p.name for p in PARAMETERS}
        for name in sorted(overrides):
            if name not in known and not name.startswith(FOREIGN_PARAMETER_PREFIXES):
                self.get_logger().warning(
                    f'parameter {name!r} is not a navigator parameter: ignored (a typo?)')

    def _coerce_numbers(self, names: list[tuple[str, int]]) -> None:
        """Store integer values of double parameters as doubles (refuse non-numbers)."""
        coerced = []
        for name, kind in names:
            value = _plain(self.get_parameter(name).value)
            problem = None
            if kind == ParameterType.PARAMETER_DOUBLE:
                if isinstance(value, bool) or not isinstance(value, (int, float)):
                    problem = 'a double'
                elif isinstance(value, int):
                    coerced.append(RosParameter(name, RosParameter.Type.DOUBLE, float(value)))
            else:
                if not isinstance(value, list) or not all(
                        isinstance(v, (int, float)) and not isinstance(v, bool) for v in value):
                    problem = 'a list of doubles'
                elif any(isinstance(v, int) for v in value):
                    coerced.append(RosParameter(name, RosParameter.Type.DOUBLE_ARRAY,
                                                [float(v) for v in value]))
            if problem:
                raise StartupError(f'parameter {name!r}: must be {problem}, got {value!r}')
        if coerced:
            self.set_parameters(coerced)

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
        emissions = self.session.set_params(new)
        if (new.sensor_qos, new.velocity_source) != (old.sensor_qos, old.velocity_source):
            self._subscribe()
        self._setup_tf()
        changed = sorted(k for k, v in new.to_flat().items() if old.to_flat()[k] != v)
        self.get_logger().info(f'parameters changed: {", ".join(changed)}')
        self._send(emissions)

    # --- inputs -----------------------------------------------------------------------------

    def _subscribe(self) -> None:
        """
        (Re)create the input subscriptions for the current QoS and velocity source.

        The old subscriptions are destroyed first. An executor may still hold one (the
        EventsExecutor until it refreshes its entities, any executor while it waits on it), and
        until it is finalised the middleware refuses a subscription of another type on the same
        topic: such an input is retried every :data:`RESUBSCRIBE_PERIOD` s from a timer (the
        executor has dropped the old one by then), never left without a subscription silently.
        """
        for subscription in self._subscriptions_by_input.values():
            self.destroy_subscription(subscription)
        self._subscriptions_by_input = {}
        types: dict[str, type | None] = {
            name: interface.message_class(msg_type) for name, msg_type in interface.types(
                interface.Role.INPUT, velocity_source=self.params.velocity_source,
                absolute=False).items()}
        self._unsubscribed = {name: t for name, t in types.items() if t is not None}
        self._resubscribe_attempts = 0
        self._create_subscriptions()

    def _create_subscriptions(self) -> None:
        """Create the subscriptions still missing; retry from a timer those refused."""
        qos = sensor_qos(self.params.sensor_qos)
        refused = {}
        for name, msg_type in self._unsubscribed.items():
            try:
                decode = RAW_INPUTS.get(name)
                self._subscriptions_by_input[name] = self.create_subscription(
                    msg_type, name, self._input_callback(name, decode), qos,
                    qos_overriding_options=QoSOverridingOptions.with_default_policies(),
                    raw=decode is not None)
            except RCLError as error:   # the old subscription of another type still exists
                refused[name] = msg_type
                last_error = str(error).splitlines()[0]
        self._unsubscribed = refused
        if not refused:
            if self._resubscribe_timer is not None:
                self.destroy_timer(self._resubscribe_timer)
                self._resubscribe_timer = None
                inputs = ', '.join(sorted(self._subscriptions_by_input))
                self.get_logger().info(f'inputs resubscribed: {inputs}')
            return
        self._resubscribe_attempts += 1
        if self._resubscribe_attempts > RESUBSCRIBE_ATTEMPTS:
            self.get_logger().error(
                f'cannot subscribe to {", ".join(sorted(refused))}: {last_error}')
            if self._resubscribe_timer is not None:
                self.destroy_timer(self._resubscribe_timer)
                self._resubscribe_timer = None
            return
        if self._resubscribe_timer is None:
            self._resubscribe_timer = self.create_timer(
                RESUBSCRIBE_PERIOD, self._guarded('subscribe', self._create_subscriptions),
                clock=self._steady_clock)

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

    def _input_callback(self, name: str,
                        decode: Callable[[Any], Any] | None = None) -> Callable[[Any], None]:
        """
        Return the callback of input ``name``: the session's input, warnings, sending.

        ``decode``: the input is subscribed raw, and this reads each payload (:data:`RAW_INPUTS`).
        """
        session_handle = self.session.handle
        send = self._send
        listened = self._listened

        def callback(msg: Any) -> None:
            try:
                if decode is not None:
                    msg = decode(msg)
                result, emissions = session_handle(name, msg, listened())
                if result.info is not None:
                    self.get_logger().info(result.info)
                if result.rejected is not None:
                    self._warn_rejected(name, result.rejected, result.detail)
                if emissions:
                    send(emissions)
            except Exception:  # noqa: B902 (one bad message must never stop the node)
                self._count_error(name)
                self._warn_throttled(
                    f'internal_error/{name}',
                    f'unexpected error on {name!r} (message dropped):\n{traceback.format_exc()}',
                    error=True)
        return callback

    def _on_tf_static(self, msg: Any) -> None:
        """Take a /tf_static message into the pipeline's static tree."""
        refused = dict(self.pipeline.static_tree.refused)
        changed = self.pipeline.tf_static(msg)
        if changed:
            self.get_logger().debug(f'/tf_static: {changed} static transforms changed')
        now = self.pipeline.static_tree.refused
        for reason, count in now.items():
            if count > refused.get(reason, 0):
                self._warn_throttled(f'tf_static/{reason}',
                                     f'/tf_static: refused {count - refused.get(reason, 0)} '
                                     f'transform(s) ({reason})')

    def _guarded_msg(self, name: str, function: Callable[[Any], None]) -> Callable[[Any], None]:
        """Wrap a subscription callback so that an exception is logged and counted."""
        def callback(msg: Any) -> None:
            try:
                function(msg)
            except Exception:  # noqa: B902 (one bad message must never stop the node)
                self._count_error(name)
                self._warn_throttled(f'internal_error/{name}',
                                     f'unexpected error in {name}:\n{traceback.format_exc()}',
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
        last = now if last is None else last
        self._last_warning[key] = now
        quiet = self._suppressed.pop(key, 0)
        if quiet:
            text += f' ({quiet} more like this in the last {now - last:.0f} s)'
        logger = self.get_logger()
        (logger.error if error else logger.warning)(text)

    # --- outputs ----------------------------------------------------------------------------

    def _send(self, emissions: Iterable[Emission]) -> None:
        """
        Publish what the session emits: outputs to their publishers, transforms to /tf(_static).

        The pipeline built only the listened outputs (:meth:`_listened`), so each is published
        without asking for subscribers per message; ``origin`` is latched, always published.
        Each emission is built as it is taken, so ``odometry`` leaves before the last output
        is built.
        """
        publishers = self._publishers_by_topic
        for emission in emissions:
            if emission.topic == TF:        # the CDR of a TFMessage
                if self._tf_pub is not None:
                    self._tf_pub.publish(emission.payload)
            elif emission.topic == TF_STATIC:
                if self._tf_static_pub is not None:
                    self._tf_static_pub.publish(self._tf_type(transforms=emission.payload))
            else:
                publishers[emission.topic[1:]].publish(emission.payload)

    def _setup_tf(self) -> None:
        """Create the /tf and /tf_static publishers that ``tf.publish`` needs; send statics."""
        wanted = self.params.tf_set
        if not self.params.publish_tf:
            self._warn_throttled('publish_tf', 'publish_tf is deprecated: use tf.publish: '
                                 '[none] (publish_tf false overrides tf.publish)')
        if wanted and self._tf_type is None:
            self.get_logger().error(
                'tf2_msgs is not installed: no /tf or /tf_static is published (the odometry '
                'topics carry the same poses); install ros-jazzy-tf2-msgs')
            return
        if wanted & {'map_odom', 'odom_base'} and self._tf_pub is None:
            self._tf_pub = self.create_publisher(self._tf_type, '/tf', TF_QOS)
        elif not wanted & {'map_odom', 'odom_base'} and self._tf_pub is not None:
            self.destroy_publisher(self._tf_pub)
            self._tf_pub = None
        if wanted & {'earth_map', 'frd_ned'} and self._tf_static_pub is None:
            self._tf_static_pub = self.create_publisher(self._tf_type, '/tf_static',
                                                        TF_STATIC_QOS)
        self._send(self.session.statics())

    def _publish_diagnostics(self) -> None:
        """Publish the pipeline's DiagnosticArray, with the node's own error counts added."""
        diagnostics = self.pipeline.diagnostics(self.get_clock().now().nanoseconds,
                                                self.get_name())
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


def _user_args(argv: Sequence[str]) -> list[str]:
    """Return the arguments outside ``--ros-args ... [--]`` (without parsing the ROS ones)."""
    user, in_ros = [], False
    for arg in argv[1:]:
        if arg == '--ros-args':
            in_ros = True
        elif in_ros and arg == '--':
            in_ros = False
        elif not in_ros:
            user.append(arg)
    return user


def _params_file_problem(argv: Sequence[str]) -> str | None:
    """Return why a ``--params-file`` of ``argv`` cannot be read as YAML, or None."""
    for flag, path in zip(argv, argv[1:]):
        if flag != '--params-file':
            continue
        try:
            with open(path, encoding='utf-8') as stream:
                yaml.safe_load(stream)
        except OSError as error:
            return f'cannot read --params-file {path}: {error.strerror}'
        except (yaml.YAMLError, UnicodeDecodeError) as error:
            return f'--params-file {path} is not valid YAML: {str(error).splitlines()[0]}'
    return None


def main(args: Sequence[str] | None = None) -> int:
    """Run the navigator until SIGINT/SIGTERM; return 1 when a parameter is invalid."""
    argv = list(sys.argv if args is None else args)
    if {'-h', '--help'} & set(_user_args(argv)):
        print(USAGE)
        return 0
    problem = _params_file_problem(argv)
    if problem:
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
            rclpy.logging.get_logger(NODE_NAME).fatal(f'cannot start: {error}')
            return 1
        executor = make_executor()
        executor.add_node(node)
        # spin_once in a loop rather than spin(): the EventsExecutor's spin() does not return
        # when rclpy's signal handler shuts the context down; this loop notices within 0.2 s.
        with fewer_collections():
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
