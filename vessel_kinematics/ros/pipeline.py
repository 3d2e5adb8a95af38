"""
One pipeline, two drivers: messages in, the estimator, messages out.

A driver builds one :class:`Pipeline` from :class:`~vessel_kinematics.ros.params.NavigatorParams`,
feeds it every input message (rclpy message instances, whether they came over DDS or were
deserialised from a bag with ``rclpy.serialization.deserialize_message``) with
:meth:`Pipeline.handle`, and publishes or writes the :class:`Output` messages it returns. All
message conversion happens in ``ros_io``; all estimation in ``estimator``. Because both drivers
call exactly this code in the same order, their outputs are equal.
"""

from __future__ import annotations

from dataclasses import dataclass, field
import functools
import math
from typing import AbstractSet, Any, Callable, Collection, Iterator

import numpy as np

from vessel_kinematics.estimation import (Estimator, Mode, NavPose, NavState, Reason,
                                          Rejection)
from vessel_kinematics.ros import interface, ros_io
from vessel_kinematics.ros.params import filter_config, NavigatorParams
from vessel_kinematics.ros.static_tf import Mounting, StaticTree, strip_frame

__all__ = ['CLOCK_WENT_BACK', 'DEAD_RECKONING_ERROR', 'DEAD_RECKONING_WARN', 'DIAGNOSTIC_TASKS',
           'INPUTS', 'KNOT', 'MAX_MOUNTINGS', 'MOUNTING_LABELS', 'Output', 'OUTPUTS', 'Pipeline',
           'Result']

#: The pipeline's input names (relative topic names of the node, remappable).
INPUTS = interface.input_names()

#: The output names: relative topic names of the node, and the topics of the replay's bag.
OUTPUTS = interface.output_names()

_OUTPUT_SET = frozenset(OUTPUTS)
#: The outputs made from the state (all but ``origin``, which the pipeline emits itself).
_STATE_OUTPUTS = frozenset(ros_io.STATE_OUTPUTS)

#: The transforms of ``tf.publish`` that move with the state (the others are static).
_DYNAMIC_TF = frozenset({'map_odom', 'odom_base'})

#: The tasks of ``/diagnostics``: one status each, named ``'<node name>: <task>'`` as
#: diagnostic_updater names them (``navigator: estimate``, ``navigator: fix``...).
DIAGNOSTIC_TASKS = ('estimate',) + INPUTS

#: Dead reckoning with GNSS enabled but no fix for longer than this (s) is a warning...
DEAD_RECKONING_WARN = 10.0
#: ...and for longer than this (s) an error (the position σ has grown by hundreds of metres).
DEAD_RECKONING_ERROR = 300.0

#: What an age says instead of a negative number when the clock went back (issue 8).
CLOCK_WENT_BACK = 'clock went back'

#: One knot in m/s.
KNOT = 1852.0 / 3600.0

#: What each input's mounting is called in the log and in ``/diagnostics``.
MOUNTING_LABELS = {'fix': 'gnss antenna', 'imu': 'imu mounting',
                   'velocity': 'velocity mounting'}
