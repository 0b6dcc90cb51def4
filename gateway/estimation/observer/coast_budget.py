"""How far the observer's dead-reckoned reference point may be off, t seconds into an outage.

The observer keeps no position covariance through an outage (the position channel stops
with the fixes), so its 1-sigma comes from an error budget taken when GNSS velocity stops.
Under the wheeled-vehicle constraints (``ObserverEngine._coast_on_the_ground``) only the
forward speed is inertial, so:

- along the track, the forward speed error grows from the last velocity's error with the
  forward acceleration error (x accelerometer bias and g times the tilt error) and with the
  tilt the gyro adds open loop: its x/y bias (g b_g t) and its angular random walk (a
  random walk of tilt, twice integrated: g ARW t^2.5 / sqrt(20), as large as the bias's
  term at 20 s with the ADIS16334's figures): position error
  p0 + v0 t + a t^2 / 2 + g b_g t^3 / 6 + g ARW t^2.5 / sqrt(20);
- across the track, the heading error (and the z gyro bias's growth of it) turns the
  distance driven sideways: s t (psi0 + b_z t / 2).

Each term is a 1-sigma taken from the engine's own estimates and added linearly along the
track (they share the outage's start, not independent draws), then combined with the
cross-track part as two perpendicular axes. On the 40 s and 60 s outages of the ``outages``
scenario (seed 5) the true error stayed within this sigma to 16 s and within 2 sigma after;
the seconds at which the engine reports DEGRADED and withholds the position follow from it
(``coast_sigma_m``, ``max_coast_sigma_m``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from drivers.units import GRAVITY_MPS2


@dataclass(frozen=True, slots=True)
class CoastBudget:
    """1-sigma error sources at the start of an outage (SI)."""

    sigma_p0_m: float  # horizontal position (both axes together)
    sigma_v0_mps: float  # forward speed
    sigma_a_mps2: float  # forward acceleration: x accelerometer bias and g x tilt error
    sigma_bg_rps: float  # x/y gyro bias: the tilt it adds open loop accelerates the platform
    arw_rad_per_sqrt_s: float  # gyro angular random walk: so does the tilt it walks
    sigma_psi_rad: float  # heading
    sigma_bz_rps: float  # z gyro bias: the heading error it adds

    def sigma_u_mps(self, t_s: float) -> float:
        """Forward speed 1-sigma ``t_s`` into the outage: the along-track terms' rate."""
        t = max(t_s, 0.0)
        return (
            self.sigma_v0_mps
            + self.sigma_a_mps2 * t
            + 0.5 * GRAVITY_MPS2 * self.sigma_bg_rps * t * t
            + 2.5 * GRAVITY_MPS2 * self.arw_rad_per_sqrt_s * t * math.sqrt(t / 20.0)
        )

    def sigma_h_m(self, t_s: float, speed_mps: float) -> float:
        """Horizontal 1-sigma ``t_s`` into the outage, driving at ``speed_mps``."""
        t = max(t_s, 0.0)
        along = (
            self.sigma_v0_mps * t
            + 0.5 * self.sigma_a_mps2 * t * t
            + GRAVITY_MPS2 * self.sigma_bg_rps * t * t * t / 6.0
            + GRAVITY_MPS2 * self.arw_rad_per_sqrt_s * t * t * math.sqrt(t / 20.0)
        )
        cross = abs(speed_mps) * t * (self.sigma_psi_rad + 0.5 * self.sigma_bz_rps * t)
        return math.sqrt(self.sigma_p0_m**2 + along * along + cross * cross)
