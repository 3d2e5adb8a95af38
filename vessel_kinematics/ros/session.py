"""
The output policy, written once: when the navigator emits what, for both drivers.

A driver hands every input message to :meth:`Session.handle` and sends what comes back where it
goes: the node to its publishers, the replay to its bag writer. Nothing else decides what is
emitted, so the node and the replay emit the same messages for the same inputs by
construction (``test/test_equivalence.py`` keeps it so). The policy:

* ``publish_rate`` 0: the outputs after every accepted input;
* ``publish_rate`` > 0: one snapshot of the outputs when an accepted input's header stamp
  reaches the next multiple of the period (stamp time, not a wall-clock timer: a replayed bag
  and the live node emit at the same stamps, and a node fed nothing emits nothing new);
* ``/tf`` after each emission of the state (one transform per stamp, ``tf.publish``);
* ``/tf_static`` whenever the set of static transforms changes (the origin was set, a
  parameter changed), all of them in one message, as tf2's static broadcaster sends them.

Diagnostics are not part of it: each driver publishes them once a second of its own clock
(the node's clock; the replay's bag time), so a node whose inputs stopped still says so.
"""

from __future__ import annotations

from contextlib import contextmanager
from dataclasses import dataclass
import gc
from typing import Any, Collection, Iterable, Iterator

from vessel_kinematics.core.frames import stamp_to_ns
from vessel_kinematics.ros.params import NavigatorParams
from vessel_kinematics.ros.pipeline import Output, Pipeline, Result

__all__ = ['Emission', 'GC_THRESHOLD', 'Session', 'TF', 'TF_STATIC', 'fewer_collections']

#: The absolute topics of the transforms (their payload is a list of TransformStamped).
TF = '/tf'
TF_STATIC = '/tf_static'

#: The cyclic garbage collector's threshold for its youngest generation while a driver runs
#: (CPython's default is 700; see :func:`fewer_collections`).
GC_THRESHOLD = 10_000

#: No outputs: :meth:`Session.step` folds an input in without building any.
_NOTHING: frozenset[str] = frozenset()


@dataclass(frozen=True)
class Emission:
    """
    One message to send: its absolute ``topic``, its ``stamp_ns`` and the ``payload``.

    The payload is the pipeline's output message for an output topic, or a list of
    geometry_msgs/TransformStamped for :data:`TF` and :data:`TF_STATIC` (a driver wraps it in
    a tf2_msgs/TFMessage, or serialises it).
    """

    topic: str
    stamp_ns: int
    payload: Any


