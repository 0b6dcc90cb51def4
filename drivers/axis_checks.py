"""Each IMU sample's six axis values against the last ones taken: stuck axes and spikes.

**Stuck.** A working ADIS16334 never repeats an axis for long: its noise alone moves every
output word from sample to sample (at 204.8 Hz the gyro's 2 deg/sqrt(h) is 0.48 deg/s, about
10 LSB, per sample, the accelerometer's 0.12 m/s/sqrt(h) about 3 mg, 3 LSB; engine vibration
adds more), so the chance that one axis repeats its word is about 0.1 per sample, and that it
does so 24 samples running, 1e-24. A sensor that stopped converting, a bridge re-sending its
last SPI read (SEQ counting, ND set), or a data line stuck high or low all give such runs,
and the engines would integrate them as a vehicle that stopped rotating, or fell: roll went
out 4 deg off while STATUS said navigating (a 10 s freeze on the field run). At the lowest
rate (DEC 6, 12.8 Hz, the accelerometer's noise 0.73 LSB) a noisy axis repeats with a chance
of 0.36 a sample, and 24 running once in some 3 x 10^5 hours of running. A source with no
noise (a bench stimulus, a simulator without an error model) repeats its words whenever the
vehicle stands still: ``ImuCanConfig.stuck_samples`` = 0 turns the check off for it.

**Spikes.** SPI has no checksum: a bit flipped on the way from the sensor to the bridge is
a value sent with a good CAN CRC. One gyro sample 102.4 deg/s off (bit 11) put roll 0.5 deg
out for seconds with 0.09 stated (field seed 7: 41 observer and 58 EKF frames beyond 0.1 deg
+ 3 sigma), one accelerometer sample 2 g off 9 EKF frames, 4 g 57 observer and 22 EKF
frames; 51.2 deg/s and 1 g did not. A vehicle does not change its rate by
:data:`GYRO_JUMP_RPS` or its specific force by :data:`ACCEL_JUMP_MPS2` within one sample (the
distance of a triad's three axes from the last values taken): a chassis turns at tens of
deg/s at most, and the sensor's noise and engine vibration move a sample by little (the
simulator's, 0.2 deg/s and 0.6 m/s^2 at 28 Hz plus broadband: 3.6 deg/s and 0.16 g at most
from one sample to the next over the 16 min field run); an IMU bolted to a chassis that
shakes it by 1.5 g from one sample to the next (some 4 m/s^2 RMS of broadband vibration) is
beyond the noise either engine models anyway. So a triad that far from the last values
taken is taken for a transfer error, and the last values stand in for it, once: if the next
sample is as far, the change is real (a shock) and taken from there, having cost one sample
of it. What passes (a gyro bit flip of 25.6 deg/s or less, an accelerometer one of 1 g)
costs at most 0.13 deg or 0.05 m/s, which the engines take out within their stated accuracy.
"""

from __future__ import annotations

import math
from math import dist

from drivers.samples import Float3
from drivers.units import GRAVITY_MPS2

#: Samples in a row with one axis's value unchanged that make it stuck (module docstring).
STUCK_SAMPLES = 24
#: One sample's change of a triad (its distance) beyond which it is a transfer error.
GYRO_JUMP_RPS = math.radians(40.0)
ACCEL_JUMP_MPS2 = 1.5 * GRAVITY_MPS2

_NO_RUNS = (0, 0, 0, 0, 0, 0)
_AXES = ("gyro x", "gyro y", "gyro z", "accel x", "accel y", "accel z")


class AxisChecks:
    """Runs of unchanged values and one-sample jumps over the six outputs (gyro x, y, z,
    accel x, y, z), in SI: :meth:`check` takes a sample's values, and :attr:`w` / :attr:`f`
    are then the values to use: the same tuples, or the last ones taken when a triad jumped."""

    __slots__ = ("_held_f", "_held_w", "check", "f", "runs", "stuck_after", "w")

    def __init__(self, stuck_after: int = STUCK_SAMPLES) -> None:
        self.stuck_after = stuck_after  # a run this long is stuck (0: never)
        self.runs = _NO_RUNS  # samples since each axis last changed
        self.w: Float3 = (0.0, 0.0, 0.0)  # the values taken, rad/s and m/s^2
        self.f: Float3 = (0.0, 0.0, 0.0)
        self._held_w = self._held_f = False  # the last sample's triad was held
        self.check = self._first

    def _first(self, w: Float3, f: Float3) -> bool:
        """The first sample: nothing to compare it with."""
        self.w, self.f = w, f
        self.check = self._next
        return False

    def _next(self, w: Float3, f: Float3) -> bool:
        """Take one sample's rates and specific forces; True while some axis is stuck. (Per
        sample: two C-level distances, and six comparisons when none of them is equal.)"""
        lw, lf = self.w, self.f
        if dist(w, lw) <= GYRO_JUMP_RPS or self._held_w:
            self.w, self._held_w = w, False
        else:
            self._held_w = True
        if dist(f, lf) <= ACCEL_JUMP_MPS2 or self._held_f:
            self.f, self._held_f = f, False
        else:
            self._held_f = True
        if (
            w[0] != lw[0] and w[1] != lw[1] and w[2] != lw[2]
            and f[0] != lf[0] and f[1] != lf[1] and f[2] != lf[2]
        ):  # fmt: skip
            self.runs = _NO_RUNS
            return False
        a, b, c, d, e, h = self.runs
        runs = self.runs = (
            a + 1 if w[0] == lw[0] else 0,
            b + 1 if w[1] == lw[1] else 0,
            c + 1 if w[2] == lw[2] else 0,
            d + 1 if f[0] == lf[0] else 0,
            e + 1 if f[1] == lf[1] else 0,
            h + 1 if f[2] == lf[2] else 0,
        )
        return 0 < self.stuck_after <= max(runs)

    def stuck_axes(self) -> list[str]:
        """The names of the axes stuck now (for a log line)."""
        return [name for name, run in zip(_AXES, self.runs, strict=True) if run >= self.stuck_after]
