"""Robustness: the gateway on variants of the field run, judged through its SPEC interfaces.

Run:  .venv/bin/python benchmarks/robustness.py                     # every variant, seed 1
      .venv/bin/python benchmarks/robustness.py --variants default gnss-1hz --seeds 1 2
      .venv/bin/python benchmarks/robustness.py --engines observer observer-eq12
      .venv/bin/python benchmarks/robustness.py --base headland-reversing --seeds 42
      .venv/bin/python benchmarks/robustness.py --variants gnss-1hz+host-clock-free

Each variant changes one thing a user's setup may differ in (receiver rate, latency, clock,
sentences, IMU mounting, IMU grade, antenna position, output rate of the IMU) against the
`field` preset (or ``--base``); ``a+b`` applies both (sections merged key by key, the later
variant's keys winning), for setups that differ in more than one thing. The run is
simulated, then replayed exactly as ``navgw replay`` does, with a config holding only the
SPEC 5 [vehicle] keys (everything else at its default), and the output frames are decoded
with the independent ``nmea2000`` package and compared with the truth after 10 minutes
(after half the run where it is under 15): roll, pitch, yaw RMS (127257) and the reference
point's horizontal RMS and max (129025); and over the whole run the attitude frames that
state an accuracy and those beyond 0.1 deg + 3 stated sigma of the truth (the never-lie
check of docs/ROBUSTNESS.md), and those whose heading is beyond 0.1 deg + 3 x NAVIGATING's
0.5 deg 1-sigma without NAVGW_STATUS saying DEGRADED (the bus states no heading accuracy;
the mode does), and the reference points (129025) beyond their mode's
(`tests/n2k_check.py::position_beyond_mode`).
Parameters are the product defaults; nothing here is tuned per variant.
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from warm_start import VARIANTS as ENGINES
from warm_start import with_variant

from gateway.config.gateway_config import GatewayConfig, VehicleSection
from gateway.offline.log_replay import replay
from sim_bus.scenarios import SCENARIOS, generate, scenario_from_toml
from sim_bus.truth import Truth
from tests.n2k_check import (
    attitude_errors_deg,
    decode_log,
    heading_beyond_navigating,
    position_beyond_mode,
    position_errors_m,
    tilt_beyond_stated,
)

#: rough-slope's vehicle: 3x the bumps, 6-9 deg side slopes, 4 deg along
ROUGH_GROUND = {
    "bump_amplitude_m": 0.03,
    "side_slope_min_deg": 6.0,
    "side_slope_max_deg": 9.0,
    "along_slope_deg": 4.0,
}
#: Variant name -> (what it changes, scenario overrides on the field preset).
VARIANTS: dict[str, tuple[str, dict[str, Any]]] = {
    "default": ("field preset: 10 Hz, ~68 ms to the last sentence, UTC host clock", {}),
    "gnss-1hz": ("1 Hz receiver", {"gnss": {"rate_hz": 1.0}}),
    "gnss-5hz": ("5 Hz receiver", {"gnss": {"rate_hz": 5.0}}),
    "gnss-20hz": ("20 Hz receiver", {"gnss": {"rate_hz": 20.0}}),
    "latency-150ms": ("150 ms receiver latency", {"gnss": {"latency_s": 0.15}}),
    "latency-0ms": (
        "sentences ready at their epoch (the last ~28 ms after it, the serial link's time)",
        {"gnss": {"latency_s": 0.0}},
    ),
    "rough-prompt": (
        "rough-slope's ground, sentences ready at their epoch",
        {
            "gnss": {"latency_s": 0.0},
            "vehicle": ROUGH_GROUND,
        },
    ),
    "host-clock-free": (
        "host clock 30 s off UTC (no NTP/PPS): epochs from receive time - default 50 ms",
        {"gnss": {"host_clock_offset_s": 30.0}},
    ),
    "gga-rmc-only": (
        "GP talker, GGA + RMC only (no VTG, GST, ZDA)",
        {"gnss": {"talker": "GP", "vtg": False, "gst": False, "zda": False}},
    ),
    "rmc-1hz": (
        "GGA at 10 Hz, RMC, VTG, GST and ZDA at 1 Hz (the velocity once a second)",
        {"gnss": {"slow_sentences": ["RMC", "VTG", "GST", "ZDA"], "slow_rate_hz": 1.0}},
    ),
    "dr-hold": (
        "through an outage the receiver carries its last fix on at its velocity for 20 s, "
        "as dead reckoning (a u-blox without sensors)",
        {"gnss": {"dead_reckoning_limit_s": 20.0}},
    ),
    "vel-5cm": (
        "receiver velocity 5 cm/s 1-sigma (u-blox F9P's datasheet), 2 cm/s configured",
        {"gnss": {"velocity_sigma_mps": 0.05}},
    ),
    "pos-white": (
        "2 cm per horizontal axis of white position noise on every fix (a receiver that "
        "does not smooth its solution), GST stating it",
        {"gnss": {"position_white_sigma_m": 0.02}},
    ),
    "hdt": ("dual-antenna heading (HDT)", {"gnss": {"hdt": True}}),
    "imu-mounted-rotated": (
        "IMU upside down and turned 90 deg (config gives the mounting)",
        {"imu": {"imu_mounting_rpy_deg": [180.0, 0.0, 90.0]}},
    ),
    "imu-102hz": ("IMU DEC = 3: 102.4 Hz", {"imu": {"dec": 3}}),
    "imu-51hz": ("IMU DEC = 4: 51.2 Hz", {"imu": {"dec": 4}}),
    "imu-819hz": ("IMU DEC = 0: 819.2 Hz", {"imu": {"dec": 0}}),
    "long-stop": (
        "a 5-minute stop after the first pass, engine running",
        {"vehicle": {"mid_stop_pass": 1, "mid_stop_s": 300.0}},
    ),
    "imu-noise-x2": (
        "IMU twice as noisy: ARW, VRW, in-run and turn-on biases",
        {
            "imu": {
                "gyro_arw_rad_per_sqrt_s": 2 * 2.0 * math.pi / 180 / 60,
                "accel_vrw_mps_per_sqrt_s": 2 * 0.12 / 60,
                "gyro_bias_stability_rps": 2 * 0.007 * math.pi / 180,
                "accel_bias_stability_mps2": 2 * 0.1e-3 * 9.80665,
                "gyro_turn_on_sigma_rps": 2 * 0.1 * math.pi / 180,
                "accel_turn_on_sigma_mps2": 2 * 5e-3 * 9.80665,
            }
        },
    ),
    "imu-bias-x5": (
        "turn-on biases 5x the datasheet-class sigma: 0.5 deg/s, 25 mg",
        {
            "imu": {
                "gyro_turn_on_sigma_rps": 0.5 * math.pi / 180,
                "accel_turn_on_sigma_mps2": 25e-3 * 9.80665,
            }
        },
    ),
    "imu-warm-up": (
        "IMU cold, warming 5 -> 45 degC (5 min time constant), its biases following at "
        "0.01 deg/s and 0.1 mg per degC 1-sigma",
        {
            "imu": {
                "temp_start_c": 5.0,
                "temp_end_c": 45.0,
                "temp_tau_s": 300.0,
                "gyro_bias_tempco_sigma_rps_per_c": 0.01 * math.pi / 180,
                "accel_bias_tempco_sigma_mps2_per_c": 0.1e-3 * 9.80665,
            }
        },
    ),
    "fast-wide": (
        "6 m/s work speed, 30 m swaths, 12 m turns at 3 m/s, north-east swaths",
        {
            "vehicle": {
                "work_speeds_mps": [6.0],
                "swath_spacing_m": 30.0,
                "swath_length_m": 400.0,
                "turn_radius_m": 12.0,
                "turn_speed_mps": 3.0,
                "swath_heading_deg": 45.0,
            }
        },
    ),
    "rough-slope": (
        "3x the bumps, 6-9 deg side slopes, 4 deg along",
        {"vehicle": ROUGH_GROUND},
    ),
    "implement-lift": (
        "chassis pitched 0.5 deg on its tyres, 1 deg more (in 2 s) over every headland",
        {"vehicle": {"chassis_pitch_deg": 0.5, "implement_lift_deg": 1.0}},
    ),
    "antenna-offset": (
        "antenna 0.8 m right, 1.5 m forward, 3.5 m up",
        {"vehicle": {"antenna_lever_arm_m": [1.5, 0.8, -3.5]}},
    ),
}


def variant_overrides(name: str) -> dict[str, dict[str, Any]]:
    """The scenario sections of a variant, or of ``a+b+...`` merged left to right."""
    merged: dict[str, dict[str, Any]] = {}
    for part in name.split("+"):
        if part not in VARIANTS:
            raise ValueError(f"unknown variant {part!r} in {name!r}; known: {', '.join(VARIANTS)}")
        for section, keys in VARIANTS[part][1].items():
            merged[section] = {**merged.get(section, {}), **keys}
    return merged


def variant_label(name: str) -> str:
    """What a variant, or each part of ``a+b``, changes."""
    return "; ".join(VARIANTS[part][0] for part in name.split("+"))


AFTER_S = 600.0  # the targets' "after 10 minutes" (half the run where it is under 15)


def run_variant(
    name: str, seed: int, engines: Sequence[str] = ("observer", "ekf"), base: str = "field"
) -> dict[str, tuple[float, ...]]:
    """(roll, pitch, yaw RMS deg, ref RMS cm, ref max cm, attitude frames stating an
    accuracy, those beyond it, headings beyond NAVIGATING's, positions beyond their mode's,
    engine faults: the times the engine raised and the core went on with a new one) of each
    engine on one variant."""
    scenario = scenario_from_toml({"base": base, "name": name, **variant_overrides(name)})
    out: dict[str, tuple[float, ...]] = {}
    with tempfile.TemporaryDirectory(prefix="navgw-rob-") as tmp:
        run = generate(scenario, tmp, seed)
        truth = Truth.load(run.truth_file)
        vehicle = VehicleSection(
            antenna_lever_arm_m=tuple(float(v) for v in truth.antenna_lever_arm_m),  # type: ignore[arg-type]
            imu_lever_arm_m=tuple(float(v) for v in truth.imu_lever_arm_m),  # type: ignore[arg-type]
            imu_mounting_rpy_deg=scenario.imu.imu_mounting_rpy_deg,
        )
        for label in engines:
            frames = Path(tmp) / f"{label}.log"
            summary = replay(
                run.imu_log,
                run.gnss_log,
                frames,
                with_variant(GatewayConfig(vehicle=vehicle), label),
            )
            decoded = decode_log(frames)
            span_s = float(truth.t[-1] - truth.t[0])
            after_s = AFTER_S if span_s > 1.5 * AFTER_S else 0.5 * span_s
            att = attitude_errors_deg(decoded, truth, after_s)
            pos = position_errors_m(decoded, truth, after_s) * 100.0
            pos = pos[np.isfinite(pos)]  # not the frames "not available" (an outage's)
            rms = np.sqrt(np.mean(np.square(att), axis=0))
            checked, beyond = tilt_beyond_stated(frames, truth)
            _, heading_beyond = heading_beyond_navigating(frames, truth)
            _, position_beyond = position_beyond_mode(frames, truth)
            out[label] = (
                *rms,
                math.sqrt(float(np.mean(pos**2))) if pos.size else math.nan,  # none sent
                float(np.max(pos)) if pos.size else math.nan,
                checked,
                len(beyond),
                len(heading_beyond),
                len(position_beyond),
                summary.stats.engine_faults,
            )
    return out


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--variants",
        nargs="+",
        default=list(VARIANTS),
        metavar="VARIANT[+VARIANT]",
        help=f"of {', '.join(VARIANTS)}; a+b applies both",
    )
    parser.add_argument("--seeds", nargs="+", type=int, default=[1])
    parser.add_argument("--engines", nargs="+", choices=list(ENGINES), default=["observer", "ekf"])
    parser.add_argument("--base", default="field", choices=sorted(SCENARIOS), help="scenario")
    parser.add_argument("--jobs", type=int, default=2, help="worker processes")
    args = parser.parse_args(argv)
    for name in args.variants:
        try:
            variant_overrides(name)
        except ValueError as exc:
            parser.error(str(exc))
    jobs = [(v, s) for v in args.variants for s in args.seeds]
    columns = [
        "roll rms", "pitch rms", "yaw rms", "ref rms cm", "ref max cm", "frames", "beyond",
        "hdg beyond", "pos beyond", "faults",
    ]  # fmt: skip
    print("| variant | what changes | seed | engine | " + " | ".join(columns) + " |")
    print("|---" * (4 + len(columns)) + "|")
    names, seeds = [v for v, _ in jobs], [s for _, s in jobs]
    with ProcessPoolExecutor(args.jobs) as pool:
        results = pool.map(
            run_variant, names, seeds, [args.engines] * len(jobs), [args.base] * len(jobs)
        )
        for (name, seed), result in zip(jobs, results, strict=True):
            for engine, row in result.items():
                roll, pitch, yaw, ref, ref_max, checked, beyond, hdg_beyond, pos_beyond = row[:9]
                faults = row[9]
                print(
                    f"| {name} | {variant_label(name)} | {seed} | {engine} | {roll:.3f} | "
                    f"{pitch:.3f} | {yaw:.3f} | {ref:.2f} | {ref_max:.2f} | {checked:.0f} | "
                    f"{beyond:.0f} | {hdg_beyond:.0f} | {pos_beyond:.0f} | {faults:.0f} |",
                    flush=True,
                )


if __name__ == "__main__":
    main()
