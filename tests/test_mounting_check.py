"""The check of the IMU mounting in effect (gateway.fusion.mounting_check): what the drive
shows, and the bound it is judged by.

Synthetic drives: the same 600 m line on a plane driven north and south twice (RTK heights
with 1 cm noise, 10 Hz, 3 m/s), the engine's solution the body's attitude turned by a
mounting error (the axes' pitch off by ``pitch``, roll by ``roll``, and a yaw turning the
roll into the pitch), with 0.03 deg of noise and a stated 1-sigma of 0.05 deg. Then the
whole path on a simulated drive: the IMU bolted 3 deg off, none configured, through
``navgw replay``.
"""

from __future__ import annotations

import dataclasses
import logging
import math
from pathlib import Path

import numpy as np
import pytest

from drivers.samples import FixQuality, GnssFix
from gateway.config.gateway_config import Engine, load_config
from gateway.estimation.solution import Mode, Solution
from gateway.fusion.mounting_check import MIN_BLOCKS, MountingCheck
from gateway.offline.log_replay import replay
from sim_bus.scenarios import SCENARIOS, SimRun, generate, scenario_from_toml
from sim_bus.truth import Truth
from tests.n2k_check import (
    DEGRADED,
    attitude_errors_deg,
    decode_log,
    settled,
    status_modes,
    tilt_beyond_stated,
)

M_PER_DEG = 6_371_000.0 * math.pi / 180.0  # InsTilt's sphere
SIGMA_TILT_DEG = 0.05
TRUE_RPY = (0.0, -3.0, 0.0)  # the simulated unit's mounting


def drive(
    check: MountingCheck,
    *,
    pitch_deg: float = 0.0,
    roll_deg: float = 0.0,
    yaw_deg: float = 0.0,
    slip_deg: float = 0.0,
    along_deg: float = 1.0,
    cross_deg: float = 5.0,
    cross_end_deg: float | None = None,
    settling_deg: float = 0.0,
    line_m: float = 600.0,
    passes: int = 4,
    seed: int = 1,
    sigma_tilt_deg: float = SIGMA_TILT_DEG,
) -> None:
    """``passes`` of the line (north, south, ...), a second's stop between them. The cross
    slope goes from ``cross_deg`` to ``cross_end_deg`` along the line (default: the same);
    the engine's pitch starts ``settling_deg`` off and settles to none over the drive."""
    rng = np.random.default_rng(seed)
    speed, dt = 3.0, 0.1
    t = 0.0
    for k in range(passes):
        north = k % 2 == 0
        steps = int(line_m / (speed * dt))
        for i in range(-10, steps + 1):
            moving = i >= 0
            n = (i if north else steps - i) * speed * dt if moving else (0.0 if north else line_m)
            # the body on the plane h = n tan(along) + e tan(cross), e = 0: going north the
            # right side is east, uphill (roll negative); going south the other way
            body_pitch = math.radians(along_deg if north else -along_deg)
            cross = (
                cross_deg + (cross_end_deg - cross_deg) * n / line_m
                if cross_end_deg is not None
                else cross_deg
            )
            body_roll = math.radians(-cross if north else cross)
            psi = math.radians(yaw_deg)
            slip = math.radians(slip_deg if north else -slip_deg)  # downhill: east, west
            pitch = body_pitch - body_roll * math.sin(psi) + math.radians(pitch_deg)
            pitch += body_roll * math.sin(slip)  # the track's slope leaves out this much
            pitch += math.radians(settling_deg) * (1.0 - (k * steps + i) / (passes * steps))
            roll = body_roll + body_pitch * math.sin(psi) + math.radians(roll_deg)
            noise = rng.normal(0.0, math.radians(0.03), 2)
            height = n * math.tan(math.radians(along_deg)) + rng.normal(0.0, 0.01)
            t += dt
            fix = GnssFix(
                t=t,
                t_utc=None,
                quality=FixQuality.RTK_FIXED,
                lat_deg=50.0 + n / M_PER_DEG,
                lon_deg=8.0,
                alt_m=100.0 + height,
                sog_mps=speed if moving else 0.0,
            )
            sol = Solution(
                t=t,
                mode=Mode.NAVIGATING,
                roll_rad=roll + noise[0],
                pitch_rad=pitch + noise[1],
                yaw_rad=0.0 if north else math.pi,
                lat_deg=fix.lat_deg,
                lon_deg=fix.lon_deg,
                sigma_tilt_rad=math.radians(sigma_tilt_deg),
            )
            check.epoch(fix, sol)


