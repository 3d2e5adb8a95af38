"""
Offline replay and live navigator give the same outputs for the same bag and parameters.

A short simulated voyage (``vessel_kinematics.tools.sim``, with a GNSS outage) gets a few bad
messages
injected (a NaN fix, a NO_FIX fix with a plausible position, an IMU sample with the zero
quaternion, a NaN body velocity) and is written as an mcap bag with one parameters file beside
it. Then:

* offline: :func:`vessel_kinematics.tools.replay.replay_in_memory` replays the bag with the file's
  parameters; :class:`~vessel_kinematics.ros.pipeline.Pipeline` run message by message over
  :func:`~vessel_kinematics.tools.replay.input_messages` (the replay's input sequence) says which
  outputs each input produced, and is checked to give exactly the replay's bytes;
* live: the installed ``navigator`` (as ``ros2 run`` starts it, with the same
  ``--params-file``, ``sensor_qos: reliable``) gets the bag's input messages over DDS in the
  replay's header-stamp order, one at a time, as the bag's very bytes: after each message the
  test waits for the outputs the offline run says it produced, or, for a message that produced
  none (rejected, or before the origin is known), until ``/diagnostics`` counts it as
  processed.

Every output topic (``odometry``, ``odometry/local``, ``odometry/ned``, ``course_sideslip``,
``current`` in the water-referenced case, ``fix/filtered``, ``origin``) is then compared message
by message and field by field: strings and integers (stamps, frame ids, status, covariance
types) exactly, every float within :data:`TOLERANCE`; the node's final diagnostics counts
(accepted and rejected by reason) must equal the pipeline's.
"""

from __future__ import annotations

import array
from collections import Counter
from dataclasses import dataclass
import math
from pathlib import Path
from typing import Any, Callable

from dds_harness import DdsTester, diagnostic_values, LATCHED, NodeProcess, RELIABLE
from diagnostic_msgs.msg import DiagnosticArray
from nav_msgs.msg import Odometry
import numpy as np
import pytest
from rclpy.serialization import deserialize_message, serialize_message
from rosbags.typesys import get_typestore, Stores
from sensor_msgs.msg import NavSatFix, NavSatStatus
import vessel_kinematics
from vessel_kinematics.ros import interface
from vessel_kinematics.ros.pipeline import OUTPUTS, Pipeline
from vessel_kinematics.tools import replay, sim
import yaml

#: Absolute tolerance on every float field (m, rad, m/s, deg, variances).
TOLERANCE = 1e-9
STORE = get_typestore(Stores.ROS2_JAZZY)
#: Longest wait for one input's outputs or diagnostics (s): generous for a loaded machine
#: (the node answers in milliseconds; ``/diagnostics`` comes every second).
WAIT = 20.0
#: Sim time (s) of the voyage, its IMU rate (Hz) and seed.
DURATION = 20.0
IMU_RATE = 50.0
SEED = 11

#: Message class of each output topic (the interface table, as the navigator publishes them).
OUTPUT_TYPES: dict[str, type] = {
    topic: interface.message_class(msg_type)
    for topic, msg_type in interface.types(interface.Role.OUTPUT).items()}
#: Message class of each input topic.
INPUT_TYPES: dict[str, type] = {
    name: interface.message_class(msg_type)
    for name, msg_type in interface.types(interface.Role.INPUT, absolute=False).items()}

#: The two cases: DVL bottom track (no current) and water track (current estimated), each
#: with a few non-default parameters, in a ROS 2 parameters file for both drivers.
CASES: dict[str, dict[str, Any]] = {
    'ground': {
        'sensor_qos': 'reliable',
        'publish_rate': 0.0,
        'velocity': {'reference': 'ground'},
        'gnss': {'antenna_position': [-3.0, 0.0, 5.0], 'gate_sigma': 6.0},
    },
    'water': {
        'sensor_qos': 'reliable',
        'publish_rate': 0.0,
        'velocity': {'reference': 'water'},
        'gnss': {'antenna_position': [-3.0, 0.0, 5.0]},
        'projection': 'flat',
        'integrator': 'euler',
        'motion': 'ground',
    },
}


# --- the bag ---------------------------------------------------------------------------------

