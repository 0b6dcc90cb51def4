"""Simulated RTK GNSS receiver: truth antenna motion in, NMEA 0183 lines with receive times out.

The receiver computes a solution at whole multiples of 1/rate in UTC and prints, per epoch,
GGA and RMC (always), VTG, GST, ZDA (on by default) and HDT (dual-antenna heading, off by
default) in the formats of SPEC 2. Error model per fix quality (:class:`NoiseModel`):

- position: first-order Gauss-Markov per axis (RTK multipath and atmosphere residuals are
  correlated over tens of seconds, not white), one process per quality so that a quality
  change makes the jump a real receiver shows; plus, if set, white noise at every epoch
  (``position_white_sigma_m``: a receiver that does not smooth its solution);
- velocity: white per horizontal axis (carrier-phase Doppler is smooth and independent of the
  position error), giving SOG and COG;
- heading (HDT): white, ``heading_sigma_rad``.

GST reports the 1-sigma values of the model in use, so a consumer that weights by GST weights
correctly. COG below ``cog_min_speed_mps`` (measured speed) holds the last course computed above
it, as most RTK receivers do, and is empty until there has been one; SOG is always printed.
Reversing needs no special case: COG is the direction of the antenna velocity.

Receive times model the serial link: the epoch's sentences become ready ``latency_s`` plus a
uniform jitter in [0, ``latency_jitter_s``) after the epoch, then leave the UART at ``baud``
8N1 (10 bits a byte) one after another; a line's host time is when its LF has arrived (queued
behind the previous epoch if the link is still busy). The host clock is the truth's (and the
IMU log's); ``host_clock_offset_s`` is how far it is ahead of the receiver's UTC, so a
non-zero value is a host whose clock is not synchronised: the sentences' UTC times then
differ from the log stamps by the offset, as on an ECU without NTP or PPS.
"""

from __future__ import annotations

import datetime as dt
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from drivers.nmea import nmea_checksum
from drivers.samples import CORRECTED_QUALITIES, FixQuality
from gateway.estimation.geodesy import ned_to_lla
from sim_bus.truth import Truth

Array = npt.NDArray[np.float64]

KNOT_MPS = 1852.0 / 3600.0
BITS_PER_BYTE_8N1 = 10

# RMC/VTG mode indicator (NMEA 2.3+) for each GGA fix quality.
MODE_INDICATOR: Mapping[FixQuality, str] = {
    FixQuality.NONE: "N",
    FixQuality.GNSS: "A",
    FixQuality.DGNSS: "D",
    FixQuality.RTK_FIXED: "R",
    FixQuality.RTK_FLOAT: "F",
    FixQuality.DEAD_RECKONING: "E",
}


@dataclass(frozen=True, slots=True)
class NoiseModel:
    """Error model of one fix quality (1-sigma values, SI)."""

    sigma_h_m: float  # position, per horizontal axis (north, east)
    sigma_v_m: float  # position, vertical
    tau_s: float  # correlation time of the position error
    sigma_vel_mps: float  # velocity, per horizontal axis, white


DEFAULT_NOISE: Mapping[FixQuality, NoiseModel] = {
    FixQuality.RTK_FIXED: NoiseModel(0.010, 0.025, 30.0, 0.02),  # 1.4 cm horizontal RMS
    FixQuality.RTK_FLOAT: NoiseModel(0.15, 0.30, 60.0, 0.03),  # 0.21 m
    FixQuality.DGNSS: NoiseModel(0.35, 0.70, 120.0, 0.05),  # 0.5 m
    FixQuality.GNSS: NoiseModel(1.05, 2.0, 300.0, 0.08),  # 1.5 m
    FixQuality.DEAD_RECKONING: NoiseModel(2.0, 4.0, 60.0, 0.20),
}


class FixInterval(NamedTuple):
    """Fix quality during [t_start_s, t_end_s), seconds since the first truth sample."""

    t_start_s: float
    t_end_s: float
    quality: FixQuality


#: The sentence types a receiver may send at a slower rate than its epochs'
SLOW_SENTENCES = frozenset({"RMC", "VTG", "GST", "ZDA"})
ALL_SENTENCES = SLOW_SENTENCES | {"GGA", "HDT"}


