"""Built-in simulation scenarios and the function that turns one into logs and truth.

A scenario is the vehicle motion plus the sensors on it: the ADIS16334 behind its CAN
bridge and the RTK receiver. :func:`generate` writes what the real sensors would put on
the wires, in the log formats of SPEC 3, with the truth beside it:

- ``imu.log``    candump ``-L`` lines of IMU_GYRO / IMU_ACCEL / IMU_AUX (SPEC 1)
- ``gnss.nmea``  host-stamped NMEA 0183 sentences (SPEC 2)
- ``truth.npz``  :class:`sim_bus.truth.Truth`, including the IMU's true biases
- ``navgw.toml`` the gateway config of the simulated vehicle and sensors (SPEC 5), which
  replay needs to put the reference point where the truth has it
"""

from __future__ import annotations

import dataclasses
import itertools
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from drivers.logs.candump import write_candump
from drivers.logs.nmea_log import read_nmea_log, write_nmea_log
from drivers.nmea import read_fixes_from_log
from drivers.samples import FixQuality
from gateway.config.config_schema import ConfigError, from_table
from gateway.config.gateway_config import (
    GatewayConfig,
    GnssSection,
    ImuSection,
    VehicleSection,
    config_toml,
)
from gateway.estimation.attitude import dcm_from_rpy_deg
from gateway.estimation.epoch_clock import DELAY_WINDOW_S
from sim_bus.adis16334 import Adis16334Config, Adis16334Output, simulate, temperature_c
from sim_bus.gnss_receiver import (
    FixInterval,
    GnssReceiverConfig,
    ReceiverOutput,
    simulate_receiver,
)
from sim_bus.imu_frames import BridgeConfig, frames
from sim_bus.truth import Truth
from sim_bus.vehicle import VEHICLE_PRESETS, VehicleConfig, simulate_vehicle

IMU_LOG = "imu.log"
GNSS_LOG = "gnss.nmea"
TRUTH_FILE = "truth.npz"
CONFIG_FILE = "navgw.toml"
#: The gateway config sections a scenario determines; the rest keep their defaults.
CONFIG_SECTIONS = ("vehicle", "imu", "gnss")

#: Default host-clock start of a run (UTC s): 2023-11-14 22:13:20.
T0_S = 1_700_000_000.0


@dataclass(frozen=True)
class Scenario:
    """Vehicle motion plus sensors. ``seed`` draws every random part of one run."""

    name: str
    description: str
    vehicle: VehicleConfig
    imu: Adis16334Config = field(default_factory=Adis16334Config)
    bridge: BridgeConfig = field(default_factory=BridgeConfig)
    gnss: GnssReceiverConfig = field(default_factory=GnssReceiverConfig)
    t0_s: float = T0_S


@dataclass(frozen=True)
class SimRun:
    """What :func:`generate` wrote, and how much."""

    imu_log: Path
    gnss_log: Path
    truth_file: Path
    config_file: Path
    imu_samples: int
    can_frames: int
    nmea_lines: int
    duration_s: float


_OUTAGES = (
    FixInterval(180.0, 210.0, FixQuality.RTK_FLOAT),
    FixInterval(210.0, 240.0, FixQuality.DGNSS),
    FixInterval(240.0, 260.0, FixQuality.NONE),
    FixInterval(260.0, 300.0, FixQuality.RTK_FLOAT),
    FixInterval(520.0, 525.0, FixQuality.NONE),
    FixInterval(700.0, 760.0, FixQuality.GNSS),
)

