"""An engine that raises does not stop the gateway: FAULT on the bus, a new engine from cold.

:meth:`FusionCore._engine_raised` is the barrier. The fault is injected by giving the running
engine a method that raises once, the stand-in for a bug some input reaches (the one found,
epochs out of time order reaching the observer, is fixed at its cause: the epoch clock).
The real core from a config, fed exact motion; frames written as candump and read back with
the nmea2000 package (attitude) and as raw NAVGW_STATUS bytes (mode).
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from drivers.nmea import NmeaCounters
from drivers.samples import ImuAux, ImuCounters
from gateway.cli.cmd_replay import summary_text
from gateway.config.gateway_config import Engine, GatewayConfig
from gateway.estimation.solution import Mode
from gateway.fusion.fusion_core import FusionCore
from gateway.fusion.output_guard import GuardLimits
from gateway.offline.log_replay import ReplaySummary
from tests.kinematics import T0_S, gnss_stream, imu_stream, motion_time
from tests.n2k_check import SHARE_RESOLUTION_M, decode_log, status_tilt_shares_m
from tests.test_outages import LEVER, MOTION, attitude_within_stated, run, status

FAULT_AT_S = 60.0  # motion time, s: on the straight after the first turn's alignment


def raise_once_after(core: FusionCore, where: str) -> None:
    """Give ``core``'s engine a ``where`` (imu, gnss or solution) that raises once, at the
    first call after motion time :data:`FAULT_AT_S` (for the solution: the first after an
    IMU sample of that time)."""
    engine = core.engine
    armed = [False, True]  # the time has come, not yet raised

    def wrap(method: Callable[..., Any], timed: bool) -> Callable[..., Any]:
        def call(*args: Any) -> Any:
            if timed and motion_time(args[0].t) >= FAULT_AT_S:
                armed[0] = True
            if armed[0] and armed[1] and (timed == (where != "solution")):
                armed[1] = False
                raise ZeroDivisionError("injected")
            return method(*args)

        return call

    timed_name = "gnss" if where == "gnss" else "imu"
    setattr(engine, timed_name, wrap(getattr(engine, timed_name), True))
    if where == "solution":
        engine.solution = wrap(engine.solution, False)  # type: ignore[method-assign]


@pytest.mark.parametrize("engine", [Engine.OBSERVER, Engine.EKF])
@pytest.mark.parametrize("where", ["imu", "gnss", "solution"])
def test_an_engine_that_raises_is_replaced_and_the_bus_says_fault(
    tmp_path: Path, caplog: pytest.LogCaptureFixture, engine: Engine, where: str
) -> None:
    """The error is logged once with its traceback and counted; NAVGW_STATUS says FAULT from
    that instant until the new engine (from cold) has aligned, NAVIGATING after; no attitude
    goes out until it has levelled, and every one sent, before and after, is within its
    stated accuracy."""
    imu = imu_stream(MOTION, noise_g_rps=1e-4, noise_a_mps2=0.01)
    fixes = gnss_stream(MOTION, antenna_lever_arm_m=LEVER, latency_s=0.07)
    log = tmp_path / "out.log"
    with caplog.at_level(logging.ERROR, logger="gateway.fusion.fusion_core"):
        core = run(log, engine, imu, fixes, prepare=lambda c: raise_once_after(c, where))
    assert core.stats.engine_faults == 1 and core.stats.engine_restarts == 0
    errors = [r for r in caplog.records if r.name == "gateway.fusion.fusion_core"]
    assert len(errors) == 1 and errors[0].exc_info is not None
    message = errors[0].getMessage()
    caplog.clear()  # (tests/conftest.py fails a test whose engine raised unasked)
    what = {"imu": "an IMU sample", "gnss": "a GNSS fix", "solution": "its solution"}[where]
    assert f"the engine raised on {what} at t=" in message and "ZeroDivisionError" in message
    t_fault = float(message.split(" at t=")[1].split(" ")[0]) - T0_S
    assert FAULT_AT_S <= t_fault < FAULT_AT_S + 0.2
    summary = ReplaySummary(core.stats, ImuCounters(), NmeaCounters(), 0, 0, 1.0, 1.0)
    assert "frames, 1 engine faults (raised: see above)" in summary_text(summary)

    modes = [(t, Mode(d[2])) for t, d in status(log)]
    assert {m for t, m in modes if 40.0 <= t < t_fault} == {Mode.NAVIGATING}
    back = next(t for t, m in modes if t > t_fault and m is not Mode.FAULT)
    assert back > t_fault + 5.0  # FAULT until the new engine has aligned ...
    # ... then NAVIGATING, or DEGRADED while its tilt, levelled on the move, is too uncertain
    # for an RTK-class reference point on the mast
    limit_m = GuardLimits().navigating_position_sigma_m
    after = [
        (Mode(mode), share)
        for t, mode, share in status_tilt_shares_m(log, LEVER)
        if back <= motion_time(t) < back + 30.0
    ]
    assert {m for m, _ in after} <= {Mode.NAVIGATING, Mode.DEGRADED}
    degraded = [s for m, s in after if m is Mode.DEGRADED]
    assert all(s is not None and s > limit_m - SHARE_RESOLUTION_M for s in degraded)
    assert len(degraded) < 0.6 * len(after) and after[-1][0] is Mode.NAVIGATING
    attitude = [
        motion_time(m.t)
        for m in decode_log(log)
        if m.id == "attitude" and m.fields["roll"] is not None
    ]
    assert not [t for t in attitude if t_fault <= t < t_fault + 1.0]  # levelling anew
    assert attitude_within_stated(log, MOTION, (20.0, MOTION.duration_s)) > 4000


def test_an_engine_that_raises_on_the_imu_temperature_is_replaced(
    caplog: pytest.LogCaptureFixture,
) -> None:
    """IMU_AUX reaches the engine too (its temperature): a bug there is the same barrier's."""
    core = FusionCore.from_config(GatewayConfig())
    first = core.engine

    def raises(t_s: float, temp_c: float) -> None:
        raise ZeroDivisionError("injected")

    first.temperature = raises  # type: ignore[method-assign]
    with caplog.at_level(logging.ERROR, logger="gateway.fusion.fusion_core"):
        list(core.on_input(ImuAux(T0_S, 21.0, 5.0, 0, 1)))
    assert core.stats.engine_faults == 1 and core.engine is not first
    assert "the engine raised on an IMU temperature at t=" in caplog.text
    caplog.clear()  # (tests/conftest.py fails a test whose engine raised unasked)
    list(core.on_input(ImuAux(T0_S + 1.0, 21.1, 5.0, 0, 1)))  # the new engine takes it
    assert core.stats.engine_faults == 1