def _bad_messages(records: list[sim.Record]) -> list[sim.Record]:
    """Return copies of a few voyage messages made unusable, stamped between the good ones."""
    def first(topic: str, after_s: float) -> tuple[Any, int]:
        start = records[0].stamp_ns + int(after_s * 1e9)
        rec = next(r for r in records if r.topic == topic and r.stamp_ns >= start)
        return deserialize_message(rec.data, INPUT_TYPES[topic.lstrip('/')]), rec.stamp_ns

    def record(topic: str, msg: Any, stamp_ns: int) -> sim.Record:
        msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(stamp_ns, 1_000_000_000)
        return sim.Record(topic, stamp_ns, serialize_message(msg))

    bad = []
    fix, at = first(sim.TOPIC_FIX, 0.3 * DURATION)
    fix.latitude = math.nan                                   # rejected: fix/nan_field
    bad.append(record(sim.TOPIC_FIX, fix, at + 3_000_000))
    fix, at = first(sim.TOPIC_FIX, 0.45 * DURATION)
    fix.status.status = NavSatStatus.STATUS_NO_FIX            # rejected: fix/no_fix
    bad.append(record(sim.TOPIC_FIX, fix, at + 7_000_000))
    imu, at = first(sim.TOPIC_IMU, 0.35 * DURATION)
    imu.orientation.x = imu.orientation.y = imu.orientation.z = imu.orientation.w = 0.0
    bad.append(record(sim.TOPIC_IMU, imu, at + 1_000_000))   # rejected: imu/zero_quaternion
    velocity, at = first(sim.TOPIC_VELOCITY, 0.8 * DURATION)
    velocity.twist.twist.linear.x = math.nan                  # rejected: velocity/nan_field
    bad.append(record(sim.TOPIC_VELOCITY, velocity, at + 2_000_000))
    return bad


def write_voyage(directory: Path, reference: str) -> Path:
    """Write the voyage's inputs (and the bad messages) as an mcap bag; return its path."""
    config = sim.VoyageConfig(duration=DURATION, seed=SEED, reference=reference,
                              imu_rate=IMU_RATE, truth_rate=10.0,
                              outage=(0.6 * DURATION, 2.5))
    inputs = {sim.TOPIC_FIX, sim.TOPIC_IMU, sim.TOPIC_VELOCITY}
    records = [r for r in sim.sensor_records(sim.simulate(config), config) if r.topic in inputs]
    records += _bad_messages(records)
    records.sort(key=lambda r: r.stamp_ns)
    return sim.write_bag(directory / f'voyage_{reference}', records,
                         {t: m for t, m in sim.TOPICS.items() if t in inputs})


def write_params(directory: Path, values: dict[str, Any]) -> Path:
    """Write ``values`` as a ROS 2 parameters file for the node named navigator."""
    path = directory / 'navigator.yaml'
    path.write_text(yaml.safe_dump({'navigator': {'ros__parameters': values}}))
    return path


# --- the offline side ------------------------------------------------------------------------

@dataclass
class Step:
    """One input of the replay's sequence and the outputs the pipeline produced for it."""

    name: str
    stamp_ns: int
    raw: bytes
    outputs: list[tuple[str, bytes]]

    def messages(self) -> list[tuple[str, Any]]:
        """Return the outputs as rclpy reads them from the wire."""
        return [(topic, deserialize_message(data, OUTPUT_TYPES[topic]))
                for topic, data in self.outputs]


def offline_steps(bag: Path, params: Any
                  ) -> tuple[list[Step], dict[str, int], list[tuple[str, bytes]]]:
    """
    Run the pipeline over the replay's input sequence; return the steps and their counts.

    And the outputs of the replay's end (:meth:`Pipeline.flush`: what waited for an IMU sample
    that never came), which the live node, still waiting, does not send.
    """
    pipeline = Pipeline(params)
    steps = []
    for item in replay.input_messages(bag, params):
        result = pipeline.handle(item.name, item.msg, item.arrival_ns)
        outputs = [(e.topic, e.cdr) for e in result.emissions if e.topic in OUTPUT_TYPES]
        steps.append(Step(item.name, item.stamp_ns, item.raw, outputs))
    counts = pipeline.counts
    end = [(e.topic, e.cdr) for e in pipeline.flush().emissions if e.topic in OUTPUT_TYPES]
    return steps, counts, end


