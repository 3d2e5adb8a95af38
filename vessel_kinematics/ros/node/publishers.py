"""
The node's publishers: every output of the interface table, TF and diagnostics, as CDR bytes.

:class:`NodeOutputs` publishes each :class:`~vessel_kinematics.ros.pipeline.Emission` as the
bytes it carries (rclpy's publish of a serialised message): the bytes the replay writes, no
message built or serialised here. Each topic has the interface table's QoS (``origin`` latched;
``/tf`` and ``/tf_static`` as tf2's broadcasters). ``/tf`` and ``/tf_static`` exist only for
what ``tf.publish`` chooses, and only where tf2_msgs is installed (the odometry topics carry the
same poses).
"""

from __future__ import annotations

from typing import Any, Iterable

from rclpy.node import Node
from vessel_kinematics.ros import interface
from vessel_kinematics.ros.node.qos import topic_qos
from vessel_kinematics.ros.params import NavigatorParams, TfTransform
from vessel_kinematics.ros.pipeline import DIAGNOSTICS, Emission, TF, TF_STATIC

__all__ = ['NodeOutputs', 'tf_message_type']

_DYNAMIC = frozenset({TfTransform.MAP_ODOM, TfTransform.ODOM_BASE})
_STATIC = frozenset({TfTransform.EARTH_MAP, TfTransform.FRD_NED})


def tf_message_type() -> type | None:
    """Return tf2_msgs/TFMessage, or None where tf2_msgs is not installed."""
    try:
        return interface.message_class(interface.topic(TF).msg_type or '')
    except ImportError:
        return None


class NodeOutputs:
    """The node's publishers, by absolute topic; :meth:`send` publishes emissions."""

    def __init__(self, node: Node, params: NavigatorParams, log: Any) -> None:
        self._node = node
        self._log = log
        self._publishers: dict[str, Any] = {
            t.absolute: node.create_publisher(interface.message_class(t.msg_type), t.name,
                                              topic_qos(t.name))
            for t in interface.by_role(interface.Role.OUTPUT) if t.msg_type is not None}
        self._publishers[DIAGNOSTICS] = node.create_publisher(
            interface.message_class(interface.topic(DIAGNOSTICS).msg_type or ''), DIAGNOSTICS,
            topic_qos(DIAGNOSTICS))
        self.tf_type = tf_message_type()
        if self.tf_type is None:
            log.warning('tf2_msgs is not installed: /tf_static is not read, the mountings '
                        'come from the parameters')
        self.set_params(params)

    def set_params(self, params: NavigatorParams) -> None:
        """Create or destroy the /tf and /tf_static publishers that ``tf.publish`` needs."""
        wanted = params.tf_set
        if wanted and self.tf_type is None:
            self._log.error('tf2_msgs is not installed: no /tf or /tf_static is published '
                            '(the odometry topics carry the same poses); install '
                            'ros-jazzy-tf2-msgs')
            return
        for topic, kinds in ((TF, _DYNAMIC), (TF_STATIC, _STATIC)):
            publisher = self._publishers.get(topic)
            if wanted & kinds and publisher is None:
                self._publishers[topic] = self._node.create_publisher(self.tf_type, topic,
                                                                      topic_qos(topic))
            elif not wanted & kinds and publisher is not None and topic == TF:
                self._node.destroy_publisher(self._publishers.pop(topic))

    def send(self, emissions: Iterable[Emission]) -> None:
        """Publish each emission's bytes on its topic (a topic not published is skipped)."""
        publishers = self._publishers
        for emission in emissions:
            publisher = publishers.get(emission.topic)
            if publisher is not None:
                publisher.publish(emission.cdr)

    def subscribers(self, topic: str) -> int:
        """Return the number of subscriptions matched to ``topic``'s publisher (0 if none)."""
        publisher = self._publishers.get(topic)
        return 0 if publisher is None else publisher.get_subscription_count()
