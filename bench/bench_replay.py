"""
Replay throughput against its peer, rosbags reading the same bag (prints numbers, asserts nothing).

The voyage: the simulator's (``vessel_kinematics.tools.sim``) inputs only, IMU at 100 Hz, fixes
and body velocity at 10 Hz each, as long as it takes to hold ``--messages`` messages (200,000 by
default: 1,667 s). The peer: rosbags' AnyReader reading and deserialising every message of that
bag. The replay: the ``replay`` command at the navigator's default parameters (outputs at
``publish_rate`` 30 Hz, the inputs copied into the output bag), run through its ``main`` as a
user runs it. The machine may be shared, so the two are timed back to back, ``--repeat`` times,
and the ratios of those pairs are printed (median and range), never ratios of separate bests.

``--profile`` adds a cProfile of one replay, by module (where its time goes). The voyage's
messages are logged at their arrival, with the simulator's delivery latencies (fixes 0.1-0.5 s
late, which the replay fuses at their stamps by re-applying the history); ``--no-latency``
logs each at its stamp, for the cost without late inputs.

``python bench/bench_replay.py [--messages N] [--repeat N] [--profile] [--no-latency]``
"""

from __future__ import annotations

import argparse
import contextlib
import cProfile
import io
import os
from pathlib import Path
import pstats
import shutil
import statistics
import sys
import tempfile
import time

from rosbags.highlevel import AnyReader

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
from vessel_kinematics.tools import replay, sim  # noqa: E402

#: The sensor rates of the guard case (Hz): IMU, fix, velocity.
RATES = (100.0, 10.0, 10.0)


def voyage(path: Path, messages: int, latency: bool = True) -> int:
    """
    Write the inputs of a simulated voyage of about ``messages`` messages; return the count.

    ``latency``: each message logged at its arrival, the simulator's delivery latencies (fixes
    0.1-0.5 s after their stamps: the replay fuses each at its stamp by re-applying what came
    after it); False: logged at its stamp.
    """
    imu, fix, velocity = RATES
    none = (0.0, 0.0)
    config = sim.VoyageConfig(duration=messages / sum(RATES), imu_rate=imu, fix_rate=fix,
                              velocity_rate=velocity,
                              **({} if latency else {'fix_latency': none, 'imu_latency': none,
                                                     'velocity_latency': none}))
    inputs = {sim.TOPIC_FIX, sim.TOPIC_IMU, sim.TOPIC_VELOCITY}
    records = [r for r in sim.sensor_records(sim.simulate(config), config) if r.topic in inputs]
    sim.write_bag(path, records, {t: m for t, m in sim.TOPICS.items() if t in inputs})
    return len(records)


def read_deserialise(bag: Path) -> float:
    """Return the wall time (s) of rosbags reading and deserialising every message of ``bag``."""
    start = time.perf_counter()
    with AnyReader([bag]) as reader:
        for connection, _, raw in reader.messages():
            reader.deserialize(raw, connection.msgtype)
    return time.perf_counter() - start


def run_replay(bag: Path, out: Path) -> float:
    """Return the wall time (s) of ``replay BAG OUT`` at the default parameters."""
    if out.exists():
        shutil.rmtree(out)
    start = time.perf_counter()
    with contextlib.redirect_stdout(io.StringIO()):
        code = replay.main([str(bag), str(out), '--no-progress'])
    elapsed = time.perf_counter() - start
    if code != 0:
        raise SystemExit(f'replay exited with {code}')
    return elapsed


def profile(bag: Path, out: Path) -> None:
    """Print the replay's cumulative time per module of the package (cProfile)."""
    if out.exists():
        shutil.rmtree(out)
    profiler = cProfile.Profile()
    with contextlib.redirect_stdout(io.StringIO()):
        profiler.runcall(replay.main, [str(bag), str(out), '--no-progress'])
    stats = pstats.Stats(profiler).stats
    own: dict[str, float] = {}
    for (file, _, _), (_, _, tt, _, _) in stats.items():
        parts = Path(file).parts
        key = ('/'.join(parts[parts.index('vessel_kinematics'):]) if 'vessel_kinematics' in parts
               else 'rosbags' if 'rosbags' in parts else 'numpy' if 'numpy' in parts
               else 'other')
        own[key] = own.get(key, 0.0) + tt
    total = sum(own.values())
    print(f'profile (own time per module, {total:.1f} s under cProfile):')
    for key, seconds in sorted(own.items(), key=lambda kv: -kv[1])[:15]:
        print(f'  {key:58s} {seconds:6.2f} s {100 * seconds / total:5.1f} %')


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark and print its numbers."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument('--messages', type=int, default=200_000, help='input messages')
    parser.add_argument('--repeat', type=int, default=3, help='timed pairs')
    parser.add_argument('--profile', action='store_true', help='also profile one replay')
    parser.add_argument('--no-latency', action='store_true',
                        help='every message logged at its stamp (no late fix to re-apply)')
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix='bench_replay_') as tmp:
        work = Path(tmp)
        bag = work / 'voyage'
        count = voyage(bag, args.messages, not args.no_latency)
        print(f'voyage: {count} messages (IMU {RATES[0]:g} Hz, fix {RATES[1]:g} Hz, velocity '
              f'{RATES[2]:g} Hz, ' + ('no delivery latency' if args.no_latency else
                                      "the simulator's delivery latencies")
              + f'); load average {os.getloadavg()[0]:.2f}')
        ratios, pairs = [], []
        for _ in range(args.repeat):
            read = read_deserialise(bag)
            elapsed = run_replay(bag, work / 'out')
            ratios.append(read / elapsed)
            pairs.append((read, elapsed))
        for read, elapsed in pairs:
            print(f'  rosbags read + deserialise {read:6.2f} s ({count / read:7.0f} msg/s), '
                  f'replay {elapsed:6.2f} s ({count / elapsed:6.0f} msg/s): '
                  f'{read / elapsed:.3f}')
        print(f'replay / rosbags read + deserialise: {statistics.median(ratios):.3f} '
              f'(median of {args.repeat} pairs, {min(ratios):.3f}-{max(ratios):.3f}; '
              'guard >= 0.13)')
        if args.profile:
            profile(bag, work / 'profiled')
    return 0


if __name__ == '__main__':
    sys.exit(main())
