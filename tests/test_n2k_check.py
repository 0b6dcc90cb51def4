"""The tests' own yardstick: frames against the truth (tests/n2k_check.py)."""

from __future__ import annotations

import math

import numpy as np

from drivers.units import wrap_pi
from sim_bus.truth import Truth
from tests.n2k_check import Decoded, attitude_errors_deg, tilt_off_deg


def _turning_through_south(n: int = 5, dt_s: float = 0.005) -> Truth:
    """A truth whose heading crosses +-180 deg between its 3rd and 4th samples (1 deg each)."""
    t = 100.0 + dt_s * np.arange(n, dtype=float)
    yaw = np.radians(177.5 + np.arange(n))  # 177.5 ... 181.5 deg
    rpy = np.column_stack([np.full(n, 0.01), np.full(n, -0.02), wrap_pi(yaw)])
    zeros = np.zeros((n, 3))
    return Truth(
        t=t, pos_ned_m=zeros, lla=zeros, vel_ned_mps=zeros, rpy_rad=rpy, w_ib_b=zeros,
        f_ib_b_imu=zeros, pos_ant_ned_m=zeros, lla_ant=zeros, vel_ant_ned_mps=zeros,
        reversing=np.zeros(n, bool), stationary=np.zeros(n, bool), bias_g_rps=zeros,
        bias_a_mps2=zeros,
    )  # fmt: skip


def test_a_frame_between_truth_samples_either_side_of_south_is_compared_with_south() -> None:
    # The live vcan test stamps frames at reception, between the truth's samples: interpolating
    # the wrapped yaw there put the truth near 0 deg and one exact frame 180 deg "off".
    truth = _turning_through_south()
    t = float(truth.t[2] + truth.t[3]) / 2  # truth 180 deg there
    sent: dict[str, object] = {"roll": 0.01, "pitch": -0.02, "yaw": math.radians(-180.0)}
    err = attitude_errors_deg([Decoded(t, 127257, "attitude", sent)], truth, after_s=0.0)
    assert err.shape == (1, 3)
    assert np.all(np.abs(err) < 1e-9), err
    # and a frame 2 deg to the other side of south reads 2 deg off, wrapped
    sent["yaw"] = math.radians(-178.0)  # 182 deg
    err = attitude_errors_deg([Decoded(t, 127257, "attitude", sent)], truth, after_s=0.0)
    assert abs(err[0, 2] - 2.0) < 1e-9, err


def test_a_tilt_sent_between_truth_samples_is_compared_with_the_truth_at_its_time() -> None:
    """A body pitching 40 deg/s (rough ground at 6 m/s): a frame 4 ms after a truth sample
    that is exact there reads 0 deg off, not the 0.16 deg of the sample before it; with a
    lag the nearest truth in the window counts, its ends included."""
    truth = _turning_through_south()
    pitch_rate = math.radians(40.0)
    truth.rpy_rad[:, 1] = pitch_rate * (truth.t - truth.t[0])
    t = float(truth.t[1]) + 0.004
    exact = pitch_rate * (t - float(truth.t[0]))
    roll_off, pitch_off = tilt_off_deg(truth, t, 0.0, 0.01, exact)
    assert roll_off < 1e-9 and pitch_off < 1e-9
    _, late = tilt_off_deg(truth, t, 0.0, 0.01, exact - pitch_rate * 0.003)
    assert abs(late - 0.12) < 1e-9  # 3 ms behind the truth at t: 0.12 deg off
    _, lagged = tilt_off_deg(truth, t, 0.003, 0.01, exact - pitch_rate * 0.003)
    assert lagged < 1e-9  # ... the truth 3 ms before t, within the lag