class Session:
    """The navigator's output policy over one :class:`~vessel_kinematics.ros.pipeline.Pipeline`."""

    def __init__(self, pipeline: Pipeline) -> None:
        self.pipeline = pipeline
        self._next_publish: int | None = None
        self._statics_sent: list[tuple[Any, ...]] | None = None
        # What the static transforms depend on (the origin, the parameters' object) when
        # they were last built: unchanged, they are not built again at each emission.
        self._statics_inputs: tuple[Any, NavigatorParams] | None = None

    @property
    def params(self) -> NavigatorParams:
        """Return the parameters in use."""
        return self.pipeline.params

    def statics(self) -> list[Emission]:
        """Return /tf_static with every static transform when the set has changed, else []."""
        return self._statics()

    def handle(self, name: str, msg: Any,
               topics: Collection[str] | None = None) -> tuple[Result, Iterable[Emission]]:
        """
        Fold one input message in; return its result and what to send now.

        ``topics``: the outputs to build (None: all; the node passes those somebody listens
        to, which changes what is built, never the state or the timing). What to send is
        ``[]`` or an iterator that builds each emission as it is taken: send each as it comes
        (the first output leaves before the last is built) and take them all, at once.
        """
        result, due = self._fold(name, msg, topics)
        if not due:
            return result, []
        if self.params.publish_rate <= 0.0:
            return result, self._emit(result.outputs)
        return result, self._emit(self.pipeline.iter_snapshot(topics))

    def step(self, name: str, msg: Any) -> tuple[Result, bool]:
        """
        Fold one input message in, building nothing; return its result and whether to emit.

        When it says so, :meth:`emissions` (here, or on a copy of this session given the
        pipeline's :meth:`~vessel_kinematics.ros.pipeline.Pipeline.hand_off`) gives what
        :meth:`handle` would have sent for all outputs: a driver may build the outputs in
        another process.
        """
        return self._fold(name, msg, _NOTHING)

    def emissions(self) -> Iterator[Emission]:
        """Yield the emission of all outputs for the current state, as :meth:`handle` does."""
        return self._emit(self.pipeline.iter_snapshot(None))

    def _fold(self, name: str, msg: Any,
              topics: Collection[str] | None) -> tuple[Result, bool]:
        """Fold one input message in; return its result and whether an emission is due."""
        result = self.pipeline.handle(name, msg, topics)
        if result.rejected is not None:
            return result, False
        rate = self.params.publish_rate
        if rate <= 0.0:
            return result, True
        stamp = self.pipeline.estimator.t        # the accepted stamps' latest: validated
        if stamp is None:
            return result, False
        if self._next_publish is None:
            self._next_publish = stamp
        if stamp < self._next_publish:
            return result, False
        period = int(round(1e9 / rate))
        self._next_publish += period * max(1, (stamp - self._next_publish) // period + 1)
        return result, True

    def set_params(self, params: NavigatorParams) -> list[Emission]:
        """Apply new parameters; return what to send (a new origin, new static transforms)."""
        if params.publish_rate != self.params.publish_rate:
            self._next_publish = None
        return list(self._emit(self.pipeline.set_params(params), state=False))

    def _emit(self, outputs: Iterable[Output], state: bool = True) -> Iterator[Emission]:
        """Yield the outputs, then /tf of the state, then /tf_static if it changed."""
        stamp = self.pipeline.estimator.t or 0
        for o in outputs:
            yield Emission('/' + o.topic, stamp, o.msg)
        if state:
            transforms = self.pipeline.transforms()
            if transforms:
                yield Emission(TF, stamp, transforms)
        yield from self._statics()

    def _statics(self) -> list[Emission]:
        """Return /tf_static with every static transform when the set has changed."""
        inputs = (self.pipeline.estimator.origin, self.params)
        if (self._statics_inputs is not None and inputs[0] == self._statics_inputs[0]
                and inputs[1] is self._statics_inputs[1]):
            return []
        self._statics_inputs = inputs
        statics = self.pipeline.static_transforms()
        key = [(t.header.frame_id, t.child_frame_id, t.transform) for t in statics]
        if not key or key == self._statics_sent:
            return []
        self._statics_sent = key
        stamp = stamp_to_ns(statics[0].header.stamp.sec, statics[0].header.stamp.nanosec)
        return [Emission(TF_STATIC, stamp, statics)]


@contextmanager
def fewer_collections() -> Iterator[None]:
    """
    Run the block with the young generation collected every :data:`GC_THRESHOLD` allocations.

    Per message the drivers allocate tuples, small arrays and records that reference counting
    frees at once; CPython's cyclic collector still walks the young generation every 700 net
    container allocations and, through the older generations, all of the process's objects
    now and then, finding next to nothing: on the 300 s voyage, 98 young, 9 middle and one
    full collection, about 6 % of the replay's estimator process (one young collection is
    left at this threshold). The cycles that do arise are still collected, fourteen times
    less often; the thresholds of the older generations are kept. The node sets this for its
    life (``main``), the replay for a run (both of its processes).
    """
    old = gc.get_threshold()
    gc.set_threshold(GC_THRESHOLD, *old[1:])
    try:
        yield
    finally:
        gc.set_threshold(*old)
