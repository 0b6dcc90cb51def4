"""The live service end to end: simulator -> CAN bus + pty -> service -> ISOBUS -> decoded.

Two paths: ``navgw run`` as a subprocess on ``udp_multicast`` in real time (needs a multicast
route to loopback, so root), and the service object in this process on ``virtual``, faster
than real time on its TimeBase, recording its inputs. Output frames are decoded independently
(the nmea2000 package) and compared with the truth, with replay of the same logs, and with
replay of the service's own recording.
"""

from __future__ import annotations

import asyncio
import dataclasses
import json
import math
import os
import random
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

import can
import numpy as np
import numpy.typing as npt
import pytest

from drivers.logs.candump import CandumpWriter, read_candump
from drivers.samples import GnssFix, ImuAux, ImuSample
from gateway.config.gateway_config import (
    ENGINE_SECTIONS,
    SECTIONS,
    RecordingSection,
    config_toml,
)
from gateway.demo.demo_run import OutputLog, demo_config
from gateway.demo.playback import SyncedPlayback
from gateway.estimation.solution import IMU_GAP_DEGRADED_S, MAX_IMU_STEP_S, Mode
from gateway.fusion.fusion_core import BusFrame
from gateway.offline.log_replay import replay
from gateway.service.live_loop import GatewayService
from gateway.service.timebase import TimeBase
from sim_bus.scenarios import SCENARIOS, generate
from sim_bus.truth import Truth
from tests.multicast import GROUP
from tests.n2k_check import (
    Decoded,
    Plausible,
    attitude_errors_deg,
    cadence_problems,
    decode_log,
    implausible_frames,
    pauses,
    position_errors_m,
    status_modes,
    tilt_beyond_stated,
)
from tests.notify_socket import NotifySocket

REPO = Path(__file__).resolve().parents[1]
STATUS_ID = 0x18FF221C  # NAVGW_STATUS from 0x1C
CLAIM_ID = 0x18EEFF1C  # address claim from 0x1C
ALIGNED_S = 38.0  # short: 30 s rest, navigating from about 34 s
IMU_HZ = 204.8
#: The longest a guidance controller may go without attitude or position while navigating,
#: in real (wall) seconds: 12 frames at 50 Hz. A faster-than-real-time test allows its speed
#: times more log time, and compares a frame with the truth that long before its stamp.
MAX_GAP_WALL_S = 0.25

pytestmark = pytest.mark.live


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("live")
    generate(SCENARIOS["short"], out, seed=3)
    return out