# --- comparison ------------------------------------------------------------------------------

class Differences:
    """Field-by-field comparison of messages: the largest float difference, every mismatch."""

    def __init__(self, tolerance: float) -> None:
        self.tolerance = tolerance
        self.max_diff: dict[str, float] = {}
        self.mismatches: list[str] = []

    def compare(self, topic: str, index: int, expected: Any, actual: Any) -> None:
        """Compare two messages of ``topic`` (the ``index``-th on it)."""
        self._walk(topic, f'{topic}[{index}]', expected, actual)

    def _walk(self, topic: str, path: str, expected: Any, actual: Any) -> None:
        if hasattr(expected, 'get_fields_and_field_types'):
            if type(expected) is not type(actual):
                self.mismatches.append(f'{path}: type {type(actual).__name__}, expected '
                                       f'{type(expected).__name__}')
                return
            for name in expected.get_fields_and_field_types():
                self._walk(topic, f'{path}.{name}', getattr(expected, name),
                           getattr(actual, name))
        elif isinstance(expected, (list, tuple, array.array, np.ndarray)):
            if len(expected) != len(actual):
                self.mismatches.append(f'{path}: length {len(actual)}, expected '
                                       f'{len(expected)}')
                return
            if isinstance(expected, np.ndarray) and expected.dtype.kind == 'f':
                self._floats(topic, path, expected, np.asarray(actual, dtype=float))
                return
            for i, (e, a) in enumerate(zip(expected, actual)):
                self._walk(topic, f'{path}[{i}]', e, a)
        elif isinstance(expected, float):
            self._float(topic, path, float(expected), float(actual))
        elif expected != actual or type(expected) is not type(actual):
            self.mismatches.append(f'{path}: {actual!r}, expected {expected!r}')

    def _floats(self, topic: str, path: str, expected: np.ndarray, actual: np.ndarray) -> None:
        """Compare float arrays (covariances) element by element, NaN equal to NaN only."""
        with np.errstate(invalid='ignore'):
            diff = np.where(expected == actual, 0.0, np.abs(expected - actual))
        nan_expected, nan_actual = np.isnan(expected), np.isnan(actual)
        diff[nan_expected & nan_actual] = 0.0
        diff[nan_expected ^ nan_actual] = math.inf
        if diff.size:
            self.max_diff[topic] = max(self.max_diff.get(topic, 0.0), float(diff.max()))
        for i in np.flatnonzero(~(diff <= self.tolerance)).tolist():
            self._float(topic, f'{path}[{i}]', float(expected[i]), float(actual[i]))

    def _float(self, topic: str, path: str, expected: float, actual: float) -> None:
        if math.isnan(expected) or math.isnan(actual):
            diff = 0.0 if math.isnan(expected) and math.isnan(actual) else math.inf
        elif expected == actual:
            diff = 0.0
        else:
            diff = abs(expected - actual)
        self.max_diff[topic] = max(self.max_diff.get(topic, 0.0), diff)
        if not diff <= self.tolerance:
            self.mismatches.append(f'{path}: {actual!r}, expected {expected!r} '
                                   f'(difference {diff:.3g})')


def by_topic(outputs: list[tuple[str, Any]]) -> dict[str, list[Any]]:
    """Return the messages of ``(topic, msg)`` pairs grouped by topic, in order."""
    grouped: dict[str, list[Any]] = {}
    for topic, msg in outputs:
        grouped.setdefault(topic, []).append(msg)
    return grouped


def processed(values: dict[str, str], name: str) -> int:
    """Return how many ``name`` messages a diagnostics status counts (taken, held, refused)."""
    return sum(int(v) for k, v in values.items()
               if k in (f'accepted {name}', f'waiting {name}')
               or k.startswith((f'rejected {name}/', f'internal_error/{name}')))


def pipeline_counts(values: dict[str, str]) -> dict[str, int]:
    """Return the pipeline's counts (:attr:`Pipeline.counts` keys) of a diagnostics status."""
    counts = {}
    for key, value in values.items():
        if key.startswith('accepted '):
            counts[key.removeprefix('accepted ')] = int(value)
        elif key.startswith('rejected '):
            counts[key.removeprefix('rejected ')] = int(value)
        elif key == 'resets':
            counts[key] = int(value)
    return counts