def checked(**kwargs: float) -> MountingCheck:
    check = MountingCheck((0.0, 0.0, 0.0))
    drive(check, **kwargs)  # type: ignore[arg-type]
    return check


def test_the_mounting_of_the_body_is_not_seen_off() -> None:
    check = checked()
    assert not check.off
    assert check.found == ()
    pitch, roll = check.tilt.pitch(), check.tilt.roll()
    assert pitch.blocks >= MIN_BLOCKS and roll.blocks >= MIN_BLOCKS  # judged, not waiting
    assert abs(math.degrees(pitch.angle_rad or 9.0)) < 0.05


@pytest.mark.parametrize(("axis", "error"), [("pitch", 1.0), ("roll", -1.0), ("yaw", 5.0)])
def test_a_mounting_off_the_body_is_found_with_its_size(axis: str, error: float) -> None:
    check = checked(**{f"{axis}_deg": error})
    assert check.off
    found = {o.axis: o for o in check.found}
    assert set(found) == {axis}
    tolerance = 0.05 if axis != "yaw" else 0.5
    assert abs(abs(found[axis].angle_deg) - abs(error)) < tolerance, found[axis]


def test_a_mounting_yaw_on_level_ground_tilts_nothing_and_is_not_judged_here() -> None:
    """On level ground the yaw turns no roll into the pitch: nothing sent is off by it."""
    assert not checked(yaw_deg=5.0, cross_deg=0.0).off


def test_an_error_within_three_sigma_and_the_margin_is_not_called_off() -> None:
    """The pitch's 1-sigma is at least the engine's stated 0.05 deg: the bound is 3 x 0.05
    + 0.5 = 0.65 deg (a chassis leans on its tyres). 0.6 deg is within it; 0.7 is not. The
    yaw's margin is 0.1 deg of pitch at the roll driven (5 deg): 1 deg of yaw (0.09 deg of
    pitch) is within it, 2 deg (0.17) not."""
    assert not checked(pitch_deg=0.6).off
    assert checked(pitch_deg=0.7).off
    assert not checked(yaw_deg=1.0).off
    assert checked(yaw_deg=2.0).off


def test_a_chassis_that_crabs_down_a_side_slope_is_not_a_mounting_yaw() -> None:
    """Slipping 2 deg downhill on the 5 deg side slope both ways: the track's slope is
    not the body's pitch (pitch off by roll x sin(slip)), but the roll and the slip turn
    over together with the way driven: an offset of 0.17 deg, not a coupling."""
    assert not checked(slip_deg=2.0).off


def test_a_settling_pitch_on_one_swath_is_not_a_mounting_yaw() -> None:
    """The first 300 m of a drive on one swath, the roll 3.6-4.0 deg as the side slope
    steepens, the engine's pitch 0.15 deg off settling to none (within the 0.09 deg it
    states), as an engine's does while it learns its biases (latency-150ms seed 41,
    observer). Against the roll, the segments' pitch lines up along a slope of 0.37 that
    their scatter about it does not show (the check said "yaw -19 +/- 4.6 deg" and held
    DEGRADED to the end of the run). Each segment's error is taken as no less than the
    engine's stated tilt: with 0.4 deg of roll spread that is no coupling to judge by; with
    the roll of both ways of the line, the same settling is none either."""
    one_swath = {"cross_deg": 3.6, "cross_end_deg": 4.0, "settling_deg": -0.15}
    check = checked(line_m=300.0, passes=1, sigma_tilt_deg=0.09, **one_swath)
    fit = check.tilt.roll_coupling()
    assert fit is not None and fit.segments >= MIN_BLOCKS  # judged, not waiting
    assert abs(fit.coupling) > 0.3  # the slope is there ...
    assert not check.off  # ... and not taken for a yaw
    assert not checked(settling_deg=-0.15, sigma_tilt_deg=0.09).off


