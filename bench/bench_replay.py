"""
Replay throughput and accuracy on a long simulated voyage (prints numbers, asserts nothing).

1. Throughput: bag messages per second of ``replay`` (read, convert, estimate, serialise, write
   outputs and copied inputs) as a ratio to reading and deserialising the same bag with
   ``rosbags`` alone, in the same run. Measured with the demo's parameters (outputs at 20 Hz)
   and with the navigator's default (outputs on every input).
2. Accuracy against the simulator's truth: position, heading, course, sideslip and current,
   fused and dead-reckoning only.

``python bench/bench_replay.py [--duration S]``
"""

from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path
import sys
import tempfile
import time

from rosbags.highlevel import AnyReader

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
from vessel_kinematics.tools import replay  # noqa: E402


def _voyage(path: Path, duration: float) -> Path:
    """Write the simulated voyage (vessel_kinematics.tools.sim) of ``duration`` s at ``path``."""
    from vessel_kinematics.tools import sim
    sim.generate(path, sim.VoyageConfig(duration=duration))
    return path


def _rosbags_rate(bag: Path) -> tuple[int, float]:
    start = time.perf_counter()
    count = 0
    with AnyReader([bag]) as reader:
        for connection, _, raw in reader.messages():
            reader.deserialize(raw, connection.msgtype)
            count += 1
    return count, count / (time.perf_counter() - start)


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark and print its numbers."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument('--duration', type=float, default=300.0, help='voyage length, s')
    args = parser.parse_args(argv)
    demo_params = replay.load_params(REPO / 'config' / 'demo.yaml')
    with tempfile.TemporaryDirectory(prefix='bench_replay_') as tmp:
        work = Path(tmp)
        bag = _voyage(work / 'voyage', args.duration)
        count, base_rate = _rosbags_rate(bag)
        print(f'voyage: {args.duration:.0f} s simulated, {count} messages')
        print(f'rosbags read + deserialise: {base_rate:9.0f} msg/s')
        runs = ((f'demo parameters (publish_rate {demo_params.publish_rate:g} Hz)',
                 demo_params, 'demo'),
                ('outputs on every input (publish_rate 0)',
                 replace(demo_params, publish_rate=0.0), 'every'))
        for label, params, name in runs:
            start = time.perf_counter()
            summary = replay.run(bag, work / name, params, progress=False, accuracy=False)
            elapsed = time.perf_counter() - start
            rate = count / elapsed
            print(f'replay, {label}: {rate:9.0f} msg/s  ratio {rate / base_rate:.3f}  '
                  f'({sum(summary.messages_out.values())} messages out, {elapsed:.1f} s)')
        # Where the time goes: the same replay without writing a bag (inputs read and
        # deserialised, the pipeline, its outputs built but not serialised), and the reading
        # and deserialising of the input topics alone.
        start = time.perf_counter()
        replay.replay_in_memory(bag, demo_params)
        elapsed = time.perf_counter() - start
        print(f'  of which, in memory (no bag written): {count / elapsed:9.0f} msg/s  '
              f'ratio {count / elapsed / base_rate:.3f}')
        start = time.perf_counter()
        for _ in replay.input_messages(bag, demo_params, rclpy_messages=False):
            pass
        elapsed = time.perf_counter() - start
        print(f'  of which, input messages only (read, deserialise, order): '
              f'{count / elapsed:9.0f} msg/s  ratio {count / elapsed / base_rate:.3f}')
        text, _, _ = replay.accuracy_report(work / 'demo', demo_params)
        print('accuracy vs truth, demo parameters (RMS / max):')
        print(text)
    return 0


if __name__ == '__main__':
    sys.exit(main())
