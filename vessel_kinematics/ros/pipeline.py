"""
One pipeline, two drivers: messages in, the estimator, the messages to send out.

A driver (the node, the replay) makes one :class:`Pipeline` of its
:class:`~vessel_kinematics.ros.params.NavigatorParams`, sends what :meth:`Pipeline.start`
returns, hands it every input message with its arrival time (:meth:`Pipeline.handle`: the
node's clock, the replay's bag log time) and sends the :class:`Emission` s each call returns:
the node to its publishers, the replay to its bag. Nothing else decides what is sent and when,
so the node and the replay send the same bytes for the same inputs (``test_equivalence``).

The output policy:

* the outputs follow the IMU while it flows (:mod:`~vessel_kinematics.estimation.timeline`):
  after an accepted IMU sample, carrying whatever was fused since (a fix, late or not, goes
  out with the next IMU sample), so their stamps do not depend on when the other inputs
  arrive; after a refused IMU sample (a frozen compass) when anything was fused since the
  last outputs; with no IMU flowing, after any accepted input;
* ``publish_rate`` 0: every output each time; ``publish_rate`` > 0: one set of outputs when
  such a stamp reaches the next multiple of the period (stamp time, not a wall-clock timer:
  a replayed bag and the live node emit at the same stamps, and a node fed nothing emits
  nothing new);
* the outputs (:mod:`.outputs`, the interface table's order), then ``origin`` once whenever the
  origin is set or changed (latched), then ``/tf`` (:mod:`.tf`, one transform per stamp), then
  ``/tf_static`` whenever the set of static transforms changed;
* nothing before the estimator is ready (origin, position and attitude known).

``/diagnostics`` is the driver's to time (:meth:`Pipeline.diagnostics`, once a second of its
clock: a node whose inputs stopped still says so). The arrival time is carried to the
diagnostics (the time since each input last arrived); the estimate is by header stamp.
"""

from __future__ import annotations

from contextlib import contextmanager
import dataclasses
from dataclasses import dataclass
import gc
from typing import Any, Callable, Iterator, Mapping, NamedTuple

from vessel_kinematics.core.quaternion import euler2q
from vessel_kinematics.estimation import Estimator, Event, Level, NavState, Reason, Rejection
from vessel_kinematics.estimation.timeline import Timeline
from vessel_kinematics.ros import inputs, interface, outputs
from vessel_kinematics.ros.diagnostics import Diagnostics, estimates
from vessel_kinematics.ros.failover import HeadingFailover
from vessel_kinematics.ros.mountings import Mountings
from vessel_kinematics.ros.params import (filter_config, ImuSource, NavigatorParams,
                                          time_offsets, VelocitySource)
from vessel_kinematics.ros.static_tf import Mounting
from vessel_kinematics.ros.tf import TfOutput
from vessel_kinematics.ros.timing import InputTiming, JUMP_MESSAGES

__all__ = ['DIAGNOSTICS', 'Emission', 'fewer_collections', 'GC_THRESHOLD', 'INPUTS', 'OUTPUTS',
           'Pipeline', 'Result', 'TF', 'TF_STATIC']

#: The pipeline's input names (relative topic names of the node, remappable).
INPUTS = interface.input_names()
#: The output names: relative topic names of the node, and the topics of the replay's bag.
OUTPUTS = interface.output_names()
#: The absolute topics of the transforms and of the diagnostics.
TF, TF_STATIC, DIAGNOSTICS = '/tf', '/tf_static', '/diagnostics'
#: The cyclic garbage collector's threshold for its youngest generation while a driver runs
#: the pipeline (CPython's default is 700; see :func:`fewer_collections`).
GC_THRESHOLD = 10_000


class Emission(NamedTuple):
    """One message to send: its absolute ``topic``, header ``stamp_ns`` and ``cdr`` bytes."""

    topic: str
    stamp_ns: int
    cdr: bytes

    def __repr__(self) -> str:
        """Return the emission without its bytes (their length only)."""
        return f'Emission({self.topic!r}, {self.stamp_ns}, <{len(self.cdr)} bytes>)'


