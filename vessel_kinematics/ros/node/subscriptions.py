"""
The node's subscriptions: the inputs, ``/tf_static`` and a guarded ``/clock``.

:class:`NodeInputs` subscribes to the relative topics of ``fix.topics`` and ``imu.topics`` (its
type per ``imu.source``), ``velocity`` (per ``velocity.source``) and ``gnss_velocity`` (per
``gnss_velocity.source``) with the inputs' QoS (``sensor_qos``; ``qos_overrides`` per topic as
rclpy reads them) and hands each message to ``on_message(name, msg)``. Every input is taken raw
and deserialised here, so that a payload that is no message of its type reaches the pipeline as
a ``cdr_error`` to count, as in the replay (the middleware would drop it unseen); the 400 Hz
``imu`` is read straight from its CDR (:mod:`~vessel_kinematics.ros.imu_cdr`), as the replay
reads it. A change of source or QoS subscribes anew; the middleware may refuse a subscription
of another type on a topic until the executor let go of the old one, so a refused input is
retried from a timer, never left without a subscription silently. An input topic silent for
:data:`INPUT_SILENCE` s while a publisher is matched is subscribed anew (:meth:`NodeInputs.
revive`): one empty payload from a reliable peer wedges the DDS reader for that peer, and
nothing of it arrives again, while a new reader takes its next messages.

``/tf_static`` is read as tf2's static listener reads it (the sensors' mountings), raw: the
node checks a message's size before it deserialises it. With
``use_sim_time`` rclpy's own ``/clock`` subscription is wrapped so that a message it cannot take
(a negative ``sec``) is counted and dropped, not raised through the executor.
"""

from __future__ import annotations

from functools import partial
import time
from typing import Any, Callable

from rclpy.clock import Clock, ClockType
from rclpy.impl.implementation_singleton import rclpy_implementation
from rclpy.node import Node
from rclpy.qos_overriding_options import QoSOverridingOptions
from sensor_msgs.msg import Imu
from vessel_kinematics.ros import interface
from vessel_kinematics.ros.imu_cdr import imu_from_raw, message_from_raw
from vessel_kinematics.ros.node.qos import qos_profile
from vessel_kinematics.ros.params import NavigatorParams, SensorQos

__all__ = ['INPUT_SILENCE', 'NodeInputs', 'RESUBSCRIBE_ATTEMPTS', 'RESUBSCRIBE_PERIOD']

#: What rcl raises when the middleware refuses an entity.
RCLError = rclpy_implementation.RCLError
#: A refused subscription is retried this often (s, steady clock), at most this many times.
RESUBSCRIBE_PERIOD = 0.05
RESUBSCRIBE_ATTEMPTS = 200
#: An input topic silent this long (s, steady clock) while a publisher is matched is subscribed
#: anew: five fixes of a 1 Hz receiver.
INPUT_SILENCE = 5.0


