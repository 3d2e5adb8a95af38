"""
The estimator's per-IMU hot path on a 400 Hz stream (prints numbers, asserts nothing).

The stream of ``bench_pipeline`` (a vessel turning at 3 deg/s: IMU 400 Hz with orientation and
rate, body velocity 20 Hz, fix 10 Hz) is converted to measurements once (``ros.inputs``); then
``Estimator.imu`` (``_time`` -> ``_propagate`` -> ``Attitude.set_q``/``Pending.add``) is timed
per IMU message, against a peer in the same run: rosbags deserialising one sensor_msgs/Imu
(the replay's per-message read cost). A cProfile of one pass shows where the rest goes.

``python bench/bench_estimator.py [--seconds S] [--repeat N]``
"""

from __future__ import annotations

import argparse
import cProfile
import math
from pathlib import Path
import pstats
import statistics
import sys
import time

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / 'bench'))
import bench_pipeline  # noqa: E402
from vessel_kinematics.estimation import Estimator  # noqa: E402
from vessel_kinematics.ros import inputs  # noqa: E402
from vessel_kinematics.ros.params import filter_config, NavigatorParams  # noqa: E402


def _pass(measurements: list, params: NavigatorParams) -> tuple[float, int]:
    """Run the stream through a fresh estimator; return (time in imu() s, IMU count)."""
    est = Estimator(filter_config(params))
    updates = {'fix': est.fix, 'velocity': est.velocity}
    imu, spent, count = est.imu, 0.0, 0
    clock = time.perf_counter
    for name, m in measurements:
        if name == 'imu':
            start = clock()
            imu(m)
            spent += clock() - start
            count += 1
        else:
            updates[name](m)
    return spent, count


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark and print its numbers."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument('--seconds', type=float, default=30.0, help='simulated seconds')
    parser.add_argument('--repeat', type=int, default=3, help='passes (the best is kept)')
    args = parser.parse_args(argv)
    lat, lon, h = bench_pipeline.ORIGIN
    params = NavigatorParams.from_flat({'origin': [math.degrees(lat), math.degrees(lon), h]})
    convert = {'fix': inputs.fix_from_msg, 'imu': inputs.imu_from_msg,
               'velocity': inputs.velocity_from_msg}
    measurements = [(name, convert[name](msg, params))
                    for name, msg, _ in bench_pipeline.stream(args.seconds)]
    best = min(_pass(measurements, params)[0] for _ in range(args.repeat))
    count = sum(name == 'imu' for name, _ in measurements)
    per_imu = best / count * 1e6
    peer = bench_pipeline._rosbags_imu()
    peer_us = statistics.median(bench_pipeline.time_call(peer)) if peer else float('nan')
    print(f'Estimator.imu, 400 Hz stream of {args.seconds:g} s ({count} IMU): '
          f'{per_imu:.1f} us per message (best of {args.repeat})')
    print(f'  peer: rosbags deserialising one Imu {peer_us:.1f} us; ratio {per_imu / peer_us:.2f}')
    profiler = cProfile.Profile()
    profiler.enable()
    _pass(measurements, params)
    profiler.disable()
    pstats.Stats(profiler).sort_stats('tottime').print_stats(12)
    return 0


if __name__ == '__main__':
    sys.exit(main())
