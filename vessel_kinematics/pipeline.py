"""
One pipeline, two drivers: messages in, the estimator, messages out.

INTERFACE STUB (to be implemented): the signatures and docstrings below are the contract that
``navigator`` (rclpy node) and ``replay`` (rosbag driver) are written against.

A driver builds one :class:`Pipeline` from :class:`~vessel_kinematics.params.NavigatorParams`,
feeds it every input message (rclpy message instances, whether they came over DDS or were
deserialised from a bag with ``rclpy.serialization.deserialize_message``) with
:meth:`Pipeline.handle`, and publishes or writes the :class:`Output` messages it returns. All
message conversion happens in ``ros_io``; all estimation in ``estimator``. Because both drivers
call exactly this code in the same order, their outputs are equal.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from vessel_kinematics.params import NavigatorParams

#: The pipeline's input names (relative topic names of the node, remappable).
INPUTS = ('fix', 'imu', 'velocity')

#: The output names: relative topic names of the node, and the topics of the replay's bag.
OUTPUTS = ('odometry', 'odometry/local', 'odometry/ned', 'course_sideslip', 'current',
           'fix/filtered', 'origin')


@dataclass(frozen=True)
class Output:
    """A message to publish on the relative topic ``topic`` (one of :data:`OUTPUTS`)."""

    topic: str
    msg: Any


@dataclass
class Result:
    """
    What one input message did.

    ``outputs`` are the messages to publish now (empty when ``publish_rate`` > 0: the driver
    then calls :meth:`Pipeline.snapshot` at that rate). ``rejected`` is the reason the message
    was refused (a short snake_case key also counted in diagnostics, e.g. ``'nan_field'``,
    ``'no_fix'``, ``'stale_stamp'``) with ``detail`` a human sentence for the throttled warning;
    both ``None`` when accepted.
    """

    outputs: list[Output] = field(default_factory=list)
    rejected: str | None = None
    detail: str | None = None


class Pipeline:
    """The navigator's whole behaviour, free of any driver: no rclpy node, no bag, no clock."""

    def __init__(self, params: NavigatorParams) -> None:
        self.params = params
        raise NotImplementedError

    def velocity_type(self) -> type | None:
        """Return the message class of the ``velocity`` input for ``velocity.source``, or None."""
        raise NotImplementedError

    def handle(self, name: str, msg: Any) -> Result:
        """Fold one input message (``name`` in :data:`INPUTS`) into the state, by its stamp."""
        raise NotImplementedError

    def snapshot(self) -> list[Output]:
        """Return the outputs for the current state (empty before the origin is known)."""
        raise NotImplementedError

    def transforms(self) -> list[Any]:
        """Return geometry_msgs/TransformStamped map->odom and odom->base_link (REP-105)."""
        raise NotImplementedError

    def static_transforms(self) -> list[Any]:
        """Return geometry_msgs/TransformStamped earth->map from the origin (ECEF, ENU axes)."""
        raise NotImplementedError

    def set_params(self, params: NavigatorParams) -> list[Output]:
        """Apply new parameters at run time (a new origin re-expresses the state, no jump)."""
        raise NotImplementedError

    def diagnostics(self, now_ns: int) -> Any:
        """Return a diagnostic_msgs/DiagnosticArray: mode, ages of inputs, counts by reason."""
        raise NotImplementedError

    @property
    def counts(self) -> dict[str, int]:
        """Return accepted messages per input and rejected ones per reason (``'fix/no_fix'``)."""
        raise NotImplementedError