#: A minute of RTK float twice, a DGNSS and a single-point spell, each followed by RTK fixed.
_FLOAT_SPELLS = (
    FixInterval(200.0, 260.0, FixQuality.RTK_FLOAT),
    FixInterval(380.0, 410.0, FixQuality.DGNSS),
    FixInterval(500.0, 560.0, FixQuality.RTK_FLOAT),
    FixInterval(680.0, 710.0, FixQuality.GNSS),
)
#: Outages of 5 to 60 s, each followed by two minutes of RTK fixed.
_OUTAGE_SPANS = (
    FixInterval(180.0, 185.0, FixQuality.NONE),
    FixInterval(300.0, 310.0, FixQuality.NONE),
    FixInterval(430.0, 450.0, FixQuality.NONE),
    FixInterval(570.0, 610.0, FixQuality.NONE),
    FixInterval(730.0, 790.0, FixQuality.NONE),
)
#: 8-10 deg side slope, 4 m/s work speed, 6 m headland turns (issue 16's steep run).
_STEEP = VehicleConfig(
    swath_heading_deg=60.0,
    swath_length_m=150.0,
    swath_spacing_m=14.0,
    n_passes=8,
    work_speeds_mps=(4.0, 3.5),
    turn_radius_m=6.0,
    turn_speed_mps=2.5,
    start_stop_s=30.0,
    side_slope_min_deg=8.0,
    side_slope_max_deg=10.0,
    side_slope_wavelength_m=90.0,
    along_slope_deg=2.0,
)
#: A cold start parked across a 9 deg slope, 4 deg along: 5 s of rest, then work.
_SLOPE_START = VehicleConfig(
    swath_heading_deg=-30.0,
    swath_length_m=120.0,
    swath_spacing_m=16.0,
    n_passes=4,
    work_speeds_mps=(3.0, 3.5),
    start_stop_s=5.0,
    side_slope_min_deg=8.0,
    side_slope_max_deg=9.0,
    side_slope_wavelength_m=200.0,
    along_slope_deg=4.0,
)
#: A calibration drive (issue 17): 20 s at rest, seven 120 m passes on one line, each the
#: other way, across a 4-6 deg side slope, joined by three-point turns, a stop half-way.
_CALIBRATION = VehicleConfig(
    swath_heading_deg=30.0,
    swath_length_m=120.0,
    swath_spacing_m=0.0,
    n_passes=7,
    work_speeds_mps=(3.0, 3.5),
    turn_speed_mps=2.5,
    start_stop_s=20.0,
    mid_stop_pass=3,
    mid_stop_s=15.0,
    end_stop_s=10.0,
    side_slope_min_deg=4.0,
    side_slope_max_deg=6.0,
    side_slope_wavelength_m=200.0,
    along_slope_deg=1.5,
)

SCENARIOS: dict[str, Scenario] = {
    "field": Scenario(
        "field",
        "~16 min: nine 250 m swaths, U-turns both ways, 2-4 deg side slopes, RTK fixed",
        VEHICLE_PRESETS["field"],
    ),
    "hillside": Scenario(
        "hillside",
        "~9 min on a 5-8 deg side slope whose roll sign flips every pass",
        VEHICLE_PRESETS["hillside"],
    ),
    "headland-reversing": Scenario(
        "headland-reversing",
        "~8 min of narrow swaths; every headland turn is a fishtail with ~12 m of reversing",
        VEHICLE_PRESETS["headland-reversing"],
    ),
    "gnss-outage": Scenario(
        "gnss-outage",
        "the field run with RTK float, DGNSS, single-point spells and 20 s and 5 s outages",
        VEHICLE_PRESETS["field"],
        gnss=GnssReceiverConfig(fix_schedule=_OUTAGES),
    ),
    "steep-turns": Scenario(
        "steep-turns",
        "~9 min on an 8-10 deg side slope at 4 m/s, 6 m headland turns, RTK fixed",
        _STEEP,
    ),
    "float-spells": Scenario(
        "float-spells",
        "the field run with two minutes of RTK float, 30 s of DGNSS and 30 s of single point",
        VEHICLE_PRESETS["field"],
        gnss=GnssReceiverConfig(fix_schedule=_FLOAT_SPELLS),
    ),
    "outages": Scenario(
        "outages",
        "the field run with GNSS outages of 5, 10, 20, 40 and 60 s, RTK fixed between",
        VEHICLE_PRESETS["field"],
        gnss=GnssReceiverConfig(fix_schedule=_OUTAGE_SPANS),
    ),
    "slope-start": Scenario(
        "slope-start",
        "~3.5 min: cold start parked on a 9 deg side slope (4 deg along), 5 s rest, four passes",
        _SLOPE_START,
    ),
    "calibration": Scenario(
        "calibration",
        "~8.5 min: the same 120 m line driven both ways seven times on a 4-6 deg side slope, "
        "three-point turns, stops (navgw calibrate)",
        _CALIBRATION,
    ),
    "short": Scenario(
        "short",
        "~2 min: 30 s rest, three 50 m passes, a right and a left U-turn (tests, demo)",
        VEHICLE_PRESETS["short"],
    ),
}


