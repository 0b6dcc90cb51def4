"""Parameters of the loosely coupled GNSS/INS EKF engine (ALGORITHMS.md 3, seed 002).

Sensor noise defaults are the ADIS16334 datasheet figures (Analog Devices, Rev. B, Table 1,
typical; the same table as :mod:`sim_bus.adis16334`, which models them). Field names carry
their unit so that the TOML keys read the same; degrees and mg appear only here (the engine
converts to SI once, :class:`EkfTuning`). Fields whose meaning is the observer's keep its name
(:class:`gateway.estimation.observer.observer_config.ObserverConfig`): lever arms, GNSS timing,
alignment,
stationarity, fix-quality sets, convergence thresholds.
"""

from __future__ import annotations

from dataclasses import dataclass

from drivers.units import DEG_TO_RAD, MG_MPS2, SQRT_SECONDS_PER_HOUR
from gateway.estimation.epoch_clock import RECEIVE_EPOCH_SIGMA_S, EpochTime
from gateway.estimation.imu_noise import vibration_per_sample
from gateway.estimation.observer.observer_config import Vec3Tuple

#: Allan-deviation floor of a first-order Gauss-Markov process / its sigma (at tau = 1.89 T):
#: a datasheet "in-run bias stability" B is a Gauss-Markov sigma of B / 0.6174.
GM_ALLAN_FLOOR = 0.6174


@dataclass(frozen=True)
class EkfConfig:
    """Everything :class:`gateway.estimation.ekf.ekf_engine.EkfEngine` can be tuned with."""

    # --- IMU noise, ADIS16334 datasheet (Table 1) ---
    gyro_arw_deg_per_sqrt_h: float = 2.0  # angular random walk: white rate noise density
    accel_vrw_mps_per_sqrt_h: float = 0.12  # velocity random walk: white accel noise density
    gyro_bias_stability_dps: float = 0.007  # in-run bias stability (Allan floor)
    accel_bias_stability_mg: float = 0.1  # in-run bias stability (Allan floor)
    bias_correlation_time_s: float = 100.0  # Gauss-Markov time of the in-run bias
    # the biases' temperature coefficients (datasheet, 1-sigma; [imu], as the observer's):
    # the temperature's rate adds to the wander (gateway/estimation/temperature.py)
    gyro_bias_tempco_dps_per_c: float = 0.01
    accel_bias_tempco_mg_per_c: float = 0.1
    # Turn-on bias 1-sigma after installation nulling (initial P; what the simulator draws)
    gyro_bias_sigma0_dps: float = 0.1
    accel_bias_sigma0_mps2: float = 5.0 * MG_MPS2
    # Turn-on accelerometer bias 1-sigma that the stated roll/pitch accuracy covers until the
    # filter has observed the bias: a unit not nulled at installation (seed 000's had
    # 0.11 m/s^2; the observer's sigma model takes the same). P0 keeps the figure above.
    accel_bias_sigma_covered_mps2: float = 0.1
    # Engine vibration seen by the IMU (installation, not datasheet): broadband 1-sigma per
    # sample at 204.8 Hz (its density kept at other rates), added to the white noise
    # densities as sigma^2 dt; the least the filter assumes (the noise measured at rest
    # replaces it where larger: gateway/estimation/imu_noise.py)
    vibration_gyro_dps: float = 0.05
    vibration_accel_mps2: float = 0.2

    # --- vehicle geometry (SPEC 5) ---
    antenna_lever_arm_m: Vec3Tuple = (0.0, 0.0, 0.0)  # antenna rel. reference point, body
    imu_lever_arm_m: Vec3Tuple = (0.0, 0.0, 0.0)  # IMU rel. reference point, body
    # roll/pitch 1-sigma of the IMU mounting, deg: added to the stated tilt accuracy
    imu_mounting_sigma_deg: float = 0.0

    # --- GNSS timing ---
    epoch_time: EpochTime = EpochTime.AUTO  # how epochs are placed on the host clock
    receiver_latency_s: float = 0.0  # least delay from an epoch to its last sentence's receipt
    receiver_latency_sigma_s: float = RECEIVE_EPOCH_SIGMA_S  # its 1-sigma (not measured)
    gnss_timeout_s: float = 1.5  # no accepted fix for this long (receive time): COASTING
    max_coast_s: float = 30.0  # beyond this, coasting position is no longer output
    # a dead-reckoned position's horizontal 1-sigma: COASTING up to coast_sigma_m (what DGNSS
    # gives), DEGRADED beyond, not sent beyond max_coast_sigma_m (SPEC 4's integrity rule)
    coast_sigma_m: float = 0.3
    max_coast_sigma_m: float = 2.0
    history_s: float = 5.0  # INS history kept for late epochs (a loaded host delays them)

    # --- GNSS measurement noise ---
    # the fix's position error (gateway/estimation/gnss_error.py, as the observer's position
    # channel): Gauss-Markov states for its wander plus a white share; sigma from GST, else
    # the quality's default scaled by HDOP and the age of corrections
    gnss_error_correlation_s: float = 60.0  # fix errors wander (multipath, atmosphere)
    gnss_white_share: float = 0.3  # share of a fix's sigma that is white epoch to epoch
    gnss_vel_sigma_mps: float = 0.02  # horizontal velocity 1-sigma with RTK fixed
    navigating_fix_qualities: tuple[int, ...] = (4,)  # other usable qualities: DEGRADED
    # NAVIGATING states the heading within this 1-sigma (the bus carries none); beyond: DEGRADED
    navigating_heading_sigma_deg: float = 0.5

    # --- gating and recovery ---
    gate_sigma: float = 5.0  # NIS gate: chi-square tail of a 5-sigma normal event per dof
    reset_outage_s: float = 30.0  # no accepted position this long: re-initialise from GNSS
    reset_rejections: int = 20  # or this many positions of a continuous GNSS track rejected
    position_reset_s: float = 60.0  # or rejected this long after a GNSS jump (it moved, reset)

    # --- land-vehicle pseudo-measurements ---
    nhc_sigma_mps: float = 0.05  # reference-point lateral/vertical body velocity 1-sigma
    nhc_interval_s: float = 0.1  # non-holonomic constraint fused this often (with the epochs)
    hdt_sigma_deg: float = 0.2  # dual-antenna heading 1-sigma

    # --- covariance propagation ---
    # the covariance is stepped at each GNSS epoch, and after this long without one (F
    # accumulated over the IMU samples of the interval): 1.5 epochs of a 10 Hz receiver
    covariance_period_s: float = 0.15

    # --- initial alignment ---
    align_quiet_rate_dps: float = 2.0  # |w| below this counts as still
    align_tilt_time_s: float = 1.0  # mean specific force over this long gives roll/pitch
    # first heading at this speed from the last second's courses over ground, slower once
    # the last seconds' give NAVIGATING's accuracy and the direction of travel is known
    align_min_speed_mps: float = 1.5
    # a course over ground is a heading measurement above this: the receiver's course hold
    # speed, as the observer's (1 m/s: a planter at 0.5-0.9 m/s gave the EKF none)
    cog_min_speed_mps: float = 0.5
    heading_gate_deg: float = 10.0  # a course this far off the latest one's is another drive
    align_vel_sigma_mps: float = 0.1  # velocity 1-sigma at alignment (lever arm, latency)

    # --- read-out ---
    stationary_speed_mps: float = 0.1  # reference-point speed below this ...
    stationary_rate_dps: float = 1.0  # ... and |w_b| below this: stationary
    reverse_detect_speed_mps: float = 0.3  # forward/reverse decided above this body speed
    gyro_xy_converged_dps: float = 0.005  # P 1-sigma for "gyro x/y bias converged"
    gyro_z_converged_dps: float = 0.02  # P 1-sigma for "gyro z bias converged"
    accel_xy_converged_mps2: float = 0.01  # P 1-sigma for "accel x/y bias converged"
    imu_fault_s: float = 1.0  # invalid or saturated IMU data for this long: FAULT