def check_install_is_source(install: Path) -> None:
    """Fail when the installed package's modules are not the ones this test imports."""
    installed = sorted(install.rglob('site-packages/vessel_kinematics/__init__.py'))
    if not installed:
        pytest.fail(f'no installed vessel_kinematics under {install}')
    package = installed[0].parent
    source = Path(vessel_kinematics.__file__).resolve().parent
    stale = [str(p.relative_to(package)) for p in sorted(package.rglob('*.py'))
             if not (source / p.relative_to(package)).is_file()
             or (source / p.relative_to(package)).read_bytes() != p.read_bytes()]
    if stale:
        pytest.fail(f'the install space {install} is not built from {source} '
                    f'({", ".join(stale)} differ): rebuild it, the two sides must run the '
                    f'same code')


def test_differences_catch_what_the_equivalence_test_must_catch() -> None:
    """A float beyond the tolerance, a stamp, a frame id, a status or a NaN all differ."""
    reference = Odometry()
    reference.header.stamp.sec, reference.header.stamp.nanosec = 1_717_243_200, 5
    reference.header.frame_id, reference.child_frame_id = 'map', 'base_link'
    reference.pose.pose.position.x = 1234.5
    reference.pose.covariance[7] = 0.25

    def variant(change: Callable[[Odometry], None]) -> Odometry:
        msg = deserialize_message(serialize_message(reference), Odometry)
        change(msg)
        return msg

    def differs(msg: Any, expected: Any = reference) -> bool:
        differences = Differences(TOLERANCE)
        differences.compare('/odometry', 0, expected, msg)
        return bool(differences.mismatches)

    assert not differs(variant(lambda m: None))
    assert not differs(variant(lambda m: setattr(m.pose.pose.position, 'x', 1234.5 + 4e-10)))
    assert differs(variant(lambda m: setattr(m.pose.pose.position, 'x', 1234.5 + 3e-9)))
    assert differs(variant(lambda m: m.pose.covariance.__setitem__(7, 0.25 + 2e-9)))
    assert differs(variant(lambda m: m.twist.covariance.__setitem__(35, math.nan)))
    assert differs(variant(lambda m: setattr(m.header.stamp, 'nanosec', 6)))
    assert differs(variant(lambda m: setattr(m.header, 'frame_id', 'odom')))
    assert differs(variant(lambda m: setattr(m, 'child_frame_id', 'base_link_frd')))
    fix = NavSatFix(latitude=63.44, longitude=10.4)
    assert differs(NavSatFix(latitude=63.44, longitude=10.4, status=NavSatStatus(status=-1)),
                   fix)
    assert differs(NavSatFix(latitude=63.44, longitude=10.4 + 1e-8), fix)
    assert not differs(NavSatFix(latitude=63.44, longitude=10.4), fix)


# --- the live side ---------------------------------------------------------------------------

def play_in_step(dds: DdsTester, node: NodeProcess, steps: list[Step]) -> None:
    """
    Publish every step's input, then wait for its outputs (or for diagnostics to count it).

    Fails with the step, the counts seen and the node's log when a wait times out.
    """
    received = dds.received
    diagnostics = received['/diagnostics']
    expected = Counter()
    sent = Counter()
    for index, step in enumerate(steps):
        dds.publish('/' + step.name, step.raw)         # the bag's own bytes
        sent[step.name] += 1
        condition: Callable[[], bool]
        if step.outputs:
            expected.update(topic for topic, _ in step.outputs)

            def condition() -> bool:
                return all(len(received[t]) >= n for t, n in expected.items())
        else:
            name, count = step.name, sent[step.name]

            def condition() -> bool:
                return bool(diagnostics) and processed(
                    diagnostic_values(diagnostics[-1]), name) >= count
        if not dds.spin_until(condition, WAIT):
            seen = {t: len(received[t]) for t in OUTPUT_TYPES}
            last = diagnostic_values(diagnostics[-1]) if diagnostics else {}
            pytest.fail(f'input {index} ({step.name}, stamp {step.stamp_ns}): '
                        f'no answer in {WAIT} s; expected outputs {dict(expected)}, received '
                        f'{seen}; last diagnostics {last}; node alive {node.alive()}\n'
                        f'{node.output()[-3000:]}')