def scenario_from_toml(
    table: dict[str, Any], where: str = "scenario", default_base: str = "field"
) -> Scenario:
    """A scenario from a TOML document: ``base = "field"`` (``default_base`` if it has none)
    plus overriding tables.

    Tables ``[vehicle]``, ``[imu]``, ``[bridge]``, ``[gnss]`` override fields of the base
    scenario's configs by name (e.g. ``[imu] gyro_turn_on_bias_rps = [0.001, 0.002, 0]``);
    an unknown key is an error that names it.
    """
    table = dict(table)
    base_name = table.pop("base", default_base)
    if base_name not in SCENARIOS:
        raise ConfigError(f"{where}.base = {base_name!r}: expected one of {', '.join(SCENARIOS)}")
    base = SCENARIOS[base_name]
    parts: dict[str, Any] = {"name": table.pop("name", f"{base_name}*")}
    for key in ("vehicle", "imu", "bridge", "gnss"):
        if key in table:
            current = getattr(base, key)
            parts[key] = from_table(type(current), table.pop(key), key, base=current)
    if "t0_s" in table:
        parts["t0_s"] = float(table.pop("t0_s"))
    if table:
        raise ConfigError(
            f"unknown key {next(iter(table))!r} in {where}: expected base, name, t0_s, "
            "[vehicle], [imu], [bridge], [gnss]"
        )
    return dataclasses.replace(base, **parts)


def continuation(
    previous: Scenario,
    truth: Truth,
    scenario: Scenario,
    pause_s: float = 60.0,
    previous_seed: int | None = None,
) -> Scenario:
    """``scenario``'s drive with the IMU of ``previous`` (whose run's truth is ``truth``),
    started ``pause_s`` after it ended: a restart of the same gateway, e.g. after a break.

    The IMU is the same (model settings, mounting, bridge): its turn-on bias is where the
    previous run's bias ended, its in-run wander starts from 0 there, and its temperature
    starts where it ended (a short pause: no time to cool). The clock goes on, and the
    vehicle starts where it stopped, its first pass along its last heading. With
    ``previous_seed`` (the seed ``previous`` ran with) it stands on the same ground, so its
    attitude at the start is the one it stopped with (a parked vehicle); without, the
    ground is ``scenario``'s own (as if it had been moved while off). Runs that are not
    continuations are unchanged.
    """
    imu = previous.imu
    c_b_imu = dcm_from_rpy_deg(imu.imu_mounting_rpy_deg)
    bias_g = truth.bias_g_rps[-1] @ c_b_imu  # body -> IMU axes: C^T b
    bias_a = truth.bias_a_mps2[-1] @ c_b_imu
    t_run = float(truth.t[-1] - truth.t[0])
    temp_end_c = float(temperature_c(np.asarray(t_run), imu))
    lat, lon, alt = (float(x) for x in truth.lla[-1])
    vehicle = dataclasses.replace(
        scenario.vehicle,
        origin_lla=(lat, lon, alt),
        swath_heading_deg=math.degrees(float(truth.rpy_rad[-1, 2])),
    )
    if previous_seed is not None:
        vehicle = _on_the_ground_of(vehicle, previous, truth, previous_seed)
    return dataclasses.replace(
        scenario,
        name=f"{scenario.name} after {previous.name}",
        vehicle=vehicle,
        imu=dataclasses.replace(
            imu,
            gyro_turn_on_bias_rps=_vec3(bias_g),
            accel_turn_on_bias_mps2=_vec3(bias_a),
            gyro_in_run_bias0_rps=(0.0, 0.0, 0.0),
            accel_in_run_bias0_mps2=(0.0, 0.0, 0.0),
            temp_start_c=temp_end_c,
        ),
        bridge=previous.bridge,
        t0_s=float(truth.t[-1]) + pause_s,
    )


def _on_the_ground_of(
    vehicle: VehicleConfig, previous: Scenario, truth: Truth, previous_seed: int
) -> VehicleConfig:
    """``vehicle`` on the terrain of ``previous``'s run (seed ``previous_seed``, truth
    ``truth``), its origin where that run stopped."""
    ground = previous.vehicle
    end_ne = truth.pos_ned_m[-1, :2]
    return dataclasses.replace(
        vehicle,
        side_slope_min_deg=ground.side_slope_min_deg,
        side_slope_max_deg=ground.side_slope_max_deg,
        side_slope_wavelength_m=ground.side_slope_wavelength_m,
        along_slope_deg=ground.along_slope_deg,
        bump_amplitude_m=ground.bump_amplitude_m,
        bump_wavelength_min_m=ground.bump_wavelength_min_m,
        bump_wavelength_max_m=ground.bump_wavelength_max_m,
        bump_count=ground.bump_count,
        terrain_heading_deg=(
            ground.swath_heading_deg
            if ground.terrain_heading_deg is None
            else ground.terrain_heading_deg
        ),
        terrain_seed=(
            _seeded(previous, previous_seed)[0]
            if ground.terrain_seed is None
            else ground.terrain_seed
        ),
        terrain_origin_ne_m=(
            ground.terrain_origin_ne_m[0] + float(end_ne[0]),
            ground.terrain_origin_ne_m[1] + float(end_ne[1]),
        ),
    )


