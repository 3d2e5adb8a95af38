"""
Marine logs read directly: NMEA 0183 logs and NMEA 2000 captures as the navigator's inputs.

``open_log(path)`` returns a :class:`MarineLog`, which the replay reads as it reads a bag (the
surface of rosbags' AnyReader: ``connections``, ``messages()`` yielding ``(connection,
arrival ns, CDR bytes)``, ``deserialize``), with the topics and conventions of the project's
marine bags (:mod:`~vessel_kinematics.marine.messages`): ``/fix``, ``/imu``, ``/speed_log``
(through the water) and the receiver's ``/gnss/cog_sog`` (a reference). ``MarineLog.counts``
says what the log held and what was skipped, by reason.

Modules: ``records`` (what a log says, in SI units), ``nmea0183`` (sentences through pynmea2,
the log's clock), ``nmea2000`` (capture formats, fast packets, PGNs), ``assemble`` (which
source feeds each topic; the IMU of heading, attitude and rate), ``messages`` (the ROS
messages), ``log`` (the reader), ``writer`` (logs of a simulated voyage, for the tests).

Offline, with the tools (the replay reads through it; the node never does): it imports
``core``, ``ros.interface`` and ``tools.bags`` (the one place rosbags is used: its typestore
builds and reads the messages), never the replay.
"""

from vessel_kinematics.marine.log import (Counts, detect_format, is_marine_log, MarineLog,
                                          MarineLogError, NoPositionError, open_log)
from vessel_kinematics.marine.messages import INPUT_TOPICS, TOPICS, VELOCITY_REFERENCE

__all__ = ['Counts', 'detect_format', 'INPUT_TOPICS', 'is_marine_log', 'MarineLog',
           'MarineLogError', 'NoPositionError', 'open_log', 'TOPICS', 'VELOCITY_REFERENCE']
