"""Typed, timestamped samples that the drivers hand to the fusion loop.

Everything here is SI (rad, rad/s, m, m/s, m/s^2, s) in the body frame FRD or the local
navigation frame NED. Times are host-clock UTC seconds (the clock both logs share, SPEC 3).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import IntEnum

import numpy as np

#: Three floats: a body vector on the per-sample path (a numpy array of 3 costs more to make
#: and to read than the arithmetic done with it).
Float3 = tuple[float, float, float]


class FixQuality(IntEnum):
    """GGA fix quality indicator (NMEA 0183), also sent in NAVGW_STATUS byte 3."""

    NONE = 0
    GNSS = 1
    DGNSS = 2
    PPS = 3
    RTK_FIXED = 4
    RTK_FLOAT = 5
    DEAD_RECKONING = 6
    MANUAL = 7
    SIMULATION = 8


#: Qualities computed with a reference station's corrections (GGA's station id and age of
#: corrections are theirs; the corrections' age degrades them).
CORRECTED_QUALITIES = frozenset({FixQuality.DGNSS, FixQuality.RTK_FIXED, FixQuality.RTK_FLOAT})

#: Qualities whose positions and velocities measure the antenna. A receiver's dead reckoning
#: (6) is its last solution carried on (u-blox holds the velocity, course and all, up to its
#: drLimit; others run sensors of their own) and manual input (7) a position typed in:
#: neither is a measurement, so the engines coast on their own IMU through them, as through
#: epochs without a fix.
MEASURING_QUALITIES = frozenset(
    set(FixQuality) - {FixQuality.NONE, FixQuality.DEAD_RECKONING, FixQuality.MANUAL}
)


@dataclass(frozen=True, slots=True)
class ImuSample:
    """One IMU output sample (gyro and accel of the same SEQ), body frame FRD, SI.

    ``t`` is the sample time on the host clock, reconstructed from SEQ and DEC and anchored
    to frame arrival (so CAN jitter does not enter ``dt``); ``dt`` is the nominal sample
    period 2^DEC / 819.2 Hz that this sample closes.
    """

    t: float
    dt: float
    w_ib_b: Float3  # rad/s, after the mounting rotation
    f_ib_b: Float3  # m/s^2, specific force, after the mounting rotation
    seq: int
    alarm: bool = False  # EA bit of any output word: some DIAG_STAT flag is set
    saturated: bool = False  # some axis at the end of its 14-bit register range
    stuck: bool = False  # some axis's word unchanged for many samples (drivers.axis_checks)
    # after a SEQ gap with its frames over half a SEQ wrap late: an outage longer than a wrap
    # (t then a whole number of wraps early) or a host stall, not yet told apart
    # (drivers.imu_can): the sample time is not known
    timing_unknown: bool = False


@dataclass(frozen=True, slots=True)
class ImuAux:
    """IMU_AUX contents (1 Hz): temperature, supply and diagnostics."""

    t: float
    temp_c: float
    supply_v: float
    diag_stat: int  # DIAG_STAT register bits as sent (SPEC 1)
    smpl_prd: int


#: Default GNSS 1-sigma per fix quality when the receiver sends no GST: (horizontal position
#: per axis m, vertical position m, horizontal velocity per axis m/s). Typical receiver figures.
DEFAULT_GNSS_SIGMAS: dict[int, tuple[float, float, float]] = {
    1: (1.5, 3.0, 0.10),  # single point
    2: (0.5, 1.0, 0.05),  # DGNSS
    4: (0.02, 0.04, 0.02),  # RTK fixed
    5: (0.2, 0.4, 0.04),  # RTK float
}


@dataclass(frozen=True, slots=True)
class GnssFix:
    """One receiver epoch, combining the NMEA sentences that describe it.

    ``t`` is the host receive time of the epoch (last sentence of the epoch, or the
    sentence's own UTC time when the log line has no host stamp); ``t_utc`` the epoch's
    UTC time from the sentences (None if the receiver gave no time). Optional fields are
    None when the receiver did not send them.
    """

    t: float
    t_utc: float | None
    quality: FixQuality
    lat_deg: float | None = None
    lon_deg: float | None = None
    # ellipsoidal height = GGA altitude (MSL) + geoid separation; the MSL altitude when the
    # receiver sends no separation (geoid_sep_m None): its datum unknown, its changes right
    alt_m: float | None = None
    num_sats: int | None = None
    hdop: float | None = None
    age_s: float | None = None  # age of differential corrections
    sog_mps: float | None = None  # speed over ground
    cog_rad: float | None = None  # course over ground, true, [0, 2 pi)
    heading_rad: float | None = None  # HDT true heading (dual antenna)
    sigma_n_m: float | None = None  # GST 1-sigma north
    sigma_e_m: float | None = None  # GST 1-sigma east
    sigma_d_m: float | None = None  # GST 1-sigma down
    mode: str | None = None  # RMC/VTG mode indicator: A, D, R, F, E, N, ...
    geoid_sep_m: float | None = None  # GGA geoid height above the ellipsoid (as alt_m: a fix)
    # GGA differential reference station id as sent (receivers send 0000 without corrections)
    reference_station_id: int | None = None
    # GGA talker id (GP, GL, GA, GB, GN, ...): the systems used; None if the epoch's GGAs
    # have several (one per system)
    talker: str | None = None
    # the least step of the position as printed (its minutes' last decimal), m: a receiver
    # printing 4 decimals rounds it to 18.5 cm (drivers.nmea._position_step)
    position_step_m: float | None = None
    # host time less ``t``: the host clock's steps taken out of the receive time, s
    # (drivers.host_clock; 0 while it has not stepped)
    host_offset_s: float = 0.0

    @property
    def measures(self) -> bool:
        """Whether the epoch measures the antenna (:data:`MEASURING_QUALITIES`)."""
        return self.quality in MEASURING_QUALITIES

    @property
    def position_sigma_m(self) -> tuple[float, float, float] | None:
        """Position 1-sigma north, east, down: GST when sent, else the quality's typical
        figure (:data:`DEFAULT_GNSS_SIGMAS`), with the rounding of the position as printed
        (uniform over its step: step / sqrt(12) north and east); None for a quality without
        a figure."""
        if self.sigma_n_m is not None and self.sigma_e_m is not None and self.sigma_d_m is not None:
            n, e, d = self.sigma_n_m, self.sigma_e_m, self.sigma_d_m
        elif int(self.quality) in DEFAULT_GNSS_SIGMAS:
            n, d, _ = DEFAULT_GNSS_SIGMAS[int(self.quality)]
            e = n
        else:
            return None
        if self.position_step_m is None:
            return (n, e, d)
        rounding = self.position_step_m / math.sqrt(12.0)
        return (math.hypot(n, rounding), math.hypot(e, rounding), d)

    @property
    def horizontal_sigma_m(self) -> float:
        """Horizontal position 1-sigma (root sum of north and east), 0 when unknown."""
        sig = self.position_sigma_m
        return math.hypot(sig[0], sig[1]) if sig is not None else 0.0

    @property
    def vel_ne_mps(self) -> tuple[float, float] | None:
        """Horizontal velocity (north, east) from SOG and COG, None without both."""
        if self.sog_mps is None or self.cog_rad is None:
            return None
        return (
            self.sog_mps * float(np.cos(self.cog_rad)),
            self.sog_mps * float(np.sin(self.cog_rad)),
        )


@dataclass
class ImuCounters:
    """What the IMU decoder (:mod:`drivers.imu_can`) has seen. ``samples + lost +
    out_of_order`` spans the SEQ stream."""

    frames: int = 0  # frames with one of our ids
    ignored: int = 0  # other frames the decoder was fed
    samples: int = 0  # ImuSample emitted
    aux: int = 0  # ImuAux emitted
    lost: int = 0  # samples that never arrived (SEQ gaps not filled later)
    duplicates: int = 0  # samples whose SEQ was already emitted
    out_of_order: int = 0  # samples that arrived after a later one (dropped, not emitted)
    malformed: int = 0  # our ids with wrong DLC, remote/standard frame or bad reserved bits
    unpaired: int = 0  # gyro or accel halves whose partner never came
    alarms: int = 0  # samples with an EA bit set
    saturated: int = 0  # samples with some axis at the end of its register range
    no_new_data: int = 0  # samples with an ND bit clear
    stuck: int = 0  # samples with some axis stuck (drivers.axis_checks)
    spikes: int = 0  # samples with a triad taken for a transfer error (same): held
    reanchors: int = 0  # time anchor restarts (DEC change, early arrivals, missed SEQ wraps)
    clock_steps: int = 0  # steps of the host clock found (drivers.host_clock)
    seq_errors: int = 0  # samples on time for the next SEQ but carrying another: taken as it
    seq_restarts: int = 0  # the bridge's SEQ counter restarted: counted from its new value
    bad_stamps: int = 0  # frames stamped before their partner by more than a stall can explain
