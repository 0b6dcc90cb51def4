"""The output guard: an engine that misbehaves never puts an implausible value on the bus.

A scripted engine drives the real FusionCore (claim, scheduler, encoders); its frames are
written as candump and read back with the independent nmea2000 decoder (positions, attitude)
and the raw NAVGW_STATUS bytes (SPEC 4).
"""

from __future__ import annotations

import logging
import math
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from drivers.logs.candump import CandumpWriter, read_candump
from drivers.samples import FixQuality, Float3, GnssFix, ImuSample
from gateway.config.gateway_config import GatewayConfig
from gateway.estimation.heading_hint import HeadingHint
from gateway.estimation.solution import LearnedState, Mode, Solution
from gateway.fusion.fusion_core import FusionCore
from gateway.fusion.output_guard import GuardLimits, OutputGuard, Withheld
from tests.n2k_check import decode_log

T0 = 1_700_000_000.0
DT = 1.0 / 204.8
LAT0, LON0 = 52.2, 10.5
SPEED = 3.0  # m/s east
M_PER_DEG = 111_195.0
STATUS_ID = 0x18FF221C


def track_lon(t: float) -> float:
    """Longitude of the true track (east at SPEED from LON0)."""
    return LON0 + SPEED * (t - T0) / (M_PER_DEG * math.cos(math.radians(LAT0)))


class ScriptedEngine:
    """Navigates along the track, except in the windows where it misbehaves."""

    RESET_AT = 12.0  # from here the engine's position is 8 m north (a real re-fix)

    def __init__(self) -> None:
        self.t = T0

    def imu(self, sample: ImuSample) -> None:
        self.t = sample.t

    def gnss(self, fix: GnssFix) -> None:
        pass

    def seed(self, learned: LearnedState, f_rest_b_mps2: Float3 | None = None) -> bool:
        return False  # learns nothing, takes nothing

    def temperature(self, t_s: float, temp_c: float) -> None:
        return None  # scripted: no biases to walk

    def learned_state(self) -> LearnedState | None:
        return None

    def moving_before(self) -> None:
        return None  # scripted: no levelling to tell

    def heading_before(self, hint: HeadingHint) -> None:
        return None  # scripted: no heading to find

    def solution(self) -> Solution:
        s = self.t - T0
        lat, lon, alt = LAT0, track_lon(self.t), 100.0
        roll, vel = 0.02, (0.0, SPEED, 0.0)
        if 5.0 <= s < 6.0:  # the antipode, as a diverged vertical channel gives it
            lat, lon, alt = -LAT0, LON0 - 180.0, 1.2e15
        if 8.0 <= s < 8.5:
            roll = math.nan
        if 10.0 <= s < 10.2:  # a 500 m spike
            lat += 500.0 / M_PER_DEG
        if s >= self.RESET_AT:
            lat += 8.0 / M_PER_DEG
        return Solution(
            t=self.t,
            mode=Mode.NAVIGATING,
            roll_rad=roll,
            pitch_rad=-0.01,
            yaw_rad=math.pi / 2,
            yaw_rate_rps=0.0,
            lat_deg=lat,
            lon_deg=lon,
            alt_m=alt,
            vel_ned_mps=vel,
            bias_g_rps=(0.0, 0.0, 0.0),
            bias_a_mps2=(0.0, 0.0, 0.0),
            sigma_tilt_rad=0.002,
            fix_quality=FixQuality.RTK_FIXED,
            gnss_ok=True,
            imu_ok=True,
        )


def run_core(path: Path, seconds: float) -> FusionCore:
    core = FusionCore.from_config(GatewayConfig())
    core.engine = ScriptedEngine()
    with CandumpWriter(path, "can0") as writer:
        writer.write_all(core.start(T0))
        for k in range(round(seconds / DT)):
            t = T0 + k * DT
            sample = ImuSample(
                t=t, dt=DT, w_ib_b=(0.0, 0.0, 0.0), f_ib_b=(0.0, 0.0, 0.0), seq=k % 256
            )
            writer.write_all(core.on_imu(sample))
    return core