@dataclass(frozen=True)
class GnssReceiverConfig:
    """Receiver model settings; defaults are a 10 Hz RTK receiver on 115200 baud."""

    rate_hz: float = 10.0  # 1, 2, 4, 5, 10 or 20: the epoch must be whole centiseconds
    talker: str = "GN"
    # decimals of the minutes of latitude and longitude printed: 7 (0.2 mm) as RTK receivers
    # print them, 4 (18.5 cm) as older ones do
    position_decimals: int = 7
    vtg: bool = True
    gst: bool = True
    zda: bool = True
    hdt: bool = False
    # Sentence types (of RMC, VTG, GST, ZDA) sent at slow_rate_hz only, a whole fraction of
    # rate_hz, the others at every epoch: a receiver set to send its positions faster
    slow_sentences: tuple[str, ...] = ()
    slow_rate_hz: float = 1.0
    # Later intervals override earlier ones; RTK fixed outside every interval.
    fix_schedule: tuple[FixInterval, ...] = ()
    # A receiver without sensors of its own carrying its last fix on through an outage, s:
    # epochs without a fix up to this long after it are DEAD_RECKONING at its position moved
    # on at its velocity, course and all (u-blox's drLimit); 0 sends them without a fix
    dead_reckoning_limit_s: float = 0.0
    noise: Mapping[FixQuality, NoiseModel] = field(default_factory=lambda: dict(DEFAULT_NOISE))
    # the velocity's 1-sigma per horizontal axis at every fix quality (Doppler's noise is the
    # same with RTK or without; u-blox F9P's datasheet has 0.05 m/s); None: each quality's
    # sigma_vel_mps from ``noise``
    velocity_sigma_mps: float | None = None
    # white position noise added to every fix, 1-sigma per horizontal axis (vertical twice
    # it): a receiver that does not smooth its solution, or rounds it; GST includes it
    position_white_sigma_m: float = 0.0
    heading_sigma_rad: float = math.radians(0.15)
    latency_s: float = 0.040
    latency_jitter_s: float = 0.003
    baud: int = 115200
    host_clock_offset_s: float = 0.0  # host clock minus UTC: the sentences' times are shifted
    # GGA field: ellipsoidal height minus MSL altitude; None sends it blank, the altitude
    # the ellipsoid's (a receiver without a geoid model)
    geoid_separation_m: float | None = 47.0
    num_sats: int = 22  # mean number of satellites used
    hdop: float = 0.7  # HDOP with num_sats satellites
    correction_period_s: float = 1.0  # base station message interval (UTC-aligned)
    correction_latency_s: float = 0.6  # base to rover link delay
    base_station_id: int = 0
    cog_min_speed_mps: float = 0.1
    seed: int = 0

    def __post_init__(self) -> None:
        period_cs = 100.0 / self.rate_hz
        if not 1.0 <= self.rate_hz <= 20.0 or abs(period_cs - round(period_cs)) > 1e-9:
            raise ValueError(
                f"rate_hz={self.rate_hz}: expected 1, 2, 4, 5, 10 or 20 "
                "(an epoch of whole centiseconds, as printed in hhmmss.ss)"
            )
        if not set(self.slow_sentences) <= SLOW_SENTENCES:
            raise ValueError(
                f"slow_sentences={self.slow_sentences}: expected some of "
                f"{', '.join(sorted(SLOW_SENTENCES))}"
            )
        if not (
            0.0 < self.slow_rate_hz <= self.rate_hz
            and abs(100.0 / self.slow_rate_hz - round(100.0 / self.slow_rate_hz)) < 1e-9
            and round(100.0 / self.slow_rate_hz) % self.period_cs == 0
        ):
            raise ValueError(
                f"slow_rate_hz={self.slow_rate_hz} with rate_hz={self.rate_hz}: expected a "
                "whole fraction of rate_hz (1 with 10 Hz epochs)"
            )
        if not 1 <= self.position_decimals <= 9:
            raise ValueError(
                f"position_decimals={self.position_decimals}: expected 1-9 decimals of a minute"
            )
        if len(self.talker) != 2 or not self.talker.isalpha() or not self.talker.isupper():
            raise ValueError(f"talker={self.talker!r}: expected two capital letters, e.g. 'GN'")
        if not 0.0 <= self.dead_reckoning_limit_s < math.inf:
            raise ValueError(
                f"dead_reckoning_limit_s={self.dead_reckoning_limit_s}: expected a finite "
                "time, s, 0 or more (0: no dead reckoning)"
            )
        if self.velocity_sigma_mps is not None and not 0.0 <= self.velocity_sigma_mps < math.inf:
            raise ValueError(
                f"velocity_sigma_mps={self.velocity_sigma_mps}: expected a finite 1-sigma, "
                "m/s, 0 or more (or none: the noise table's)"
            )
        if not 0.0 <= self.position_white_sigma_m < math.inf:
            raise ValueError(
                f"position_white_sigma_m={self.position_white_sigma_m}: expected a finite "
                "1-sigma, m, 0 or more"
            )
        for interval in self.fix_schedule:
            quality = FixQuality(interval[2])
            if quality != FixQuality.NONE and quality not in self.noise:
                raise ValueError(
                    f"fix_schedule quality {quality.name}: no noise model; expected NONE or "
                    f"one of {', '.join(q.name for q in self.noise)}"
                )

    @property
    def period_cs(self) -> int:
        """Epoch interval in centiseconds."""
        return round(100.0 / self.rate_hz)


