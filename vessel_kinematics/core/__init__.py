"""
The kinematics core: Fossen (2021), chapter 2, as pure functions (numpy and stdlib only).

``rotation`` (Euler angles, 2.2.1), ``quaternion`` (2.2.2-2.2.4), ``geodesy`` (WGS-84,
ECEF, NED, flat earth; 2.3), ``flow`` (course, sideslip, angle of attack, current; 2.4),
``frames`` (every convention between Fossen's frames and ROS's, written once) and
``dispatch`` (one scalar/array rule for all of them).
"""
