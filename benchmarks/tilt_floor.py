"""Roll/pitch, heading and outage floors: a covariance analysis (issue 16).

What the best causal filter can do with this IMU (ADIS16334 datasheet, the simulator's engine
vibration) and an RTK receiver at 10 Hz, whatever its design; the engines' figures are
measured against these (docs/ACCURACY.md).

Tilt, one horizontal axis, steady state: states position p, velocity v, tilt theta and the
fix's position error b,

    p' = v,  v' = g theta + n_a,  theta' = n_g,  b' = -b / T_b + n_b,

measured at 10 Hz by the GNSS velocity (white) and position (p + b; RTK fixed 1 cm wandering
with 30 s, sim_bus/gnss_receiver.py). n_g is the gyro's ARW; n_a the accelerometer's VRW plus
the engine vibration's broadband part, sigma^2 dt per sample (the simulator's 0.15 m/s^2 at
204.8 Hz: 0.0105 m/s/sqrt(s), 16 times the datasheet's VRW and the largest term here). Biases
are taken as known: the floor is lower than any real filter's.

The observer's tilt loop has its own floor with the same noise (the loop's own figures,
gateway/estimation/observer/tilt_loop.py): seed 000's first order at tau = 4 s, ARW
sqrt(tau / 2) from the gyro, sigma_v / (g tau) from the GNSS velocity (e is a velocity
difference: its integral telescopes), sqrt(q_a / (2 tau)) / g from the accelerometer (e's mean
f_p is a velocity random walk over each epoch, filtered by the loop); the product's second
order at the tau it takes for this noise, ARW sqrt(5 tau / 8), the velocity's times
sqrt(2 T / tau), the accelerometer's the same.

Heading: the same filter on the course over ground (sigma_v / u at speed u) and the z gyro's
ARW; at the end of an outage of T s the cross-track 1-sigma is
sqrt((u T sigma_psi)^2 + u^2 ARW^2 T^3 / 3) (the heading at the start, then its random walk).

Cold start: before the first turn a turn-on accelerometer bias b and a tilt b / g give the same
specific force; nothing separates them, so the tilt is off by the bias's 1-sigma over g
(the simulator's 5 mg: 0.29 deg) until the vehicle turns, or a warm start knows the bias.

    .venv/bin/python benchmarks/tilt_floor.py
"""

from __future__ import annotations

import math

import numpy as np

from drivers.units import DEG_TO_RAD, GRAVITY_MPS2, MG_MPS2, SQRT_SECONDS_PER_HOUR
from gateway.estimation.observer.observer_config import ObserverConfig
from gateway.estimation.observer.tilt_loop import TiltLoop

EPOCH_S = 0.1  # 10 Hz receiver
IMU_DT_S = 4.0 / 819.2  # 204.8 Hz
ARW_RAD_PER_SQRT_S = 2.0 * DEG_TO_RAD / SQRT_SECONDS_PER_HOUR  # ADIS16334
VRW_MPS_PER_SQRT_S = 0.12 / SQRT_SECONDS_PER_HOUR
VIBRATION_MPS2 = 0.15  # sim_bus.adis16334.EngineVibration broadband, 1-sigma per sample
VEL_SIGMA_MPS = 0.02  # RTK fixed, per horizontal axis (sim_bus.gnss_receiver.DEFAULT_NOISE)
POS_SIGMA_M = 0.01
POS_TAU_S = 30.0
TURN_ON_BIAS_MPS2 = 5.0 * MG_MPS2  # sim_bus.adis16334: turn-on sigma after nulling
TAU_OBSERVER_S = 4.0  # seed 000, section 4


def steady_state(f: np.ndarray, q: np.ndarray, h: np.ndarray, r: np.ndarray) -> np.ndarray:
    """Posterior covariance of the Kalman filter (f, q, h, r) in its steady state."""
    p = np.eye(len(f))
    for _ in range(200_000):
        prior = f @ p @ f.T + q
        k = prior @ h.T @ np.linalg.inv(h @ prior @ h.T + r)
        post = prior - k @ h @ prior
        if np.allclose(post, p, rtol=1e-10, atol=1e-16):
            return np.asarray(post)
        p = post
    raise RuntimeError("no steady state")


def accel_psd(vibration_mps2: float) -> float:
    """White accelerometer noise PSD, (m/s^2)^2/Hz: VRW^2 plus sigma^2 dt of vibration."""
    return VRW_MPS_PER_SQRT_S**2 + vibration_mps2**2 * IMU_DT_S