class NodeInputs:
    """
    The node's input subscriptions.

    ``on_message(name, msg, index)``: an input message (a payload that does not deserialise
    as its ``Rejection``) of the ``index``-th topic of input ``name``; ``on_tf_static(msg)``:
    a /tf_static message (where tf2_msgs exists);
    ``guard(name, function)``: wraps a callback so that nothing it raises leaves it;
    ``on_bad_clock()``: a /clock message rclpy refused.
    """

    def __init__(self, node: Node, params: NavigatorParams,
                 on_message: Callable[[str, Any, int], None],
                 on_tf_static: Callable[[Any], None] | None,
                 guard: Callable[[str, Callable[..., None]], Callable[..., None]],
                 on_bad_clock: Callable[[Exception], None], log: Any) -> None:
        self._node = node
        self._on_message = on_message
        self._guard = guard
        self._log = log
        self._steady = Clock(clock_type=ClockType.STEADY_TIME)
        self._subscriptions: dict[str, Any] = {}
        #: What each input topic is subscribed as: (input name, topic index, message class).
        self._specs: dict[str, tuple[str, int, type]] = {}
        #: The topics of _specs still to subscribe.
        self._missing: dict[str, tuple[str, int, type]] = {}
        #: When each topic's subscription last delivered or was made (time.monotonic()).
        self._heard: dict[str, float] = {}
        self._timer: Any = None
        self._attempts = 0
        self._last_error = ''
        self.params = params
        self.subscribe(params)
        self.tf_static = None
        #: The /tf_static message class (taken raw: ``on_tf_static`` gets the CDR bytes).
        self.tf_static_type: Any = None
        if on_tf_static is not None:
            self.tf_static_type = interface.message_class(
                interface.topic('/tf_static').msg_type or '')
            self.tf_static = node.create_subscription(
                self.tf_static_type, '/tf_static', guard('tf_static', on_tf_static),
                qos_profile(interface.QOS[interface.Qos.TF_STATIC_LISTENER]), raw=True)
        self._guard_clock(guard, on_bad_clock)

    @property
    def names(self) -> list[str]:
        """Return the inputs subscribed to."""
        return sorted(self._subscriptions)

    def problem(self, params: NavigatorParams) -> str | None:
        """
        Return why the input topics of ``params`` cannot be subscribed to, or None.

        Each must resolve by rcl's rules (a tilde only as ``~/``, at most 247 characters in
        full), and none may be one of this node's outputs of another type: rcl refuses a
        second type on a topic within one node, so that input would never be subscribed.
        """
        node = self._node
        outputs = {}
        for name, msg_type in interface.types(interface.Role.OUTPUT,
                                              interface.Role.AUXILIARY).items():
            try:
                outputs[node.resolve_topic_name(name)] = msg_type
            except RCLError:        # an output name with a substitution rcl cannot expand
                continue
        inputs = interface.types(interface.Role.INPUT, imu_source=params.imu_source,
                                 absolute=False)
        for parameter, name, topics in (('fix.topics', 'fix', params.fix_topics),
                                        ('imu.topics', 'imu', params.imu_topics)):
            for topic in topics:
                try:
                    resolved = node.resolve_topic_name(topic)
                except RCLError as error:
                    reason = str(error).splitlines()[0].removeprefix('failed to resolve name: ')
                    reason = reason.split(', at /')[0]     # rcl's source file and line
                    return f"parameter '{parameter}': {topic[:80]!r} is not a topic name: {reason}"
                if resolved in outputs and outputs[resolved] != inputs[name]:
                    return (f"parameter '{parameter}': {resolved} is this node's "
                            f'{outputs[resolved]} output, not a {inputs[name]} input')
        return None

    def subscribe(self, params: NavigatorParams) -> None:
        """(Re)create the input subscriptions for ``params``' QoS, topics and sources."""
        self.params = params
        for subscription in self._subscriptions.values():
            self._node.destroy_subscription(subscription)
        self._subscriptions = {}
        self._specs = {}
        topics = {'fix': params.fix_topics, 'imu': params.imu_topics}
        for name, msg_type in interface.types(
                interface.Role.INPUT, velocity_source=params.velocity_source, absolute=False,
                imu_source=params.imu_source,
                gnss_velocity_source=params.gnss_velocity_source).items():
            for index, topic in enumerate(topics.get(name, (name,))):
                self._specs[topic] = (name, index, interface.message_class(msg_type))
        self._missing = dict(self._specs)
        self._attempts = 0
        self._create()

    def revive(self) -> list[str]:
        """
        Subscribe anew to each input topic silent for INPUT_SILENCE s with a publisher matched.

        Return those topics. The new reader counts as heard now, so a publisher that is there
        and says nothing (a driver without a fix) is subscribed anew once per INPUT_SILENCE.
        """
        now = time.monotonic()
        silent = [topic for topic, subscription in self._subscriptions.items()
                  if now - self._heard.get(topic, now) > INPUT_SILENCE
                  and subscription.get_publisher_count() > 0]
        for topic in silent:
            self._node.destroy_subscription(self._subscriptions.pop(topic))
            self._missing[topic] = self._specs[topic]
        if silent:
            self._attempts = 0
            self._create()
        return silent

    def _callback(self, topic: str, name: str, index: int,
                  msg_type: type) -> Callable[[Any], None]:
        on_message, heard, clock = self._on_message, self._heard, time.monotonic
        decode: Callable[[Any], Any] = (imu_from_raw if msg_type is Imu
                                        else partial(message_from_raw, msg_class=msg_type))

        def take(data: Any) -> None:
            heard[topic] = clock()
            on_message(name, decode(data), index)
        return self._guard(name, take)

    def _create(self) -> None:
        """Create the subscriptions still missing; retry from a timer those refused."""
        qos = qos_profile(interface.input_qos(self.params.sensor_qos is SensorQos.RELIABLE))
        refused = {}
        for topic, (name, index, msg_type) in self._missing.items():
            try:
                self._subscriptions[topic] = self._node.create_subscription(
                    msg_type, topic, self._callback(topic, name, index, msg_type), qos,
                    qos_overriding_options=QoSOverridingOptions.with_default_policies(),
                    raw=True)
                self._heard[topic] = time.monotonic()
            except RCLError as error:   # the old subscription of another type still exists
                refused[topic] = (name, index, msg_type)
                self._last_error = str(error).splitlines()[0]
        self._missing = refused
        if not refused:
            if self._timer is not None:
                self._node.destroy_timer(self._timer)
                self._timer = None
                self._log.info(f'inputs resubscribed: {", ".join(self.names)}')
            return
        self._attempts += 1
        if self._attempts > RESUBSCRIBE_ATTEMPTS:
            self._log.error(f'cannot subscribe to {", ".join(sorted(refused))}: '
                            f'{self._last_error}')
            if self._timer is not None:
                self._node.destroy_timer(self._timer)
                self._timer = None
            return
        if self._timer is None:
            self._timer = self._node.create_timer(
                RESUBSCRIBE_PERIOD, self._guard('subscribe', self._create), clock=self._steady)

    def _guard_clock(self, guard: Callable[[str, Callable[..., None]], Callable[..., None]],
                     on_bad_clock: Callable[[Exception], None]) -> None:
        """
        Wrap rclpy's /clock callback: a message it refuses is counted, not raised.

        So is one whose nanoseconds are not below 10⁹, which rclpy would take as a time
        seconds ahead (an input stamp so made is refused as ``bad_stamp`` too).
        """
        for subscription in self._node.subscriptions:
            if subscription.topic_name != '/clock':
                continue
            take = subscription.callback

            def guarded(msg: Any, take: Callable[[Any], None] = take) -> None:
                nanosec = msg.clock.nanosec
                if not 0 <= nanosec < 1_000_000_000:
                    on_bad_clock(ValueError(f'nanosec {nanosec} is not below 10^9'))
                    return
                try:
                    take(msg)
                except (ValueError, OverflowError, TypeError) as error:
                    on_bad_clock(error)
            subscription.callback = guard('clock', guarded)