def test_too_little_driving_is_not_judged() -> None:
    """Four 50 m segments: a scatter of four says too little of its own sigma."""
    check = checked(pitch_deg=2.0, line_m=220.0, passes=1)
    assert check.tilt.pitch().blocks < MIN_BLOCKS
    assert not check.off


def test_the_verdict_is_logged_once_with_what_to_do(caplog: pytest.LogCaptureFixture) -> None:
    with caplog.at_level(logging.WARNING, logger="gateway.fusion.mounting_check"):
        checked(pitch_deg=1.0)
    text = [r.getMessage() for r in caplog.records]
    assert len(text) == 1, text
    assert "pitch +1.0" in text[0] and "navgw calibrate" in text[0], text[0]


@pytest.fixture(scope="module")
def bolted_off(tmp_path_factory: pytest.TempPathFactory) -> SimRun:
    """The calibration drive (9.6 min, a 4-6 deg side slope driven both ways, turns both
    ways) with the IMU bolted 3 deg nose-down."""
    sc = SCENARIOS["calibration"]
    sc = dataclasses.replace(sc, imu=dataclasses.replace(sc.imu, imu_mounting_rpy_deg=TRUE_RPY))
    return generate(sc, tmp_path_factory.mktemp("mounted"), seed=1)


@pytest.mark.parametrize("engine", list(Engine))
@pytest.mark.parametrize("configured", [TRUE_RPY, (0.0, 0.0, 0.0)], ids=["true", "unset"])
def test_a_unit_bolted_off_and_not_configured_is_degraded_on_the_bus(
    engine: Engine,
    configured: tuple[float, float, float],
    bolted_off: SimRun,
    tmp_path: Path,
    caplog: pytest.LogCaptureFixture,
) -> None:
    """``navgw replay`` of the drive, the attitude decoded by the independent ``nmea2000``
    package. With the mounting unset, pitch goes out off by the mounting (the EKF's 1.2 deg:
    its no-vertical-velocity constraint puts the rest into its x accelerometer bias) while
    the engines state tenths: from the check's verdict on (within 8 minutes), every
    NAVGW_STATUS says DEGRADED, to the end. Before it, the heading's corrections in the
    turns may show more than the heading states (DEGRADED for a second or two,
    :mod:`gateway.estimation.bias_change`). With the true mounting configured there is no
    verdict, and no DEGRADED spell of more than 2 s (one after a reverse at 1 m/s on the
    slope, the heading 0.6 deg off with 0.14 stated: the courses of 18 s of reversing
    averaged 0.3 deg off by their noise and the mast's sway)."""
    base = load_config(bolted_off.config_file).with_engine(engine)
    cfg = dataclasses.replace(
        base, vehicle=dataclasses.replace(base.vehicle, imu_mounting_rpy_deg=configured)
    )
    out = tmp_path / "out.log"
    with caplog.at_level(logging.WARNING, logger="gateway.fusion.mounting_check"):
        replay(bolted_off.imu_log, bolted_off.gnss_log, out, cfg)
    verdicts = [
        r.getMessage() for r in caplog.records if "IMU mounting in effect" in r.getMessage()
    ]
    truth = Truth.load(bolted_off.truth_file)
    modes = settled(status_modes(out))
    if configured == TRUE_RPY:
        assert verdicts == []
        spells = _degraded_spells(modes)
        assert all(b - a < 2.0 for a, b in spells), spells
        return
    assert len(verdicts) == 1, verdicts
    t_off = float(verdicts[0].split(":")[0][2:])
    assert t_off - truth.t[0] < 480.0
    assert all(mode == DEGRADED for t, mode in modes if t >= t_off + 0.2)
    errors = attitude_errors_deg(decode_log(out), truth, after_s=t_off - truth.t[0])
    assert np.median(np.abs(errors[:, 1])) > 1.0  # the pitch so excused was that far off


