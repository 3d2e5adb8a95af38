"""
The ROS edge: the only layer that knows rclpy and message types.

``interface`` (the table of topics), ``params`` (the parameter table and its validation),
``ros_io`` (messages <-> the estimator's records), ``static_tf`` (sensor mountings),
``pipeline`` (messages -> estimator -> messages), ``session`` (when to emit what) and
``navigator`` (the rclpy node).
"""
