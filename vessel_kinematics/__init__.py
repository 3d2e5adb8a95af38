"""
vessel_kinematics: Fossen's kinematics of marine craft for ROS 2.

The core modules (``rotation``, ``quaternion``, ``geodesy``, ``flow``, ``frames``,
``estimator``) import numpy only. ROS message types are touched in ``ros_io`` alone;
``navigator`` (rclpy node) and ``replay`` (rosbag driver) both run ``pipeline``.
"""

__version__ = '0.1.0'
