"""The live service when its host cannot keep up: fair to every input, honest on the bus.

The service object runs in this process on virtual buses and a pty (the demo's path), with
its engine slowed down so that it cannot process the IMU stream at the rate it arrives: a
deterministic stand-in for a host too busy for its load. It must shed IMU samples it
gets too late (counted), keep reading the GNSS port promptly and feed every fix (the starved
serial reader was the root of the antipodal positions), and put no implausible or stale value
on the bus.
"""

from __future__ import annotations

import asyncio
import contextlib
import dataclasses
import json
import os
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import can
import numpy as np
import pytest

from drivers.logs.candump import CandumpWriter
from drivers.samples import GnssFix, ImuAux, ImuSample
from gateway.demo.demo_run import OutputLog, demo_config
from gateway.demo.playback import SyncedPlayback
from gateway.service.live_loop import GatewayService
from sim_bus.scenarios import SCENARIOS, generate
from sim_bus.truth import Truth
from tests.multicast import GROUP
from tests.n2k_check import (
    Decoded,
    decode_log,
    implausible_frames,
    status_modes,
    tilt_beyond_stated,
)

pytestmark = pytest.mark.live


def assert_nothing_false(decoded: list[Decoded], truth: Truth, log: Path) -> None:
    """Nothing wrong unless NAVGW_STATUS says so (SPEC 4: DEGRADED or FAULT from the same
    instant), and roll/pitch within the accuracy stated (at most 0.5 % beyond, by chance).
    Held to the gross bounds without the status, a CI run under stress-ng failed on pitch
    3.5 deg off for 0.5 s that went out under DEGRADED."""
    assert implausible_frames(decoded, truth, status=status_modes(log)) == []
    checked, beyond = tilt_beyond_stated(log, truth, lag_s=0.5)
    assert len(beyond) <= 0.005 * checked, beyond[:10]


SPEED = 4.0
SECONDS = 60.0  # of the short run: rest, alignment, then driving
#: CPU each IMU sample costs the slowed engine, s: 1.6 ms against the 1.22 ms between
#: samples at 4x, so the core falls behind for the whole run.
SLOW_S = 0.0016


async def serve_while_playing(
    service: GatewayService, pb: SyncedPlayback, isobus: can.BusABC, writer: CandumpWriter
) -> None:
    """Run ``service`` while ``pb`` plays, its ISOBUS output written; then stop it cleanly."""
    with can.Notifier(isobus, [OutputLog(writer, service.timebase)]):
        running = asyncio.create_task(service.run())
        while not pb.wait(0):
            await asyncio.sleep(0.1)
        await asyncio.sleep(0.3)
        service.request_stop()
        assert await running == 0


