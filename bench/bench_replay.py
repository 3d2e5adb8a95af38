"""
Replay throughput against its peers, and where its time goes (prints numbers, asserts nothing).

On a simulated voyage (``vessel_kinematics.tools.sim``: IMU 100 Hz, fixes and speed log 5 Hz),
in one run on the same machine:

1. rosbags reading and deserialising every message of the input bag (the peer of the issue);
2. the replay at the navigator's default parameters (outputs at ``publish_rate`` 30 Hz, inputs
   copied; the outputs built and the bag written by a second process where one can be
   forked, with the CPU time of either process), the same in the replay's own process, and
   with outputs on every update (``publish_rate`` 0), as ratios to (1);
3. the pure I/O of the same volume: reading and deserialising the input, copying it, and
   serialising (rosbags ``serialize_cdr``) and writing the very output messages the replay
   wrote (read back from its bag beforehand), as the replay's ratio to it;
4. a cProfile of the replay at 30 Hz, in one process, split into reading/deserialising the
   input, the estimator (``Pipeline.handle`` and the deferred propagation in
   ``Estimator.staged_state``, with its completion), building and serialising the outputs
   and TF, writing them, copying the inputs, and the rest.

``python bench/bench_replay.py [--duration S] [--repeat N]``
"""

from __future__ import annotations

import argparse
import cProfile
from dataclasses import replace
import os
from pathlib import Path
import pstats
import shutil
import statistics
import sys
import tempfile
import time

from rosbags.highlevel import AnyReader
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import get_typestore, Stores

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
from vessel_kinematics.ros.params import NavigatorParams  # noqa: E402
from vessel_kinematics.tools import replay  # noqa: E402


def _voyage(path: Path, duration: float) -> Path:
    """Write the simulated voyage (vessel_kinematics.tools.sim) of ``duration`` s at ``path``."""
    from vessel_kinematics.tools import sim
    sim.generate(path, sim.VoyageConfig(duration=duration))
    return path


def _best(repeat: int, work: callable) -> float:
    """Return the shortest wall time (s) of ``repeat`` calls of ``work()``."""
    best = float('inf')
    for _ in range(repeat):
        start = time.perf_counter()
        work()
        best = min(best, time.perf_counter() - start)
    return best


def _read_deserialise(bag: Path) -> int:
    count = 0
    with AnyReader([bag]) as reader:
        for connection, _, raw in reader.messages():
            reader.deserialize(raw, connection.msgtype)
            count += 1
    return count


def _outputs_of(out_bag: Path) -> list[tuple[str, str, int, object]]:
    """Return the replay's own outputs (not the copied inputs) as rosbags messages."""
    with AnyReader([out_bag]) as reader:
        wanted = [c for c in reader.connections if c.topic in replay.OUTPUT_TYPES]
        return [(c.topic, c.msgtype, ns, reader.deserialize(raw, c.msgtype))
                for c, ns, raw in reader.messages(connections=wanted)]


def _pure_io(bag: Path, outputs: list[tuple[str, str, int, object]], target: Path) -> None:
    """Read + deserialise + copy the input, serialise + write ``outputs``: the replay's I/O."""
    store = get_typestore(Stores.ROS2_JAZZY)
    writer = Writer(target, version=Writer.VERSION_LATEST, storage_plugin=StoragePlugin.MCAP)
    writer.open()
    try:
        connections = {}
        for topic, msgtype in replay.OUTPUT_TYPES.items():
            connections[topic] = writer.add_connection(topic, msgtype, typestore=store)
        with AnyReader([bag]) as reader:
            copies = {c.id: writer.add_connection(c.topic, c.msgtype, typestore=store)
                      for c in reader.connections}
            for connection, ns, raw in reader.messages():
                reader.deserialize(raw, connection.msgtype)
                writer.write(copies[connection.id], ns, raw)
        for topic, msgtype, ns, msg in outputs:
            writer.write(connections[topic], ns, store.serialize_cdr(msg, msgtype))
    finally:
        writer.close()


#: The estimator's state for the outputs, in its two stages (``Estimator.state`` calls both).
_STATE = [('estimator.py', 'staged_state'), ('estimator.py', '_completed')]
#: Profile split: (label, functions whose cumulative time counts, functions subtracted).
#: Functions are (file name ending, function name).
_SPLIT = (
    ('reading + deserialising the input', [('replay.py', '_decoded')],
     [('replay_output.py', 'copy')]),
    ('estimator (Pipeline.handle + deferred propagation)',
     [('pipeline.py', 'handle')] + _STATE, []),
    ('building + serialising the outputs and TF',
     [('pipeline.py', 'iter_snapshot'), ('pipeline.py', 'transforms'),
      ('pipeline.py', 'static_transforms'), ('pipeline.py', 'diagnostics'),
      ('replay.py', '_output_bytes')],
     _STATE),
    ('writing the outputs and TF', [('replay_output.py', 'write')], []),
    ('copying the inputs (raw bytes)', [('replay_output.py', 'copy')], []),
)