def _vec3(a: np.ndarray) -> tuple[float, float, float]:
    return (float(a[0]), float(a[1]), float(a[2]))


def _seeded(scenario: Scenario, seed: int) -> tuple[int, Scenario]:
    """Spread one run seed over the independent random parts: (terrain seed, scenario)."""
    s_vehicle, s_imu, s_bridge, s_gnss = (
        int(x) for x in np.random.SeedSequence(seed).generate_state(4)
    )
    return s_vehicle, dataclasses.replace(
        scenario,
        imu=dataclasses.replace(scenario.imu, seed=s_imu),
        bridge=dataclasses.replace(scenario.bridge, seed=s_bridge),
        gnss=dataclasses.replace(scenario.gnss, seed=s_gnss),
    )


def simulate_run(
    scenario: Scenario, seed: int = 0
) -> tuple[Truth, Adis16334Output, ReceiverOutput]:
    """Run the vehicle and the sensor models of one seeded run, in memory."""
    s_vehicle, sc = _seeded(scenario, seed)
    truth = simulate_vehicle(sc.vehicle, sc.t0_s, sc.imu.dt_s, s_vehicle)
    imu_out = simulate(truth.t, truth.w_ib_b, truth.f_ib_b_imu, sc.imu)
    truth.bias_g_rps = imu_out.bias_g_rps
    truth.bias_a_mps2 = imu_out.bias_a_mps2
    return truth, imu_out, simulate_receiver(truth, sc.gnss)


def generate(scenario: Scenario, out_dir: str | Path, seed: int = 0) -> SimRun:
    """Write ``imu.log``, ``gnss.nmea``, ``truth.npz`` and ``navgw.toml`` of one seeded run
    into ``out_dir``."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    truth, imu_out, gnss_out = simulate_run(scenario, seed)
    run = SimRun(
        imu_log=out / IMU_LOG,
        gnss_log=out / GNSS_LOG,
        truth_file=out / TRUTH_FILE,
        config_file=out / CONFIG_FILE,
        imu_samples=len(truth),
        can_frames=write_candump(out / IMU_LOG, frames(imu_out, _seeded(scenario, seed)[1].bridge)),
        nmea_lines=len(gnss_out.lines),
        duration_s=float(truth.t[-1] - truth.t[0]),
    )
    write_nmea_log(run.gnss_log, gnss_out.lines)
    truth.save(run.truth_file)
    config = gateway_config(scenario, receiver_latency_s(run.gnss_log, scenario.gnss))
    title = (
        f"navgw config of the vehicle and sensors of simulated scenario {scenario.name} "
        "(all keys: navgw config --example)"
    )
    run.config_file.write_text(config_toml(config, title, CONFIG_SECTIONS))
    return run


def gateway_config(scenario: Scenario, receiver_latency_s: float) -> GatewayConfig:
    """The gateway config an integrator would write for the scenario's vehicle and sensors."""
    return GatewayConfig(
        vehicle=VehicleSection(
            antenna_lever_arm_m=scenario.vehicle.antenna_lever_arm_m,
            imu_lever_arm_m=scenario.vehicle.imu_lever_arm_m,
            imu_mounting_rpy_deg=scenario.imu.imu_mounting_rpy_deg,
        ),
        imu=ImuSection(bridge_source_address=scenario.bridge.source_address),
        gnss=GnssSection(baudrate=scenario.gnss.baud, receiver_latency_s=receiver_latency_s),
    )


def receiver_latency_s(gnss_log: Path, receiver: GnssReceiverConfig) -> float:
    """``[gnss] receiver_latency_s`` as an integrator measures it on the receiver's log: the
    least delay from an epoch to the receipt of its last sentence over the epoch clock's window
    at the start, less the host clock's offset from UTC; to the millisecond."""
    with read_nmea_log(gnss_log) as reader:
        fixes = read_fixes_from_log(reader)
        first = next(fixes)
        window = itertools.takewhile(lambda f: f.t <= first.t + DELAY_WINDOW_S, fixes)
        delays = [fix.t - fix.t_utc for fix in (first, *window) if fix.t_utc is not None]
    return round(min(delays) - receiver.host_clock_offset_s, 3)