@pytest.mark.dds
@pytest.mark.parametrize('case', sorted(CASES))
def test_live_navigator_equals_offline_replay(case: str, tmp_path: Path, dds: DdsTester,
                                              run_navigator: Callable[..., NodeProcess],
                                              navigator_install: Path) -> None:
    """The navigator over DDS publishes what the replay writes, message for message."""
    check_install_is_source(navigator_install)
    bag = write_voyage(tmp_path, CASES[case]['velocity']['reference'])
    params_file = write_params(tmp_path, CASES[case])
    params = replay.load_params(params_file)
    assert params.publish_rate == 0.0 and params.sensor_qos == 'reliable'

    # Offline: the replay's outputs, and which input produced which of them, byte for byte.
    written, summary = replay.replay_in_memory(bag, params)
    steps, counts, end = offline_steps(bag, params)
    stepped = by_topic([output for step in steps for output in step.outputs] + end)
    for topic in OUTPUT_TYPES:
        replayed = written[topic]
        assert [s for s, _ in replayed] == [
            m.header.stamp.sec * 10 ** 9 + m.header.stamp.nanosec for _, m in replayed]
        msgtype = interface.topic(topic).msg_type
        assert [bytes(STORE.serialize_cdr(m, msgtype)) for _, m in replayed] == \
            stepped.get(topic, []), topic
    per_topic = by_topic([output for step in steps for output in step.messages()])
    # The voyage exercises what it should: every output topic, and rejections of each kind.
    assert set(per_topic) == {'/' + o for o in OUTPUTS
                              if not interface.topic(o).water_only or case == 'water'
                              }, sorted(per_topic)
    for key in ('fix/nan_field', 'fix/no_fix', 'imu/zero_quaternion', 'velocity/nan_field'):
        assert counts.get(key, 0) >= 1, (key, counts)
    assert summary.rejected == Counter({k: v for k, v in counts.items() if '/' in k}), (
        summary.rejected, counts)
    silent = sum(1 for step in steps if not step.outputs)

    # Live: the installed navigator with the same parameters file, all outputs subscribed.
    node = run_navigator(params_file=params_file)
    dds.wait_for_node('navigator', node, timeout=30.0)
    for topic, msg_type in OUTPUT_TYPES.items():
        dds.collect(topic, msg_type, LATCHED if interface.topic(topic).latched else RELIABLE)
    dds.collect('/diagnostics', DiagnosticArray)
    for name, msg_type in INPUT_TYPES.items():
        dds.publisher('/' + name, msg_type, RELIABLE)
    dds.wait_for_match(['/' + n for n in INPUT_TYPES] + list(OUTPUT_TYPES) + ['/diagnostics'],
                       timeout=30.0)
    dds.spin_for(1.0)   # let the node's side of the discovery settle as well
    play_in_step(dds, node, steps)
    dds.spin_for(0.5)   # anything published beyond the expected would show up here

    diagnostics = dds.received['/diagnostics']
    assert dds.spin_until(
        lambda: pipeline_counts(diagnostic_values(diagnostics[-1])) == counts, WAIT), (
        pipeline_counts(diagnostic_values(diagnostics[-1])), counts)
    assert diagnostic_values(diagnostics[-1]).get('internal_errors') == '0'
    assert node.alive(), node.output()

    differences = Differences(TOLERANCE)
    for topic in OUTPUT_TYPES:
        offline, live = per_topic.get(topic, []), dds.received[topic]
        assert len(live) == len(offline), (topic, len(live), len(offline))
        for index, (expected, actual) in enumerate(zip(offline, live)):
            differences.compare(topic, index, expected, actual)
    total = sum(len(v) for v in per_topic.values())
    print(f'\n{case}: {len(steps)} inputs ({silent} without outputs), {total} outputs '
          f'compared; max |difference| by topic: '
          + ', '.join(f'{t} {d:.3g}' for t, d in sorted(differences.max_diff.items())))
    assert not differences.mismatches, (
        f'{len(differences.mismatches)} fields differ, e.g.:\n'
        + '\n'.join(differences.mismatches[:20]))
