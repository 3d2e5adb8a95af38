"""The interface table's QoS profiles (:data:`~vessel_kinematics.ros.interface.QOS`) as rclpy's."""

from __future__ import annotations

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from vessel_kinematics.ros import interface

__all__ = ['qos_profile', 'topic_qos']


def qos_profile(profile: interface.QosProfile) -> QoSProfile:
    """Return an interface profile as an rclpy ``QoSProfile`` (keep last ``depth``)."""
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST, depth=profile.depth,
        reliability=(ReliabilityPolicy.RELIABLE if profile.reliable
                     else ReliabilityPolicy.BEST_EFFORT),
        durability=(DurabilityPolicy.TRANSIENT_LOCAL if profile.transient_local
                    else DurabilityPolicy.VOLATILE))


def topic_qos(name: str) -> QoSProfile:
    """Return the rclpy profile of a topic of the interface table."""
    return qos_profile(interface.topic(name).profile)