@dataclass(frozen=True)
class Result:
    """
    What one input message did.

    ``rejected``: the reason it was refused, the plain value of its
    :class:`~vessel_kinematics.estimation.Reason` (``'nan_field'``, ``'too_late'``...), with
    ``detail`` a sentence for the log; both None when accepted or held until the IMU reaches its
    stamp (:mod:`~vessel_kinematics.estimation.timeline`). ``later``: the refusals, as
    (input, reason, detail), of held messages applied now. ``info``: a line for the log at
    INFO level (e.g. where the input's mounting comes from), once, else None. ``emissions``:
    what to send now, in order; ``state``: the state they were built from (None when none).
    ``events``: what the estimator found meanwhile (a recovery, a fault found or over, the log
    gone or back: :meth:`Estimator.pop_events`), each said once, for the log at its level.
    """

    rejected: str | None = None
    detail: str | None = None
    info: str | None = None
    emissions: tuple[Emission, ...] = ()
    state: NavState | None = None
    events: tuple[Event, ...] = ()
    later: tuple[tuple[str, str, str | None], ...] = ()


_ACCEPTED = Result()
_PAUSED = Rejection(Reason.PAUSED, 'fusion is paused (~/enable false)')


class Pipeline:
    """The navigator's whole behaviour, free of any driver: no rclpy node, no bag, no clock."""

    def __init__(self, params: NavigatorParams) -> None:
        self.params = params
        est = self.estimator = Estimator(filter_config(params))
        self._diagnostics = Diagnostics()
        self.mountings = Mountings(params)
        self._tf = TfOutput()
        self._next_publish: int | None = None
        self._statics_origin: tuple[float, float, float] | None = None
        self._no_rate_said = False
        #: Fusion paused (the node's ``~/enable``): every input is counted as ``paused``.
        self.paused = False
        self._convert: dict[str, Callable[..., Any]] = {
            'fix': inputs.fix_from_msg, 'imu': inputs.imu_from_msg,
            'velocity': inputs.velocity_from_msg, 'gnss_velocity': inputs.ground_velocity_from_msg}
        self.timeline = Timeline(est, {'fix': est.fix, 'imu': est.imu, 'velocity': est.velocity,
                                       'gnss_velocity': est.ground_velocity},
                                 params.history_length)
        self.timing = InputTiming(INPUTS, time_offsets(params), params.future_tolerance,
                                  params.history_length)
        self._events: list[Event] = []
        #: An input taken since the last outputs that did not send them (not the IMU's).
        self._unsent = False
        self.failover = HeadingFailover(params.imu_topics, params.imu_failover_timeout)
        self._set_types()

    def _set_types(self) -> None:
        """Take the message type of each input (``velocity.source`` chooses the velocity's...)."""
        p = self.params
        self._types = interface.types(interface.Role.INPUT, absolute=False,
                                      velocity_source=p.velocity_source, imu_source=p.imu_source,
                                      gnss_velocity_source=p.gnss_velocity_source)
        self._convert['imu'] = (inputs.heading_from_msg if p.imu_source is ImuSource.QUATERNION
                                else inputs.imu_from_msg)
        self._classes: dict[str, set[type]] = {name: set() for name in INPUTS}

    # --- inputs -------------------------------------------------------------------------

    def start(self) -> list[Emission]:
        """Return what to send before any input: ``/tf_static``."""
        return self._static_emissions(force=True)

    def handle(self, name: str, msg: Any, arrival_ns: int, source: int = 0) -> Result:
        """
        Fold one input message (``name`` in :data:`INPUTS`) in by its stamp; say what to send.

        ``arrival_ns``: when it arrived (the node's clock, the bag's log time); ``source``: the
        index of its topic in ``fix.topics`` / ``imu.topics`` (its mounting in the parameters,
        its priority among headings). A driver passes
        a payload it could not decode as its :class:`Rejection` (``cdr_error``): counted,
        nothing else. A message of another type than the input takes now (a velocity queued
        before ``velocity.source`` changed) is refused as ``unused_input``.
        """
        try:
            convert = self._convert[name]
        except KeyError:
            raise ValueError(f'unknown input {name!r}; expected one of {INPUTS}') from None
        self._diagnostics.received(name, arrival_ns)
        if self.timing.clock_went_back(arrival_ns):
            self._time_jump('the clock went back (a bag played again, /clock restarted)')
        if self.paused:
            return self._reject(name, _PAUSED)
        if type(msg) is Rejection:      # a payload the driver could not decode (CDR_ERROR)
            return self._reject(name, msg)
        wrong = self._wrong_type(name, msg)
        if wrong is not None:
            return self._reject(name, wrong)
        frame = msg.child_frame_id if self._types[name].endswith('/Odometry') else \
            msg.header.frame_id
        mounting, info = self.mountings.of(name, frame)
        if mounting is None and source:
            mounting = self._parameter_mounting(name, source)
        if name == 'velocity':
            measurement = convert(msg, self.params, mounting, self._imu_rate_flu())
            if not self._no_rate_said and not isinstance(measurement, Rejection):
                info = self._say_no_rate(mounting, measurement, info)
        else:
            measurement = convert(msg, self.params, mounting)
        if name == 'imu' and len(self.failover.topics) > 1:
            result = self._heading(source, measurement, arrival_ns)
        else:
            result = self._fold(name, measurement, arrival_ns, source)
        events = tuple(self._events) + tuple(self.estimator.pop_events())
        self._events.clear()
        if info is not None or events:
            return dataclasses.replace(result, info=info, events=events)
        return result

    def _parameter_mounting(self, name: str, source: int) -> Mounting | None:
        """Return the parameters' mounting of topic ``source`` (> 0) of ``fix`` or ``imu``."""
        p = self.params
        if name == 'fix':
            return Mounting((1.0, 0.0, 0.0, 0.0), p.antenna_position(source), 'parameters')
        if name == 'imu':
            q = tuple(float(c) for c in euler2q(*p.imu_mounting(source)))
            return Mounting(q, (0.0, 0.0, 0.0), 'parameters')  # type: ignore[arg-type]
        return None

    def _heading(self, source: int, measurement: Any, arrival_ns: int) -> Result:
        """Fold a heading of topic ``source`` when it is the one in use (failover)."""
        if isinstance(measurement, Rejection):
            return self._reject('imu', measurement)
        if not self.failover.offer(source, measurement.stamp_ns):
            return self._reject('imu', Rejection(
                Reason.STANDBY, f'{self.failover.topics[source]} stands by: '
                                f'{self.failover.in_use} is in use'))
        result = self._fold('imu', measurement, arrival_ns, source)
        if result.rejected is not None:
            self.failover.refused(source, measurement.stamp_ns, result.rejected)
        return result

    def _wrong_type(self, name: str, msg: Any) -> Rejection | None:
        """Return the rejection of a message of another type than input ``name`` takes."""
        cls = type(msg)
        if cls in self._classes[name]:
            return None
        expected = self._types.get(name)
        got = interface.type_name(msg)
        if got == expected:
            self._classes[name].add(cls)
            return None
        if expected is None:
            return Rejection(Reason.UNUSED_INPUT, f'{name}.source is none: {name} ignored')
        chosen = getattr(self.params, f'{name}_source', None)
        return Rejection(Reason.UNUSED_INPUT, f'{got} on {name}, which takes {expected}'
                                              + ('' if chosen is None else
                                                 f' ({name}.source {chosen})'))

    def _fold(self, name: str, measurement: Any, arrival_ns: int, source: int = 0) -> Result:
        """Fold a converted measurement (or its rejection) in at its stamp; say what to send."""
        if isinstance(measurement, Rejection):
            return self._reject(name, measurement)
        timing = self.timing
        measurement = timing.shifted(name, measurement)
        if measurement.stamp_ns > 0 and arrival_ns > 0:   # 0: a sim clock not started yet
            future = timing.future(name, measurement.stamp_ns, arrival_ns)
            if future is not None:
                return self._reject(name, future)
            measurement = timing.corrected(name, measurement)
            ahead = timing.ahead_of_others(name, measurement.stamp_ns, arrival_ns)
            if ahead is not None:
                return self._reject(name, ahead)
        own: Rejection | None = None
        later = []
        taken = False
        for outcome in self.timeline.apply(name, measurement, source):
            rejection = outcome.rejection
            if rejection is None:
                self._diagnostics.accepted(outcome.name)
                taken = True
            else:
                self._diagnostics.rejected(outcome.name, rejection.reason)
                if outcome.measurement is measurement:
                    own = rejection
                else:
                    later.append((outcome.name, rejection.reason.value, rejection.detail))
            too_late = rejection is not None and rejection.reason is Reason.TOO_LATE
            if timing.outcome(outcome.name, too_late, arrival_ns):
                self._time_jump(f'every input stamped over {self.params.history_length:g} s '
                                f'behind the newest {JUMP_MESSAGES} times in a row (a looped bag)')
        # Outputs follow the IMU while it flows (a late or held fix is in the next one), so
        # that their stamps do not depend on when the other inputs arrive. A pace sample
        # refused (a frozen compass) still sends what was taken since the last outputs.
        paced = name == self.timeline.pace or not self.timeline.pace_flowing
        self._unsent = self._unsent or (taken and not paced)
        result = self._outputs() if paced and (taken or self._unsent) else _ACCEPTED
        if own is None and not later:
            return result
        return dataclasses.replace(result, rejected=None if own is None else own.reason.value,
                                   detail=None if own is None else own.detail,
                                   later=tuple(later))

    def _outputs(self) -> Result:
        """Return the outputs when due (``publish_rate``), with /tf_static when it changed."""
        if not self._due():
            return _ACCEPTED
        self._unsent = False
        state = self.state()
        out = [] if state is None else self._emissions(state)
        out += self._static_emissions()
        return Result(emissions=tuple(out), state=state) if out else _ACCEPTED

    def flush(self) -> Result:
        """
        Apply what still waits for the IMU to reach its stamp (the end of a replay).

        And send the outputs of what was taken since the last ones. The node never calls it:
        there the next IMU sample does both.
        """
        taken = False
        later = []
        for outcome in self.timeline.flush():
            if outcome.rejection is None:
                self._diagnostics.accepted(outcome.name)
                taken = True
            else:
                self._diagnostics.rejected(outcome.name, outcome.rejection.reason)
                later.append((outcome.name, outcome.rejection.reason.value,
                              outcome.rejection.detail))
        result = self._outputs() if taken or self._unsent else _ACCEPTED
        return dataclasses.replace(result, later=tuple(later)) if later else result

    def _time_jump(self, why: str) -> None:
        """Re-initialise on a real time jump, keeping the origin; say it once (at the old time)."""
        t = self.estimator.t
        self._restart()
        self._events.append(Event(t or 0, Level.WARN,
                                  f'time jump: {why}; the estimate is re-initialised'))

    def _restart(self) -> None:
        """Re-initialise the estimator, its history and the output schedule; count it."""
        self.estimator.reset()
        self.timeline.clear()
        self.timing.reset()
        self._diagnostics.resets(1)
        self._next_publish = None

    def _reject(self, name: str, rejection: Rejection) -> Result:
        self._diagnostics.rejected(name, rejection.reason)
        return Result(rejected=rejection.reason.value, detail=rejection.detail)

    def _due(self) -> bool:
        """Return whether the outputs are due after an accepted input (``publish_rate``)."""
        rate = self.params.publish_rate
        if rate <= 0.0:
            return True
        stamp = self.estimator.t        # the accepted stamps' latest
        if stamp is None:
            return False
        if self._next_publish is None:
            self._next_publish = stamp
        if stamp < self._next_publish:
            return False
        period = int(round(1e9 / rate))
        self._next_publish += period * max(1, (stamp - self._next_publish) // period + 1)
        return True

    def _imu_rate_flu(self) -> tuple[float, float, float] | None:
        """
        Return the IMU's latest body rate (FLU, rad/s) while fresh, else None.

        ω of a velocity sensor's lever arm (v_base = R v_sensor − ω × r): the rate the state
        turns with when an IMU gives it (within ``max_gap``); without one the velocity
        message's own angular part is used (``inputs.velocity_from_msg``).
        """
        est = self.estimator
        att = est.attitude
        if (att.omega_from_imu and est.t is not None and att.omega is not None
                and att.rates_fresh(est.t, self.params.max_gap)):
            p, q, r = att.omega
            return (p, -q, -r)
        return None

    def _say_no_rate(self, mounting: Mounting | None, measurement: Any,
                     info: str | None) -> str | None:
        """Say once when a velocity sensor's lever arm meets no known body rate (ω = 0)."""
        position = (mounting.t if mounting is not None
                    else self.params.velocity_sensor_position)
        if not any(position) or measurement.omega_b is not None or self._imu_rate_flu():
            return info
        self._no_rate_said = True
        line = ('velocity lever arm: no body rate known (no fresh IMU rate, no angular part in '
                'the velocity message): omega x r taken as zero')
        return line if info is None else f'{info}; {line}'

    def reset(self) -> None:
        """Re-initialise the estimate, keeping the origin (the node's ``~/reset``)."""
        self._restart()

    def tf_static(self, msg: Any) -> int:
        """
        Take one ``/tf_static`` message (tf2_msgs/TFMessage) for the sensors' mountings.

        The inputs' mountings are resolved again from the next message on. Return the number
        of transforms that changed.
        """
        return self.mountings.take(msg)

    # --- outputs ------------------------------------------------------------------------

    def state(self) -> NavState | None:
        """Return the estimator's current state, or None before it is ready."""
        return self.estimator.state() if self.estimator.ready else None

    def _emissions(self, state: NavState) -> list[Emission]:
        """Return the outputs of ``state``, ``origin`` if it was set or changed, and /tf."""
        stamp = state.stamp_ns
        out = [Emission('/' + name, stamp, data)
               for name, data in outputs.state_outputs(state, self.params)]
        if self.estimator.pop_origin_event():
            out.append(self._origin_emission(stamp))
        dynamic = self._tf.dynamic(state, self.params)
        if dynamic is not None:
            out.append(Emission(TF, stamp, dynamic))
        return out

    def _origin_emission(self, stamp_ns: int) -> Emission:
        origin = self.estimator.origin
        assert origin is not None                   # only with an origin event
        return Emission('/origin', stamp_ns, outputs.origin(origin, stamp_ns, self.params))

    def _static_emissions(self, *, force: bool = False) -> list[Emission]:
        """Return /tf_static when the static transforms changed (they hang on the origin)."""
        est = self.estimator
        if not force and est.origin == self._statics_origin:
            return []
        self._statics_origin = est.origin
        stamp = est.t or 0
        data = self._tf.static(est.origin, stamp, self.params)
        return [] if data is None else [Emission(TF_STATIC, stamp, data)]

    def set_params(self, params: NavigatorParams) -> list[Emission]:
        """Apply new parameters at run time; return what to send (a new origin, statics)."""
        if params.publish_rate != self.params.publish_rate:
            self._next_publish = None
        if (params.imu_topics, params.imu_failover_timeout) != (
                self.params.imu_topics, self.params.imu_failover_timeout):
            self.failover = HeadingFailover(params.imu_topics, params.imu_failover_timeout)
        self.params = params
        self.mountings.set_params(params)
        self._set_types()
        est = self.estimator
        self.timeline.reconfigure(filter_config(params))
        self.timing.set_params(time_offsets(params), params.future_tolerance,
                               params.history_length)
        out = []
        if est.origin is not None and est.pop_origin_event():
            out.append(self._origin_emission(est.t or 0))
        return out + self._static_emissions(force=True)

    def diagnostics(self, now_ns: int, node_name: str = 'navigator',
                    extra: Mapping[str, int] | None = None) -> Emission:
        """
        Return ``/diagnostics`` at ``now_ns`` (the driver's clock): see :mod:`.diagnostics`.

        ``extra``: the driver's own counts (the node's internal errors), added to the
        estimate's status with the messages waiting for the IMU (``waiting <input>``).
        """
        refused = self.mountings.tree.refused
        counts = {**self.mountings.counts,
                  **{f'rejected tf_static/{reason}': n for reason, n in refused.items()}}
        in_use = self.failover.in_use if len(self.failover.topics) > 1 else None
        waiting = {f'waiting {name}': n for name, n in self.timeline.waiting_by_input().items()}
        data = self._diagnostics.array(now_ns, node_name, self.estimator, self.state(),
                                       self.params, self.mountings.sources,
                                       {**counts, **waiting, **(extra or {})},
                                       paused=self.paused, heading_in_use=in_use,
                                       timing=self.timing)
        return Emission(DIAGNOSTICS, now_ns, data)

    def estimates(self) -> dict[str, str]:
        """Return the calibrations and the current as text (``diagnostics.estimates``)."""
        return estimates(self.estimator, self.state())

    @property
    def counts(self) -> dict[str, int]:
        """Return accepted messages per input and rejected ones per reason (``'fix/no_fix'``)."""
        return self._diagnostics.counts

    @property
    def velocity_source(self) -> VelocitySource:
        """Return the velocity input's source in use."""
        return self.params.velocity_source


@contextmanager
def fewer_collections() -> Iterator[None]:
    """
    Run the block with the young generation collected every :data:`GC_THRESHOLD` allocations.

    Per message the pipeline allocates tuples, small arrays and records that reference counting
    frees at once; CPython's cyclic collector would still walk the young generation every 700
    net allocations, finding next to nothing (about a tenth of the replay's time,
    docs/performance.md). The cycles that do arise are still collected, less often. The node
    runs so for its life, the replay for a run.
    """
    old = gc.get_threshold()
    gc.set_threshold(GC_THRESHOLD, *old[1:])
    try:
        yield
    finally:
        gc.set_threshold(*old)
