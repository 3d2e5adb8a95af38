"""
vessel_kinematics: Fossen's kinematics of marine craft for ROS 2.

Four layers, each importing only those below it (``test/test_layers.py`` keeps it so):

* ``core`` -- Fossen ch. 2 as pure functions, numpy and the standard library only:
  ``rotation``, ``quaternion``, ``geodesy``, ``flow``, ``frames`` (the conventions: NED/ENU,
  FRD/FLU, scalar-first/xyzw, stamps, covariance maps), ``dispatch`` (scalar or array);
* ``estimation`` -- the navigation state and its updates, no ROS: records, configuration,
  named state layout, attitude, process and measurement models, Kalman update, the estimator
  facade; ``magnetic`` (the World Magnetic Model's declination);
* ``ros`` -- the only layer that knows rclpy and message types: ``interface`` (the one table
  of topics and QoS), ``params`` (the one table of parameters), ``params_file`` (the one
  reader of parameters files), ``inputs`` (messages -> records), ``mountings``, ``outputs``
  and ``cdr`` (the state -> the bytes of each output), ``tf``, ``diagnostics``, ``pipeline``
  (the one pipeline and output policy), ``navigator`` and ``node`` (the rclpy node);
* ``tools`` -- offline: ``bags`` (bag I/O), ``replay`` (the bag driver), ``evaluate`` (runs
  and their scores, numbers only), ``plot`` (the figure), ``sim`` (the simulated voyage),
  ``demo``. docs/architecture.md has the map.
"""

__version__ = '0.1.0'
