"""
A peer process for test_interfaces.py: serves and publishes the interface packages' types.

Run as ``python interfaces_peer.py``; the node ``/vk_interfaces_peer`` serves, as its own (``~/``),

* ``datum`` (robot_localization/srv/SetDatum): keeps the request's GeoPose as its datum;
* ``fromLL`` (FromLL): the GeoPoint minus the datum's, as (longitude, latitude, altitude) in
  ``map_point`` (x, y, z): a plain difference, enough to show every field crossed intact;
* ``toLL`` (ToLL): the inverse of ``fromLL``;
* ``toggle`` (ToggleFilterProcessing): answers ``status`` = the requested ``on``;
* ``tf2_frames`` (tf2_msgs/srv/FrameGraph): a fixed YAML text;

and publishes, every 0.1 s, a tf2_msgs/TFMessage on ``interfaces_tf`` and the datum as a
geographic_msgs/GeoPoseStamped on ``interfaces_datum``. SIGINT or SIGTERM (rclpy's handlers)
ends it with code 0.
"""

import sys

from geographic_msgs.msg import GeoPose, GeoPoseStamped
from geometry_msgs.msg import TransformStamped
import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from robot_localization.srv import FromLL, SetDatum, ToggleFilterProcessing, ToLL
from tf2_msgs.msg import TFMessage
from tf2_msgs.srv import FrameGraph

FRAME_YAML = 'map: {parent: earth}\n'


class InterfacesPeer(Node):
    """The services and publishers described in the module docstring."""

    def __init__(self) -> None:
        super().__init__('vk_interfaces_peer')
        self.datum = GeoPose()
        self.create_service(SetDatum, '~/datum', self.set_datum)
        self.create_service(FromLL, '~/fromLL', self.from_ll)
        self.create_service(ToLL, '~/toLL', self.to_ll)
        self.create_service(ToggleFilterProcessing, '~/toggle', self.toggle)
        self.create_service(FrameGraph, '~/tf2_frames', self.frame_graph)
        self.tf = self.create_publisher(TFMessage, 'interfaces_tf', 10)
        self.datum_out = self.create_publisher(GeoPoseStamped, 'interfaces_datum', 10)
        self.create_timer(0.1, self.publish)

    def set_datum(self, request: SetDatum.Request,
                  response: SetDatum.Response) -> SetDatum.Response:
        """Keep the requested datum."""
        self.datum = request.geo_pose
        return response

    def from_ll(self, request: FromLL.Request, response: FromLL.Response) -> FromLL.Response:
        """Return the point minus the datum, (longitude, latitude, altitude) as (x, y, z)."""
        origin = self.datum.position
        response.map_point.x = request.ll_point.longitude - origin.longitude
        response.map_point.y = request.ll_point.latitude - origin.latitude
        response.map_point.z = request.ll_point.altitude - origin.altitude
        return response

    def to_ll(self, request: ToLL.Request, response: ToLL.Response) -> ToLL.Response:
        """Return the inverse of :meth:`from_ll`."""
        origin = self.datum.position
        response.ll_point.longitude = request.map_point.x + origin.longitude
        response.ll_point.latitude = request.map_point.y + origin.latitude
        response.ll_point.altitude = request.map_point.z + origin.altitude
        return response

    def toggle(self, request: ToggleFilterProcessing.Request,
               response: ToggleFilterProcessing.Response) -> ToggleFilterProcessing.Response:
        """Answer the requested state."""
        response.status = request.on
        return response

    def frame_graph(self, request: FrameGraph.Request,
                    response: FrameGraph.Response) -> FrameGraph.Response:
        """Answer a fixed frame graph."""
        response.frame_yaml = FRAME_YAML
        return response

    def publish(self) -> None:
        """Publish one TFMessage and the datum."""
        transform = TransformStamped()
        transform.header.stamp = self.get_clock().now().to_msg()
        transform.header.frame_id = 'earth'
        transform.child_frame_id = 'map'
        transform.transform.rotation.w = 1.0
        self.tf.publish(TFMessage(transforms=[transform]))
        self.datum_out.publish(GeoPoseStamped(header=transform.header, pose=self.datum))


def main() -> int:
    """Serve until SIGINT or SIGTERM."""
    rclpy.init()
    node = InterfacesPeer()
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main())