@contextlib.contextmanager
def port_watch(device: str) -> Iterator[list[float]]:
    """Watch ``device`` from a process of its own (:mod:`tests.port_watch`); on exit the
    list yielded holds the spans (s) in which it held data unread, longest first."""
    spans: list[float] = []
    watcher = subprocess.Popen(
        [sys.executable, "-m", "tests.port_watch", device],
        cwd=Path(__file__).resolve().parent.parent,
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        yield spans
    finally:
        out, _ = watcher.communicate(timeout=10.0)  # closes its stdin: it reports and ends
    spans.extend(json.loads(out))


def busy_wait(seconds: float) -> None:
    end = time.perf_counter() + seconds
    while time.perf_counter() < end:
        pass


def test_an_overloaded_service_stays_fair_and_honest(tmp_path: Path) -> None:
    generate(SCENARIOS["short"], tmp_path, seed=5)
    truth = Truth.load(tmp_path / "truth.npz")
    tag = f"overload-{os.getpid()}"
    out_log = tmp_path / "live.log"
    hold_delays: list[float] = []  # wall seconds from the read of a fix to the engine
    unread_s: list[float] = []  # spans in which the serial port held data unread, s

    async def main() -> GatewayService:
        with (
            can.Bus(
                interface="virtual", channel=f"navgw-demo-imu-{tag}", preserve_timestamps=True
            ) as imu_bus,
            can.Bus(interface="virtual", channel=f"navgw-demo-isobus-{tag}") as isobus,
            CandumpWriter(out_log) as writer,
            SyncedPlayback(
                tmp_path / "imu.log", tmp_path / "gnss.nmea", imu_bus, SPEED, SECONDS
            ) as pb,
        ):
            timebase = pb.start(time.time() + 0.3)
            service = GatewayService(demo_config(truth, pb.device, tag), timebase=timebase)
            engine_imu, core_input = service.core.engine.imu, service.core.on_input

            def slow_imu(sample: ImuSample) -> None:
                busy_wait(SLOW_S)
                engine_imu(sample)

            def watch(item: ImuSample | GnssFix) -> object:
                if isinstance(item, GnssFix):
                    hold_delays.append(time.time() - timebase.wall_at(item.t))
                return core_input(item)

            service.core.engine.imu = slow_imu  # type: ignore[method-assign]
            service.core.on_input = watch  # type: ignore[method-assign,assignment]
            with port_watch(pb.device) as spans:
                await serve_while_playing(service, pb, isobus, writer)
            unread_s.extend(spans)
        return service

    service = asyncio.run(main())
    # it really was overloaded: samples that reached the core too late to be worth sending
    # were shed, and counted where NAVGW_STATUS byte 6 takes its losses from. Usually
    # 4400-4800 of the 12,300; the player is a thread of this process, and on a busy host
    # the slowed engine's GIL holds it back, so fewer arrive late (808 in one CI run)
    stats = service.stats
    assert stats.stale_samples > 300, stats
    assert service.core.stats.imu_dropped == stats.stale_samples + service.inbox.overloads
    # ... but every fix the GNSS decoder made reached the engine (the inbox drops IMU
    # samples only), soon after it was read, and the serial port never held data unread for
    # long (the starved reader left it there for seconds). What the port held is watched by
    # a process of its own: the time from the player's write to the read also has the
    # kernel's delivery to the port, which on a saturated host (two stress-ng hogs) was
    # 0.8-2.8 s at times, the loop selecting every few ms and the port empty meanwhile.
    assert service.core.stats.gnss_fixes == service.gnss.decoder.counters.fixes > 0.9 * 10 * SECONDS
    assert len(hold_delays) == service.core.stats.gnss_fixes
    assert np.percentile(hold_delays, 95) < 0.25, np.percentile(hold_delays, [50, 95, 100])
    assert not unread_s or unread_s[0] < 1.0, (unread_s[:5], service.status_line())
    # nothing implausible went out while the core ran behind
    decoded = decode_log(out_log)
    assert [m for m in decoded if m.id == "attitude"], "no attitude frame at all"
    assert_nothing_false(decoded, truth, out_log)


#: Time each IMU frame holds up the slowed reader, s: at SPEED 1638 frames arrive a second,
#: one every 0.61 ms. Slept, not spun: the player is a thread of this process, and a reader
#: spinning with the GIL held made the player late, not the reader.
SLOW_FRAME_S = 0.0008


def test_a_reader_slower_than_its_input_sheds_what_is_stale_and_keeps_sending(
    tmp_path: Path, multicast_port: int
) -> None:
    """The IMU on udp_multicast (read in the loop, stamped by the kernel on arrival, as
    SocketCAN) and the reader, not the core, too slow for it: once behind, it must drop
    what is stale unread and go on with fresh frames. Decoding every frame, it stayed the
    socket's buffer behind and not one sample reached the engine (an emulated guest on a
    busy CI host sent FAULT for 20 s)."""
    generate(SCENARIOS["short"], tmp_path, seed=5)
    truth = Truth.load(tmp_path / "truth.npz")
    tag = f"shed-{os.getpid()}"
    out_log = tmp_path / "live.log"

    async def main() -> GatewayService:
        with (
            can.Bus(interface="udp_multicast", channel=GROUP) as imu_bus,
            can.Bus(interface="virtual", channel=f"navgw-demo-isobus-{tag}") as isobus,
            CandumpWriter(out_log) as writer,
            SyncedPlayback(
                tmp_path / "imu.log", tmp_path / "gnss.nmea", imu_bus, SPEED, SECONDS
            ) as pb,
        ):
            timebase = pb.start(time.time() + 0.3)
            config = demo_config(truth, pb.device, tag)
            imu = dataclasses.replace(config.imu, interface="udp_multicast", channel=GROUP)
            config = dataclasses.replace(config, imu=imu)
            service = GatewayService(config, timebase=timebase)
            feed = service.imu_decoder.feed

            def slow_feed(msg: can.Message) -> list[ImuSample | ImuAux]:
                time.sleep(SLOW_FRAME_S)
                return feed(msg)

            service.imu_decoder.feed = slow_feed  # type: ignore[method-assign]
            await serve_while_playing(service, pb, isobus, writer)
        return service

    service = asyncio.run(main())
    # Without shedding: 16 of the 12,288 samples reached the engine, no attitude went out.
    # With it: 37 % of them (the rest shed, or lost in the socket), 1,347 attitude frames,
    # NAVGW_STATUS ALIGNING, then DEGRADED over the gaps (one run).
    played = 204.8 * SECONDS
    assert service.stats.frames_shed > 0.1 * 2 * played, service.status_line()
    assert service.core.stats.imu_samples > 0.1 * played, service.status_line()
    decoded = decode_log(out_log)
    assert_nothing_false(decoded, truth, out_log)
    sent = [m for m in decoded if m.id == "attitude" and m.fields["roll"] is not None]
    assert len(sent) > 3 * SECONDS, service.status_line()