#: Most (input, frame id) mountings remembered (frame ids come from messages: bounded).
MAX_MOUNTINGS = 64


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
    was refused, as the plain string value of its :class:`~vessel_kinematics.estimation.Reason`
    (the snake_case key also counted in diagnostics, e.g. ``'nan_field'``, ``'no_fix'``,
    ``'stale_stamp'``; a str, so that drivers format it as is) with ``detail`` a human
    sentence for the throttled warning; both ``None`` when accepted. ``info``: a line for the
    log at INFO level, once, e.g. which source the input's mounting comes from (``'imu
    mounting from /tf_static: frame imu_link (rpy ..., xyz ...)'``), else None.
    """

    outputs: list[Output] = field(default_factory=list)
    rejected: str | None = None
    detail: str | None = None
    info: str | None = None


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
        # The update count, the NavPose made at it and the function completing it into the
        # NavState (called at most once): snapshot() and transforms() after the same message
        # share them (the estimator is unchanged between them).
        self._updates = 0
        self._stages: tuple[int, NavPose, Callable[[], NavState]] | None = None
        self._topics_seen: tuple[Any, AbstractSet[str] | None] = (None, None)
        # The stamp of the last transform returned per child frame (one per stamp).
        self._tf_sent: dict[str, int] = {}
        # Messages received per input (accepted or not), and at the previous diagnostics
        # (its time, the counts): the measured rates; the first diagnostics' time.
        self._received: dict[str, int] = dict.fromkeys(INPUTS, 0)
        self._diag_prev: tuple[int, dict[str, int]] | None = None
        self._diag_start: int | None = None
        self._convert: dict[str, tuple[Callable[..., Any], Callable[[Any], Any]]] = {
            'fix': (ros_io.fix_from_msg, self.estimator.fix),
            'imu': (ros_io.imu_from_msg, self.estimator.imu),
            'velocity': (ros_io.velocity_from_msg, self.estimator.velocity),
        }
        # Mountings from /tf_static: the tree, the mounting per (input, frame id) resolved at
        # the tree's version (None: the parameters), the line last logged per (input, frame
        # id), the source in use per input (for /diagnostics), a log line to hand out.
        self.static_tree = StaticTree()
        self._mountings: dict[tuple[str, str], Mounting | None] = {}
        self._mountings_version = 0
        self._mounting_said: dict[tuple[str, str], str] = {}
        self._mounting_source: dict[str, str] = {}
        self._info: str | None = None
        self._no_rate_said = False

    def velocity_type(self) -> type | None:
        """Return the message class of the ``velocity`` input for ``velocity.source``, or None."""
        msg_type = interface.VELOCITY_TYPES[self.params.velocity_source]
        return None if msg_type is None else interface.message_class(msg_type)

    def handle(self, name: str, msg: Any, topics: Collection[str] | None = None) -> Result:
        """
        Fold one input message (``name`` in :data:`INPUTS`) into the state, by its stamp.

        ``topics``: the outputs to build (names of :data:`OUTPUTS`), None for all; see
        :meth:`snapshot`. The state update does not depend on it. A driver passes a payload
        it could not decode as its :class:`Rejection` (``cdr_error``): counted, nothing else.
        """
        try:
            convert, update = self._convert[name]
        except KeyError:
            raise ValueError(f'unknown input {name!r}; expected one of {INPUTS}') from None
        self._received[name] += 1
        if type(msg) is Rejection:      # a payload the driver could not decode (CDR_ERROR)
            return self._reject(name, msg)
        if name == 'velocity' and self.params.velocity_source == 'none':
            return self._reject(name, Rejection(Reason.UNUSED_INPUT,
                                                'velocity.source is none: velocity ignored'))
        mounting = self._mounting(name, msg)
        if name == 'velocity':
            measurement = convert(msg, self.params, mounting, self._imu_rate_flu())
            if not self._no_rate_said and not isinstance(measurement, Rejection):
                self._say_no_rate(mounting, measurement)
        else:
            measurement = convert(msg, self.params, mounting)
        if self._info is not None:
            result = self._after_mounting(name, measurement, update, topics)
            result.info, self._info = self._info, None
            return result
        return self._after_mounting(name, measurement, update, topics)

    def _after_mounting(self, name: str, measurement: Any, update: Any,
                        topics: Collection[str] | None) -> Result:
        """Fold a converted measurement (or its rejection) into the state."""
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

    def tf_static(self, msg: Any) -> int:
        """
        Take one ``/tf_static`` message (tf2_msgs/TFMessage) into the static tree.

        The latest transform per child frame is kept (several latched broadcasters each
        re-send their own); the inputs' mountings are resolved again from the next message
        on. Return the number of transforms that changed.
        """
        return self.static_tree.update(ros_io.static_transforms_from_msg(msg))

    def _mounting(self, name: str, msg: Any) -> Mounting | None:
        """
        Return the mounting of the input's frame from /tf_static, None for the parameters.

        The sensor frame is ``header.frame_id`` (an Odometry's twist: ``child_frame_id``).
        The base frame itself (or no frame id) takes the parameters (identity by default),
        as does a frame /tf_static does not connect to the base frame. Resolved once per
        (input, frame id) and tree version; a change of source is said once (:attr:`_info`).
        """
        if name == 'velocity' and self.params.velocity_source == 'odometry':
            frame = msg.child_frame_id
        else:
            frame = msg.header.frame_id
        key = (name, frame)
        if self._mountings_version == self.static_tree.version:
            try:
                return self._mountings[key]
            except KeyError:
                pass
        else:
            self._mountings.clear()
            self._mountings_version = self.static_tree.version
        if len(self._mountings) >= MAX_MOUNTINGS:
            self._mountings.clear()
        label = MOUNTING_LABELS[name]
        stripped = strip_frame(frame)
        base = self.params.base_frame
        mounting = None
        if not stripped or stripped == base:
            why = 'no frame_id' if not stripped else f'frame {stripped} is the base frame'
        else:
            mounting = self.static_tree.lookup(stripped, base)
            why = (f'frame {stripped} not in /tf_static' if stripped not in self.static_tree
                   else f'frame {stripped} not connected to {base} in /tf_static')
        if mounting is not None:
            source = f'tf_static {stripped}'
            line = f'{label} from /tf_static: frame {stripped} ({mounting.describe()})'
        else:
            source = 'parameters'
            line = f'{label} from parameters ({self._parameter_text(name)}) ({why})'
        self._mountings[key] = mounting
        self._mounting_source[name] = source
        if self._mounting_said.get(key) != line:
            if len(self._mounting_said) >= MAX_MOUNTINGS:
                self._mounting_said.clear()
            self._mounting_said[key] = line
            self._info = line
        return mounting

    def _parameter_text(self, name: str) -> str:
        """Return the parameters that give the mounting of input ``name``, with values."""
        p = self.params
        if name == 'fix':
            return f'gnss.antenna_position {list(p.gnss_antenna_position)}'
        if name == 'imu':
            return f'imu.mounting_rpy {list(p.imu_mounting_rpy)}'
        return (f'velocity.mounting_rpy {list(p.velocity_mounting_rpy)}, '
                f'velocity.sensor_position {list(p.velocity_sensor_position)}')

    def _imu_rate_flu(self) -> tuple[float, float, float] | None:
        """
        Return the IMU's latest body rate (FLU, rad/s) while fresh, else None.

        ω of a velocity sensor's lever arm (v_base = R v_sensor − ω × r): the rate the state
        turns with when an IMU gives it (within ``max_gap``); without one the velocity
        message's own angular part is used (``ros_io.velocity_from_msg``).
        """
        est = self.estimator
        att = est.attitude
        if (att.omega_from_imu and est.t is not None and att.omega is not None
                and att.rates_fresh(est.t, self.params.max_gap)):
            p, q, r = att.omega
            return (p, -q, -r)
        return None

    def _say_no_rate(self, mounting: Mounting | None, measurement: Any) -> None:
        """Say once when a velocity sensor's lever arm meets no known body rate (ω = 0)."""
        position = (mounting.t if mounting is not None
                    else self.params.velocity_sensor_position)
        if any(position) and measurement.omega_b is None and self._imu_rate_flu() is None:
            self._no_rate_said = True
            line = ('velocity lever arm: no body rate known (no fresh IMU rate, no angular '
                    'part in the velocity message): omega x r taken as zero')
            self._info = line if self._info is None else f'{self._info}; {line}'

    def _reject(self, name: str, rejection: Rejection) -> Result:
        reason = rejection.reason.value     # the key's text (an f-string of the enum is not)
        key = f'{name}/{reason}'
        self._counts[key] = self._counts.get(key, 0) + 1
        return Result(rejected=reason, detail=rejection.detail)

    def snapshot(self, topics: Collection[str] | None = None) -> list[Output]:
        """
        Return the outputs for the current state (empty before the origin is known).

        ``topics``: build only these outputs (names of :data:`OUTPUTS`; None = all, e.g. the
        topics somebody subscribes to). Leaving ``'origin'`` out keeps a pending origin event
        for a later call that asks for it. With nothing to build, the state is not even
        computed. Each output is the same message whether built alone or with all.
        """
        return list(self.iter_snapshot(topics))

    def iter_snapshot(self, topics: Collection[str] | None = None) -> Iterator[Output]:
        """
        Yield :meth:`snapshot`'s outputs, each built as it is taken.

        A driver that sends each one as it comes sends the first (``odometry``) before the
        last is built. Take them all, at once: the origin event is taken after the state's
        outputs, as in :meth:`snapshot`.
        """
        est = self.estimator
        if not est.ready:
            return
        if topics is not None:
            topics = self._checked_topics(topics)
        # The origin is stamped as the state (all outputs) or the estimator's time (a subset).
        origin_stamp = est.t
        if topics is None or not topics.isdisjoint(_STATE_OUTPUTS):
            pose, complete = self._staged_state()   # the odometry before the rest is computed
            stamp = pose.stamp_ns
            if topics is None:
                origin_stamp = stamp
            for topic, msg in ros_io.iter_state_msgs(pose, self.params, est.water, topics,
                                                     cdr=self.cdr, complete=complete):
                yield Output(topic, msg, stamp)
        if (topics is None or 'origin' in topics) and est.pop_origin_event():
            yield self._origin_output(origin_stamp)

    def hand_off(self) -> bytes:
        """
        Return the estimator's state for building all outputs elsewhere (:meth:`take_over`).

        A copy of this pipeline given it builds what :meth:`snapshot` would build here now
        (the bytes of :meth:`~vessel_kinematics.estimation.Estimator.freeze`). A pending
        origin event goes with it where :meth:`snapshot` would take it (once the state is
        ready), so it is taken here too.
        """
        est = self.estimator
        frozen = est.freeze()
        if est.ready:
            est.pop_origin_event()
        return frozen

    def take_over(self, frozen: bytes) -> None:
        """Take the estimator of a :meth:`hand_off` (in a copy of the pipeline that handed it)."""
        self.estimator.thaw(frozen)
        self._updates += 1

    def _origin_output(self, stamp_ns: int | None) -> Output:
        est = self.estimator
        assert est.origin is not None                # only with an origin event
        build = ros_io.origin_cdr if self.cdr else ros_io.origin_msg
        stamp = stamp_ns or 0
        return Output('origin', build(est.origin, stamp, self.params), stamp)

    def _checked_topics(self, topics: Collection[str]) -> AbstractSet[str] | None:
        """Return ``topics`` as a set of known output names, None for all (frozenset: cached)."""
        if topics is self._topics_seen[0]:
            return self._topics_seen[1]
        given = frozenset(topics)
        unknown = given - _OUTPUT_SET
        if unknown:
            raise ValueError(f'unknown outputs {sorted(unknown)}; expected some of {OUTPUTS}')
        known: AbstractSet[str] | None = None if given == _OUTPUT_SET else given
        if isinstance(topics, frozenset):
            self._topics_seen = (topics, known)
        return known

    def transforms(self) -> Any:
        """
        Return the dynamic transforms of ``tf.publish`` (map->odom, odom->base_link).

        A list of geometry_msgs/TransformStamped, or with ``cdr`` the CDR bytes of the
        tf2_msgs/TFMessage holding them (what the replay writes); ``[]`` when there is none.
        Exactly one transform per child frame and stamp: a transform whose stamp was already
        sent (two inputs with one stamp) is left out, so a TF buffer never sees
        TF_REPEATED_DATA. Call it when publishing: it remembers what it returned.
        """
        which = self.params.tf_set & _DYNAMIC_TF
        if not which or not self.estimator.ready:
            return []
        pose = self._staged_state()[0]           # the pose is all the transforms need
        out = []
        for parts in ros_io.transform_parts(pose, self.params, which):
            child = parts[2]
            if self._tf_sent.get(child) == pose.stamp_ns:
                continue
            self._tf_sent[child] = pose.stamp_ns
            out.append(parts)
        if not out:
            return []
        return ros_io.tf_cdr(out) if self.cdr else [ros_io.transform_msg(p) for p in out]

    def state(self) -> NavState | None:
        """Return the estimator's current NavState (None before the origin is known)."""
        return self._current_state() if self.estimator.ready else None

    def pose(self) -> NavPose | None:
        """Return the current state's NavPose alone (None before the origin is known)."""
        return self._staged_state()[0] if self.estimator.ready else None

    def _current_state(self) -> NavState:
        """Return the estimator's state, computed once per update."""
        return self._staged_state()[1]()

    def _staged_state(self) -> tuple[NavPose, Callable[[], NavState]]:
        """Return the estimator's pose and the function of its whole state, once per update."""
        if self._stages is None or self._stages[0] != self._updates:
            pose, complete = self.estimator.staged_state()
            self._stages = (self._updates, pose, functools.cache(complete))
        return self._stages[1], self._stages[2]

    def static_transforms(self) -> list[Any]:
        """
        Return all static transforms of ``tf.publish`` in one list (one /tf_static message).

        earth->map from the origin (ECEF, ENU axes) once it is known, and map->map_ned,
        base_link->base_link_frd; re-send the whole list whenever one changes (the origin,
        the frame names or ``tf.publish``), as tf2's StaticTransformBroadcaster does.
        """
        est = self.estimator
        return ros_io.static_transform_msgs(est.origin, est.t or 0, self.params,
                                            self.params.tf_set - _DYNAMIC_TF)

    def set_params(self, params: NavigatorParams) -> list[Output]:
        """Apply new parameters at run time (a new origin re-expresses the state, no jump)."""
        self.params = params
        self._updates += 1
        self._mountings.clear()    # the parameters' mountings and the base frame may change
        self.estimator.set_config(filter_config(params))
        est = self.estimator
        if est.origin is not None and est.pop_origin_event():
            return [self._origin_output(est.t or 0)]
        return []

    def diagnostics(self, now_ns: int, node_name: str = 'navigator') -> Any:
        """
        Return a diagnostic_msgs/DiagnosticArray as diagnostic_updater builds them.

        One status per task of :data:`DIAGNOSTIC_TASKS`, named ``'<node_name>: <task>'``:
        ``estimate`` (mode, origin, counts by reason; WARN waiting for the origin or dead
        reckoning for :data:`DEAD_RECKONING_WARN` s, ERROR after :data:`DEAD_RECKONING_ERROR`
        s) and one per input (frequency and staleness: the measured rate since the previous
        call, the age of the last accepted message by its stamp; WARN beyond
        ``diagnostics.stale_warn`` s, ERROR beyond ``diagnostics.stale_error`` s or never
        received by then). Ages never go negative: an age from a clock that went back below
        the stamp says :data:`CLOCK_WENT_BACK`. ``now_ns`` is the driver's clock (the node's
        ROS clock; the bag's time in the replay).
        """
        if self._diag_start is None or now_ns < self._diag_start:
            self._diag_start = now_ns
        clock_back = self._diag_prev is not None and now_ns < self._diag_prev[0]
        statuses = [self._estimate_status(now_ns, node_name)]
        statuses += [self._input_status(name, now_ns, node_name, clock_back)
                     for name in INPUTS]
        self._diag_prev = (now_ns, dict(self._received))
        return ros_io.diagnostics_array_msg(now_ns, statuses)

    def _age(self, stamp: int | None, now_ns: int) -> tuple[float | None, str]:
        """Return (age s or None, its text): 'never', 'clock went back' or seconds."""
        if stamp is None:
            return None, 'never'
        if now_ns < stamp:
            return None, CLOCK_WENT_BACK
        age = (now_ns - stamp) * 1e-9
        return age, f'{age:.3f}'

    def _estimate_status(self, now_ns: int, node_name: str) -> Any:
        est = self.estimator
        mode = est.mode
        values: dict[str, str] = {'mode': mode.value}
        if est.origin is not None:
            values['origin'] = (f'{math.degrees(est.origin[0]):.8f}, '
                                f'{math.degrees(est.origin[1]):.8f}, {est.origin[2]:.3f}')
        for name, stamp in (('fix', est.last_fix_ns), ('imu', est.last_imu_ns),
                            ('velocity', est.last_velocity_ns)):
            values[f'age {name} (s)'] = self._age(stamp, now_ns)[1]
        values.update(self.estimates())
        for key, count in sorted(self._counts.items()):
            label = f'rejected {key}' if '/' in key else (
                key if key == 'resets' else f'accepted {key}')
            values[label] = str(count)
        level, summary = ros_io.OK, mode.replace('_', ' ')
        if mode is Mode.WAITING:
            level = ros_io.WARN
        elif mode is Mode.DEAD_RECKONING and self.params.gnss_enabled:
            fix_age, fix_text = self._age(est.last_fix_ns, now_ns)
            if fix_text == CLOCK_WENT_BACK:
                level, summary = ros_io.WARN, f'{summary} ({CLOCK_WENT_BACK})'
            elif fix_age is None:
                level, summary = ros_io.WARN, summary + ' without GNSS'
            elif fix_age > DEAD_RECKONING_WARN:
                level = ros_io.ERROR if fix_age > DEAD_RECKONING_ERROR else ros_io.WARN
                summary += f' for {fix_age:.0f} s'
        return ros_io.diagnostic_status(f'{node_name}: estimate', level, summary, values)

    def _input_status(self, name: str, now_ns: int, node_name: str, clock_back: bool) -> Any:
        est = self.estimator
        stamp = {'fix': est.last_fix_ns, 'imu': est.last_imu_ns,
                 'velocity': est.last_velocity_ns}[name]
        received = self._received[name]
        rejected = sum(c for k, c in self._counts.items() if k.startswith(name + '/'))
        values = {'received': str(received), 'accepted': str(self._counts[name]),
                  'rejected': str(rejected)}
        if name in self._mounting_source:
            values[MOUNTING_LABELS[name]] = self._mounting_source[name]
        rate = None
        if self._diag_prev is not None and now_ns > self._diag_prev[0]:
            rate = (received - self._diag_prev[1][name]) / ((now_ns - self._diag_prev[0]) * 1e-9)
        values['rate (Hz)'] = CLOCK_WENT_BACK if clock_back else (
            'n/a' if rate is None else f'{rate:.2f}')
        age, age_text = self._age(stamp, now_ns)
        values['age (s)'] = age_text
        warn_s = self.params.diagnostics_stale_warn
        error_s = self.params.diagnostics_stale_error
        values['stale warn (s)'], values['stale error (s)'] = f'{warn_s:g}', f'{error_s:g}'
        status_name = f'{node_name}: {name}'
        if name == 'velocity' and self.params.velocity_source == 'none':
            return ros_io.diagnostic_status(status_name, ros_io.OK,
                                            'not used (velocity.source none)', values)
        if age_text == CLOCK_WENT_BACK or clock_back:
            return ros_io.diagnostic_status(status_name, ros_io.WARN, CLOCK_WENT_BACK, values)
        if age is None:
            waited = (now_ns - (self._diag_start or now_ns)) * 1e-9
            level = ros_io.ERROR if waited > error_s else ros_io.WARN
            what = 'nothing accepted' if received else 'no message'
            return ros_io.diagnostic_status(status_name, level,
                                            f'{what} for {waited:.0f} s', values)
        if age > error_s:
            return ros_io.diagnostic_status(status_name, ros_io.ERROR,
                                            f'stale: last message {age:.1f} s ago', values)
        if age > warn_s:
            return ros_io.diagnostic_status(status_name, ros_io.WARN,
                                            f'late: last message {age:.1f} s ago', values)
        summary = 'ok' if rate is None else f'{rate:.1f} Hz'
        return ros_io.diagnostic_status(status_name, ros_io.OK, summary, values)

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
            cov = state.cov_current if state.cov_current is not None else np.zeros((3, 3))
            sigma = math.sqrt(max(0.0, float(cov[0, 0] + cov[1, 1])))
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