@dataclass(frozen=True)
class EkfTuning:
    """The config's noise figures in SI, as the filter uses them (continuous-time)."""

    q_gyro_rad2_per_s: float  # white rate noise PSD (rad/s)^2/Hz
    q_accel_m2_per_s3: float  # white accel noise PSD (m/s^2)^2/Hz
    q_bias_g_rad2_per_s3: float  # gyro bias random-walk PSD
    q_bias_a_m2_per_s5: float  # accel bias random-walk PSD
    sigma_bias_g0_rps: float
    sigma_bias_a0_mps2: float

    @classmethod
    def from_config(cls, cfg: EkfConfig, imu_dt_s: float) -> EkfTuning:
        """ARW/VRW -> PSD; vibration sigma^2 dt adds to it; bias stability -> Gauss-Markov.

        The in-run bias is the Gauss-Markov process of the datasheet (sigma = stability /
        0.6174, time constant T), driven by white noise of PSD 2 sigma^2 / T. The filter keeps
        the driving noise but not the decay towards zero: the turn-on part of the bias is
        constant and a decaying model would pull it back to zero between observations.
        """
        arw = cfg.gyro_arw_deg_per_sqrt_h * DEG_TO_RAD / SQRT_SECONDS_PER_HOUR
        vrw = cfg.accel_vrw_mps_per_sqrt_h / SQRT_SECONDS_PER_HOUR
        sig_g = cfg.gyro_bias_stability_dps * DEG_TO_RAD / GM_ALLAN_FLOOR
        sig_a = cfg.accel_bias_stability_mg * MG_MPS2 / GM_ALLAN_FLOOR
        tau = cfg.bias_correlation_time_s
        vib_g = vibration_per_sample(cfg.vibration_gyro_dps * DEG_TO_RAD, imu_dt_s)
        vib_a = vibration_per_sample(cfg.vibration_accel_mps2, imu_dt_s)
        return cls(
            q_gyro_rad2_per_s=arw**2 + vib_g**2 * imu_dt_s,
            q_accel_m2_per_s3=vrw**2 + vib_a**2 * imu_dt_s,
            q_bias_g_rad2_per_s3=2.0 * sig_g**2 / tau,
            q_bias_a_m2_per_s5=2.0 * sig_a**2 / tau,
            sigma_bias_g0_rps=cfg.gyro_bias_sigma0_dps * DEG_TO_RAD,
            sigma_bias_a0_mps2=cfg.accel_bias_sigma0_mps2,
        )
