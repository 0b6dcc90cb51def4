"""The chassis's own pitch against its track: what a wheeled vehicle's constraint allows.

A wheeled vehicle moves along its body x axis, so its track's climb angle is its pitch
(both engines use it: the observer's accel-bias filter, the EKF's non-holonomic
constraint), less the pitch the chassis takes on its tyres against the ground it drives: a
lifted rear implement pitches a tractor some 0.5 deg nose-up, ballast and draught change
it, an implement lowered at the headland moves it within seconds. Both engines estimate it
as a random walk with these figures; without it, 0.5 deg of it went into the EKF's x
accelerometer bias and its pitch went out 0.2-0.33 deg off with 0.065 stated. An implement
lifted or lowered steps it (1 deg in 2 s), which no random walk of these figures allows:
the observer stops reading the track's climb once its x bias is learnt
(:mod:`gateway.estimation.observer.accel_bias_filter`); the EKF, its constraint weighed at
0.05 m/s each epoch, stayed within 0.12 deg of pitch and 0.005 m/s^2 of x bias through
sixteen headlands of such steps.
"""

from __future__ import annotations

from drivers.units import DEG_TO_RAD

#: 1-sigma of the chassis's pitch against its track when an engine starts, rad ...
CHASSIS_PITCH_SIGMA_RAD = 0.25 * DEG_TO_RAD
#: ... and the time in which it wanders by that much, s (random walk).
CHASSIS_PITCH_WANDER_S = 120.0
