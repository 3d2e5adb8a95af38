"""
One pipeline, two drivers: messages in, the estimator, messages out.

A driver builds one :class:`Pipeline` from :class:`~vessel_kinematics.params.NavigatorParams`,
feeds it every input message (rclpy message instances, whether they came over DDS or were
deserialised from a bag with ``rclpy.serialization.deserialize_message``) with
:meth:`Pipeline.handle`, and publishes or writes the :class:`Output` messages it returns. All
message conversion happens in ``ros_io``; all estimation in ``estimator``. Because both drivers
call exactly this code in the same order, their outputs are equal.
"""

from __future__ import annotations

from dataclasses import dataclass, field
import math
from typing import AbstractSet, Any, Collection

from vessel_kinematics import ros_io
from vessel_kinematics.estimation import Estimator, NavState, Rejection
from vessel_kinematics.params import filter_config, NavigatorParams

#: The pipeline's input names (relative topic names of the node, remappable).
INPUTS = ('fix', 'imu', 'velocity')

#: The output names: relative topic names of the node, and the topics of the replay's bag.
OUTPUTS = ('odometry', 'odometry/local', 'odometry/ned', 'course_sideslip', 'current',
           'relative_flow', 'fix/filtered', 'origin')

_OUTPUT_SET = frozenset(OUTPUTS)
#: The outputs made from the state (all but ``origin``).
_STATE_OUTPUTS = _OUTPUT_SET - {'origin'}

#: Name of the DiagnosticStatus the navigator publishes.
DIAGNOSTIC_NAME = 'navigator: state'

#: Dead reckoning with GNSS enabled but no fix for longer than this (s) is a warning.
DEAD_RECKONING_WARN = 10.0

#: One knot in m/s.
KNOT = 1852.0 / 3600.0