class NmeaLine(NamedTuple):
    """One sentence (without CRLF) and the host time its last byte arrived, s."""

    host_t: float
    sentence: str


@dataclass
class ReceiverOutput:
    """The lines the receiver sent and, per epoch, the solution they carry (SI)."""

    lines: list[NmeaLine]
    t_utc: Array  # (n,) epoch instants, UTC s
    quality: npt.NDArray[np.int64]  # (n,) FixQuality values
    lla: Array  # (n, 3) reported antenna lat deg, lon deg, ellipsoidal height m; NaN no fix
    vel_ne_mps: Array  # (n, 2) reported horizontal velocity; NaN with no fix
    heading_rad: Array  # (n,) reported HDT heading; NaN with no fix


def nmea_sentence(body: str) -> str:
    """``$body*hh`` with the NMEA checksum (XOR of the body characters) in hex."""
    return f"${body}*{nmea_checksum(body):02X}"


def gauss_markov(
    rng: np.random.Generator, n: int, dt_s: float, tau_s: float, sigma: Array
) -> Array:
    """Stationary first-order Gauss-Markov sequences, shape (n, len(sigma)), in steady state.

    x_k = a x_{k-1} + sqrt(1 - a^2) sigma w_k with a = exp(-dt/tau): variance sigma^2 at every k.
    """
    a = math.exp(-dt_s / tau_s)
    x = rng.standard_normal((n, len(sigma))) * sigma
    x[1:] *= math.sqrt(1.0 - a * a)
    for k in range(1, n):  # 9000 epochs: ~10 ms; a closed form would overflow a^-k
        x[k] += a * x[k - 1]
    return x


