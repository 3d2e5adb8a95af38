"""
Cost of Pipeline.handle per message, next to peers measured in the same run (prints only).

A vessel turning at 3 deg/s at 2 m/s sends IMU at 400 Hz (orientation and rate), a body
velocity (TwistWithCovarianceStamped) at 20 Hz and a GNSS fix at 10 Hz, as rclpy messages
built beforehand. Each call of :meth:`Pipeline.handle` is timed alone (perf_counter_ns), in
two modes:

(a) outputs built on every update (``publish_rate`` 0);
(b) at the default ``publish_rate`` 30 Hz (outputs with one message in 13).

Printed per message type: p50 and p99 in microseconds, and the p50 as a ratio to peers timed
in the same run (the machine is shared: compare ratios, not absolute times), and the sum of
all calls (the CPU the node's guard counts, DDS aside). ``--fix-delay S`` hands each fix in
S s after its stamp (a receiver's latency: each is fused at its stamp by re-applying the
history, docs/timing.md), the others at their stamps:
constructing one nav_msgs/Odometry, rclpy ``deserialize_message`` of one sensor_msgs/Imu, and
``rosbags`` deserialisation of one Imu (the replay's read baseline).

``python bench/bench_pipeline.py [--seconds S] [--repeat N]`` from the repository root.
"""

from __future__ import annotations

import argparse
from dataclasses import replace
import gc
import math
from pathlib import Path
import statistics
import sys
import time
from typing import Any, Callable

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from geometry_msgs.msg import TwistWithCovarianceStamped  # noqa: E402
from nav_msgs.msg import Odometry  # noqa: E402
from rclpy.serialization import deserialize_message, serialize_message  # noqa: E402
from sensor_msgs.msg import Imu, NavSatFix  # noqa: E402
from vessel_kinematics.core import geodesy  # noqa: E402
from vessel_kinematics.ros.params import NavigatorParams  # noqa: E402
from vessel_kinematics.ros.pipeline import Pipeline  # noqa: E402

ORIGIN = (math.radians(63.4389), math.radians(10.3994), 40.0)
T0_NS = 1_700_000_000 * 10 ** 9
SPEED = 2.0                  # m/s, forward
YAW_RATE = math.radians(3.0)  # rad/s, FRD r (turning to starboard)


def _stamp(msg: Any, t_ns: int) -> Any:
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(t_ns, 10 ** 9)
    return msg


def _imu(t: float) -> Imu:
    psi = YAW_RATE * t
    yaw = math.pi / 2 - psi                      # ROS yaw: from east, counter-clockwise
    msg = _stamp(Imu(), T0_NS + round(t * 1e9))
    msg.header.frame_id = 'imu_link'
    msg.orientation.z, msg.orientation.w = math.sin(yaw / 2), math.cos(yaw / 2)
    msg.orientation_covariance = [1e-4, 0.0, 0.0, 0.0, 1e-4, 0.0, 0.0, 0.0, 1e-4]
    msg.angular_velocity.z = -YAW_RATE
    msg.angular_velocity_covariance = [1e-6, 0.0, 0.0, 0.0, 1e-6, 0.0, 0.0, 0.0, 1e-6]
    msg.linear_acceleration.z = 9.81
    return msg


def _velocity(t: float) -> TwistWithCovarianceStamped:
    msg = _stamp(TwistWithCovarianceStamped(), T0_NS + round(t * 1e9))
    msg.header.frame_id = 'base_link'
    msg.twist.twist.linear.x = SPEED
    msg.twist.twist.angular.z = -YAW_RATE
    cov = [0.0] * 36
    for i in range(3):
        cov[7 * i] = 0.01 ** 2
        cov[7 * (i + 3)] = 1e-4
    msg.twist.covariance = cov
    return msg


def _fix(t: float) -> NavSatFix:
    radius = SPEED / YAW_RATE
    psi = YAW_RATE * t
    north, east = radius * math.sin(psi), radius * (1.0 - math.cos(psi))
    lat, lon, h = geodesy.ned2llh((north, east, 0.0), *ORIGIN)
    msg = _stamp(NavSatFix(), T0_NS + round(t * 1e9))
    msg.header.frame_id = 'gnss'
    msg.latitude, msg.longitude, msg.altitude = math.degrees(lat), math.degrees(lon), h
    msg.position_covariance = [0.25, 0.0, 0.0, 0.0, 0.25, 0.0, 0.0, 0.0, 1.0]
    msg.position_covariance_type = NavSatFix.COVARIANCE_TYPE_DIAGONAL_KNOWN
    return msg


def stream(seconds: float, fix_delay: float = 0.0) -> list[tuple[str, Any, int]]:
    """
    Return (input name, message, arrival ns): 400 Hz IMU, 20 Hz velocity, 10 Hz fix.

    Each arrives at its stamp, a fix ``fix_delay`` s after it; in the order of arrival.
    """
    events = []
    for k in range(int(seconds * 400)):
        t = k / 400.0
        events.append((t, 0, 'imu', _imu(t)))
        if k % 20 == 0:
            events.append((t + 1e-4, 1, 'velocity', _velocity(t + 1e-4)))
        if k % 40 == 0:
            events.append((t + 2e-4, 2, 'fix', _fix(t + 2e-4)))
    delay = {'fix': round(fix_delay * 1e9)}
    arrivals = [(T0_NS + round(t * 1e9) + delay.get(name, 0), order, name, msg)
                for t, order, name, msg in events]
    arrivals.sort(key=lambda e: (e[0], e[1]))
    return [(name, msg, arrival) for arrival, _, name, msg in arrivals]