@dataclass(frozen=True)
class Output:
    """
    A message to publish on the relative topic ``topic`` (one of :data:`OUTPUTS`).

    ``msg`` is an rclpy message, or its serialised CDR bytes from a pipeline made with
    ``cdr=True``; ``stamp_ns`` is its header stamp.
    """

    topic: str
    msg: Any
    stamp_ns: int = 0


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
    """
    The navigator's whole behaviour, free of any driver: no rclpy node, no bag, no clock.

    The ``origin`` output is emitted once whenever the origin is set or changed (in the
    outputs of :meth:`handle`, or of :meth:`snapshot` when ``publish_rate`` > 0, or of
    :meth:`set_params`): publish it latched, and re-send :meth:`static_transforms` then.
    """

    def __init__(self, params: NavigatorParams, *, cdr: bool = False) -> None:
        """
        Make the pipeline of ``params``.

        ``cdr``: build every output as the CDR bytes of its message (what
        ``rclpy.serialization.serialize_message`` gives), never the rclpy message itself: a
        driver that writes bags (the replay) saves building and serialising the messages.
        :meth:`transforms` and :meth:`static_transforms` then return the CDR of a
        tf2_msgs/TFMessage holding them (empty bytes where there is none).
        """
        self.params = params
        self.cdr = cdr
        self.estimator = Estimator(filter_config(params))
        self._counts: dict[str, int] = dict.fromkeys(INPUTS, 0)
        self._counts['resets'] = 0
        # The last NavState and the update count it was made at: snapshot() and transforms()
        # after the same message share one (the estimator is unchanged between them).
        self._updates = 0
        self._state: tuple[int, NavState] | None = None
        self._topics_seen: tuple[Any, AbstractSet[str] | None] = (None, None)
        self._convert = {
            'fix': (ros_io.fix_from_msg, self.estimator.fix),
            'imu': (ros_io.imu_from_msg, self.estimator.imu),
            'velocity': (ros_io.velocity_from_msg, self.estimator.velocity),
        }

    def velocity_type(self) -> type | None:
        """Return the message class of the ``velocity`` input for ``velocity.source``, or None."""
        return ros_io.VELOCITY_TYPES[self.params.velocity_source]

    def handle(self, name: str, msg: Any, topics: Collection[str] | None = None) -> Result:
        """
        Fold one input message (``name`` in :data:`INPUTS`) into the state, by its stamp.

        ``topics``: the outputs to build (names of :data:`OUTPUTS`), None for all; see
        :meth:`snapshot`. The state update does not depend on it.
        """
        try:
            convert, update = self._convert[name]
        except KeyError:
            raise ValueError(f'unknown input {name!r}; expected one of {INPUTS}') from None
        if name == 'velocity' and self.params.velocity_source == 'none':
            return self._reject(name, Rejection('unused_input',
                                                'velocity.source is none: velocity ignored'))
        measurement = convert(msg, self.params)
        if isinstance(measurement, Rejection):
            return self._reject(name, measurement)
        self._updates += 1
        resets = self.estimator.resets
        rejection = update(measurement)
        self._counts['resets'] += self.estimator.resets - resets
        if rejection is not None:
            return self._reject(name, rejection)
        self._counts[name] += 1
        if self.params.publish_rate > 0.0:
            return Result()
        return Result(outputs=self.snapshot(topics))

    def _reject(self, name: str, rejection: Rejection) -> Result:
        key = f'{name}/{rejection.reason}'
        self._counts[key] = self._counts.get(key, 0) + 1
        return Result(rejected=rejection.reason, detail=rejection.detail)

    def snapshot(self, topics: Collection[str] | None = None) -> list[Output]:
        """
        Return the outputs for the current state (empty before the origin is known).

        ``topics``: build only these outputs (names of :data:`OUTPUTS`; None = all, e.g. the
        topics somebody subscribes to). Leaving ``'origin'`` out keeps a pending origin event
        for a later call that asks for it. With nothing to build, the state is not even
        computed. Each output is the same message whether built alone or with all.
        """
        est = self.estimator
        if not est.ready:
            return []
        if topics is not None:
            topics = self._checked_topics(topics)
        outputs = []
        # The origin is stamped as the state (all outputs) or the estimator's time (a subset).
        origin_stamp = est.t
        if topics is None or not topics.isdisjoint(_STATE_OUTPUTS):
            state = self._current_state()
            stamp = state.stamp_ns
            if topics is None:
                origin_stamp = stamp
            outputs = [Output(topic, msg, stamp) for topic, msg in ros_io.state_msgs(
                state, self.params, est.water, topics, cdr=self.cdr)]
        if (topics is None or 'origin' in topics) and est.pop_origin_event():
            outputs.append(self._origin_output(origin_stamp))
        return outputs

    def _origin_output(self, stamp_ns: int) -> Output:
        est = self.estimator
        build = ros_io.origin_cdr if self.cdr else ros_io.origin_msg
        return Output('origin', build(est.origin, stamp_ns, self.params), stamp_ns)

    def _checked_topics(self, topics: Collection[str]) -> AbstractSet[str] | None:
        """Return ``topics`` as a set of known output names, None for all (frozenset: cached)."""
        if topics is self._topics_seen[0]:
            return self._topics_seen[1]
        known = frozenset(topics)
        unknown = known - _OUTPUT_SET
        if unknown:
            raise ValueError(f'unknown outputs {sorted(unknown)}; expected some of {OUTPUTS}')
        if known == _OUTPUT_SET:
            known = None
        if isinstance(topics, frozenset):
            self._topics_seen = (topics, known)
        return known

    def transforms(self) -> list[Any]:
        """Return geometry_msgs/TransformStamped map->odom and odom->base_link (REP-105)."""
        if not self.estimator.ready:
            return b'' if self.cdr else []
        if self.cdr:
            return ros_io.transforms_cdr(self._current_state(), self.params)
        return ros_io.transform_msgs(self._current_state(), self.params)

    def state(self) -> NavState | None:
        """Return the estimator's current NavState (None before the origin is known)."""
        return self._current_state() if self.estimator.ready else None

    def _current_state(self) -> NavState:
        """Return the estimator's state, computed once per update."""
        if self._state is None or self._state[0] != self._updates:
            self._state = (self._updates, self.estimator.state())
        return self._state[1]

    def static_transforms(self) -> list[Any]:
        """Return geometry_msgs/TransformStamped earth->map from the origin (ECEF, ENU axes)."""
        est = self.estimator
        if est.origin is None:
            return b'' if self.cdr else []
        build = ros_io.static_transforms_cdr if self.cdr else ros_io.static_transform_msgs
        return build(est.origin, est.t or 0, self.params)

    def set_params(self, params: NavigatorParams) -> list[Output]:
        """Apply new parameters at run time (a new origin re-expresses the state, no jump)."""
        self.params = params
        self._updates += 1
        self.estimator.set_config(filter_config(params))
        est = self.estimator
        if est.origin is not None and est.pop_origin_event():
            return [self._origin_output(est.t or 0)]
        return []

    def diagnostics(self, now_ns: int) -> Any:
        """Return a diagnostic_msgs/DiagnosticArray: mode, ages of inputs, counts by reason."""
        est = self.estimator
        mode = est.mode

        def age(stamp: int | None) -> str:
            return 'never' if stamp is None else f'{(now_ns - stamp) * 1e-9:.3f}'

        values = {'mode': mode}
        if est.origin is not None:
            values['origin'] = (f'{math.degrees(est.origin[0]):.8f}, '
                                f'{math.degrees(est.origin[1]):.8f}, {est.origin[2]:.3f}')
        values['age fix (s)'] = age(est.last_fix_ns)
        values['age imu (s)'] = age(est.last_imu_ns)
        values['age velocity (s)'] = age(est.last_velocity_ns)
        values.update(self.estimates())
        for key, count in sorted(self._counts.items()):
            label = f'rejected {key}' if '/' in key else (
                key if key == 'resets' else f'accepted {key}')
            values[label] = str(count)
        level, summary = ros_io.OK, mode.replace('_', ' ')
        if mode == 'waiting_for_origin':
            level = ros_io.WARN
        elif mode == 'dead_reckoning' and self.params.gnss_enabled:
            fix_age = None if est.last_fix_ns is None else (now_ns - est.last_fix_ns) * 1e-9
            if fix_age is None or fix_age > DEAD_RECKONING_WARN:
                level = ros_io.WARN
                summary += ' without GNSS' if fix_age is None else f' for {fix_age:.0f} s'
        return ros_io.diagnostics_msg(now_ns, DIAGNOSTIC_NAME, level, summary, values)

    def estimates(self) -> dict[str, str]:
        """
        Return the calibrations and the current as a navigator reads them (value ± σ).

        Log scale (reading / truth), leeway and heading offset in degrees (+ clockwise), the
        declination applied, the current as set (the direction it flows to, degrees true)
        and drift (kn), and whether the course has fallen back to the heading at low speed.
        For ``/diagnostics`` and the replay's summary; empty before the first state.
        """
        est = self.estimator
        if not est.ready:
            return {}
        state = self._current_state()
        cal = state.calibration
        values: dict[str, str] = {}
        if cal.log_scale is not None:
            values['log scale'] = f'{cal.log_scale.value:.3f} ± {cal.log_scale.sigma:.3f}'
        if cal.leeway is not None:
            values['leeway (deg)'] = (f'{math.degrees(cal.leeway.value):.1f} ± '
                                      f'{math.degrees(cal.leeway.sigma):.1f}')
        if cal.turn_drift is not None:
            values['turn drift (m/rad)'] = (f'{cal.turn_drift.value:.1f} ± '
                                            f'{cal.turn_drift.sigma:.1f}')
        if est.layout.dpsi is not None:
            values['heading offset (deg)'] = (
                'waiting for the vessel to move' if cal.heading_offset is None else
                f'{math.degrees(cal.heading_offset.value):.1f} ± '
                f'{math.degrees(cal.heading_offset.sigma):.1f}')
        if cal.declination is not None:
            values['declination (deg)'] = (f'{math.degrees(cal.declination):.2f}'
                                           if est.declination_error is None
                                           else f'not applied: {est.declination_error}')
        if state.current is not None:
            n, e = float(state.current[0]), float(state.current[1])
            sigma = math.sqrt(max(0.0, float(state.cov_current[0, 0] + state.cov_current[1, 1])))
            values['current set (deg)'] = f'{math.degrees(math.atan2(e, n)) % 360.0:.0f}'
            values['current drift (kn)'] = (f'{math.hypot(n, e) / KNOT:.2f} ± '
                                            f'{sigma / KNOT:.2f}')
        values['course'] = ('heading (speed below course.min_speed)' if state.low_speed
                            else 'over ground')
        if est.recoveries:
            values['recoveries'] = str(est.recoveries)
        return values

    @property
    def counts(self) -> dict[str, int]:
        """
        Return accepted messages per input and rejected ones per reason (``'fix/no_fix'``).

        ``'resets'`` counts the re-initialisations on a stamp that went back further than
        ``max_gap`` (a bag looped).
        """
        return dict(self._counts)
