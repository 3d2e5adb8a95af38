"""
Offline tools, above the ROS edge.

``replay`` (recorded bags through the navigator's session), ``report`` (scores from data and
the figure), ``sim`` (a simulated voyage with truth) and ``demo`` (``make demo``).
"""