def _profile(bag: Path, params: NavigatorParams, target: Path) -> None:
    profiler = cProfile.Profile()
    profiler.enable()
    replay.run(bag, target, params, progress=False, accuracy=False, background=False)
    profiler.disable()
    stats = pstats.Stats(profiler).stats  # {(file, line, name): (cc, nc, tt, ct, callers)}

    def cumulative(keys: list[tuple[str, str]]) -> float:
        return sum(ct for (file, _, name), (_, _, _, ct, _) in stats.items()
                   if (Path(file).name, name) in {(Path(f).name, n) for f, n in keys}
                   and 'vessel_kinematics' in file)

    total = cumulative([('replay.py', 'run')])
    print(f'profile of the replay at {params.publish_rate:g} Hz (cProfile, {total:.2f} s '
          'under the profiler):')
    accounted = 0.0
    for label, plus, minus in _SPLIT:
        part = cumulative(plus) - cumulative(minus)
        accounted += part
        print(f'  {label:52s} {part:6.2f} s  {100 * part / total:5.1f} %')
    print(f'  {"the rest (merge by stamp, bookkeeping, open/close)":52s} '
          f'{total - accounted:6.2f} s  {100 * (total - accounted) / total:5.1f} %')


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark and print its numbers."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument('--duration', type=float, default=300.0, help='voyage length, s')
    parser.add_argument('--repeat', type=int, default=3, help='timed pairs per ratio')
    parser.add_argument('--publish-rate', type=float, default=None,
                        help='instead of the default publish_rate (e.g. to compare versions)')
    args = parser.parse_args(argv)
    params = NavigatorParams()
    if args.publish_rate is not None:
        params = replace(params, publish_rate=args.publish_rate)
    with tempfile.TemporaryDirectory(prefix='bench_replay_') as tmp:
        work = Path(tmp)
        bag = _voyage(work / 'voyage', args.duration)
        count = _read_deserialise(bag)
        print(f'voyage: {args.duration:.0f} s simulated, {count} messages in')

        def replayed(p: NavigatorParams, name: str,
                     background: bool | None = None) -> replay.Summary:
            target = work / name
            if target.exists():
                shutil.rmtree(target)
            return replay.run(bag, target, p, progress=False, accuracy=False,
                              background=background)

        # The machine is shared: each replay is timed right after its peers, and the ratios
        # of those pairs are reported (median and range), not ratios of separate bests.
        for label, p, name, background in (
                (f'default parameters, publish_rate {params.publish_rate:g} Hz', params,
                 'default', None),
                ('default parameters, all in the replay process', params, 'one',
                 False),
                ('outputs on every update (publish_rate 0)', replace(params, publish_rate=0.0),
                 'every', None)):
            summary = replayed(p, name, background)
            n_out = sum(summary.messages_out.values())
            outputs = _outputs_of(work / name)
            io_target = work / f'io_{name}'

            def io() -> None:
                if io_target.exists():
                    shutil.rmtree(io_target)
                _pure_io(bag, outputs, io_target)

            read_ratios, io_ratios, times, cpu = [], [], [], []
            for _ in range(args.repeat):
                read = _best(1, lambda: _read_deserialise(bag))
                before = os.times()
                elapsed = _best(1, lambda: replayed(p, name, background))
                after = os.times()
                cpu.append((after.user + after.system - before.user - before.system,
                            after.children_user + after.children_system
                            - before.children_user - before.children_system))
                io_time = _best(1, io)
                read_ratios.append(read / elapsed)
                io_ratios.append(io_time / elapsed)
                times.append((read, elapsed, io_time))
            read, elapsed, io_time = times[read_ratios.index(statistics.median_low(read_ratios))]
            print(f'replay, {label}: {count / elapsed:8.0f} msg/s in, {n_out} out '
                  f'({elapsed:.2f} s; rosbags read + deserialise {count / read:.0f} msg/s)')
            print(f'  ratio to rosbags read + deserialise: '
                  f'{statistics.median(read_ratios):.3f} (median of {args.repeat} pairs, '
                  f'{min(read_ratios):.3f}-{max(read_ratios):.3f})')
            print(f'  ratio to the pure I/O of the same volume (read, deserialise, copy, '
                  f'serialise + write the {len(outputs)} outputs): '
                  f'{statistics.median(io_ratios):.3f} ({min(io_ratios):.3f}-'
                  f'{max(io_ratios):.3f})')
            mine, writer = (statistics.median(c) for c in zip(*cpu))
            if writer > 0.05:                # a writer process ran (not a reaped leftover)
                print(f'  CPU: the replay process {mine:.2f} s, the writer process '
                      f'{writer:.2f} s (medians; both cores busy, each runs slower)')
        _profile(bag, params, work / 'profiled')
    return 0


if __name__ == '__main__':
    sys.exit(main())