def tilt_floor_rad(vibration_mps2: float, positions: bool) -> float:
    """Steady-state tilt 1-sigma of the best filter, one axis (module docstring)."""
    t, g = EPOCH_S, GRAVITY_MPS2
    decay = math.exp(-t / POS_TAU_S)
    # exact discretisation of p' = v, v' = g theta, theta' = n_g with white n_a, n_g
    f = np.array(
        [[1.0, t, g * t * t / 2, 0.0], [0.0, 1.0, g * t, 0.0], [0.0, 0.0, 1.0, 0.0],
         [0.0, 0.0, 0.0, decay]]
    )  # fmt: skip
    qa, qg = accel_psd(vibration_mps2), ARW_RAD_PER_SQRT_S**2
    q = np.zeros((4, 4))
    q[:2, :2] = qa * np.array([[t**3 / 3, t**2 / 2], [t**2 / 2, t]])
    q[:3, :3] += qg * np.array(
        [[g * g * t**5 / 20, g * g * t**4 / 8, g * t**3 / 6],
         [g * g * t**4 / 8, g * g * t**3 / 3, g * t**2 / 2],
         [g * t**3 / 6, g * t**2 / 2, t]]
    )  # fmt: skip
    q[3, 3] = POS_SIGMA_M**2 * (1.0 - decay * decay)
    if positions:
        h = np.array([[0.0, 1.0, 0.0, 0.0], [1.0, 0.0, 0.0, 1.0]])
        r = np.diag([VEL_SIGMA_MPS**2, 1e-10])  # the fix's error is all wander (simulator)
        return math.sqrt(steady_state(f, q, h, r)[2, 2])
    vt = np.ix_([1, 2], [1, 2])  # velocity and tilt alone (position unobserved)
    h = np.array([[1.0, 0.0]])
    return math.sqrt(steady_state(f[vt], q[vt], h, np.array([[VEL_SIGMA_MPS**2]]))[1, 1])


def observer_loop_floor_rad(vibration_mps2: float, second_order: bool) -> tuple[float, float]:
    """Tilt 1-sigma of the observer's loop and its tau, s: seed 000's first order at
    ``TAU_OBSERVER_S``, or the product's second order at the tau it takes for this noise."""
    loop = TiltLoop(ObserverConfig().tau_s if second_order else TAU_OBSERVER_S, second_order)
    loop.set_imu_noise(ARW_RAD_PER_SQRT_S, accel_psd(vibration_mps2))
    loop.control((0.0, 0.0), EPOCH_S, EPOCH_S, VEL_SIGMA_MPS)
    var = loop.noise_tilt_var() + loop.velocity_tilt_sigma(VEL_SIGMA_MPS, EPOCH_S) ** 2
    return math.sqrt(var), loop.tau_now_s


def heading_floor_rad(speed_mps: float) -> float:
    """Steady-state heading 1-sigma from the course over ground and the z gyro."""
    f = np.eye(1)
    q = np.array([[ARW_RAD_PER_SQRT_S**2 * EPOCH_S]])
    r = np.array([[(VEL_SIGMA_MPS / speed_mps) ** 2]])
    return math.sqrt(steady_state(f, q, np.eye(1), r)[0, 0])


def outage_end_cross_track_m(speed_mps: float, outage_s: float) -> float:
    """Cross-track 1-sigma at the end of an outage, from the heading floor and the ARW."""
    psi0 = heading_floor_rad(speed_mps)
    u, t = speed_mps, outage_s
    return math.sqrt((u * t * psi0) ** 2 + u * u * ARW_RAD_PER_SQRT_S**2 * t**3 / 3)


def main() -> None:
    deg = 1.0 / DEG_TO_RAD
    print("Roll/pitch 1-sigma floor, deg (RTK fixed, 10 Hz, biases known):\n")
    print(
        "| accelerometer noise | best filter, velocity + position | velocity only "
        f"| seed 000's first-order loop (tau {TAU_OBSERVER_S:g} s) | second-order loop (its tau) |"
    )
    print("|---|---|---|---|---|")
    rows = (
        ("datasheet VRW only", 0.0),
        (f"+ vibration {VIBRATION_MPS2:g} m/s^2 per sample", VIBRATION_MPS2),
    )
    for label, vib in rows:
        first, _ = observer_loop_floor_rad(vib, second_order=False)
        second, tau = observer_loop_floor_rad(vib, second_order=True)
        print(
            f"| {label} | {tilt_floor_rad(vib, True) * deg:.3f} | "
            f"{tilt_floor_rad(vib, False) * deg:.3f} | {first * deg:.3f} | "
            f"{second * deg:.3f} ({tau:.1f} s) |"
        )
    print("\nHeading floor and cross-track 1-sigma at the end of an outage:\n")
    print("| speed m/s | heading deg | 20 s outage cm | 60 s outage cm |")
    print("|---|---|---|---|")
    for u in (2.0, 3.0, 4.0):
        print(
            f"| {u:g} | {heading_floor_rad(u) * deg:.3f} | "
            f"{100 * outage_end_cross_track_m(u, 20.0):.1f} | "
            f"{100 * outage_end_cross_track_m(u, 60.0):.1f} |"
        )
    print(
        "\nCold start, before the first turn: tilt 1-sigma = turn-on bias / g = "
        f"{TURN_ON_BIAS_MPS2 / GRAVITY_MPS2 * deg:.2f} deg "
        f"(bias {TURN_ON_BIAS_MPS2 / MG_MPS2:g} mg)"
    )
    print("command: .venv/bin/python benchmarks/tilt_floor.py")


if __name__ == "__main__":
    main()
