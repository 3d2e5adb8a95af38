"""
A client as nav2's GPS waypoint follower is one, for test_services.py: r_l's types, nothing else.

Run as ``python nav2_style_client.py LAT LON [LAT LON ...]``: waits for ``/fromLL``
(robot_localization/srv/FromLL, the absolute name nav2 calls), converts each waypoint as
nav2_waypoint_follower's ``convertGPSPosesToMapPoses`` does (altitude 0 unless given, the
map point taken as the goal's position in ``map``), and prints the map points as one JSON
line. It imports no part of vessel_kinematics. Exit 1 if the service does not appear in 15 s.
"""

import json
import sys

from geographic_msgs.msg import GeoPoint
import rclpy
from rclpy.node import Node
from robot_localization.srv import FromLL


def main() -> int:
    """Convert the waypoints of the command line through /fromLL; print them as JSON."""
    values = [float(v) for v in sys.argv[1:]]
    waypoints = list(zip(values[0::2], values[1::2]))
    rclpy.init()
    node = Node('vk_nav2_style_client')
    try:
        client = node.create_client(FromLL, '/fromLL')
        if not client.wait_for_service(timeout_sec=15.0):
            print('fromLL not available', file=sys.stderr)
            return 1
        out = []
        for lat, lon in waypoints:
            request = FromLL.Request()
            request.ll_point = GeoPoint(latitude=lat, longitude=lon, altitude=0.0)
            future = client.call_async(request)
            rclpy.spin_until_future_complete(node, future, timeout_sec=10.0)
            point = future.result().map_point
            out.append([point.x, point.y, point.z])
        print(json.dumps(out))
        return 0
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == '__main__':
    sys.exit(main())
