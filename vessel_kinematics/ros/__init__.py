"""
The ROS edge: the only layer that knows rclpy and message types.

``interface`` (the table of topics and their QoS), ``params`` and ``param_types`` (the
parameters, declared once), ``params_file`` (the one reader of parameters files), ``inputs`` and
``imu_cdr`` (messages -> the estimator's records), ``static_tf`` and ``mountings`` (where the
sensors sit), ``outputs`` and ``cdr`` (the state -> each output's bytes), ``tf`` (the
transforms), ``diagnostics``, ``pipeline`` (messages -> estimator -> emissions, for both
drivers), ``navigator`` (the rclpy node) and ``node`` (its parts).
"""
