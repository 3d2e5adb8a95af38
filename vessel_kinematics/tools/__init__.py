"""
Offline tools, above the ROS edge.

``bags`` (bag I/O, once), ``replay`` (recorded bags through the navigator's pipeline),
``evaluate`` (runs as numpy data and their scores), ``plot`` (the figure), ``sim`` (a simulated
voyage with truth: ``sim_model`` the vessel, ``sim_sensors`` its sensors, ``sim_bag`` the
messages) and ``demo`` (``make demo``).
"""
