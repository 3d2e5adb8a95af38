"""
Soak of the installed navigator over DDS: memory, dropped inputs and output steadiness.

Publishes 400 Hz IMU + 20 Hz velocity + 10 Hz fix in real time (a vessel at 3 m/s turning
slowly) for ``--seconds`` (default 1800) into the installed navigator at its default
parameters, with every output subscribed, and prints (asserting nothing):

* the navigator's resident memory every minute and its slope (least squares, kB/min);
* inputs published vs received by the node (its ``/diagnostics`` counts): dropped messages;
* the ``odometry`` arrival intervals: mean, standard deviation, p99 and the longest gap;
* the node's CPU time as a share of one core;
* non-finite numbers in any output message (every float field, covariances included);
* stalls: ``odometry`` gaps longer than ``--stall`` ms (default 500).

``--warmup`` (default 300 s) leaves the first samples out of the RSS slope. ``-p NAME:=VALUE``
sets a navigator parameter, e.g. ``-p velocity.reference:=water`` for the water reference.

Run: ``python bench/soak_navigator.py [--seconds N]`` with the package built (``make build``)
and its install sourced (VK_INSTALL or ``source install/setup.bash``).
"""

from __future__ import annotations

import argparse
import math
import os
from pathlib import Path
import sys
import tempfile
import time

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
sys.path.insert(0, str(REPO / 'test'))
sys.path.append(str(REPO))
os.environ.setdefault('ROS_DOMAIN_ID', str(10 + os.getpid() % 90))
os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
os.environ.setdefault('RMW_IMPLEMENTATION', 'rmw_fastrtps_cpp')

import dds_harness  # noqa: E402
from diagnostic_msgs.msg import DiagnosticArray  # noqa: E402
from geometry_msgs.msg import TwistWithCovarianceStamped  # noqa: E402
import numpy as np  # noqa: E402
from rclpy.qos import qos_profile_sensor_data  # noqa: E402
from sensor_msgs.msg import Imu, NavSatFix  # noqa: E402
from vessel_kinematics.ros import interface  # noqa: E402

ORIGIN = (63.4389, 10.3994, 40.0)
SPEED = 3.0
YAW_RATE = 0.01          # rad/s: a circle every ~10 minutes
EARTH = 6_378_137.0


def _rss_kb(pid: int) -> float:
    for line in Path(f'/proc/{pid}/status').read_text().splitlines():
        if line.startswith('VmRSS:'):
            return float(line.split()[1])
    return math.nan


def _cpu_s(pid: int) -> float:
    fields = Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')


def _non_finite(msg: object) -> int:
    """Return the number of non-finite floats anywhere in a ROS message."""
    bad = 0
    for name in msg.get_fields_and_field_types():  # type: ignore[attr-defined]
        value = getattr(msg, name)
        if isinstance(value, float):
            bad += not math.isfinite(value)
        elif hasattr(value, 'get_fields_and_field_types'):
            bad += _non_finite(value)
        elif isinstance(value, (list, tuple)) or hasattr(value, '__array__') \
                or type(value).__name__ == 'array':
            for item in value:
                if isinstance(item, float) or hasattr(item, 'dtype'):
                    bad += not math.isfinite(float(item))
                elif hasattr(item, 'get_fields_and_field_types'):
                    bad += _non_finite(item)
    return bad


def _counts(msg: DiagnosticArray) -> dict[str, int]:
    """Return ``received`` per input from the navigator's per-input statuses."""
    out = {}
    for status in msg.status:
        task = status.name.rsplit(': ', 1)[-1]
        values = {kv.key: kv.value for kv in status.values}
        if task in ('fix', 'imu', 'velocity') and 'received' in values:
            out[task] = int(values['received'])
    return out


