"""The stop's mean specific force (gateway.estimation.observer.rest_window): its noise, its
lag before a drive-off, and the restarts when GNSS or the gyro say the vehicle moved."""

from __future__ import annotations

import math

import numpy as np
import pytest

from drivers.units import DEG_TO_RAD, GRAVITY_MPS2
from gateway.estimation.observer.rest_window import (
    CREEP_M,
    LAG_S,
    SETTLE_S,
    RestLevel,
    RestWindow,
)

ARW_RPS_PER_SQRT_S = 2.0 * DEG_TO_RAD / 60.0  # ADIS16334: 2 deg/sqrt(h)
RATE_HZ, EPOCH_HZ = 204.8, 10.0
PER_EPOCH = round(RATE_HZ / EPOCH_HZ)
F_B = (0.3, -0.5, -GRAVITY_MPS2)  # about 3 deg of pitch and roll
VIBRATION_MPS2 = 0.26  # per sample, as the simulator's engine gives


class Stop:
    """Feeds a RestWindow epoch by epoch: the mean of an epoch's samples of f_b with
    vibration, a body rotation integral and a GNSS velocity."""

    def __init__(self, seed: int = 1) -> None:
        self.window = RestWindow(ARW_RPS_PER_SQRT_S)
        self.rng = np.random.default_rng(seed)
        self.t = 0.0
        self.rotation = np.zeros(2)

    def epoch(
        self,
        f_b: tuple[float, float, float] = F_B,
        rate_xy_rps: tuple[float, float] = (0.0, 0.0),
        v_ne_mps: tuple[float, float] = (0.0, 0.0),
    ) -> RestLevel | None:
        dt = 1.0 / EPOCH_HZ
        f = np.asarray(f_b) + VIBRATION_MPS2 * self.rng.standard_normal((PER_EPOCH, 3))
        mean = f.mean(axis=0)
        self.t += dt
        noise = ARW_RPS_PER_SQRT_S * math.sqrt(dt) * self.rng.standard_normal(2)
        self.rotation += np.asarray(rate_xy_rps) * dt + noise
        rot = (float(self.rotation[0]), float(self.rotation[1]))
        f_mean = (float(mean[0]), float(mean[1]), float(mean[2]))
        return self.window.epoch(self.t, self.t, f_mean, rot, v_ne_mps)

    def stand(self, seconds: float, **kw: object) -> list[RestLevel | None]:
        return [self.epoch(**kw) for _ in range(round(seconds * EPOCH_HZ))]  # type: ignore[arg-type]


def test_the_mean_comes_after_the_settling_and_its_sigma_falls_as_one_over_root_n() -> None:
    stop = Stop()
    levels = stop.stand(20.0)
    first = next(i for i, lv in enumerate(levels) if lv is not None) / EPOCH_HZ
    assert first == pytest.approx(SETTLE_S + LAG_S + 0.2, abs=0.15)  # and two epochs' means
    last = levels[-1]
    assert last is not None
    n = (20.0 - SETTLE_S - LAG_S - 0.1) * RATE_HZ
    sigma = VIBRATION_MPS2 / math.sqrt(n) / GRAVITY_MPS2
    assert last.sigma_tilt_rad == pytest.approx(sigma, rel=0.1)
    tol = 4 * VIBRATION_MPS2 / math.sqrt(n)
    assert np.asarray(last.f_b_mps2) == pytest.approx(np.asarray(F_B), abs=tol)


def test_a_mean_of_few_epochs_states_at_least_the_white_noise_in_it() -> None:
    """Two epochs' means that happen to agree (a spread of two is chi-square with one
    degree of freedom: near zero one time in four) say nothing of the noise: the sigma is
    never below the white noise's in a mean over the window, sqrt(q_a / T) / g, 0.18 deg
    after 0.2 s with the ADIS16334 and the simulator's vibration. It said 0.04 deg there,
    and the observer levelled on it, 0.3 deg off on a 9 deg slope."""
    q_a = (VIBRATION_MPS2**2) / RATE_HZ  # m^2/s^3: white noise of VIBRATION_MPS2 a sample
    window = RestWindow(ARW_RPS_PER_SQRT_S, q_a)
    dt = 1.0 / EPOCH_HZ
    levels = [
        window.epoch(k * dt, k * dt, F_B, (0.0, 0.0), (0.0, 0.0))
        for k in range(1, round((SETTLE_S + LAG_S) * EPOCH_HZ) + 6)
    ]
    first = next(lv for lv in levels if lv is not None)  # the first mean: two epochs, 0.2 s
    assert first.sigma_tilt_rad == pytest.approx(math.sqrt(q_a / 0.2) / GRAVITY_MPS2, rel=0.01)
    assert math.degrees(first.sigma_tilt_rad) > 0.15


def test_a_stop_with_no_motion_is_never_restarted() -> None:
    """The rotation test's false alarms: 60 s of a stop, ARW only, for ten seeds."""
    for seed in range(10):
        levels = Stop(seed).stand(60.0)[30:]
        assert all(lv is not None for lv in levels), seed


def test_the_last_half_second_before_a_drive_off_is_not_in_the_mean() -> None:
    """A drive-off shows in GNSS speed late: the first 0.4 s of 1 m/s^2 forward are not
    averaged in (it would tilt a 3 s mean by 0.1 m/s^2 x 0.4 / 3: 0.08 deg)."""
    stop = Stop()
    before = stop.stand(5.0)[-1]
    pulling = (F_B[0] + 1.0, F_B[1], F_B[2])
    during = stop.stand(0.4, f_b=pulling)[-1]
    assert before is not None and during is not None
    assert during.f_b_mps2[0] == pytest.approx(before.f_b_mps2[0], abs=0.015)


def test_the_body_turning_while_standing_restarts_the_mean() -> None:
    """A hitch lifting an implement pitches the body by 0.5 deg in 2 s: the mean of the
    attitude before would be 0.4 deg off; the gyro ends the window and the new mean holds only
    the new attitude."""
    stop = Stop()
    stop.stand(15.0)
    pitch_rate = 0.25 * DEG_TO_RAD
    d_pitch = 0.5 * DEG_TO_RAD
    f_after = (F_B[0] - GRAVITY_MPS2 * d_pitch, F_B[1], F_B[2])  # f_x = g sin(pitch)
    turning = stop.stand(2.0, rate_xy_rps=(0.0, pitch_rate), f_b=f_after)
    assert any(lv is None for lv in turning)
    after = stop.stand(10.0, f_b=f_after)[-1]
    assert after is not None
    assert after.f_b_mps2[0] == pytest.approx(f_after[0], abs=0.004)  # 0.02 deg


def test_creeping_restarts_the_mean_before_it_has_moved_much() -> None:
    """0.05 m/s forward is a stop for the speed test (0.1 m/s) but climbs bumps: the window
    ends each time the integrated GNSS velocity reaches CREEP_M (2 s here), so a mean is
    given for at most the second of it that is older than the lag, never for long."""
    levels = Stop().stand(30.0, v_ne_mps=(0.05, 0.0))
    runs, run = [], 0
    for lv in levels:
        run = run + 1 if lv is not None else 0
        runs.append(run)
    assert 0 < max(runs) <= (CREEP_M / 0.05 - LAG_S) * EPOCH_HZ
