"""The IMU's white noise as installed, measured at rest: sensor noise plus engine vibration.

The datasheet gives the sensor's noise; the engine's vibration is the installation's, and
on a rough engine it is several times what ``[ekf] vibration_*`` assumes: a filter whose
process noise is too small states an attitude better than it is (three times the
simulator's vibration: 0.40 deg off with 0.063 stated). At rest the IMU's output is
constant but for its noise, so the spread of its means over blocks of one GNSS epoch
(0.1 s) is the noise the filter integrates between two velocity updates: broadband noise
in full, the engine's firing frequency (a sinusoid near 28 Hz, 2.7 cycles a block) only
as far as it does not average out over a block, which is the share that reaches the
velocity at the epochs.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field

from drivers.samples import Float3

#: A block's length, s: a GNSS epoch at 10 Hz (20 samples at 204.8 Hz, 82 at 819.2). Counted
#: as 20 samples, an 819.2 Hz unit's block held 0.7 cycle of a 28 Hz engine vibration, taken
#: for noise: both engines stated 1.05 deg of tilt where 0.59 was right (DEGRADED until the
#: first turn on `short` seed 3 at DEC 0 and 1).
BLOCK_S = 0.1
#: Block differences before the measurement is used: 2 s at 204.8 Hz, a sigma within ~9 %
#: (60 differences over the three axes; :meth:`ImuNoiseMeter.excess` takes an excess only
#: beyond three times that scatter). 3 s was longer than a short first rest allows: a cold
#: start 5 s at rest (`slope-start`) never measured a unit twice as noisy as its datasheet,
#: and the observer stated its datasheet's noise all run (roll 0.4 deg off with 0.1 stated,
#: seed 600 of imu-noise-x2+gnss-1hz).
MIN_BLOCK_PAIRS = 20
#: Blocks left out at the start of a rest and held back until this many more have come
#: (1 s): the last of the braking and the suspension settling, and the first of a drive-off,
#: which a rest test on the GNSS speed sees only 0.3-0.6 s after it began (its acceleration
#: in one block difference counts as much as a minute of vibration at rest).
EDGE_BLOCKS = 10
#: The sample period at which the configs' ``vibration_*`` are 1-sigma per sample: DEC 2,
#: 204.8 Hz (SPEC 1's default).
VIBRATION_SAMPLE_PERIOD_S = 4.0 / 819.2


def vibration_per_sample(sigma_at_default: float, dt_s: float) -> float:
    """Broadband vibration's 1-sigma per sample at sample period ``dt_s``, from its 1-sigma
    per sample at :data:`VIBRATION_SAMPLE_PERIOD_S`: the decimation filter averages 2^DEC
    internal samples, which keeps a broadband noise's density, so its 1-sigma per sample
    doubles at DEC 0 and halves at DEC 4. Taken per sample at every rate, the filters
    assumed a quarter of the vibration's density at 819.2 Hz and four times it at 51.2 Hz."""
    return sigma_at_default * math.sqrt(VIBRATION_SAMPLE_PERIOD_S / dt_s)


@dataclass
class ImuNoiseMeter:
    """White noise per sample of the gyro and accelerometer, from successive block means
    at rest: for white noise of sigma per sample, the difference of two block means of n
    samples has variance 2 sigma^2 / n. Fed only at rest; :meth:`restart` when a rest ends
    (the next rest starts a new chain, the statistics are kept). A rest's first and last
    :data:`EDGE_BLOCKS` are left out."""

    _sums: list[float] = field(default_factory=lambda: [0.0] * 6)
    _n: int = 0
    _prev: tuple[float, ...] | None = None  # the last block's means, w then f
    _sq_g: float = 0.0  # sums of n d^2 / 2 over differences of block means, all three axes
    _sq_a: float = 0.0
    _blocks: int = 0  # blocks of this rest so far
    _held: deque[tuple[float, float]] = field(default_factory=deque)  # the newest differences
    pairs: int = 0

    def add(self, w_rps: Float3, f_mps2: Float3, dt_s: float) -> None:
        """One sample at rest (body rate rad/s, specific force m/s^2, sample period s)."""
        s = self._sums
        s[0] += w_rps[0]
        s[1] += w_rps[1]
        s[2] += w_rps[2]
        s[3] += f_mps2[0]
        s[4] += f_mps2[1]
        s[5] += f_mps2[2]
        self._n += 1
        n = self._n
        if n < block_samples(dt_s):
            return
        means = tuple(x / n for x in s)
        prev = self._prev
        self._blocks += 1
        if prev is not None and self._blocks > EDGE_BLOCKS:
            d = [a - b for a, b in zip(means, prev, strict=True)]
            held = self._held
            held.append(  # n d^2 / 2: a sample's variance, whatever the rate
                (
                    0.5 * n * (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]),
                    0.5 * n * (d[3] * d[3] + d[4] * d[4] + d[5] * d[5]),
                )
            )
            if len(held) > EDGE_BLOCKS:
                sq_g, sq_a = held.popleft()
                self._sq_g += sq_g
                self._sq_a += sq_a
                self.pairs += 1
        self._prev = means
        self._sums = [0.0] * 6
        self._n = 0

    def restart(self) -> None:
        """The rest is over: the block under way, the chain of differences and its last
        :data:`EDGE_BLOCKS` end."""
        self._sums = [0.0] * 6
        self._n = 0
        self._prev = None
        self._blocks = 0
        self._held.clear()

    def variance_scatter(self) -> float:
        """Relative 1-sigma of the measured variances (chi-square: sqrt(2 / n) for n squared
        differences), so a caller takes them over a model only where they are beyond it."""
        return math.sqrt(2.0 / (3.0 * self.pairs)) if self.pairs else math.inf

    def excess(self, sigma_g_rps: float, sigma_a_mps2: float) -> tuple[float, float]:
        """How many times the noise measured is a model's white noise per sample and axis
        (gyro rad/s, accelerometer m/s^2), for each sensor: the ratio where the measured
        variance is beyond the model's by more than three sigma of its own scatter (~55 %
        after 2 s), else 1 (a sensor as the model says keeps the model's)."""
        measured = self.sigma_per_sample()
        if measured is None:
            return 1.0, 1.0
        k = math.sqrt(1.0 / (1.0 + 3.0 * self.variance_scatter()))
        return max(1.0, k * measured[0] / sigma_g_rps), max(1.0, k * measured[1] / sigma_a_mps2)

    def sigma_per_sample(self) -> tuple[float, float] | None:
        """(gyro rad/s, accelerometer m/s^2) white noise 1-sigma per sample and axis, or None
        before :data:`MIN_BLOCK_PAIRS` block differences."""
        if self.pairs < MIN_BLOCK_PAIRS:
            return None
        k = 1.0 / (3.0 * self.pairs)
        return math.sqrt(self._sq_g * k), math.sqrt(self._sq_a * k)


def block_samples(dt_s: float) -> int:
    """Samples in a block (:data:`BLOCK_S`) at sample period ``dt_s``."""
    return max(1, round(BLOCK_S / dt_s))
