"""
The navigator's estimator: the time policy and the measurement updates, as one facade.

The pieces live beside it: :mod:`.config` (what kind of craft, the model constants),
:mod:`.layout` (the named state), :mod:`.attitude` (q_nb from the IMU), :mod:`.model` (the
kinematics and measurement models), :mod:`.kalman` (the update), :mod:`.surface` (the sea
surface and the map frame far from the origin), :mod:`.faults` (instrument faults) and
:mod:`.health` (what /diagnostics shows). :class:`Estimator` is put together from one module
per part: :mod:`.filter_state` (the state, its reset, the origin and projection, the queries),
:mod:`.propagation` (the time update), :mod:`.updates` (what the measurement updates share),
:mod:`.fix_update`, :mod:`.imu_update` and :mod:`.velocity_update` (each measurement),
:mod:`.navstate` (the state for the outputs) and :mod:`.reconfigure` (a new configuration at
run time). This module states the policy they implement.

Time
----
Stamps are the messages' header stamps (ns). Measurements reach the updates in stamp order:
:class:`~.timeline.Timeline` keeps the last ``history_length`` s and re-applies them when one
arrives late, so each update sees a stamp at or after the state's. A message newer than the
state propagates it to the message's stamp; no integration across a gap longer than
``max_gap`` (time advances and the covariance is widened by what the vessel could have
moved). One older than the state is refused as ``too_late`` and never integrated backwards;
a real time jump (the clock going back, a looped bag) is the driver's to see, and it
re-initialises the state with :meth:`reset`, keeping the origin.

Observability
-------------
No state moves without a measurement that observes it. The velocity is held in physical units
and a log reads z = k·u: only a log reading tells the scale k, and only while the fixes (or a
receiver's velocity) tell the speed over ground too; in dead reckoning k takes no gain. With no
log reading for ``velocity_timeout`` s the log is missing: the scale, the leeway, the turning
drift and the current are held (no gain, no decay: their variance grows by their process
noise only); the fixes tell the velocity over ground, and nothing tells how it splits into
the current and the speed through the water. They are held so too while a log just started
settles (its damping ramping the reading up: :data:`~.config.LOG_SETTLE_TIME`). A log coming
back is gated against the speed the fixes kept; refused again and again while the fixes agree
among themselves, its scale is relearnt (its variance set back to the prior), never the speed.

Manoeuvres and recovery
-----------------------
The acceleration is a state and its level σ_a follows the craft (:class:`~.model.
AccelerationLevel`). A fix, a log reading or a receiver's velocity beyond the gate
(Mahalanobis distance ``gate_sigma``) is tested once more as a manoeuvre: an acceleration of up
to :data:`~.config.ACCEL_MAX` begun since the last measurement that agreed
(:func:`~.model.manoeuvre_covariance`); if that explains it, it is taken with that covariance
and the level raised. A real jump (a relocated vessel, a moved antenna) is not locked out:
after :data:`~.config.GATE_RESET_COUNT` consecutive refused fixes, or
:data:`~.config.GATE_RESET_TIME` s of them, the position is re-initialised from the fix (a
recovery: counted in :attr:`Estimator.recoveries`, its reason in :meth:`Estimator.pop_events`),
so the reported σ covers the real error again. A speed log heard meanwhile, its scale is
relearnt too (σ back to the prior): the dead reckoning from the log is what the fixes refused.

Heading offset
--------------
With ``estimate_heading_offset`` a constant offset δψ of the IMU heading is a state. Any
angle is possible (a mounting yaw off by 90°), which a linearised filter cannot find from
zero: it is held (no gain, no coupling, the heading treated as unknown in the position's
process noise) until the vessel has moved at least
:data:`~.filter_state.OFFSET_INIT_DISTANCE` m along a steady heading, then initialised from
the course over ground of those fixes minus the mean IMU heading (π more going astern), with
σ :data:`~.filter_state.OFFSET_INIT_SIGMA`, and refined by the fixes from then on.
"""

from __future__ import annotations

from vessel_kinematics.estimation.filter_state import (OFFSET_INIT_DISTANCE, OFFSET_INIT_SIGMA,
                                                       OFFSET_INIT_WINDOW)
from vessel_kinematics.estimation.fix_update import FixUpdate
from vessel_kinematics.estimation.imu_update import ImuUpdate
from vessel_kinematics.estimation.navstate import NavStateOutput
from vessel_kinematics.estimation.reconfigure import Reconfigure
from vessel_kinematics.estimation.updates import MANOEUVRE_GATE
from vessel_kinematics.estimation.velocity_update import VelocityUpdate

__all__ = ['Estimator', 'MANOEUVRE_GATE', 'OFFSET_INIT_DISTANCE', 'OFFSET_INIT_SIGMA',
           'OFFSET_INIT_WINDOW']


class Estimator(FixUpdate, ImuUpdate, VelocityUpdate, NavStateOutput, Reconfigure):
    """The navigator's state and its time and measurement updates (see the module notes)."""
