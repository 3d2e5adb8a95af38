"""
A peer of the navigator on the other "host" (network namespace) of test_two_hosts.py.

``python two_hosts_peer.py MODE SECONDS`` prints one JSON line when done:

* ``feed``: publishes 100 Hz IMU, 10 Hz velocity and 2 Hz fixes best-effort (sensor data QoS)
  for SECONDS and counts the ``/odometry`` it gets back, and the node's accepted IMU count
  from ``/diagnostics``;
* ``watch``: subscribes (as a late joiner would) to the latched ``/origin`` and
  ``/tf_static`` and to ``/odometry``, and reports the monotonic times of each arrival;
* ``sink``: a reliable ``/odometry`` subscriber (the test stops it with SIGSTOP: a dead
  consumer whose queue fills).
"""

from __future__ import annotations

import json
import math
import sys
import time

from dds_harness import LATCHED, make_fix, make_imu, make_twist
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import TwistWithCovarianceStamped
from nav_msgs.msg import Odometry
import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import (DurabilityPolicy, HistoryPolicy, qos_profile_sensor_data, QoSProfile,
                       ReliabilityPolicy)
from sensor_msgs.msg import Imu, NavSatFix
from tf2_msgs.msg import TFMessage

ORIGIN = (63.4389, 10.3994, 40.0)
TF_STATIC = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=100,
                       reliability=ReliabilityPolicy.RELIABLE,
                       durability=DurabilityPolicy.TRANSIENT_LOCAL)
RELIABLE = QoSProfile(depth=10)


def main() -> int:
    """Run one mode; print its JSON line."""
    mode, seconds = sys.argv[1], float(sys.argv[2])
    rclpy.init()
    node = rclpy.create_node(f'vk_peer_{mode}')
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    out: dict[str, object] = {'mode': mode}
    arrivals: dict[str, list[float]] = {'/origin': [], '/tf_static': [], '/odometry': []}

    def arrived(topic: str):  # noqa: ANN202
        return lambda _msg: arrivals[topic].append(time.monotonic())

    accepted = [0]

    def diagnostics(msg: DiagnosticArray) -> None:
        for status in msg.status:
            for kv in status.values:
                if kv.key == 'accepted imu':
                    accepted[0] = int(kv.value)

    if mode in ('watch', 'feed'):
        node.create_subscription(NavSatFix, '/origin', arrived('/origin'), LATCHED)
        node.create_subscription(TFMessage, '/tf_static', arrived('/tf_static'), TF_STATIC)
        node.create_subscription(Odometry, '/odometry', arrived('/odometry'), RELIABLE)
        node.create_subscription(DiagnosticArray, '/diagnostics', diagnostics, RELIABLE)
    if mode == 'sink':
        node.create_subscription(Odometry, '/odometry', arrived('/odometry'), RELIABLE)
    published = 0
    start = time.monotonic()
    if mode == 'feed':
        pubs = {name: node.create_publisher(cls, name, qos_profile_sensor_data)
                for name, cls in (('imu', Imu), ('velocity', TwistWithCovarianceStamped),
                                  ('fix', NavSatFix))}
        periods = {'imu': 0.01, 'velocity': 0.1, 'fix': 0.5}
        due = dict.fromkeys(pubs, start + 3.0)        # discovery first
        while (now := time.monotonic()) < start + seconds:
            for name, period in periods.items():
                if now >= due[name]:
                    t = time.time()
                    if name == 'imu':
                        msg = make_imu(t, (0.0, 0.0, math.sin(math.pi / 4), math.cos(math.pi / 4)))
                        published += 1
                    elif name == 'velocity':
                        msg = make_twist(t, (2.0, 0.0, 0.0))
                    else:
                        msg = make_fix(t, *ORIGIN)
                    pubs[name].publish(msg)
                    due[name] += period
            executor.spin_once(timeout_sec=0.001)
    else:
        while time.monotonic() < start + seconds:
            executor.spin_once(timeout_sec=0.05)
    out.update({'start': start, 'published_imu': published, 'accepted_imu': accepted[0],
                **arrivals})
    print(json.dumps(out), flush=True)
    node.destroy_node()
    rclpy.try_shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main())
