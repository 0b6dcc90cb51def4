"""The IMU's temperature rate, and the bias walk it drives.

A MEMS unit's biases follow its temperature (ADIS1633x-class datasheet: 0.01 deg/s and
0.1 mg per degC, 1-sigma over units), and a unit starting cold warms by tens of degC in its
first minutes (a cab in the morning, the engine bay): its biases then move 0.4 deg/s and
4 mg where the in-run wander the engines model (the Allan floor over 100 s) moves them
0.01 deg/s and 0.1 mg. The coefficient of a given unit is unknown, so the bias moves at an
unknown rate k dT/dt whose spread is the datasheet's, tempco |dT/dt|; over the in-run
correlation time T that is a walk of PSD (tempco dT/dt)^2 T, which the engines add to the
in-run wander's while the temperature moves (:class:`TemperatureWalk`). With the
paper's fixed eq. (11) time constant the observer's x/y gyro bias lagged such a warm-up
by r tau_g, and its tilt by r tau tau_g (a PI loop's error on a ramp r): `steep-turns`
seed 700 warming 5 -> 45 degC, roll/pitch RMS 0.107/0.124 deg against 0.057/0.063 at a
steady temperature.

The rate is the Theil-Sen slope (the median of the pairwise slopes) of the IMU_AUX
temperatures (1 Hz) of the last :data:`WINDOW_S`: TEMP_OUT's 0.068 degC steps and a
garbled reading (an SPI bit error, no checksum) move a median of 435 slopes little, where
one reading 100 degC off would have made a least-squares rate of 0.6 degC/s.
"""

from __future__ import annotations

import math
from collections import deque
from statistics import median

from drivers.units import DEG_TO_RAD, MG_MPS2

#: The temperature rate is taken over this much of the last readings, s.
WINDOW_S = 30.0
#: ... from at least this many readings (fewer: no rate, 0).
MIN_READINGS = 5
#: The IMU's temperature range (operating -40 to 85 degC), with a margin, degC.
TEMP_RANGE_C = (-60.0, 150.0)


def plausible(temp_c: float) -> bool:
    """A temperature the IMU can have (TEMP_OUT garbage is not one)."""
    return math.isfinite(temp_c) and TEMP_RANGE_C[0] <= temp_c <= TEMP_RANGE_C[1]


class TemperatureRate:
    """The rate of the IMU's temperature, degC/s, from its readings in time order."""

    def __init__(self, window_s: float = WINDOW_S) -> None:
        self.window_s = window_s
        self._readings: deque[tuple[float, float]] = deque()  # (t s, degC)
        self.rate_c_per_s = 0.0

    def add(self, t_s: float, temp_c: float) -> None:
        """One reading at ``t_s``; :attr:`rate_c_per_s` is then over the window up to it."""
        if not (math.isfinite(t_s) and plausible(temp_c)):
            return
        readings = self._readings
        if readings and t_s <= readings[-1][0]:  # time went back: the engine's clock restarted
            readings.clear()
        readings.append((t_s, temp_c))
        while t_s - readings[0][0] > self.window_s:
            readings.popleft()
        if len(readings) < MIN_READINGS:
            self.rate_c_per_s = 0.0
            return
        points = list(readings)
        self.rate_c_per_s = median(
            (c1 - c0) / (t1 - t0) for i, (t0, c0) in enumerate(points) for t1, c1 in points[i + 1 :]
        )


class TemperatureWalk:
    """The bias walks the IMU's temperature drives, from its readings in time order: PSD
    (tempco dT/dt)^2 T for the gyro's ((rad/s)^2 / s) and the accelerometer's ((m/s^2)^2 /
    s) biases, with the datasheet's coefficients (1-sigma over units) and the in-run
    correlation time T (module docstring)."""

    def __init__(
        self,
        gyro_tempco_dps_per_c: float,
        accel_tempco_mg_per_c: float,
        correlation_s: float,
        window_s: float = WINDOW_S,
    ) -> None:
        self.rate = TemperatureRate(window_s)
        self._scale_g = (gyro_tempco_dps_per_c * DEG_TO_RAD) ** 2 * correlation_s
        self._scale_a = (accel_tempco_mg_per_c * MG_MPS2) ** 2 * correlation_s
        self.gyro_rps2_per_s = 0.0
        self.accel_mps4_per_s = 0.0

    def add(self, t_s: float, temp_c: float) -> None:
        """One reading at ``t_s``: the walks are then those of the rate up to it."""
        self.rate.add(t_s, temp_c)
        rate2 = self.rate.rate_c_per_s**2
        self.gyro_rps2_per_s = self._scale_g * rate2
        self.accel_mps4_per_s = self._scale_a * rate2