def simulate_receiver(truth: Truth, config: GnssReceiverConfig | None = None) -> ReceiverOutput:
    """Run the receiver over the truth's time span; epochs outside it are not produced."""
    cfg = config or GnssReceiverConfig()
    rng = np.random.default_rng(cfg.seed)
    t0, offset = float(truth.t[0]), cfg.host_clock_offset_s
    k = np.arange(
        math.ceil((t0 - offset) * 100.0 / cfg.period_cs - 1e-9),
        math.floor((float(truth.t[-1]) - offset) * 100.0 / cfg.period_cs + 1e-9) + 1,
        dtype=np.int64,
    )
    t_cs = k * cfg.period_cs
    t_utc = t_cs / 100.0
    t_host = t_utc + offset  # the epochs on the host clock, which the truth is on
    n = len(t_utc)
    t_rel, truth_rel = t_host - t0, truth.t - t0

    def interp(column: Array) -> Array:
        return np.stack([np.interp(t_rel, truth_rel, c) for c in column.T], axis=-1)

    pos_ned = interp(truth.pos_ant_ned_m)
    vel_ne = interp(truth.vel_ant_ned_mps[:, :2])
    yaw = np.interp(t_rel, truth_rel, np.unwrap(truth.rpy_rad[:, 2]))

    quality = np.full(n, int(FixQuality.RTK_FIXED), dtype=np.int64)
    for start, end, q in cfg.fix_schedule:
        quality[(t_rel >= start) & (t_rel < end)] = int(q)
    fix = quality != FixQuality.NONE

    pos_err = np.zeros((n, 3))
    vel_sigma = np.zeros(n)
    sigma_h, sigma_v = np.full(n, np.nan), np.full(n, np.nan)
    for q in np.unique(quality[fix]):
        model = cfg.noise[FixQuality(int(q))]
        sel = quality == q
        sigma = np.array([model.sigma_h_m, model.sigma_h_m, model.sigma_v_m])
        pos_err[sel] = gauss_markov(rng, n, 1.0 / cfg.rate_hz, model.tau_s, sigma)[sel]
        vel_sigma[sel] = (
            model.sigma_vel_mps if cfg.velocity_sigma_mps is None else cfg.velocity_sigma_mps
        )
        sigma_h[sel], sigma_v[sel] = model.sigma_h_m, model.sigma_v_m

    pos_ned = pos_ned + pos_err
    vel_ne = vel_ne + vel_sigma[:, None] * rng.standard_normal((n, 2))
    if cfg.position_white_sigma_m > 0.0:  # drawn after the velocity's: its noise as without
        white = cfg.position_white_sigma_m * np.array([1.0, 1.0, 2.0])
        pos_ned = pos_ned + white * rng.standard_normal((n, 3))
        sigma_h, sigma_v = np.hypot(sigma_h, white[0]), np.hypot(sigma_v, white[2])
    if cfg.dead_reckoning_limit_s > 0.0:
        _carry_on(t_utc, quality, pos_ned, vel_ne, cfg.dead_reckoning_limit_s)
        fix = quality != FixQuality.NONE
        carried = quality == FixQuality.DEAD_RECKONING
        model = cfg.noise.get(FixQuality.DEAD_RECKONING, DEFAULT_NOISE[FixQuality.DEAD_RECKONING])
        sigma_h[carried], sigma_v[carried] = model.sigma_h_m, model.sigma_v_m
    lla = ned_to_lla(pos_ned, truth.origin_lla)
    lla[~fix] = np.nan
    vel_ne[~fix] = np.nan
    sog = np.hypot(vel_ne[:, 0], vel_ne[:, 1])
    cog = np.mod(np.arctan2(vel_ne[:, 1], vel_ne[:, 0]), 2.0 * np.pi)
    last_moving = np.maximum.accumulate(np.where(sog >= cfg.cog_min_speed_mps, np.arange(n), -1))
    cog = np.where(last_moving >= 0, cog[last_moving], np.nan)
    cog[~fix] = np.nan
    heading_ok = fix & (quality != FixQuality.DEAD_RECKONING)
    heading = np.mod(yaw + cfg.heading_sigma_rad * rng.standard_normal(n), 2.0 * np.pi)
    heading[~heading_ok] = np.nan

    sats = np.clip(
        np.rint(
            cfg.num_sats + gauss_markov(rng, n, 1.0 / cfg.rate_hz, 120.0, np.array([2.0]))[:, 0]
        ),
        5,
        40,
    ).astype(np.int64)
    hdop = cfg.hdop * np.sqrt(cfg.num_sats / sats)
    p, lat_c = cfg.correction_period_s, cfg.correction_latency_s
    age = t_utc - np.floor((t_utc - lat_c) / p) * p

    bodies, line_epoch = _format_epochs(
        cfg, t_cs, quality, lla, sog, cog, heading, sats, hdop, age, sigma_h, sigma_v
    )
    host_t = _receive_times(cfg, rng, t_host, bodies, line_epoch)
    lines = [NmeaLine(float(t), s) for t, s in zip(host_t, bodies, strict=True)]
    return ReceiverOutput(lines, t_utc, quality, lla, vel_ne, heading)