def attitude_deg(
    messages: list[Decoded],
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """Times and (roll, pitch, yaw) in degrees of the 127257 frames."""
    rows = [m for m in messages if m.id == "attitude" and m.fields["roll"] is not None]
    rpy = [[m.fields["roll"], m.fields["pitch"], m.fields["yaw"]] for m in rows]
    return np.array([m.t for m in rows]), np.degrees(np.array(rpy, dtype=float))


def lagged_differences_deg(
    live: list[Decoded],
    reference: list[Decoded],
    after: float,
    max_lag_s: float,
    skip: Sequence[tuple[float, float]] = (),
) -> npt.NDArray[np.float64]:
    """|live - reference| per axis, each live frame against the best reference frame sent at
    most ``max_lag_s`` before it (live frames are stamped on reception, replay on input);
    live frames in the ``skip`` intervals are not compared."""
    t_live, a_live = attitude_deg(live)
    t_ref, a_ref = attitude_deg(reference)
    rows: list[npt.NDArray[np.float64]] = []
    for t, a in zip(t_live, a_live, strict=True):
        if t < after or any(p0 <= t <= p1 for p0, p1 in skip):
            continue
        lo, hi = np.searchsorted(t_ref, [t - max_lag_s, t + 1e-6])
        if hi > lo:
            d = np.abs(a_ref[lo:hi] - a)
            d[:, 2] = np.abs((d[:, 2] + 180.0) % 360.0 - 180.0)
            rows.append(d.min(axis=0))
    errors = np.array(rows)
    return errors[~np.isnan(errors).any(axis=1)]  # yaw not available yet


def check_plausible(live: list[Decoded], truth: Truth, speed: float, log: Path) -> None:
    """No frame is wrong unless NAVGW_STATUS says so, not even on a loaded host (``speed``:
    log seconds per wall second; ``log``: the candump the frames were decoded from)."""
    limits = Plausible(lag_s=MAX_GAP_WALL_S * speed)
    bad = implausible_frames(live, truth, limits, status_modes(log))
    assert not bad, f"{len(bad)} implausible frames:\n" + "\n".join(bad[:20])


def check_output(
    live: list[Decoded],
    truth: Truth,
    end_s: float,
    speed: float,
    kept_up: bool = True,
    input_pauses: Sequence[tuple[float, float]] = (),
) -> None:
    """Once navigating (ALIGNED_S to ``end_s`` of log time), attitude and position at 50 Hz
    without a gap a guidance controller would notice, if the service kept up: on a scaled
    clock (``speed`` log seconds per wall second) a loaded host cannot always keep up, and the
    service then drops stale samples, says so (``kept_up`` False) and sends fewer frames, but
    never a wrong one (:func:`check_plausible`). ``input_pauses``: see ``cadence``."""
    start, end = truth.t[0] + ALIGNED_S, truth.t[0] + end_s
    if kept_up:
        late = cadence_problems(live, start, end, MAX_GAP_WALL_S * speed, input_pauses)
        assert not late, (late, input_pauses)


def caught_up(service: GatewayService, frames_played: int) -> bool:
    """The service has taken every frame played off the bus (decoded or dropped) and its
    core every input off the inbox."""
    reader = service.links[0].reader
    dropped = reader.dropped if reader is not None else 0
    imu = service.imu_decoder.counters
    return imu.frames + imu.ignored + dropped >= frames_played and service.inbox.empty()


def modes(log: Path, until: float = math.inf) -> list[Mode]:
    """Byte 2 of the NAVGW_STATUS frames stamped up to ``until``."""
    return [
        Mode(m.data[2]) for m in read_candump(log)
        if m.arbitration_id == STATUS_ID and m.timestamp <= until
    ]  # fmt: skip


def final_mode(log: Path, inputs_end: float) -> tuple[Mode, float]:
    """Byte 2 of the last NAVGW_STATUS frame before the inputs ended (after it, the IMU is
    silent and the gateway rightly says FAULT), and how long before that end the last frame
    in another mode was stamped (log seconds: how long the final mode had held)."""
    stamped = [
        (m.timestamp, Mode(m.data[2])) for m in read_candump(log)
        if m.arbitration_id == STATUS_ID and m.timestamp <= inputs_end
    ]  # fmt: skip
    final = stamped[-1][1]
    since = next((t for t, mode in reversed(stamped) if mode is not final), stamped[0][0])
    return final, inputs_end - since


@dataclass(frozen=True)
class SteppedClock(TimeBase):
    """The playback's clock, stepped by ``step_s`` (service seconds) from each wall time of
    ``steps`` on: the host clock as NTP or chrony step it, read by the service for the CAN
    stamps, the GNSS receive times and its timers alike."""

    steps: tuple[tuple[float, float], ...] = ()  # (wall time, step_s)

    def at(self, t_wall: float) -> float:
        return super().at(t_wall) + sum(step_s for wall, step_s in self.steps if t_wall >= wall)


def serve_in_process(
    run_dir: Path,
    tmp_path: Path,
    out_log: Path,
    steps_at: Sequence[tuple[float, float]] = (),
    made: Callable[[GatewayService], None] | None = None,
) -> GatewayService:
    """The service object on virtual buses at 8x for 80 s of ``run_dir``'s logs, recording
    its inputs, its frames written to ``out_log`` on the playback's clock; ``steps_at``: (log
    time from the start, step_s) of the host clock the service reads; ``made``: called with
    the service before it runs."""
    truth = Truth.load(run_dir / "truth.npz")
    tag = f"e2e-{os.getpid()}"

    async def main() -> GatewayService:
        with (
            can.Bus(
                interface="virtual", channel=f"navgw-demo-imu-{tag}", preserve_timestamps=True
            ) as imu_bus,
            can.Bus(interface="virtual", channel=f"navgw-demo-isobus-{tag}") as isobus,
            CandumpWriter(out_log) as writer,
            SyncedPlayback(run_dir / "imu.log", run_dir / "gnss.nmea", imu_bus, 8.0, 80.0) as pb,
        ):
            config = dataclasses.replace(
                demo_config(truth, pb.device, tag),
                recording=RecordingSection(enabled=True, directory=str(tmp_path / "rec")),
            )
            timebase = pb.start(time.time() + 0.3)
            host = SteppedClock(
                timebase.origin,
                timebase.origin_wall,
                timebase.speed,
                tuple((timebase.wall_at(truth.t[0] + t), step_s) for t, step_s in steps_at),
            )
            service = GatewayService(config, timebase=host)
            if made is not None:
                made(service)
            with can.Notifier(isobus, [OutputLog(writer, timebase)]):
                running = asyncio.create_task(service.run())
                while not pb.wait(0):
                    await asyncio.sleep(0.1)
                # a loaded host may leave the service behind: let it read what was played
                deadline = time.monotonic() + 10.0
                while not caught_up(service, pb.frames_sent) and time.monotonic() < deadline:
                    await asyncio.sleep(0.05)
                await asyncio.sleep(0.3)
                service.request_stop()
                assert await running == 0
        return service

    return asyncio.run(main())


def check_accounted(service: GatewayService) -> bool:
    """Every sample played is accounted for, received or counted lost; on a virtual bus
    nothing is lost on the way, so a sample counted lost is one whose frame the service
    dropped, and counted, itself (a full buffer, or shed as stale: no false losses). Returns
    whether the service kept up (dropped nothing)."""
    imu, stats, core = service.imu_decoder.counters, service.stats, service.core.stats
    counts = (imu, stats, core)
    # (frames shed at the very end are not yet counted lost: no later SEQ showed the gap)
    unaccounted = 80 * IMU_HZ - (imu.samples + imu.lost + imu.out_of_order)
    assert -3 <= unaccounted <= 3 + stats.frames_shed / 2, counts
    assert imu.lost <= stats.can_frames_dropped + stats.frames_shed, counts
    assert imu.duplicates == imu.out_of_order == 0, counts
    # every sample decoded reached the engine or was dropped by the live loop, and counted
    assert core.imu_samples + core.imu_aux + core.imu_dropped == imu.samples + imu.aux, counts
    assert stats.send_errors == 0
    return imu.lost == core.imu_dropped == 0


def check_final_mode(service: GatewayService, out_log: Path, truth: Truth, kept_up: bool) -> None:
    """NAVIGATING at the end, unless the service fell behind: then it may have re-aligned
    and may say less, but not FAULT unless a stall of this process in the last moments left
    it without IMU frames for IMU_SILENT_S (a FAULT that had held for a second is no stall)."""
    final, held_s = final_mode(out_log, truth.t[0] + 80.0)
    stalled = final is Mode.FAULT and held_s < 1.0
    ok = final is Mode.NAVIGATING or (not kept_up and (final is not Mode.FAULT or stalled))
    assert ok, (final, held_s, service.imu_decoder.counters, service.stats)


def check_live_run(service: GatewayService, out_log: Path, truth: Truth) -> list[Decoded]:
    """What a run of :func:`serve_in_process` sent (``out_log``), checked: returns it decoded.

    Nothing implausible; every sample accounted for. 8x magnifies the host's stalls 8 times:
    a loaded host may make the service shed stale samples, each gap DEGRADED for a while, a
    long one a new alignment: then it sends fewer frames, and says so, but no wrong one;
    else it navigates to the end at 50 Hz. What it sent is within the accuracy it stated,
    loaded or not (a few frames may be beyond 3 sigma by chance); one that fell behind may
    have re-aligned on the move, and then said it was less accurate: it is held to accuracy
    only if it kept up."""
    live = decode_log(out_log)
    check_plausible(live, truth, speed=8.0, log=out_log)
    kept_up = check_accounted(service)
    check_final_mode(service, out_log, truth, kept_up)
    check_output(live, truth, 80.0 - 0.5, speed=8.0, kept_up=kept_up)
    checked, beyond = tilt_beyond_stated(out_log, truth, lag_s=MAX_GAP_WALL_S * 8.0)
    assert checked > 500 and len(beyond) <= 0.005 * checked, beyond[:20]
    if kept_up:
        err = attitude_errors_deg(live, truth, after_s=ALIGNED_S)
        rms = np.sqrt(np.mean(err[np.isfinite(err[:, :2]).all(axis=1)] ** 2, axis=0))
        assert rms[0] < 1.0 and rms[1] < 1.0, rms  # roll, pitch (live, 8x the host's jitter)
        assert np.nanmedian(position_errors_m(live, truth, after_s=ALIGNED_S)) < 1.0
    return live


def test_in_process_on_virtual_faster_than_real_time(run_dir: Path, tmp_path: Path) -> None:
    """The service object on virtual buses at 8x; its recording replays to the same frames."""
    truth = Truth.load(run_dir / "truth.npz")
    out_log = tmp_path / "live.log"
    service = serve_in_process(run_dir, tmp_path, out_log)
    live = check_live_run(service, out_log, truth)
    imu, core = service.imu_decoder.counters, service.core.stats

    # the recording replays with navgw replay and the service's config, to the frames the
    # live service sent (without the config's 3 m antenna mast it went 2 deg off)
    (stem,) = {p.name.split(".")[0] for p in (tmp_path / "rec").iterdir()}
    rec_can, rec_nmea = (tmp_path / "rec" / (stem + s) for s in (".imu.log", ".gnss.nmea"))
    config_file = tmp_path / "navgw.toml"
    config_file.write_text(config_toml(service.config, "e2e", [*SECTIONS, *ENGINE_SECTIONS]))
    rec_out = tmp_path / "rec-out.log"
    result = subprocess.run(
        [sys.executable, "-m", "gateway.cli.main", "replay", "--can", str(rec_can), "--nmea",
         str(rec_nmea), "--config", str(config_file), "--out", str(rec_out)],
        cwd=REPO, capture_output=True, text=True, check=False,
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    assert "the engine raised" not in result.stderr, result.stderr
    replayed = decode_log(rec_out)
    bad = implausible_frames(replayed, truth, status=status_modes(rec_out))
    assert not bad, f"{len(bad)} implausible frames in the replay:\n" + "\n".join(bad[:20])
    checked, beyond = tilt_beyond_stated(rec_out, truth)
    assert checked > 500 and len(beyond) <= 0.005 * checked, beyond[:20]
    # Replay feeds the engine every sample recorded. Live may have dropped a few stale ones
    # (at 8x a 13 ms pause of the host is 100 ms of log time): each is bridged by the next
    # sample, nothing a frame would show. A restarted engine re-aligned where replay's did not.
    if core.engine_restarts or imu.lost + core.imu_dropped > 0.001 * 80 * IMU_HZ:
        return
    d = lagged_differences_deg(live, replayed, truth.t[0] + 5, 0.5)
    # Same inputs, but live feeds a fix when the decoder emits it (up to a GNSS epoch after its
    # last sentence), replay at its time; at 8x the GNSS read lag is 8x too: loose for yaw.
    p95 = np.percentile(d, 95, axis=0)
    assert p95[0] < 0.25 and p95[1] < 0.25 and np.median(d[:, 2]) < 0.5, p95


def test_in_process_through_steps_of_the_host_clock(
    run_dir: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The host clock the service reads steps +0.3 s at 50 s and -1 s at 65 s (the CAN
    stamps, the GNSS receive times and the timers alike, as chrony's or ntpd's steps do).
    Both are found and taken out: the fixes reach the core with the receive delays they
    had before (a busy host only adds to them), and the same checks hold as without the
    steps. On the tree before, the IMU's anchor slid 0.3 s over 10 s, its samples that far
    behind the clock dropped as stale (2,420 of them), and the fixes took both steps into
    their delays (replay of such logs: 3 % of the observer's tilt frames beyond their stated
    accuracy, 809 positions beyond NAVIGATING's 0.2 m).

    A fix read between a step and the IMU's arrivals showing it (0.25-0.375 s) is on the new
    clock, as nothing yet tells the service otherwise (a step back: dropped as out of order);
    under load a reader held up past the step read one so (CI, 2026-12-07: -0.89 s of
    delay, the step -1 s): such fixes are left out of the delays compared."""
    truth = Truth.load(run_dir / "truth.npz")
    out_log = tmp_path / "live.log"
    delays: list[tuple[float, float]] = []  # (UTC from the start, receive delay), s

    def watch(service: GatewayService) -> None:
        on_input = service.core.on_input
        clock = service.timebase
        assert isinstance(clock, SteppedClock)

        def seen(item: ImuSample | ImuAux | GnssFix | BusFrame) -> Iterator[can.Message]:
            stepped = sum(time.time() >= wall for wall, _ in clock.steps)
            found = len(service.imu_decoder.host_clock.steps)
            if isinstance(item, GnssFix) and item.t_utc is not None and stepped == found:
                delays.append((item.t_utc - truth.t[0], item.t - item.t_utc))
            return on_input(item)

        monkeypatch.setattr(service.core, "on_input", seen)

    steps_at = ((50.0, 0.3), (65.0, -1.0))
    service = serve_in_process(run_dir, tmp_path, out_log, steps_at, made=watch)
    steps = service.imu_decoder.host_clock.steps
    assert [round(s.delta_s, 2) for s in steps] == [0.3, -1.0], steps
    least = [  # before, between and after the steps
        min(d for t, d in delays if t0 + 1.0 < t < t1) for t0, t1 in [(10, 50), (50, 65), (65, 80)]
    ]
    # at 8x a host's pause of 12 ms is 0.1 s of receive delay: the least rises under load
    assert least[0] - 0.05 <= least[1] <= least[0] + 0.15, least
    assert least[0] - 0.05 <= least[2] <= least[0] + 0.15, least
    check_live_run(service, out_log, truth)


@pytest.fixture(scope="module")
def multicast_route() -> Iterator[None]:
    """Route the udp_multicast group to loopback for the test, as NOTES.md says; undo after."""
    ip = shutil.which("ip")
    if ip is None or os.geteuid() != 0:
        pytest.skip("udp_multicast across processes needs 'ip route add 239.74.163.2/32 dev lo' "
                    "(root) on this host")  # fmt: skip
    link = subprocess.run([ip, "link", "show", "lo"], capture_output=True, text=True, check=False)
    set_multicast = "MULTICAST" not in link.stdout
    if set_multicast and subprocess.run([ip, "link", "set", "lo", "multicast", "on"]).returncode:
        pytest.skip("cannot enable multicast on lo")
    added = subprocess.run(
        [ip, "route", "add", f"{GROUP}/32", "dev", "lo"], capture_output=True, text=True
    )
    if added.returncode and "File exists" not in added.stderr:
        pytest.skip(f"cannot route {GROUP} to lo: {added.stderr.strip()}")
    yield
    if added.returncode == 0:
        subprocess.run([ip, "route", "del", f"{GROUP}/32", "dev", "lo"], check=False)
    if set_multicast:
        subprocess.run([ip, "link", "set", "lo", "multicast", "off"], check=False)


def test_subprocess_on_udp_multicast_in_real_time(
    run_dir: Path, tmp_path: Path, multicast_route: None
) -> None:
    """``navgw run`` in its own process, 45 s of the short run played in real time."""
    truth = Truth.load(run_dir / "truth.npz")
    port = random.randrange(43200, 43999)  # a group of its own: other tests may use the default
    out_log = tmp_path / "live.log"
    notify = NotifySocket(tmp_path / "notify.sock")
    with (
        can.Bus(interface="udp_multicast", channel=GROUP, port=port) as tx,
        can.Bus(interface="udp_multicast", channel=GROUP, port=port) as rx,
        CandumpWriter(out_log) as writer,
        SyncedPlayback(run_dir / "imu.log", run_dir / "gnss.nmea", tx, 1.0, 45.0) as pb,
    ):
        config = tmp_path / "navgw.toml"
        lever = {
            k: [float(v) for v in getattr(truth, k)]
            for k in ("antenna_lever_arm_m", "imu_lever_arm_m")
        }
        config.write_text(
            "[vehicle]\n" + "".join(f"{k} = {v}\n" for k, v in lever.items())
            + f'[imu]\ninterface = "udp_multicast"\nchannel = "{GROUP}"\n'
            + f'[gnss]\nport = "{pb.device}"\nreceiver_latency_s = 0.065\n'
            + "receiver_latency_sigma_s = 0.01\n"  # the player's latency, measured
        )  # fmt: skip
        env = {
            **os.environ,
            "NOTIFY_SOCKET": str(notify.path),
            "CAN_CONFIG": json.dumps({"port": port}),
        }
        proc = subprocess.Popen(
            [sys.executable, "-m", "gateway.cli.main", "run", "--config", str(config)],
            cwd=REPO, env=env, stderr=subprocess.PIPE, text=True,
        )  # fmt: skip
        try:
            assert notify.wait_for("READY=1", 20.0), f"no READY=1: {proc.poll()}"
            timebase = pb.start(time.time() + 0.5)
            with can.Notifier(rx, [OutputLog(writer, timebase)]):
                assert pb.wait(60.0)
                time.sleep(0.5)
                proc.send_signal(signal.SIGTERM)
                assert proc.wait(timeout=5.0) == 0
        finally:
            if proc.poll() is None:
                proc.kill()
            stderr = proc.communicate()[1]
            notify.close()
    assert "Traceback" not in stderr, stderr
    live = decode_log(out_log)
    check_plausible(live, truth, speed=1.0, log=out_log)
    ours = [m for m in read_candump(out_log) if m.arbitration_id & 0xFF == 0x1C]
    # udp_multicast echoes our request: it must not be answered with a second claim
    assert sum(m.arbitration_id == CLAIM_ID for m in ours) == 1
    # the IMU frames as they went on the bus (kernel stamps): where the test's player stalled
    # (a loaded host), the gateway had nothing to work on, and rightly says DEGRADED after
    played = [m.timestamp for m in read_candump(out_log) if m.arbitration_id & 0xFF == 0x80]
    stalls = pauses(played, MAX_IMU_STEP_S)
    t_end = truth.t[0] + 45.0
    shed = "dropped" in stderr  # the gateway says it dropped IMU input (it fell behind)
    recent_stall = any(b > t_end - IMU_GAP_DEGRADED_S - 1.0 for _, b in stalls)
    final, _ = final_mode(out_log, played[-1])
    assert Mode.NAVIGATING in modes(out_log)
    assert final is Mode.NAVIGATING or (final is Mode.DEGRADED and (recent_stall or shed)), (
        final, stalls, stderr[-2000:])  # fmt: skip
    check_output(live, truth, 45.0 - 0.5, speed=1.0, input_pauses=stalls)
    err = attitude_errors_deg(live, truth, after_s=ALIGNED_S)
    rms = np.sqrt(np.mean(err**2, axis=0))
    assert rms[0] < 1.0 and rms[1] < 1.0, rms
    assert np.median(position_errors_m(live, truth, after_s=ALIGNED_S)) < 1.0

    # live and replay of the same logs: the same attitude within timing jitter, except while
    # the live gateway bridged a stall of its inputs (or its own)
    if shed:
        return
    replay(run_dir / "imu.log", run_dir / "gnss.nmea", tmp_path / "replay.log",
           demo_config(truth, "", ""))  # fmt: skip
    bridged = [(a, b + IMU_GAP_DEGRADED_S) for a, b in stalls]
    d = lagged_differences_deg(live, decode_log(tmp_path / "replay.log"), truth.t[0] + 5, 0.1,
                               bridged)  # fmt: skip
    rms_d = np.sqrt(np.mean(d**2, axis=0))
    assert rms_d[0] < 0.1 and rms_d[1] < 0.1 and rms_d[2] < 0.3, rms_d