def time_pipeline(params: NavigatorParams, events: list[tuple[str, Any, int]]
                  ) -> dict[str, list[float]]:
    """Return the µs of each handle(name, msg, arrival) call by input name (1 s warm-up)."""
    pipeline = Pipeline(params)
    times: dict[str, list[float]] = {'imu': [], 'velocity': [], 'fix': []}
    clock = time.perf_counter_ns
    handle = pipeline.handle
    warm = 400
    gc.disable()
    try:
        for i, (name, msg, arrival) in enumerate(events):
            start = clock()
            result = handle(name, msg, arrival)
            elapsed = clock() - start
            if result.rejected is not None:
                raise RuntimeError(f'{name} rejected: {result.detail}')
            if i > warm:
                times[name].append(elapsed * 1e-3)
    finally:
        gc.enable()
    return times


def time_call(function: Callable[[], Any], count: int = 3000) -> list[float]:
    """Return the µs of ``count`` single calls of ``function``."""
    clock = time.perf_counter_ns
    out = []
    gc.disable()
    try:
        for _ in range(count):
            start = clock()
            function()
            out.append((clock() - start) * 1e-3)
    finally:
        gc.enable()
    return out


def _rosbags_imu() -> Callable[[], Any] | None:
    try:
        from rosbags.typesys import get_typestore, Stores
    except ImportError:
        return None
    typestore = get_typestore(Stores.ROS2_JAZZY)
    raw = serialize_message(_imu(1.0))
    return lambda: typestore.deserialize_cdr(raw, 'sensor_msgs/msg/Imu')


def percentile(values: list[float], q: float) -> float:
    """Return the ``q`` quantile (0..1) of ``values`` (nearest rank)."""
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(q * len(ordered)))]


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark and print its numbers."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument('--seconds', type=float, default=10.0, help='simulated seconds')
    parser.add_argument('--repeat', type=int, default=3, help='rounds (the best p50 is kept)')
    parser.add_argument('--fix-delay', type=float, default=0.0,
                        help='each fix arrives this many seconds after its stamp')
    args = parser.parse_args(argv)
    events = stream(args.seconds, args.fix_delay)
    origin = tuple(math.degrees(c) for c in ORIGIN[:2]) + (ORIGIN[2],)
    base = NavigatorParams.from_flat({'origin': list(origin), 'publish_rate': 0.0})
    modes = (('(a) outputs on every update, publish_rate 0', base),
             ('(b) the default publish_rate 30', replace(base, publish_rate=30.0)))
    raw_imu = serialize_message(_imu(1.0))
    peers: dict[str, Callable[[], Any]] = {
        'Odometry()': Odometry,
        'rclpy deserialize Imu': lambda: deserialize_message(raw_imu, Imu),
    }
    rosbags_imu = _rosbags_imu()
    if rosbags_imu is not None:
        peers['rosbags deserialize Imu'] = rosbags_imu
    best: dict[tuple[str, str], tuple[float, float]] = {}
    total: dict[str, float] = {}
    best_peer: dict[str, float] = {}
    for _ in range(args.repeat):
        for label, params in modes:
            times = time_pipeline(params, events)
            spent = sum(sum(values) for values in times.values()) * 1e-6
            total[label] = min(total.get(label, math.inf), spent)
            for name, values in times.items():
                stats = (statistics.median(values), percentile(values, 0.99))
                key = (label, name)
                if key not in best or stats[0] < best[key][0]:
                    best[key] = stats
        for peer, function in peers.items():
            p50 = statistics.median(time_call(function))
            best_peer[peer] = min(best_peer.get(peer, math.inf), p50)
    counts = {name: sum(1 for n, _, _ in events if n == name)
              for name in ('imu', 'velocity', 'fix')}
    print(f'Pipeline.handle: {args.seconds:.0f} s of IMU 400 Hz + velocity 20 Hz + fix 10 Hz '
          f'({counts}), fixes {args.fix_delay:g} s late, best of {args.repeat} rounds')
    print('peers (p50 us): ' + ', '.join(f'{k} {v:.1f}' for k, v in best_peer.items()))
    header = ''.join(f'  /{peer:>24}' for peer in best_peer)
    for label, _ in modes:
        print(f'{label}: all calls after the first second {total[label]:.3f} s')
        print(f"  {'input':8} {'p50 us':>8} {'p99 us':>8}" + header)
        for name in ('imu', 'velocity', 'fix'):
            p50, p99 = best[(label, name)]
            ratios = ''.join(f'  {p50 / v:25.1f}' for v in best_peer.values())
            print(f'  {name:8} {p50:8.1f} {p99:8.1f}' + ratios)
    return 0


if __name__ == '__main__':
    sys.exit(main())
