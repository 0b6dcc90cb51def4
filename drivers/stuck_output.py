"""Stuck IMU outputs: an axis whose word stays the same sample after sample is no measurement.

A working ADIS16334 never repeats an axis for long: its noise alone moves every output word
from sample to sample (at 204.8 Hz the gyro's 2 deg/sqrt(h) is 0.48 deg/s, about 10 LSB,
per sample, the accelerometer's 0.12 m/s/sqrt(h) about 3 mg, 3 LSB; engine vibration adds
more), so the chance that one axis repeats its word is about 0.1 per sample, and that it does
so 24 samples running, 1e-24. A sensor that stopped converting, a bridge re-sending its last
SPI read (SEQ still counting, ND still set), or a data line stuck high or low all give such
runs, and the engines would integrate them as a vehicle that stopped rotating, or fell:
roll went out 4 deg off while STATUS said navigating (a 10 s freeze on the field run). At the
lowest rate (DEC 6, 12.8 Hz, under a noise of one LSB) a noisy axis repeats with a chance
under 0.4 a sample, and 24 running once in 10^4 hours of running.

A source with no noise (a bench stimulus, a simulator without an error model) repeats its
words whenever the vehicle stands still: ``ImuCanConfig.stuck_samples`` = 0 turns the check
off for it.
"""

from __future__ import annotations

from drivers.samples import Float3

#: Samples in a row with one axis's word unchanged that make it stuck (module docstring).
STUCK_SAMPLES = 24


class StuckAxes:
    """Per-axis runs of unchanged values over the six outputs (gyro x, y, z, accel x, y, z),
    in the decoder's units (one value per register word: equal values, equal words)."""

    __slots__ = ("_f", "_w", "after", "runs")

    def __init__(self, after: int = STUCK_SAMPLES) -> None:
        self.after = after  # a run this long (samples unchanged since the first) is stuck
        self.runs = (0, 0, 0, 0, 0, 0)  # samples since each axis last changed
        self._w: Float3 = (0.0, 0.0, 0.0)
        self._f: Float3 = (0.0, 0.0, 0.0)

    def __call__(self, w: Float3, f: Float3) -> bool:
        """Take one sample's rates and specific forces; True while some axis is stuck.
        (Locals and a tuple: a quarter cheaper than a list's items, on the per-sample path.)"""
        lw, lf = self._w, self._f
        self._w, self._f = w, f
        a, b, c, d, e, h = self.runs
        a = a + 1 if w[0] == lw[0] else 0
        b = b + 1 if w[1] == lw[1] else 0
        c = c + 1 if w[2] == lw[2] else 0
        d = d + 1 if f[0] == lf[0] else 0
        e = e + 1 if f[1] == lf[1] else 0
        h = h + 1 if f[2] == lf[2] else 0
        self.runs = (a, b, c, d, e, h)
        n = self.after
        return a >= n or b >= n or c >= n or d >= n or e >= n or h >= n

    def stuck_axes(self) -> list[str]:
        """The names of the axes stuck now (for a log line)."""
        names = ("gyro x", "gyro y", "gyro z", "accel x", "accel y", "accel z")
        return [name for name, run in zip(names, self.runs, strict=True) if run >= self.after]
