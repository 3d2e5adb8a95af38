"""
The replay's output bag in time: no message logged before the input's first, the input's span.

``ros2 bag play`` plays a bag in log time from its metadata's start: one message logged at 0
(the navigator's ``/tf_static`` of :meth:`~vessel_kinematics.ros.pipeline.Pipeline.start`,
stamped 0 before any input) would date the output from 1970 and make it wait 56 years. The
output is read back here with rosbags' AnyReader, as a player reads it: every log time at or
after the input's first, the input's start time, its duration (within the last output), and
the navigator's ``/tf_static`` at the start.

The input: a voyage of the project's simulator logged :data:`LATENCY_NS` after its header
stamps, as a recorder receives a sensor's messages, so that the first outputs are stamped
before the input's first log time; and, where ``../shared/data`` is beside the repository,
the IJsselmeer sailboat's bag.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from rosbags.highlevel import AnyReader
from rosbags.rosbag2 import StoragePlugin, Writer
from test_replay import write_voyage
from test_replay_safety import STORE
from vessel_kinematics.tools import bags, replay, sim

#: How long after its header stamp each simulated message is logged (ns).
LATENCY_NS = 50_000_000
#: The simulated voyage (s).
DURATION = 30.0


class Span:
    """A bag as a player sees it: start, duration, and every message's (topic, log ns)."""

    def __init__(self, path: Path) -> None:
        with AnyReader([path]) as reader:
            self.start_ns: int = reader.start_time
            self.duration_ns: int = reader.duration
            self.logged: list[tuple[str, int]] = [(c.topic, ns)
                                                  for c, ns, _ in reader.messages()]

    @property
    def end_ns(self) -> int:
        """Return the last message's log time."""
        return max(ns for _, ns in self.logged)


@pytest.fixture(scope='module')
def voyage(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Return a simulated voyage logged :data:`LATENCY_NS` after its stamps (mcap)."""
    config = sim.VoyageConfig(duration=DURATION, seed=3)
    records = sim.sensor_records(sim.simulate(config), config)
    return bags.write_bag(tmp_path_factory.mktemp('voyage') / 'in',
                          ((r.topic, r.stamp_ns + LATENCY_NS, r.data) for r in records),
                          sim.TOPICS)


def _check(source: Span, output: Span, last_output_ns: int) -> None:
    """
    Assert that ``output`` starts where ``source`` does and ends within ``last_output_ns``.

    Start: exact, the statics are logged at the input's first log time. End: the output's last
    message is logged at most ``last_output_ns`` before the input's last; 0 when the inputs are
    copied (the last input is), else the last emission's, whose stamp can be a header stamp,
    :data:`LATENCY_NS` before the last input's log time in the simulated voyage.
    """
    assert output.start_ns == source.start_ns
    assert all(ns >= source.start_ns for _, ns in output.logged), \
        sorted({topic for topic, ns in output.logged if ns < source.start_ns})
    early = source.end_ns - output.end_ns
    assert 0 <= early <= last_output_ns, early
    assert abs(output.duration_ns - source.duration_ns) <= last_output_ns
    statics = [ns for topic, ns in output.logged if topic == '/tf_static']
    assert statics and statics[0] == source.start_ns


@pytest.mark.parametrize('copy_inputs', [True, False])
def test_the_output_spans_the_simulated_input(voyage: Path, tmp_path: Path,
                                              copy_inputs: bool) -> None:
    """Copied inputs: the same start and end; without them, the end within the latency."""
    out = tmp_path / 'out'
    replay.run(voyage, out, copy_inputs=copy_inputs, progress=False, accuracy=False)
    _check(Span(voyage), Span(out), 0 if copy_inputs else LATENCY_NS)


@pytest.mark.slow
def test_the_output_spans_a_real_input(shared_data: Path, repo: Path, tmp_path: Path) -> None:
    """The IJsselmeer sailboat (mcap, 146 s) as the command replays it: the same span."""
    out = tmp_path / 'out'
    params = replay.load_params(repo / 'config' / 'sailboat.yaml')
    replay.run(shared_data / 'sailboat_ijsselmeer', out, params,
               ['imu:=/imu', 'velocity:=/speed_log'], progress=False)
    _check(Span(shared_data / 'sailboat_ijsselmeer'), Span(out), 0)


def test_by_stamp_merges_a_bag_whose_log_times_say_nothing(tmp_path: Path) -> None:
    """Every message logged at one instant, topic by topic: only a merge by stamp can use it."""
    source = write_voyage(tmp_path / 'in', duration=10.0)
    shuffled = tmp_path / 'shuffled'
    with AnyReader([source]) as reader, Writer(shuffled, version=9,
                                               storage_plugin=StoragePlugin.MCAP) as writer:
        connections = {c.id: writer.add_connection(c.topic, c.msgtype, typestore=STORE)
                       for c in reader.connections}
        t = reader.start_time
        for connection in sorted(reader.connections, key=lambda c: c.topic):
            for _, _, raw in reader.messages([connection]):
                writer.write(connections[connection.id], t, raw)
    # By log time the topics come one after another: every fix before the first IMU sample,
    # the log's readings after the last; most are too late, and no output comes.
    with pytest.raises(replay.ReplayError, match='no navigation output'):
        replay.run(shuffled, tmp_path / 'out1', progress=False, accuracy=False)
    by_stamp = replay.run(shuffled, tmp_path / 'out2', progress=False, accuracy=False,
                          by_stamp=True)
    assert not any(k.endswith('/too_late') for k in by_stamp.rejected), by_stamp.rejected
    assert by_stamp.messages_out['/odometry'] > 250
    assert replay.main([str(shuffled), str(tmp_path / 'out3'), '--by-stamp',
                        '--no-progress']) == 0
