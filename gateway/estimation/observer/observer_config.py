"""Parameters of the observer engine: paper values (seed 000, seed 001) and product choices.

Field names are snake_case and carry their unit so that the TOML keys read the same; degrees
appear only here (the engine converts to SI once). Lever arms are body FRD, metres, relative
to the vehicle reference point (SPEC 5).
"""

from __future__ import annotations

from dataclasses import dataclass

from gateway.estimation.epoch_clock import RECEIVE_EPOCH_SIGMA_S, EpochTime

Vec3Tuple = tuple[float, float, float]


@dataclass(frozen=True)
class ObserverConfig:
    """Everything :class:`gateway.estimation.observer.observer_engine.ObserverEngine` can be tuned
    with."""

    # --- Tereshkov observer (seed 000, section 4 values) ---
    tau_s: float = 2.0  # tilt time constant tau = 1/(k g), s; second order: the shortest
    # e low-passed over tau / 4 before eq. (3) applies it: a critically damped second-order
    # loop that passes less GNSS velocity noise, its tau the least-noise one for the IMU and
    # each fix, tau_s to 4 tau_s (the product's extension: tilt_loop.py, docs/ACCURACY.md);
    # false, with tau_s = 4: the paper's loop
    second_order_tilt_loop: bool = True
    tau_g_s: float = 40.0  # gyro bias observer time constant, eq. (11)
    omega_a_dps: float = 45.0  # accelerometer bias observer rate constant, eq. (12)
    estimate_biases: bool = True  # False: the "observer without bias estimation" baseline
    # x/y accelerometer biases from a Kalman filter on the tilt loop's residual, not eq. (12):
    # the product's extension (docs/ACCURACY.md); false: the paper's eq. (12)
    accel_bias_filter: bool = True

    # --- vehicle geometry (SPEC 5) ---
    antenna_lever_arm_m: Vec3Tuple = (0.0, 0.0, 0.0)  # antenna rel. reference point, body
    imu_lever_arm_m: Vec3Tuple = (0.0, 0.0, 0.0)  # IMU rel. reference point, body
    # roll/pitch 1-sigma of the IMU mounting, deg: added to the stated tilt accuracy
    imu_mounting_sigma_deg: float = 0.0

    # --- GNSS timing ---
    epoch_time: EpochTime = EpochTime.AUTO  # how epochs are placed on the host clock
    receiver_latency_s: float = 0.0  # least delay from an epoch to its last sentence's receipt
    receiver_latency_sigma_s: float = RECEIVE_EPOCH_SIGMA_S  # its 1-sigma (not measured)
    gnss_timeout_s: float = 1.5  # no usable velocity for this long (receive time): COASTING
    max_gnss_interval_s: float = 1.2  # epochs further apart are not differenced (1 Hz fits)
    max_coast_s: float = 30.0  # beyond this, coasting position is no longer output
    # a dead-reckoned position's horizontal 1-sigma: COASTING up to coast_sigma_m (what DGNSS
    # gives), DEGRADED beyond, not sent beyond max_coast_sigma_m (SPEC 4's integrity rule)
    coast_sigma_m: float = 0.3
    max_coast_sigma_m: float = 2.0
    gnss_vel_sigma_mps: float = 0.02  # horizontal velocity 1-sigma (RTK carrier-phase Doppler)
    # receivers hold their course over ground below some speed (u-blox: 0.1 m/s; static hold
    # and low-speed course filters further up): below this, once the heading is known, the
    # speed is taken along body x, forward or reversing as the inertial velocity says
    course_hold_speed_mps: float = 0.5
    # the reference point's lateral/vertical body velocity 1-sigma per 0.1 s while coasting
    # (sideslip, bounce): the wheeled-vehicle constraint holds roll with the tilt loop's tau
    # for it (ground_constraint.py); the EKF's nhc_sigma_mps
    ground_sigma_mps: float = 0.05

    # --- IMU noise (ADIS16334 datasheet): roll/pitch sigma, heading gain, bias at rest ---
    gyro_arw_deg_per_sqrt_h: float = 2.0  # gyro angular random walk
    accel_vrw_mps_per_sqrt_h: float = 0.12  # accelerometer velocity random walk
    # in-run bias wander (the accel-bias filter's process noise; [imu], as the EKF's)
    gyro_bias_stability_dps: float = 0.007  # in-run bias stability (Allan floor)
    accel_bias_stability_mg: float = 0.1  # in-run bias stability (Allan floor)
    bias_correlation_time_s: float = 100.0  # Gauss-Markov time of the in-run bias
    # the biases' temperature coefficients (datasheet, 1-sigma; [imu], as the EKF's): the
    # temperature's rate adds to the wander (gateway/estimation/temperature.py)
    gyro_bias_tempco_dps_per_c: float = 0.01
    accel_bias_tempco_mg_per_c: float = 0.1
    # Engine vibration seen by the IMU (installation): broadband 1-sigma per sample at
    # 204.8 Hz (its density kept at other rates), as [ekf]'s; the stated accuracy holds for
    # it, and grows with the noise measured at rest where that is beyond it
    # (gateway/estimation/imu_noise.py)
    vibration_gyro_dps: float = 0.05
    vibration_accel_mps2: float = 0.2

    # --- learning gates ---
    learning_fix_qualities: tuple[int, ...] = (2, 4, 5)  # GGA DGNSS, RTK fixed, RTK float
    navigating_fix_qualities: tuple[int, ...] = (4,)  # other usable qualities: DEGRADED
    # NAVIGATING states the heading within this 1-sigma (the bus carries none); beyond: DEGRADED
    navigating_heading_sigma_deg: float = 0.5
    # a GNSS glitch: the velocity change over an epoch interval T disagrees with the
    # platform's by more than glitch_sigma of the white GNSS velocity noise plus e_gate T
    glitch_sigma: float = 5.0  # Rayleigh tail exp(-25/2): 4e-6 false alarms per epoch
    e_gate_mps2: float = 1.0  # specific-force mismatch beyond noise: tilt at start, vibration
    glitch_persist_s: float = 5.0  # glitches this long mean a tilted platform: e used, clipped
    learning_holdoff_s: float = 8.0  # learning stays frozen this long after any gate (2 tau)
    stationary_speed_mps: float = 0.1  # reference-point speed below this ...
    stationary_rate_dps: float = 1.0  # ... and |w_b| below this: stationary

    # --- initial alignment ---
    align_quiet_rate_dps: float = 2.0  # |w| below this counts as straight or still
    align_tilt_time_s: float = 1.0  # mean specific force over this long gives roll/pitch
    # first heading at this speed from the last second's courses over ground, slower once
    # the last seconds' give NAVIGATING's accuracy and the direction of travel is known
    align_min_speed_mps: float = 1.5

    # --- heading channel (ALGORITHMS.md 2, seed 001) ---
    # course over ground is a heading reference above this (weighed by its sigma, 2 cm/s
    # over the speed): the receiver's course hold speed (a 1 m/s crawl on the gyro alone
    # drifted with the z bias's error, 1.7 deg off after a wander with 1 Hz fixes)
    cog_min_speed_mps: float = 0.5
    reverse_detect_speed_mps: float = 0.3  # forward/reverse decided above this speed
    heading_gate_deg: float = 10.0  # larger heading residuals are rejected (glitch)
    heading_realign_s: float = 5.0  # after this long of rejected residuals, realign
    hdt_sigma_deg: float = 0.2  # dual-antenna heading 1-sigma
    ab_line_bearing_deg: float | None = None  # guidance line bearing, true, if known
    ab_line_window_deg: float = 3.0  # heading within this of the line (either direction) ...
    ab_line_max_rate_dps: float = 0.5  # ... with yaw rate below this ...
    ab_line_min_time_s: float = 5.0  # ... for this long: the line is a heading reference
    ab_line_sigma_deg: float = 0.5  # how well the driver/autosteer holds the line bearing
    gyro_z_window_s: float = 5.0  # heading residual interval of one bias observation
    gyro_z_bias_sigma0_dps: float = 0.3  # initial z-gyro bias 1-sigma (KF P0)

    # --- reference-point propagation ---
    # position channel (position_channel.py): each fix weighed by its sigma (GST, else the
    # quality's default scaled by HDOP and age of corrections) against dead reckoning
    gnss_error_correlation_s: float = 60.0  # fix errors wander (multipath, atmosphere)
    gnss_white_share: float = 0.3  # share of a fix's sigma that is white epoch to epoch
    # error of a fix's reference-point velocity besides its own sigma and the antenna lever
    # arm's rate noise (0.8 cm/s on a 3 m mast): latency (10 ms at 1 m/s^2), attitude in the
    # lever arm; weighed against the inertial velocity in the position channel
    dr_velocity_floor_mps: float = 0.01
    # a position innovation beyond glitch_sigma x its 1-sigma (the fix's, GST or the
    # quality's default, and the dead reckoning's) plus position_gate_m is a glitch: rejected,
    # dead reckoning meanwhile. The floor is what the channel does not model: lever arm and
    # attitude (1 deg on a 3 m mast at the start: 5 cm) and epoch timing (20 ms at 4 m/s:
    # 8 cm); the largest innovation of a working system on the robustness variants and
    # scenarios was 7.6 cm, at the heading's alignment. An RTK fix 0.3 m off (a wrong
    # ambiguity, multipath under a tree line) is beyond it; with 0.5 m it was followed.
    position_gate_m: float = 0.1
    reset_rejections: int = 20  # positions of a continuous GNSS track rejected: reset to it
    position_reset_s: float = 60.0  # rejected this long after a GNSS jump: it moved, reset

    # --- convergence flags and roll/pitch sigma ---
    gyro_bias_sigma0_dps: float = 0.3  # x/y gyro bias 1-sigma before learning
    accel_bias_sigma0_mps2: float = 0.1  # x/y (and z) accel bias 1-sigma before learning
    # z accel bias: the height loop's mean vertical correction, low-passed over this long
    # (RTK fixed heights only; far below the loop's bandwidth, above the bias's wander)
    accel_bias_z_tau_s: float = 60.0
    converged_time_constants: float = 3.0  # learning exponent for "converged" (e^-3 = 5 %)
    gyro_z_converged_dps: float = 0.02  # KF 1-sigma for "z gyro bias converged"
    imu_fault_s: float = 1.0  # invalid or saturated IMU data for this long: FAULT
