"""
The rclpy node's parts, each taking the node by composition (as tf2_ros's classes do).

``parameters`` (declared from the one table, validated, applied), ``services`` (r_l's
services, reset, enable), ``subscriptions`` (the inputs,
``/tf_static``, the guarded ``/clock``), ``publishers`` (the outputs, TF, diagnostics: CDR bytes
as they are), ``log`` (logging that cannot fail), ``qos`` (the interface table's profiles as
rclpy's). :mod:`vessel_kinematics.ros.navigator` puts them together.
"""
