"""Vehicle simulator truth: self-consistency of attitude, rates, velocity, position and specific
force, lever arms, reversing and rest rows, and the shape of the built-in presets."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy.spatial.transform import Rotation

from gateway.estimation.geodesy import lla_to_ned
from sim_bus.truth import Truth
from sim_bus.vehicle import VEHICLE_PRESETS, simulate_vehicle

G_NED = np.array([0.0, 0.0, 9.80665])
T0_S = 1_700_000_000.0
COARSE_DT_S = 0.05  # long presets sampled coarsely to keep the file fast


def c_bn_of(truth: Truth) -> np.ndarray:
    """C_bn (n, 3, 3) from the truth attitude, computed independently with scipy (ZYX)."""
    return Rotation.from_euler("ZYX", truth.rpy_rad[:, ::-1]).as_matrix()


@pytest.fixture(scope="module")
def short() -> Truth:
    return simulate_vehicle(VEHICLE_PRESETS["short"], T0_S, seed=7)


LIFTING = dataclasses.replace(
    VEHICLE_PRESETS["short"], chassis_pitch_deg=0.5, implement_lift_deg=1.0
)


@pytest.fixture(scope="module")
def lifting() -> Truth:
    """``short`` with the chassis pitched 0.5 deg on its tyres, 1 deg more over headlands."""
    return simulate_vehicle(LIFTING, T0_S, seed=7)


@pytest.fixture(params=["short", "lifting"])
def drive(request: pytest.FixtureRequest) -> Truth:
    """Each of the two runs (the self-consistency checks hold for both)."""
    truth: Truth = request.getfixturevalue(request.param)
    return truth


@pytest.fixture(scope="module")
def reversing() -> Truth:
    return simulate_vehicle(VEHICLE_PRESETS["headland-reversing"], T0_S, COARSE_DT_S, seed=2)


def passes(truth: Truth, swath_heading_deg: float) -> list[np.ndarray]:
    """Row indices of each pass: moving with heading within 5 deg of the swath line."""
    off = np.angle(np.exp(1j * (truth.rpy_rad[:, 2] - np.radians(swath_heading_deg))))
    label = np.where(np.abs(off) < np.radians(5), 1, np.where(np.abs(off) > np.radians(175), -1, 0))
    label[truth.stationary] = 0
    edges = np.flatnonzero(np.diff(label)) + 1
    runs = np.split(np.arange(len(truth)), edges)
    return [r for r in runs if label[r[0]] != 0 and len(r) * truth.dt_s > 5.0]


def test_short_preset_shape(short: Truth) -> None:
    duration = short.t[-1] - short.t[0]
    assert 100.0 < duration < 150.0
    assert_allclose(np.diff(short.t), 4.0 / 819.2, rtol=1e-6)
    assert short.t[0] == T0_S
    start_rest = np.argmin(short.stationary) * short.dt_s
    assert start_rest >= 30.0
    runs = passes(short, 0.0)
    assert len(runs) == 3  # a straight per pass, two U-turns between them
    east_m = [np.mean(short.pos_ned_m[r, 1]) for r in runs]  # passes head north, turn right
    assert_allclose(east_m, [0.0, 18.0, 36.0], atol=0.05)  # swath spacing; bumps nothing else
    assert not np.any(short.bias_g_rps) and not np.any(short.bias_a_mps2)


def test_body_rate_integrates_to_attitude(drive: Truth) -> None:
    """Exponential map of the trapezoid-mean rate per step: < 0.001 deg after 2 min."""
    w = drive.w_ib_b
    steps = Rotation.from_rotvec(0.5 * drive.dt_s * (w[1:] + w[:-1]))
    c = Rotation.from_matrix(c_bn_of(drive)[0])
    integrated = [c]
    for step in steps:
        c = c * step
        integrated.append(c)
    error = Rotation.concatenate(integrated).inv() * Rotation.from_matrix(c_bn_of(drive))
    assert np.degrees(error.magnitude().max()) < 1e-3


def test_velocity_integrates_to_position(drive: Truth) -> None:
    """Trapezoid integration of vel_ned_mps from the first position: < 0.1 mm after 2 min."""
    v = drive.vel_ned_mps
    steps = 0.5 * drive.dt_s * (v[1:] + v[:-1])
    pos = drive.pos_ned_m[0] + np.concatenate((np.zeros((1, 3)), np.cumsum(steps, axis=0)))
    assert np.abs(pos - drive.pos_ned_m).max() < 1e-4


def test_specific_force_is_imu_acceleration_minus_gravity(drive: Truth) -> None:
    """C_bn f_ib_b_imu + g equals the central second difference of the IMU position."""
    c_bn = c_bn_of(drive)
    p_imu = drive.pos_ned_m + c_bn @ drive.imu_lever_arm_m
    a_num = (p_imu[2:] - 2.0 * p_imu[1:-1] + p_imu[:-2]) / drive.dt_s**2
    a_truth = np.einsum("nij,nj->ni", c_bn, drive.f_ib_b_imu) + G_NED
    assert np.abs(a_num - a_truth[1:-1]).max() < 2e-3  # m/s^2; dt^2 terms and rounding
    assert np.abs(a_truth).max() > 1.0  # the check is not vacuous: turns and bumps


def test_antenna_position_and_velocity_include_lever_arm(drive: Truth) -> None:
    c_bn = c_bn_of(drive)
    assert_allclose(
        drive.pos_ant_ned_m, drive.pos_ned_m + c_bn @ drive.antenna_lever_arm_m, atol=1e-9
    )
    v_num = (drive.pos_ant_ned_m[2:] - drive.pos_ant_ned_m[:-2]) / (2.0 * drive.dt_s)
    assert np.abs(v_num - drive.vel_ant_ned_mps[1:-1]).max() < 1e-4
    lever_speed = np.linalg.norm(drive.vel_ant_ned_mps - drive.vel_ned_mps, axis=1)
    assert lever_speed.max() > 0.1  # roll rates on bumps move a 3 m mast by > 10 cm/s
    assert_allclose(lla_to_ned(drive.lla, drive.origin_lla), drive.pos_ned_m, atol=1e-6)
    assert_allclose(lla_to_ned(drive.lla_ant, drive.origin_lla), drive.pos_ant_ned_m, atol=1e-6)


def test_the_chassis_pitches_against_its_track_and_steps_over_headlands(
    short: Truth, lifting: Truth
) -> None:
    """The track is the terrain's either way; the body is pitched about its own y axis by
    0.5 deg working and 1.5 deg from the end of each pass to the start of the next, so the
    reference point moves along body x at tan(-pitch against the track) (FRD: a nose-up
    chassis on level track sees its velocity below body x)."""
    assert_allclose(lifting.pos_ned_m, short.pos_ned_m, atol=1e-12)
    v_b = np.einsum("nji,nj->ni", c_bn_of(lifting), lifting.vel_ned_mps)
    moving = np.abs(v_b[:, 0]) > 0.5
    c_deg = np.degrees(np.arctan2(v_b[moving, 2], v_b[moving, 0]))
    on_pass = np.zeros(len(lifting), dtype=bool)
    for r in passes(lifting, 0.0):
        on_pass[r[615:-615]] = True  # 3 s clear of the pass ends, where the hitch moves
    assert_allclose(c_deg[on_pass[moving]], 0.5, atol=1e-9)
    headland = ~on_pass[moving]
    assert np.isclose(c_deg[headland], 1.5, atol=1e-9).sum() > 0.5 * headland.sum()
    assert c_deg.min() > 0.5 - 1e-9 and c_deg.max() < 1.5 + 1e-9


def test_body_z_is_the_terrain_normal(short: Truth) -> None:
    terrain = VEHICLE_PRESETS["short"].terrain(seed=7).derivatives(short.pos_ned_m[:, :2])
    normal = np.column_stack((terrain.grad, np.ones(len(short))))
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    assert_allclose(c_bn_of(short)[:, :, 2], normal, atol=1e-12)
    assert_allclose(-short.pos_ned_m[:, 2], terrain.h_m, atol=1e-12)


def test_yaw_rate_is_continuous_and_acceleration_limited(short: Truth) -> None:
    assert np.abs(np.diff(short.w_ib_b[:, 2])).max() < 0.005  # rad/s per sample: no steps
    c_bn = c_bn_of(short)
    a_ref = np.einsum("nij,nj->ni", c_bn, short.f_ib_b_imu) + G_NED  # at the IMU: with lever
    speed = np.linalg.norm(short.vel_ned_mps[:, :2], axis=1)
    along = np.gradient(speed, short.dt_s)
    assert np.abs(along).max() < VEHICLE_PRESETS["short"].accel_max_mps2 + 1e-3
    assert np.abs(a_ref[:, :2]).max() < 3.0


def test_stationary_rows_are_at_rest(short: Truth, reversing: Truth) -> None:
    for truth in (short, reversing):
        rest = truth.stationary
        assert rest.sum() * truth.dt_s > 30.0
        assert np.abs(truth.vel_ned_mps[rest]).max() < 1e-12
        assert np.abs(truth.vel_ant_ned_mps[rest]).max() < 1e-12
        assert np.abs(truth.w_ib_b[rest]).max() < 1e-12
        f_rest = -np.einsum("nji,j->ni", c_bn_of(truth)[rest], G_NED)
        assert_allclose(truth.f_ib_b_imu[rest], f_rest, atol=1e-12)
        assert not np.any(truth.reversing & rest)


def test_reversing_rows_move_against_body_x(reversing: Truth) -> None:
    rows = reversing.reversing
    assert rows.sum() * reversing.dt_s > 40.0  # five fishtails, ~12 m each at 1 m/s
    cfg = VEHICLE_PRESETS["headland-reversing"]
    cross = np.radians(cfg.swath_heading_deg + 90.0)
    runs = passes(reversing, cfg.swath_heading_deg)
    offsets = [np.mean(reversing.pos_ned_m[r, :2] @ [np.cos(cross), np.sin(cross)]) for r in runs]
    assert_allclose(np.diff(offsets), cfg.swath_spacing_m, atol=0.05)
    x_b = c_bn_of(reversing)[rows][:, :, 0]
    v = reversing.vel_ned_mps[rows]
    moving = np.linalg.norm(v, axis=1) > 1e-3
    cos_angle = np.sum(x_b * v, axis=1)[moving] / np.linalg.norm(v[moving], axis=1)
    assert_allclose(cos_angle, -1.0, atol=1e-9)
    forward = ~rows & ~reversing.stationary
    v_f = reversing.vel_ned_mps[forward]
    cos_f = np.sum(c_bn_of(reversing)[forward][:, :, 0] * v_f, axis=1)
    assert np.all(cos_f >= 0.0)


def test_hillside_roll_alternates_between_passes() -> None:
    cfg = VEHICLE_PRESETS["hillside"]
    truth = simulate_vehicle(cfg, T0_S, COARSE_DT_S, seed=1)
    runs = passes(truth, cfg.swath_heading_deg)
    assert len(runs) == cfg.n_passes
    roll_deg = np.array([np.degrees(np.median(truth.rpy_rad[r, 0])) for r in runs])
    assert np.all(np.sign(roll_deg[1:]) == -np.sign(roll_deg[:-1]))
    assert np.all(
        (np.abs(roll_deg) > cfg.side_slope_min_deg - 0.5)
        & (np.abs(roll_deg) < cfg.side_slope_max_deg + 0.5)
    )
    # bumps: roll rate of a few deg/s on the straights
    roll_rate = np.degrees(np.abs(truth.w_ib_b[np.concatenate(runs), 0]))
    assert 1.0 < roll_rate.max() < 20.0


def test_field_turns_both_ways_for_fifteen_minutes() -> None:
    cfg = VEHICLE_PRESETS["field"]
    truth = simulate_vehicle(cfg, T0_S, COARSE_DT_S, seed=0)
    assert 13 * 60 < truth.t[-1] - truth.t[0] < 17 * 60
    assert np.argmin(truth.stationary) * truth.dt_s >= 30.0
    runs = passes(truth, cfg.swath_heading_deg)
    assert len(runs) == cfg.n_passes + 1  # the mid-field stop splits one pass
    yaw = np.unwrap(truth.rpy_rad[:, 2])
    turns = np.diff([np.mean(yaw[r]) for r in runs])
    turns = turns[np.abs(turns) > 1.0]  # skip the mid-field stop
    assert len(turns) == cfg.n_passes - 1
    assert_allclose(np.abs(turns), np.pi, atol=np.radians(5))
    assert np.all(np.sign(turns[1:]) == -np.sign(turns[:-1]))  # right, left, right, ...
    roll_deg = np.degrees(np.abs([np.median(truth.rpy_rad[r, 0]) for r in runs]))
    assert np.all((roll_deg > 1.5) & (roll_deg < 4.5))
    speeds = [np.median(np.linalg.norm(truth.vel_ned_mps[r], axis=1)) for r in runs]
    assert max(speeds) - min(speeds) > 0.5  # working speed changes between passes


def test_configuration_is_honoured_and_checked() -> None:
    cfg = dataclasses.replace(
        VEHICLE_PRESETS["short"],
        swath_heading_deg=123.0,
        origin_lla=(-33.9, 18.4, 12.0),
        antenna_lever_arm_m=(1.0, -0.5, -2.0),
    )
    truth = simulate_vehicle(cfg, 10.0, dt_s=0.01)
    first_move = np.argmin(truth.stationary)
    assert_allclose(np.degrees(truth.rpy_rad[first_move + 100, 2]), 123.0, atol=1e-9)
    assert_allclose(truth.lla[0], cfg.origin_lla, atol=1e-9)
    assert_allclose(truth.antenna_lever_arm_m, cfg.antenna_lever_arm_m)
    with pytest.raises(ValueError, match="too short"):
        simulate_vehicle(dataclasses.replace(cfg, swath_length_m=5.0), 0.0, 0.1)
    with pytest.raises(ValueError, match="reverse_length_m"):
        simulate_vehicle(
            dataclasses.replace(cfg, swath_spacing_m=4.0, reverse_length_m=0.0), 0.0, 0.1
        )
