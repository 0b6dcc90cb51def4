"""While coasting, the wheeled-vehicle constraint closes the tilt loop on roll.

Without GNSS velocity the reference point's body velocity is held to (u, 0, 0)
(``ObserverEngine._coast_on_the_ground``): each IMU sample, what the inertial solution gained
across the vehicle and through the ground is taken out. That is the residual eq. (3) would
have seen had a receiver measured the constrained velocity: a roll error phi puts g phi across
the vehicle, and the constraint takes it out as it builds. Summed over a period and handed to
the tilt loop as its e, it holds roll as a GNSS velocity does. The EKF fuses the same
constraint as a measurement; open loop, the observer's roll drifted with its gyro x bias error
to 0.8 deg in a 40 s outage while the EKF's stayed within 0.2 (`outages` seed 1).

Pitch is not in it: a pitch error tilts the velocity along the vehicle, which the constraint
leaves to u (there is no odometer), so pitch still drifts open loop, and the stated sigma
says so. Nor is heading.
"""

from __future__ import annotations

from dataclasses import dataclass

from drivers.units import DEG_TO_RAD

#: The constraint's residual is handed to the tilt loop this often, s (a 10 Hz receiver's).
GROUND_PERIOD_S = 0.1
#: In a turn the forward speed's error du reads as roll, du w_z / g (the constraint turns the
#: velocity it keeps with the platform, the true one turns with the true speed): a period
#: whose mean yaw rate would make more than this of the forward speed's 1-sigma leaves the
#: loop open. An outage's U-turn closed on it sent pitch 2.5 deg off (`outages` seed 1).
GROUND_TILT_RAD = 0.05 * DEG_TO_RAD


@dataclass(frozen=True, slots=True)
class GroundPeriod:
    """One period of the constraint's residual."""

    e_ne_mps2: tuple[float, float]  # the constrained velocity's change less the inertial one's
    w_z_rps: float  # mean body z rate (the yaw rate on the ground)
    span_s: float  # the period's length


class GroundResidual:
    """The horizontal velocity the constraint took out, summed over a period (NED, m/s)."""

    def __init__(self, period_s: float = GROUND_PERIOD_S) -> None:
        self.period_s = period_s
        self._dv_n = 0.0
        self._dv_e = 0.0
        self._turn_rad = 0.0
        self._t_s = 0.0

    def restart(self) -> float:
        """A new period from now (a coast's start, an IMU gap); returns how long the one
        dropped had run, s."""
        t = self._t_s
        self._dv_n = self._dv_e = self._turn_rad = self._t_s = 0.0
        return t

    def add(
        self, dv_n_mps: float, dv_e_mps: float, w_z_rps: float, dt_s: float
    ) -> GroundPeriod | None:
        """One sample's velocity taken out over ``dt_s``, at body z rate ``w_z_rps``; the
        period once it is full, else None."""
        self._dv_n += dv_n_mps
        self._dv_e += dv_e_mps
        self._turn_rad += w_z_rps * dt_s
        self._t_s += dt_s
        t = self._t_s
        if t < self.period_s - 1e-9:
            return None
        period = GroundPeriod((-self._dv_n / t, -self._dv_e / t), self._turn_rad / t, t)
        self.restart()
        return period
