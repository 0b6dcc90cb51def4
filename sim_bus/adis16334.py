"""ADIS16334 error model: true body rates and specific force in, register words out.

Model, per axis, in the sensor's own (IMU) axes, all vectorised over the sample grid:

    y = C_imu^b (mean(x_b) + vibration_b) + b_turn_on + b_in_run(t) + white noise,

then quantised to the register LSB, saturated at the 14-bit range and packed with the ND
(new data) and EA (alarm) bits as the bridge forwards them (SPEC 1). mean(x_b) is the
datasheet's average/decimation filter: each output sample is the mean of the 2^DEC internal
samples (819.2 Hz) up to it, so a sample is the mean rate and specific force over its
period, not their value at its instant (:func:`decimated`). The in-run bias is a
first-order Gauss-Markov process whose Allan-deviation floor (0.6174 sigma at tau = 1.89 T)
equals the datasheet's in-run bias stability; the white noise is the datasheet's random walk.

Datasheet figures (ADIS16334, Analog Devices, Rev. B, Table 1, typical, 25 degC, 5 V). They are
recalled, not re-read from the PDF for this module: check them against the PDF before relying
on absolute numbers. Register formats (14-bit two's complement, bit 14 EA, bit 15 ND, 0.05
deg/s and 1 mg per LSB, TEMP 0.06785 degC/LSB, SUPPLY 2.418 mV/LSB) are as in SPEC 1.

=================================  ==================  ===========================
datasheet name                     figure              attribute (SI)
=================================  ==================  ===========================
gyro in-run bias stability (1 s)   0.007 deg/s         gyro_bias_stability_rps
gyro angular random walk           2.0 deg/sqrt(h)     gyro_arw_rad_per_sqrt_s
gyro output noise, no filtering    ~0.6 deg/s rms      (follows from the ARW)
accel in-run bias stability        0.1 mg              accel_bias_stability_mps2
accel velocity random walk         0.12 m/s/sqrt(h)    accel_vrw_mps_per_sqrt_s
accel output noise, no filtering   ~4-5 mg rms         (follows from the VRW)
gyro / accel range                 +/-300 deg/s, 5 g   gyro_range_rps, accel_range_mps2
=================================  ==================  ===========================

The turn-on bias sigmas (0.1 deg/s, 5 mg) are our assumption for a unit nulled at
installation; the datasheet's raw initial bias error is larger.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt
from scipy.signal import lfilter

from drivers.imu_can import ADIS_CLOCK_HZ, GRAVITY_MPS2, DiagStat
from drivers.units import DEG_TO_RAD
from gateway.estimation.attitude import dcm_from_rpy_deg

Array = npt.NDArray[np.float64]

MG = GRAVITY_MPS2 * 1e-3
SQRT_HOUR = 60.0  # sqrt(3600 s)

GYRO_LSB_RPS = 0.05 * DEG_TO_RAD  # XGYRO_OUT.. : 0.05 deg/s per LSB
ACCEL_LSB_MPS2 = MG  # XACCL_OUT.. : 1 mg per LSB
TEMP_LSB_C = 0.06785  # TEMP_OUT, 0 = 25 degC
TEMP_ZERO_C = 25.0
SUPPLY_LSB_V = 0.002418  # SUPPLY_OUT
OUT_MIN, OUT_MAX = -(1 << 13), (1 << 13) - 1  # 14-bit two's complement
ND_BIT = 0x8000
EA_BIT = 0x4000
SMPL_PRD_INTERNAL_CLOCK = 0x0001  # SMPL_PRD bit 0: internal 819.2 Hz clock; bits 8-12: DEC
GM_ALLAN_FLOOR = 0.6174  # Allan deviation maximum of a Gauss-Markov process / its sigma
SUPPLY_LOW_V, SUPPLY_HIGH_V = 4.75, 5.25


@dataclass(frozen=True)
class EngineVibration:
    """Engine vibration seen by the IMU, body frame: a sinusoid plus broadband noise.

    Amplitudes and the broadband 1-sigma are as output at DEC 2 (204.8 Hz, the default).
    At another DEC the decimation filter averages 2^DEC internal samples: the sinusoid
    passes with that mean's gain at its frequency, the broadband noise with 1 / sqrt(2^DEC)
    (its density kept), both relative to DEC 2's (:func:`vibration_gains`).
    """

    frequency_hz: float = 28.0
    accel_amplitude_mps2: tuple[float, float, float] = (0.3, 0.2, 0.6)
    accel_broadband_mps2: float = 0.15  # 1-sigma per sample (at DEC 2)
    gyro_amplitude_rps: tuple[float, float, float] = (
        0.2 * DEG_TO_RAD,
        0.2 * DEG_TO_RAD,
        0.1 * DEG_TO_RAD,
    )
    gyro_broadband_rps: float = 0.05 * DEG_TO_RAD


@dataclass(frozen=True)
class Adis16334Config:
    """Error model settings; defaults are the datasheet figures in the module docstring."""

    dec: int = 2  # output rate 819.2 Hz / 2^DEC
    imu_mounting_rpy_deg: tuple[float, float, float] = (0.0, 0.0, 0.0)
    gyro_turn_on_bias_rps: tuple[float, float, float] | None = None  # IMU axes; None = random
    accel_turn_on_bias_mps2: tuple[float, float, float] | None = None
    # the in-run (Gauss-Markov) bias at the first sample, IMU axes; None: drawn from its
    # stationary spread. 0 with the turn-on bias set to where a previous run's bias ended
    # continues that run's IMU (sim_bus.scenarios.continuation)
    gyro_in_run_bias0_rps: tuple[float, float, float] | None = None
    accel_in_run_bias0_mps2: tuple[float, float, float] | None = None
    gyro_turn_on_sigma_rps: float = 0.1 * DEG_TO_RAD
    accel_turn_on_sigma_mps2: float = 5.0 * MG
    gyro_bias_stability_rps: float = 0.007 * DEG_TO_RAD
    accel_bias_stability_mps2: float = 0.1 * MG
    bias_correlation_time_s: float = 100.0
    gyro_arw_rad_per_sqrt_s: float = 2.0 * DEG_TO_RAD / SQRT_HOUR
    accel_vrw_mps_per_sqrt_s: float = 0.12 / SQRT_HOUR
    gyro_range_rps: float = 300.0 * DEG_TO_RAD
    accel_range_mps2: float = 5.0 * GRAVITY_MPS2
    vibration: EngineVibration | None = field(default_factory=EngineVibration)
    temp_start_c: float = 27.0  # warms up towards temp_end_c with temp_tau_s
    temp_end_c: float = 38.0
    temp_tau_s: float = 900.0
    # the biases' temperature coefficients, drawn per axis from N(0, sigma) (their own stream
    # of the seed; a continuation's run draws its own): the bias moves by them times the
    # warm-up since the first sample. 0: a unit compensated perfectly (the default; the
    # datasheet-class figures are 0.01 deg/s and 0.1 mg per degC, the config's [state] tempcos)
    gyro_bias_tempco_sigma_rps_per_c: float = 0.0
    accel_bias_tempco_sigma_mps2_per_c: float = 0.0
    supply_v: float = 5.0
    aux_period_s: float = 1.0
    seed: int = 0

    @property
    def dt_s(self) -> float:
        """Output sample period 2^DEC / 819.2 Hz."""
        return float(2**self.dec) / ADIS_CLOCK_HZ


@dataclass
class Adis16334Aux:
    """IMU_AUX register words, read by the bridge after output sample ``index``."""

    index: npt.NDArray[np.int64]  # (m,) sample index the read follows
    t: Array  # (m,) s, instant of that sample
    temp_out: npt.NDArray[np.uint16]
    supply_out: npt.NDArray[np.uint16]
    diag_stat: npt.NDArray[np.uint16]
    smpl_prd: npt.NDArray[np.uint16]


@dataclass
class Adis16334Output:
    """Register words per sample (as the bridge sends them) and the true biases."""

    t: Array  # (n,) s
    dec: int
    gyro_words: npt.NDArray[np.uint16]  # (n, 3) XGYRO_OUT, YGYRO_OUT, ZGYRO_OUT
    accel_words: npt.NDArray[np.uint16]  # (n, 3) XACCL_OUT, YACCL_OUT, ZACCL_OUT
    seq: npt.NDArray[np.uint8]  # (n,) wraps 255 -> 0
    diag_stat: npt.NDArray[np.uint16]  # (n,) DIAG_STAT latched at each sample (since last read)
    bias_g_rps: Array  # (n, 3) true gyro bias, body FRD
    bias_a_mps2: Array  # (n, 3) true accelerometer bias, body FRD
    aux: Adis16334Aux

    def __len__(self) -> int:
        return len(self.t)


def _gauss_markov(
    rng: np.random.Generator,
    n: int,
    dt: float,
    tau: float,
    sigma: float,
    x0: tuple[float, float, float] | None = None,
) -> Array:
    """(n, 3) first-order Gauss-Markov sequence of std ``sigma``: stationary, or from ``x0``."""
    a = np.exp(-dt / tau)
    w = rng.standard_normal((n, 3)) * sigma * np.sqrt(1.0 - a * a)
    w[0] = rng.standard_normal(3) * sigma
    if x0 is not None:
        w[0] = x0
    return np.asarray(lfilter([1.0], [1.0, -a], w, axis=0))


def vibration_gains(vib: EngineVibration, dec: int) -> tuple[float, float]:
    """The decimation filter's gain at ``dec`` on ``vib``'s sinusoid and on its broadband
    noise, relative to DEC 2's: the mean of m = 2^DEC internal samples at 819.2 Hz passes a
    sinusoid of frequency f with |sin(pi f m / 819.2) / (m sin(pi f / 819.2))| and white noise
    with 1 / sqrt(m). At 28 Hz: 1.03 at DEC 0, 0.59 at DEC 4 (the 0.97 of DEC 2 as 1)."""

    def sine_gain(m: int) -> float:
        x = np.pi * vib.frequency_hz / ADIS_CLOCK_HZ
        return abs(float(np.sin(m * x) / (m * np.sin(x))))

    m = 2**dec
    return sine_gain(m) / sine_gain(4), float(np.sqrt(4.0 / m))


def _vibration(rng: np.random.Generator, t: Array, amplitude: Array, broadband: float) -> Array:
    phase = rng.uniform(0.0, 2.0 * np.pi, 3)
    return amplitude * np.sin(2.0 * np.pi * t[:, None] + phase) + broadband * rng.standard_normal(
        (len(t), 3)
    )


def _words(x: Array, lsb: float, alarm: npt.NDArray[np.bool_]) -> npt.NDArray[np.uint16]:
    counts = np.clip(np.rint(x / lsb), OUT_MIN, OUT_MAX).astype(np.int32)
    words = (counts & 0x3FFF) | ND_BIT | np.where(alarm, EA_BIT, 0)[:, None]
    return words.astype(np.uint16)


def _latched(flags: npt.NDArray[np.uint16], reads: npt.NDArray[np.int64]) -> npt.NDArray[np.uint16]:
    """DIAG_STAT as read at each sample: flags OR-ed since the last read (reads clear it)."""
    n = len(flags)
    window = np.searchsorted(reads, np.arange(n), side="left")
    start = np.concatenate(([0], reads + 1))[window]
    out = np.zeros(n, dtype=np.uint16)
    for bit in DiagStat:
        c = np.concatenate(([0], np.cumsum((flags & bit.value) != 0)))
        out |= np.where(c[1:] - c[start] > 0, bit.value, 0).astype(np.uint16)
    return out


def decimated(x: Array, dec: int) -> Array:
    """Output samples (n, 3) of the average/decimation filter from values ``x`` (n, 3) at the
    output instants: the mean of the 2^dec internal samples at 819.2 Hz that end at each
    instant, the truth between two instants taken as linear. That mean is
    ((m + 1) x_k + (m - 1) x_{k-1}) / 2m with m = 2^dec (the first sample: its own value).

    A point value taken for the period's mean turns the platform half a period early: on
    ground rocking the body at 25 deg/s, 0.06 deg of tilt at 204.8 Hz and 0.12 at 102.4 Hz.
    With point values the EKF's pitch error was 1.26 times its stated sigma RMS on
    `steep-turns` seed 61 of `rough-prompt`, 0.99 with this filter.
    """
    m = 2**dec
    out = x.copy()
    out[1:] = ((m + 1) * x[1:] + (m - 1) * x[:-1]) / (2 * m)
    return out


def simulate(
    t: npt.ArrayLike, w_ib_b: npt.ArrayLike, f_ib_b_imu: npt.ArrayLike, config: Adis16334Config
) -> Adis16334Output:
    """Register words for true rates ``w_ib_b`` (n, 3) rad/s and specific force ``f_ib_b_imu``
    (n, 3) m/s^2, body FRD, at instants ``t`` (n,), which must be on the DEC grid."""
    rng = np.random.default_rng(config.seed)
    t = np.asarray(t, dtype=float)
    n = len(t)
    dt = config.dt_s
    c_b_imu = dcm_from_rpy_deg(config.imu_mounting_rpy_deg)

    def turn_on(given: tuple[float, float, float] | None, sigma: float) -> Array:
        return np.asarray(given, dtype=float) if given is not None else rng.normal(0, sigma, 3)

    b_g_imu = turn_on(config.gyro_turn_on_bias_rps, config.gyro_turn_on_sigma_rps) + _gauss_markov(
        rng,
        n,
        dt,
        config.bias_correlation_time_s,
        config.gyro_bias_stability_rps / GM_ALLAN_FLOOR,
        config.gyro_in_run_bias0_rps,
    )
    b_a_imu = turn_on(config.accel_turn_on_bias_mps2, config.accel_turn_on_sigma_mps2)
    b_a_imu = b_a_imu + _gauss_markov(
        rng,
        n,
        dt,
        config.bias_correlation_time_s,
        config.accel_bias_stability_mps2 / GM_ALLAN_FLOOR,
        config.accel_in_run_bias0_mps2,
    )
    warm_c = temperature_c(t - t[0], config) - config.temp_start_c
    tempco_rng = np.random.default_rng([config.seed, 1])
    b_g_imu = b_g_imu + np.outer(
        warm_c, tempco_rng.normal(0.0, config.gyro_bias_tempco_sigma_rps_per_c, 3)
    )
    b_a_imu = b_a_imu + np.outer(
        warm_c, tempco_rng.normal(0.0, config.accel_bias_tempco_sigma_mps2_per_c, 3)
    )
    w_b = decimated(np.asarray(w_ib_b, dtype=float), config.dec)
    f_b = decimated(np.asarray(f_ib_b_imu, dtype=float), config.dec)
    vib = config.vibration
    if vib is not None:
        tv = (t - t[0]) * vib.frequency_hz
        sine, broadband = vibration_gains(vib, config.dec)
        w_b = w_b + _vibration(
            rng, tv, sine * np.asarray(vib.gyro_amplitude_rps), broadband * vib.gyro_broadband_rps
        )
        f_b = f_b + _vibration(
            rng,
            tv,
            sine * np.asarray(vib.accel_amplitude_mps2),
            broadband * vib.accel_broadband_mps2,
        )
    sqrt_dt = np.sqrt(dt)
    w_imu = (w_b @ c_b_imu) + b_g_imu  # row-wise C^T w
    w_imu += rng.standard_normal((n, 3)) * (config.gyro_arw_rad_per_sqrt_s / sqrt_dt)
    f_imu = (f_b @ c_b_imu) + b_a_imu
    f_imu += rng.standard_normal((n, 3)) * (config.accel_vrw_mps_per_sqrt_s / sqrt_dt)

    overrange = (np.abs(w_imu) > config.gyro_range_rps).any(axis=1) | (
        np.abs(f_imu) > config.accel_range_mps2
    ).any(axis=1)
    supply_v = config.supply_v + 0.002 * rng.standard_normal(n)
    flags = (
        np.where(overrange, DiagStat.OVERRANGE.value, 0)
        | np.where(supply_v < SUPPLY_LOW_V, DiagStat.SUPPLY_LOW.value, 0)
        | np.where(supply_v > SUPPLY_HIGH_V, DiagStat.SUPPLY_HIGH.value, 0)
    ).astype(np.uint16)
    reads = np.unique(
        np.searchsorted(t, t[0] + np.arange(0.0, t[-1] - t[0] + dt, config.aux_period_s))
    )
    reads = reads[reads < n].astype(np.int64)
    diag = _latched(flags, reads)
    alarm = diag != 0

    t_read = t[reads] - t[0]
    temp_c = temperature_c(t_read, config) + 0.05 * rng.standard_normal(len(reads))
    aux_ea = np.where(alarm[reads], EA_BIT, 0)
    temp_counts = np.clip(np.rint((temp_c - TEMP_ZERO_C) / TEMP_LSB_C), -2048, 2047).astype(int)
    supply_counts = np.clip(np.rint(supply_v[reads] / SUPPLY_LSB_V), 0, 4095).astype(int)
    aux = Adis16334Aux(
        index=reads,
        t=t[reads],
        temp_out=((temp_counts & 0xFFF) | ND_BIT | aux_ea).astype(np.uint16),
        supply_out=(supply_counts | ND_BIT | aux_ea).astype(np.uint16),
        diag_stat=diag[reads],
        smpl_prd=np.full(len(reads), (config.dec << 8) | SMPL_PRD_INTERNAL_CLOCK, dtype=np.uint16),
    )
    return Adis16334Output(
        t=t,
        dec=config.dec,
        gyro_words=_words(w_imu, GYRO_LSB_RPS, alarm),
        accel_words=_words(f_imu, ACCEL_LSB_MPS2, alarm),
        seq=(np.arange(n) % 256).astype(np.uint8),
        diag_stat=diag,
        bias_g_rps=b_g_imu @ c_b_imu.T,
        bias_a_mps2=b_a_imu @ c_b_imu.T,
        aux=aux,
    )


def temperature_c(t_s: Array, config: Adis16334Config) -> Array:
    """The unit's temperature, degC, ``t_s`` after its first sample: the warm-up."""
    return config.temp_end_c + (config.temp_start_c - config.temp_end_c) * np.exp(
        -t_s / config.temp_tau_s
    )


def counts_from_words(words: npt.NDArray[np.uint16]) -> npt.NDArray[np.int32]:
    """Signed 14-bit register values of output words (EA/ND stripped)."""
    v = words.astype(np.int32) & 0x3FFF
    return np.where(v >= 1 << 13, v - (1 << 14), v)
