"""The mounting estimate of navgw calibrate inside the live service (issue 17): in the status
line and the log, never applied, and never able to stop the service."""

from __future__ import annotations

import asyncio
import dataclasses
import logging
import re
import time
from pathlib import Path

import pytest

from drivers.samples import ImuSample
from gateway.config.driver_settings import imu_config
from gateway.config.gateway_config import (
    CalibrationSection,
    GatewayConfig,
    GnssSection,
    load_config,
)
from gateway.fusion.fusion_core import BusFrame
from gateway.offline.log_inputs import LogInputs
from gateway.service.live_loop import GatewayService
from gateway.service.mounting_watch import MountingWatch
from gateway.service.timebase import TimeBase
from sim_bus.scenarios import SCENARIOS, generate

TRUE_MOUNTING_DEG = (4.0, -6.0, 8.0)


@pytest.fixture(scope="module")
def drive(tmp_path_factory: pytest.TempPathFactory) -> tuple[GatewayConfig, Path, Path]:
    """The simulated calibration drive (8.5 min) with the IMU at 4, -6, 8 deg, and its
    config (which knows the true mounting)."""
    sc = SCENARIOS["calibration"]
    sc = dataclasses.replace(
        sc, imu=dataclasses.replace(sc.imu, imu_mounting_rpy_deg=TRUE_MOUNTING_DEG)
    )
    run = generate(sc, tmp_path_factory.mktemp("calibration"), seed=11)
    return load_config(run.config_file), Path(run.imu_log), Path(run.gnss_log)


def with_mounting(config: GatewayConfig, rpy_deg: tuple[float, float, float]) -> GatewayConfig:
    return dataclasses.replace(
        config, vehicle=dataclasses.replace(config.vehicle, imu_mounting_rpy_deg=rpy_deg)
    )


def watched(config: GatewayConfig, imu_log: Path, gnss_log: Path) -> MountingWatch:
    watch = MountingWatch(config, interval_s=300.0)
    for item in LogInputs(imu_log, gnss_log, imu_config(config)):
        watch.feed(item)
    return watch


def angles(text: str) -> list[float]:
    """The numbers of the config line in a summary."""
    m = re.search(r"imu_mounting_rpy_deg = \[([^\]]+)\]", text)
    assert m, text
    return [float(x) for x in m.group(1).split(",")]


def test_with_the_mounting_configured_the_estimate_confirms_it(
    drive: tuple[GatewayConfig, Path, Path],
) -> None:
    config, imu_log, gnss_log = drive
    text = watched(config, imu_log, gnss_log).update(0.0)
    assert text is not None and "coarse" not in text
    assert angles(text) == pytest.approx(TRUE_MOUNTING_DEG, abs=0.3)


def test_a_mounting_far_off_gets_a_coarse_estimate_that_says_so(
    drive: tuple[GatewayConfig, Path, Path],
) -> None:
    """Configured 0, 0, 0: one live pass starts 10 deg from the body's axes; the estimate
    points the right way, and the line sends the user to navgw calibrate's further passes."""
    config, imu_log, gnss_log = drive
    text = watched(with_mounting(config, (0.0, 0.0, 0.0)), imu_log, gnss_log).update(0.0)
    assert text is not None and "coarse: run navgw calibrate on a recording" in text
    assert "imu_mounting_rpy_deg" not in text  # nothing to paste yet
    numbers = [float(x) for x in re.findall(r"(-?\d+\.\d+)\+/-", text)]
    assert numbers == pytest.approx(TRUE_MOUNTING_DEG, abs=1.5)


def test_the_summary_comes_at_once_then_once_per_interval() -> None:
    watch = MountingWatch(GatewayConfig(), interval_s=300.0)
    first = watch.update(100.0)
    assert first is not None and first.startswith("mounting estimate: none yet (")
    assert "turn both ways" in first  # what a drive without motion lacks
    assert watch.update(399.0) is None
    assert watch.update(400.0) == first


def test_an_internal_error_switches_it_off_not_the_service(
    caplog: pytest.LogCaptureFixture,
) -> None:
    watch = MountingWatch(GatewayConfig(), interval_s=300.0)
    broken = ImuSample(t=1.0, dt=0.005, w_ib_b=None, f_ib_b=None, seq=0)  # type: ignore[arg-type]
    with caplog.at_level(logging.ERROR, logger="gateway.service.mounting_watch"):
        watch.feed(broken)
        watch.feed(broken)
    assert len(caplog.records) == 1 and "switched off" in caplog.records[0].getMessage()
    assert watch.summary == "mounting estimate: off after an internal error"
    assert watch.update(1000.0) is None


def test_the_service_reports_it_in_its_status_and_log(
    drive: tuple[GatewayConfig, Path, Path], tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """The inputs go through the service's own path (core, then estimate); its health task
    logs the estimate and its sd_notify status line carries it. [calibration] live = false
    leaves it out."""
    base, imu_log, gnss_log = drive
    config = dataclasses.replace(
        base,
        imu=dataclasses.replace(base.imu, interface="virtual", channel=f"mw{id(tmp_path)}"),
        gnss=GnssSection(port=str(tmp_path / "no-receiver")),
    )
    inputs = [
        x for x in LogInputs(imu_log, gnss_log, imu_config(config)) if not isinstance(x, BusFrame)
    ]  # what the IMU decoder and the GNSS reader hand the loop

    async def run() -> str:
        service = GatewayService(config, timebase=TimeBase(inputs[-1].t, time.time(), 1.0))
        for item in inputs:
            service.process(item)
        running = asyncio.create_task(service.run())
        deadline = time.monotonic() + 15.0
        while "imu_mounting_rpy_deg" not in caplog.text and time.monotonic() < deadline:
            await asyncio.sleep(0.05)
        line = service.status_line()
        service.request_stop()
        assert await running == 0
        return line

    with caplog.at_level(logging.INFO, logger="gateway.service"):
        line = asyncio.run(run())
    logged = [m for r in caplog.records if (m := r.getMessage()).startswith("mounting estimate")]
    assert logged and angles(logged[0]) == pytest.approx(TRUE_MOUNTING_DEG, abs=0.3)
    assert "mounting estimate: roll" in line and angles(line) == angles(logged[0])

    off = dataclasses.replace(config, calibration=CalibrationSection(live=False))
    assert "mounting" not in GatewayService(off).status_line()
