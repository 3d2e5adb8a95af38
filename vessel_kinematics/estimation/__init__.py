"""
The navigation state and its updates: no ROS, no YAML, no message types.

Small measurement records in (:class:`GnssFix`, :class:`ImuSample`, :class:`BodyVelocity`,
:class:`GroundVelocity`), a :class:`NavState` and the :class:`Health` of each part out,
configured by a :class:`FilterConfig`. See :mod:`.estimator` for the
time policy, :mod:`.model` for the kinematics, :mod:`.layout` for the named states.
"""

from vessel_kinematics.estimation.config import FilterConfig, Motion
from vessel_kinematics.estimation.estimator import Estimator
from vessel_kinematics.estimation.records import (BodyVelocity, Calibration, DEAD_RECKONING,
                                                  Estimate, Event, FUSED, GnssFix,
                                                  GroundVelocity, Health, ImuSample, Level,
                                                  Mode, NavPose, NavState, Reason, Rejection,
                                                  RelativeFlow, WAITING)

__all__ = ['BodyVelocity', 'Calibration', 'DEAD_RECKONING', 'Estimate', 'Estimator', 'Event',
           'FUSED', 'FilterConfig', 'GnssFix', 'GroundVelocity', 'Health', 'ImuSample', 'Level',
           'Mode', 'Motion', 'NavPose', 'NavState', 'Reason', 'Rejection', 'RelativeFlow',
           'WAITING']