def main() -> int:
    """Run the soak; print its numbers."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument('--seconds', type=float, default=1800.0)
    parser.add_argument('--warmup', type=float, default=300.0,
                        help='seconds left out of the RSS slope')
    parser.add_argument('--stall', type=float, default=500.0,
                        help='an odometry gap longer than this (ms) counts as a stall')
    parser.add_argument('-p', '--param', action='append', default=[], metavar='NAME:=VALUE',
                        help='a navigator parameter (e.g. publish_rate:=0.0)')
    args = parser.parse_args()
    params: dict[str, object] = {'origin': list(ORIGIN)}
    for item in args.param:
        name, _, value = item.partition(':=')
        params[name] = float(value) if value.replace('.', '', 1).isdigit() else value
    non_finite: dict[str, int] = {}
    install = Path(os.environ.get('VK_INSTALL', REPO / 'install'))
    env = dds_harness.sourced_env(install)
    executable = dds_harness.resolve_executable(env, 'navigator')
    log = Path(tempfile.mkdtemp(prefix='vk-soak-')) / 'navigator.log'
    node = dds_harness.NodeProcess(
        executable, dds_harness.ros_args(params), env, log)
    dds = dds_harness.DdsTester('vk_soak')
    try:
        # Count the outputs (keeping them would grow this process, not the node's).
        counts: dict[str, int] = {}
        arrivals: list[float] = []
        last_diagnostics: list[DiagnosticArray] = []

        def counter(topic: str):  # noqa: ANN202
            def callback(msg: object) -> None:
                counts[topic] = counts.get(topic, 0) + 1
                bad = _non_finite(msg)
                if bad:
                    non_finite[topic] = non_finite.get(topic, 0) + bad
                if topic == '/odometry':
                    arrivals.append(time.monotonic())
            return callback

        for t in interface.by_role(interface.Role.OUTPUT):
            if t.msg_type is not None and not t.latched:
                dds.node.create_subscription(interface.message_class(t.msg_type), t.absolute,
                                             counter(t.absolute), dds_harness.RELIABLE)
        dds.node.create_subscription(DiagnosticArray, '/diagnostics',
                                     lambda m: last_diagnostics[:1].clear()
                                     or last_diagnostics.append(m), dds_harness.RELIABLE)
        pubs = {'imu': dds.publisher('imu', Imu, qos_profile_sensor_data),
                'velocity': dds.publisher('velocity', TwistWithCovarianceStamped,
                                          qos_profile_sensor_data),
                'fix': dds.publisher('fix', NavSatFix, qos_profile_sensor_data)}
        dds.wait_for_node('navigator', node, timeout=20.0)
        dds.spin_for(2.0)
        published = dict.fromkeys(pubs, 0)
        periods = {'imu': 0.0025, 'velocity': 0.05, 'fix': 0.1}
        start = time.monotonic()
        due = dict.fromkeys(pubs, start)
        cpu0, rss = _cpu_s(node.pid), [(0.0, _rss_kb(node.pid))]
        next_rss = start + 60.0
        while (now := time.monotonic()) < start + args.seconds:
            for name, period in periods.items():
                if now >= due[name]:
                    t = time.time()
                    elapsed = now - start
                    psi = YAW_RATE * elapsed
                    if name == 'imu':
                        yaw = math.pi / 2 - psi          # ENU yaw of the NED heading psi
                        msg = dds_harness.make_imu(t, (0.0, 0.0, math.sin(yaw / 2),
                                                       math.cos(yaw / 2)), (0.0, 0.0, -YAW_RATE))
                    elif name == 'velocity':
                        msg = dds_harness.make_twist(t, (SPEED, 0.0, 0.0))
                    else:
                        radius = SPEED / YAW_RATE
                        north, east = radius * math.sin(psi), radius * (1.0 - math.cos(psi))
                        msg = dds_harness.make_fix(
                            t, ORIGIN[0] + math.degrees(north / EARTH),
                            ORIGIN[1] + math.degrees(east / (EARTH * math.cos(
                                math.radians(ORIGIN[0])))), ORIGIN[2])
                    pubs[name].publish(msg)
                    published[name] += 1
                    due[name] += period
            dds.executor.spin_once(timeout_sec=0.0)
            if now >= next_rss:
                rss.append((now - start, _rss_kb(node.pid)))
                next_rss += 60.0
        cpu = _cpu_s(node.pid) - cpu0
        dds.spin_for(3.0)
        received = _counts(last_diagnostics[-1]) if last_diagnostics else {}
    finally:
        node.stop()
        dds.close()
    t_min = np.array([t for t, _ in rss]) / 60.0
    kb = np.array([v for _, v in rss])
    slope = float(np.polyfit(t_min, kb, 1)[0]) if len(rss) > 2 else math.nan
    warm = t_min >= args.warmup / 60.0
    warm_slope = float(np.polyfit(t_min[warm], kb[warm], 1)[0]) if warm.sum() > 2 else math.nan
    gaps = np.diff(np.array(arrivals)) * 1e3
    print(f'soak {args.seconds:.0f} s: 400 Hz IMU + 20 Hz velocity + 10 Hz fix, every output '
          f'subscribed, parameters {params}')
    print(f'  RSS       {kb[0] / 1024:.1f} MiB at start, {kb[-1] / 1024:.1f} MiB at the end, '
          f'slope {slope:+.1f} kB/min over {len(rss)} samples; after {args.warmup:.0f} s warm-up '
          f'{warm_slope:+.2f} kB/min ({kb[warm][0] / 1024 if warm.any() else math.nan:.1f} MiB '
          f'at its start)')
    for name in pubs:
        got = received.get(name)
        lost = published[name] - got if got is not None else None
        print(f'  {name:9s} published {published[name]}, received {got}, dropped {lost}'
              + (f' ({100.0 * lost / published[name]:.4f} %)' if lost is not None else ''))
    if gaps.size:
        print(f'  odometry  {len(arrivals)} messages, {len(arrivals) / args.seconds:.2f} Hz; '
              f'interval mean {gaps.mean():.2f} ms, std {gaps.std():.2f} ms, '
              f'p99 {np.percentile(gaps, 99):.2f} ms, max {gaps.max():.1f} ms')
    stalls = int((gaps > args.stall).sum()) if gaps.size else 0
    print(f'  stalls    {stalls} odometry gaps over {args.stall:.0f} ms')
    print(f'  non-finite values {sum(non_finite.values())} '
          + (str(non_finite) if non_finite else '(none in any output)'))
    print('  outputs   ' + ', '.join(f'{t} {n}' for t, n in sorted(counts.items())))
    print(f'  CPU       {cpu:.1f} s = {100.0 * cpu / args.seconds:.1f} % of one core')
    return 0


if __name__ == '__main__':
    sys.exit(main())