def test_a_misbehaving_engine_never_reaches_the_bus(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    log = tmp_path / "out.log"
    with caplog.at_level(logging.WARNING, logger="gateway.fusion.output_guard"):
        core = run_core(log, 15.0)
    decoded = decode_log(log)
    positions = [m for m in decoded if m.id == "positionRapidUpdate"]
    assert len(positions) > 600
    for m in positions:
        lat, lon = m.fields["latitude"], m.fields["longitude"]
        if lat is None:
            continue
        assert isinstance(lat, float) and isinstance(lon, float)
        north_m = (lat - LAT0) * M_PER_DEG
        east_m = (lon - track_lon(m.t)) * M_PER_DEG * math.cos(math.radians(LAT0))
        expected_north = 8.0 if m.t - T0 >= ScriptedEngine.RESET_AT else 0.0
        assert abs(north_m - expected_north) < 0.01 and abs(east_m) < 0.2, (m.t - T0, lat, lon)

    def available(t0: float, t1: float) -> list[bool]:
        return [m.fields["latitude"] is not None for m in positions if t0 <= m.t - T0 < t1]

    assert all(available(1.0, 4.9)) and not any(available(5.0, 5.98))
    assert not any(available(10.0, 10.18)) and all(available(10.3, 11.9))
    # the re-fix: withheld until the new track has held for settle_s (or the old one's motion
    # could have reached it: 8 m at max_accel_mps2 takes 0.9 s), then trusted
    settle = GuardLimits().settle_s
    assert not any(available(12.0, 12.5))
    assert all(available(12.0 + settle + 0.05, 15.0))

    attitude = [m for m in decoded if m.id == "attitude"]
    nan_window = [m.fields["roll"] for m in attitude if 8.0 <= m.t - T0 < 8.48]
    assert nan_window and all(r is None for r in nan_window)

    # NAVGW_STATUS says so at the same instants: fault for the attitude, degraded otherwise
    status = {
        round(f.timestamp - T0, 2): Mode(f.data[2])
        for f in read_candump(log)
        if f.arbitration_id == STATUS_ID
    }
    assert {m for s, m in status.items() if 5.0 <= s < 6.0} == {Mode.DEGRADED}
    assert {m for s, m in status.items() if 8.0 <= s < 8.5} == {Mode.FAULT}
    assert {m for s, m in status.items() if 1.0 <= s < 5.0} == {Mode.NAVIGATING}
    assert {m for s, m in status.items() if 13.2 <= s < 15.0} == {Mode.NAVIGATING}

    counts = core.guard.counts
    assert counts[Withheld.POSITION] > 0 and counts[Withheld.ATTITUDE] > 0
    # logged at a limited rate: one line per 10 s of solution time at most
    lines = [r for r in caplog.records if r.name == "gateway.fusion.output_guard"]
    assert 1 <= len(lines) <= 2
    assert "expected" in lines[0].getMessage()


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("roll_rad", math.radians(75.0)),
        ("pitch_rad", math.inf),
        ("yaw_rate_rps", math.radians(400.0)),
        ("vel_ned_mps", (45.0, 0.0, 0.0)),
        ("alt_m", 2.0e6),
        ("lat_deg", 91.0),
        ("sigma_tilt_rad", math.nan),
        ("bias_a_mps2", np.array([0.0, 3.0, 0.0])),
    ],
)
def test_each_bound_withholds_the_field_and_lowers_the_mode(field: str, value: object) -> None:
    guard = OutputGuard()
    engine = ScriptedEngine()
    engine.t = T0 + 1.0
    good = engine.solution()
    assert guard.check(good) is good
    engine.t += 0.02
    bad = guard.check(Solution(**{**_fields(engine.solution()), field: value}))
    assert getattr(bad, field) is None
    assert bad.mode in (Mode.DEGRADED, Mode.FAULT)
    assert guard.withheld == 1


def _fields(sol: Solution) -> dict[str, Any]:
    return {name: getattr(sol, name) for name in Solution.__slots__}


@pytest.mark.parametrize("sigma_deg", [None, 2.6, math.nan])
def test_tilt_without_a_stated_accuracy_goes_out_as_not_available(
    sigma_deg: float | None,
) -> None:
    """Roll/pitch 1-sigma unknown or beyond what STATUS can state: roll and pitch withheld
    quietly (normal after levelling on a moving window), and the reference point with them
    (antenna - C l: as unknown as the tilt); yaw, speed and mode kept."""
    guard = OutputGuard()
    engine = ScriptedEngine()
    engine.t = T0 + 1.0
    sigma = None if sigma_deg is None else math.radians(sigma_deg)
    sol = guard.check(Solution(**{**_fields(engine.solution()), "sigma_tilt_rad": sigma}))
    assert sol.roll_rad is None and sol.pitch_rad is None
    assert sol.lat_deg is None and sol.lon_deg is None and sol.alt_m is None
    assert sol.yaw_rad == math.pi / 2 and sol.vel_ned_mps is not None
    assert sol.mode is (Mode.NAVIGATING if sigma_deg is None or sigma_deg > 0 else Mode.DEGRADED)
    assert guard.counts[Withheld.ATTITUDE] == 0
    stated = guard.check(
        Solution(**{**_fields(engine.solution()), "sigma_tilt_rad": math.radians(2.5)})
    )
    assert stated.roll_rad == 0.02 and stated.pitch_rad == -0.01 and stated.lat_deg == LAT0


@pytest.mark.parametrize(
    ("lever_arm_ant_m", "sigma_deg", "mode"),
    [
        ((0.3, 0.0, -3.0), 0.9, Mode.NAVIGATING),  # 4.7 cm on a 3 m mast
        ((0.3, 0.0, -3.0), 1.0, Mode.DEGRADED),  # 5.3 cm
        ((0.3, 0.0, -3.0), None, Mode.DEGRADED),  # unknown
        ((0.0, 0.0, -1.0), 2.5, Mode.NAVIGATING),  # 4.4 cm on a cab roof
        ((0.0, 0.0, 0.0), 2.5, Mode.NAVIGATING),  # the antenna at the reference point
    ],
)
def test_navigating_holds_the_tilt_s_share_of_the_reference_point_to_rtk_class(
    lever_arm_ant_m: Float3, sigma_deg: float | None, mode: Mode
) -> None:
    """The reference point is the antenna minus C l: a tilt 1-sigma makes it |l| sigma
    uncertain. NAVIGATING (an RTK fix's centimetres) while that share is within
    ``navigating_position_sigma_m``, DEGRADED beyond; the values themselves still go out
    (within what STATUS byte 7 can state), nothing counted as withheld. Other modes kept."""
    guard = OutputGuard(lever_arm_ant_m=lever_arm_ant_m)
    engine = ScriptedEngine()
    engine.t = T0 + 1.0
    sigma = None if sigma_deg is None else math.radians(sigma_deg)
    sol = guard.check(Solution(**{**_fields(engine.solution()), "sigma_tilt_rad": sigma}))
    assert sol.mode is mode
    assert (sol.lat_deg is not None) is (sigma is not None)
    coasting = Solution(**{**_fields(engine.solution()), "mode": Mode.COASTING})
    assert guard.check(replace(coasting, sigma_tilt_rad=sigma)).mode is Mode.COASTING
    assert guard.withheld == 0