def _carry_on(
    t_utc: Array, quality: npt.NDArray[np.int64], pos_ned: Array, vel_ne: Array, limit_s: float
) -> None:
    """Epochs without a fix up to ``limit_s`` after the last fix become DEAD_RECKONING: its
    position moved on at its velocity, the velocity held (in place)."""
    last = -1
    for i, q in enumerate(quality.tolist()):
        if q != FixQuality.NONE:
            last = i if q != FixQuality.DEAD_RECKONING else last
        elif last >= 0 and t_utc[i] - t_utc[last] <= limit_s:
            quality[i] = FixQuality.DEAD_RECKONING
            pos_ned[i, :2] = pos_ned[last, :2] + vel_ne[last] * (t_utc[i] - t_utc[last])
            pos_ned[i, 2] = pos_ned[last, 2]
            vel_ne[i] = vel_ne[last]


def _format_epochs(
    cfg: GnssReceiverConfig,
    t_cs: npt.NDArray[np.int64],
    quality: npt.NDArray[np.int64],
    lla: Array,
    sog: Array,
    cog: Array,
    heading: Array,
    sats: npt.NDArray[np.int64],
    hdop: Array,
    age: Array,
    sigma_h: Array,
    sigma_v: Array,
) -> tuple[list[str], list[int]]:
    """All sentences of all epochs, in order, with the epoch index of each."""
    tk = cfg.talker
    day_cs = 86400 * 100
    sod = t_cs % day_cs
    times = [
        f"{h:02d}{m:02d}{s // 100:02d}.{s % 100:02d}"
        for h, m, s in zip(
            (sod // 360000).tolist(),
            (sod // 6000 % 60).tolist(),
            (sod % 6000).tolist(),
            strict=True,
        )
    ]
    days = {
        int(d): dt.date(1970, 1, 1) + dt.timedelta(days=int(d)) for d in np.unique(t_cs // day_cs)
    }
    dates = [days[d] for d in (t_cs // day_cs).tolist()]
    lat_txt = _ddmm(np.nan_to_num(lla[:, 0]), 2, cfg.position_decimals)
    lon_txt = _ddmm(np.nan_to_num(lla[:, 1]), 3, cfg.position_decimals)
    alt_msl = (lla[:, 2] - (cfg.geoid_separation_m or 0.0)).tolist()
    sog_kn = (sog / KNOT_MPS).tolist()
    cog_deg = np.degrees(cog).tolist()
    hdg_deg = np.degrees(heading).tolist()
    rms = np.sqrt(2.0 * sigma_h**2 + sigma_v**2).tolist()
    sats_n, hdop_v, age_s = sats.tolist(), hdop.tolist(), age.tolist()
    sig_h, sig_v = sigma_h.tolist(), sigma_v.tolist()
    sep = "" if cfg.geoid_separation_m is None else f"{cfg.geoid_separation_m:.3f}"
    sid = f"{cfg.base_station_id:04d}"

    slow_cs = round(100.0 / cfg.slow_rate_hz)
    fast = ALL_SENTENCES - set(cfg.slow_sentences)
    bodies: list[str] = []
    line_epoch: list[int] = []
    for i, q_int in enumerate(quality.tolist()):
        q = FixQuality(q_int)
        t, d = times[i], dates[i]
        sent = ALL_SENTENCES if int(t_cs[i]) % slow_cs == 0 else fast
        ddmmyy = f"{d.day:02d}{d.month:02d}{d.year % 100:02d}"
        mode = MODE_INDICATOR[q]
        epoch: list[str] = []
        if q == FixQuality.NONE:
            epoch.append(f"{tk}GGA,{t},,,,,0,00,99.99,,,,,,")
            if "RMC" in sent:
                epoch.append(f"{tk}RMC,{t},V,,,,,,,{ddmmyy},,,N")
            if cfg.vtg and "VTG" in sent:
                epoch.append(f"{tk}VTG,,T,,M,,N,,K,N")
            if cfg.gst and "GST" in sent:
                epoch.append(f"{tk}GST,{t},,,,,,,")
        else:
            lat, ns = lat_txt[i]
            lon, ew = lon_txt[i]
            corr = f"{age_s[i]:.1f},{sid}" if q in CORRECTED_QUALITIES else ","
            epoch.append(
                f"{tk}GGA,{t},{lat},{'N' if ns else 'S'},{lon},{'E' if ew else 'W'},{q_int},"
                f"{sats_n[i]:02d},{hdop_v[i]:.2f},{alt_msl[i]:.3f},M,{sep},M,{corr}"
            )
            status = "V" if q == FixQuality.DEAD_RECKONING else "A"  # NMEA: only A/D/F/R valid
            course = "" if math.isnan(cog_deg[i]) else f"{cog_deg[i]:.2f}"
            kn = sog_kn[i]
            if "RMC" in sent:
                epoch.append(
                    f"{tk}RMC,{t},{status},{lat},{'N' if ns else 'S'},{lon},"
                    f"{'E' if ew else 'W'},{kn:.3f},{course},{ddmmyy},,,{mode}"
                )
            if cfg.vtg and "VTG" in sent:
                epoch.append(f"{tk}VTG,{course},T,,M,{kn:.3f},N,{kn * 1.852:.3f},K,{mode}")
            if cfg.gst and "GST" in sent:
                sh, sv = sig_h[i], sig_v[i]
                epoch.append(
                    f"{tk}GST,{t},{rms[i]:.3f},{sh:.3f},{sh:.3f},0.0,{sh:.3f},{sh:.3f},{sv:.3f}"
                )
        if cfg.hdt:
            hdg = "" if math.isnan(hdg_deg[i]) else f"{hdg_deg[i]:.3f}"
            epoch.append(f"{tk}HDT,{hdg},T")
        if cfg.zda and "ZDA" in sent:
            epoch.append(f"{tk}ZDA,{t},{d.day:02d},{d.month:02d},{d.year:04d},00,00")
        bodies.extend(nmea_sentence(b) for b in epoch)
        line_epoch.extend([i] * len(epoch))
    return bodies, line_epoch


def _ddmm(deg: Array, deg_digits: int, decimals: int) -> list[tuple[str, bool]]:
    """Angle -> (``d..dmm.mmmmmmm`` text with ``decimals`` of the minutes, non-negative);
    1e-7 minute is 0.2 mm."""
    scale = 10**decimals
    units = np.rint(np.abs(deg) * 60 * scale).astype(np.int64)
    whole, rem = np.divmod(units, 60 * scale)
    minutes, frac = np.divmod(rem, scale)
    return [
        (f"{w:0{deg_digits}d}{m:02d}.{f:0{decimals}d}", pos)
        for w, m, f, pos in zip(
            whole.tolist(), minutes.tolist(), frac.tolist(), (deg >= 0).tolist(), strict=True
        )
    ]


def _receive_times(
    cfg: GnssReceiverConfig,
    rng: np.random.Generator,
    t_host: Array,
    sentences: list[str],
    line_epoch: list[int],
) -> Array:
    """Host time at which each line's LF arrives, through a FIFO serial link; ``t_host``: the
    epochs on the host clock."""
    byte_s = BITS_PER_BYTE_8N1 / cfg.baud
    line_s = np.array([len(s) + 2 for s in sentences], dtype=float) * byte_s  # + CRLF
    epoch_of_line = np.asarray(line_epoch, dtype=np.int64)
    epoch_s = np.bincount(epoch_of_line, weights=line_s, minlength=len(t_host)).astype(np.float64)
    ready = t_host + cfg.latency_s + cfg.latency_jitter_s * rng.random(len(t_host))
    # FIFO: end_k = max(ready_k, end_{k-1}) + epoch_s_k, in closed form with a running max.
    busy = np.cumsum(epoch_s)
    end = busy + np.maximum.accumulate(ready - (busy - epoch_s))
    start = end - epoch_s
    line_end = np.cumsum(line_s)
    epoch_begin = (busy - epoch_s)[epoch_of_line]
    host_t: Array = start[epoch_of_line] + (line_end - epoch_begin)
    return host_t