def _degraded_spells(modes: list[tuple[float, int]]) -> list[tuple[float, float]]:
    """(first, last) status times of each run of DEGRADED in ``modes``."""
    runs: list[tuple[float, float]] = []
    start = prev = None
    for t, mode in modes:
        if mode == DEGRADED and start is None:
            start = t
        elif mode != DEGRADED and start is not None:
            runs.append((start, prev if prev is not None else start))
            start = None
        prev = t
    if start is not None and prev is not None:
        runs.append((start, prev))
    return runs


@pytest.fixture(scope="module")
def lifting(tmp_path_factory: pytest.TempPathFactory) -> SimRun:
    """The field drive (16 min, nine passes on 2-4 deg side slopes), the IMU on the body's
    axes, the chassis pitched 0.5 deg on its tyres and 1 deg more over every headland (an
    implement lifted as each pass ends, lowered as the next begins)."""
    sc = SCENARIOS["field"]
    vehicle = dataclasses.replace(sc.vehicle, chassis_pitch_deg=0.5, implement_lift_deg=1.0)
    sc = dataclasses.replace(sc, vehicle=vehicle)
    return generate(sc, tmp_path_factory.mktemp("lifting"), seed=1)


@pytest.mark.parametrize("engine", list(Engine))
def test_an_implement_lifted_at_every_headland_is_not_a_mounting_yaw(
    engine: Engine, lifting: SimRun, tmp_path: Path
) -> None:
    """The chassis pitches 1 deg more through each headland turn, where the roll turns over
    with the way driven: segments through the turns lined the pitch up with the roll as a
    mounting yaw of 9-25 deg would (1.1-1.7 of the bound), and both engines went DEGRADED
    for good at 231-241 s with the mounting right. Segments now end where the vehicle turns
    faster than 5 deg/s: no NAVGW_STATUS says DEGRADED, and the attitude goes out within
    0.1 deg + 3 stated sigmas."""
    out = tmp_path / "out.log"
    replay(
        lifting.imu_log, lifting.gnss_log, out, load_config(lifting.config_file).with_engine(engine)
    )
    modes = settled(status_modes(out))
    assert len(modes) > 5000
    assert [t for t, mode in modes if mode == DEGRADED] == []
    checked, beyond = tilt_beyond_stated(out, Truth.load(lifting.truth_file))
    assert checked > 5000
    assert not beyond, beyond[:5]


def test_a_1_hz_receiver_at_road_speed_on_bumps_is_not_a_mounting_yaw(tmp_path: Path) -> None:
    """12 m/s passes on the field's bumpy 2-4 deg side slopes with a 1 Hz receiver, the IMU
    on the body's axes. Roll and pitch taken at the epochs alone were five samples per 60 m
    segment of a body rocking on the bumps, roll and pitch together: a pitch from roll of a
    25 deg mounting yaw (6.8 deg 1-sigma), and the EKF said DEGRADED from 230 s to the end
    with "Run navgw calibrate" in the log (seed 631). The check takes the mean roll and
    pitch sent between the epochs: no DEGRADED, nothing logged."""
    table = {"base": "field", "gnss": {"rate_hz": 1.0}, "vehicle": ROAD_SPEED}
    scenario = scenario_from_toml(table)
    run = generate(scenario, tmp_path / "run", seed=631)
    out = tmp_path / "out.log"
    cfg = load_config(run.config_file).with_engine(Engine.EKF)
    replay(run.imu_log, run.gnss_log, out, cfg)
    modes = settled(status_modes(out))
    assert len(modes) > 3000
    assert [t for t, mode in modes if mode == DEGRADED] == []


#: road speed on the field: 12 m/s passes 900 m long, 40 m turns at 6 m/s
ROAD_SPEED = {
    "work_speeds_mps": [12.0],
    "swath_length_m": 900.0,
    "swath_spacing_m": 90.0,
    "turn_radius_m": 40.0,
    "turn_speed_mps": 6.0,
    "n_passes": 4,
}
