"""navgw replay (SPEC 5): end to end on simulated logs, read back by an independent decoder."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import can
import numpy as np
import pytest

from drivers.logs.candump import CandumpWriter, read_candump
from gateway.config.gateway_config import load_config
from gateway.estimation.solution import Mode
from gateway.fusion.fusion_core import LOST_WINDOW_S, FusionCore
from gateway.isobus.j1939 import Pgn, can_id
from gateway.offline import log_inputs
from gateway.offline.log_replay import replay
from sim_bus.scenarios import SCENARIOS, generate
from sim_bus.truth import Truth
from tests.n2k_check import attitude_errors_deg, decode_log, position_errors_m


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("replay")
    generate(SCENARIOS["short"], out, seed=3)
    return out


def test_output_decodes_independently_to_the_truth(run_dir: Path, tmp_path: Path) -> None:
    truth = Truth.load(run_dir / "truth.npz")
    config = load_config(run_dir / "navgw.toml")  # what navgw sim wrote for its vehicle
    summary = replay(run_dir / "imu.log", run_dir / "gnss.nmea", tmp_path / "out.log", config)
    assert summary.stats.imu_samples == len(truth)
    assert summary.imu.lost == summary.bad_can_lines == summary.gnss.checksum_errors == 0
    messages = decode_log(tmp_path / "out.log")
    ids = [m.id for m in messages]
    # the address claim comes first, and nothing else before it
    assert ids[:2] == ["isoRequest", "isoAddressClaim"]
    span = truth.t[-1] - truth.t[0]
    assert ids.count("attitude") == pytest.approx(50 * span, abs=50)
    assert ids.count("gnssPositionData") == pytest.approx(10 * span, abs=10)
    err = attitude_errors_deg(messages, truth, after_s=60.0)
    rms = np.sqrt(np.mean(err**2, axis=0))
    assert rms[0] < 0.5 and rms[1] < 0.5, rms  # roll, pitch
    assert rms[2] < 2.0, rms  # yaw
    pos = position_errors_m(messages, truth, after_s=60.0)
    assert np.sqrt(np.mean(pos**2)) < 0.1


def test_replay_is_byte_identical_run_to_run(run_dir: Path, tmp_path: Path) -> None:
    for name in ("a.log", "b.log"):
        replay(run_dir / "imu.log", run_dir / "gnss.nmea", tmp_path / name)
    assert (tmp_path / "a.log").read_bytes() == (tmp_path / "b.log").read_bytes()


def test_damaged_logs_are_counted_not_fatal(run_dir: Path, tmp_path: Path) -> None:
    lines = (run_dir / "imu.log").read_text().splitlines(keepends=True)
    damaged = tmp_path / "imu.log"
    damaged.write_text(
        "".join(lines[:5000]) + "garbage here\n(12.5) can0 XYZ#00\n" + "".join(lines[5000:10000])
    )
    summary = replay(damaged, run_dir / "gnss.nmea", tmp_path / "out.log")
    assert summary.bad_can_lines == 2
    accel_frames = sum(" 0CFF1180#" in line for line in lines[:10000])  # each closes a sample
    assert summary.stats.imu_samples == accel_frames  # every intact sample survives
    assert summary.stats.frames_out > 0


def test_a_frame_stamped_decades_early_changes_no_output(run_dir: Path, tmp_path: Path) -> None:
    """One candump line whose time lost a digit (1700000009.98 -> 170000009.98: 48 years
    early), as a flipped byte on a copied log makes it. The decoder took it for a host
    clock stepped back and moved every GNSS time after it by as much: the replay stated
    the tilt on 117 frames of 3,573 (`short` seed 11, 1 Hz). Its partner frame's time is
    the sample's: the output is the clean log's, byte for byte."""
    lines = (run_dir / "imu.log").read_text().splitlines(keepends=True)
    i = next(k for k, line in enumerate(lines) if k > 4000 and " 0CFF1080#" in line)
    stamp_s = lines[i][1 : lines[i].index(")")]
    assert stamp_s.startswith("1700000")
    damaged = tmp_path / "imu.log"
    damaged.write_text(
        "".join(
            [*lines[:i], "(" + stamp_s.replace("0", "", 1) + lines[i][len(stamp_s) + 1 :]]
            + lines[i + 1 :]
        )
    )
    clean = replay(run_dir / "imu.log", run_dir / "gnss.nmea", tmp_path / "clean.log")
    summary = replay(damaged, run_dir / "gnss.nmea", tmp_path / "damaged.log")
    assert summary.stats.imu_samples == clean.stats.imu_samples
    assert (tmp_path / "damaged.log").read_bytes() == (tmp_path / "clean.log").read_bytes()
    assert (summary.imu.bad_stamps, summary.imu.clock_steps) == (1, 0)


def test_decoding_ahead_tells_each_loss_on_the_bus_when_live_would(
    run_dir: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Replay decodes the CAN log up to DECODE_AHEAD inputs ahead of the fusion core; the
    IMU samples lost on the bus reach NAVGW_STATUS (byte 6) with the first sample after the
    gap, as live: byte-identical to decoding one input at a time, and never, at a GNSS fix
    within the gap, a loss the bus has not shown yet."""
    lines = (run_dir / "imu.log").read_text().splitlines(keepends=True)
    gyro = [i for i, line in enumerate(lines) if " 0CFF1080#" in line]  # each opens a sample
    cuts = {4000: 6, 9000: 40, 12000: 200, 16000: 2}  # from the sample at line ~k: n samples
    kept, i, gap_s = [], 0, {}
    for k, n in sorted(cuts.items()):
        j = next(x for x, line in enumerate(gyro) if line >= k)
        kept += lines[i : gyro[j]]
        i = gyro[j + n]
        gap_s[n] = (stamp(lines[gyro[j] - 1]), stamp(lines[i]))
    gappy = tmp_path / "imu.log"
    gappy.write_text("".join(kept + lines[i:]))
    outputs = {}
    for ahead in (log_inputs.DECODE_AHEAD, 1):
        monkeypatch.setattr(log_inputs, "DECODE_AHEAD", ahead)
        out = tmp_path / f"ahead{ahead}.log"
        summary = replay(gappy, run_dir / "gnss.nmea", out)
        assert summary.imu.lost == sum(cuts.values())
        outputs[ahead] = out.read_bytes()
    assert outputs[1] == outputs[log_inputs.DECODE_AHEAD]
    told = [
        (float(f.timestamp), f.data[6])
        for f in read_candump(tmp_path / "ahead1.log")
        if (f.arbitration_id >> 8) & 0x3FFFF == Pgn.NAVGW_STATUS
    ]
    rate_hz = 204.8
    for n in (40, 200):
        start, end = gap_s[n]
        # within the gap (FAULT, IMU silent): the samples missed so far, no more
        within = [(t, lost) for t, lost in told if start < t < end - 0.01]
        assert all(lost <= (t - start) * rate_hz + 1 for t, lost in within), within
        # from the first sample after it (stamped with its sample time, a little before
        # its frame arrived): the gap's count, for a second (STATUS at 10 Hz)
        after = [lost for t, lost in told if t >= end - 0.01]
        assert after[0] == n
        assert max(after[: int(LOST_WINDOW_S / 0.1) - 1]) == n
    assert any(lost > 0 for t, lost in told if gap_s[200][0] < t < gap_s[200][1] - 0.01)


def stamp(line: str) -> float:
    """The host time of a candump -L line."""
    return float(line.split(")")[0][1:])


def test_other_nodes_claims_and_requests_replay_into_our_answers(
    run_dir: Path, tmp_path: Path
) -> None:
    """SPEC 5: CAN frames that are not the IMU bridge's are received from the ISOBUS. At 30 s
    a node requests claims (we answer from 0x1C); at 40 s a lower NAME takes 0x1C (we move
    to 0x81, never the bridge's 0x80); at 50 s a node sends from 0x81 (an address violation:
    DEGRADED and our claim again). The recorded gateway's own claim (our NAME) and its own
    frames from 0x1C before 40 s are ours, not a clone: STATUS stays as it was."""
    config = load_config(run_dir / "navgw.toml")
    ours = FusionCore.from_config(config).claimer.name
    lines = (run_dir / "imu.log").read_text().splitlines(keepends=True)
    t0 = float(lines[0].split(")")[0].strip("("))
    claim, request = Pgn.ADDRESS_CLAIM, Pgn.ISO_REQUEST
    others = [  # time after the log's start, source, PGN, data
        (5.0, 0x1C, claim, ours.to_bytes(8, "little")),
        (10.0, 0x1C, Pgn.ATTITUDE, bytes(8)),  # the recorded gateway's own output
        (30.0, 0xFE, request, int(claim).to_bytes(3, "little")),
        (40.0, 0x1C, claim, (1).to_bytes(8, "little")),
        (45.0, 0x1C, Pgn.ATTITUDE, bytes(8)),  # the new holder's: none of our business
        (50.0, 0x81, Pgn.ATTITUDE, bytes(8)),  # someone sends as us
    ]
    extra = tmp_path / "extra.log"
    with CandumpWriter(extra, "can0") as w:
        for t, source, pgn, data in others:
            w.write(can.Message(timestamp=t0 + t, arbitration_id=can_id(pgn, source, 6), data=data))
    merged = tmp_path / "imu.log"
    merged.write_text(
        "".join(
            sorted(
                lines + extra.read_text().splitlines(keepends=True),
                key=lambda line: float(line.split(")")[0].strip("(")),
            )
        )
    )
    out = tmp_path / "out.log"
    replay(merged, run_dir / "gnss.nmea", out, config)
    frames = read_candump(out)
    claims = [
        (f.timestamp - t0, f.arbitration_id & 0xFF)
        for f in frames
        if (f.arbitration_id >> 8) & 0x3FF00 == Pgn.ADDRESS_CLAIM
    ]
    assert [a for t, a in claims if 29.0 < t < 31.0] == [0x1C]  # the request answered
    assert [a for t, a in claims if 39.0 < t < 41.0] == [0x81]  # moved, not onto the bridge
    assert [a for t, a in claims if 41.0 < t < 51.0] == [0x81]  # the violation answered
    sources = {f.arbitration_id & 0xFF for f in frames if f.timestamp - t0 > 41.0}
    assert sources == {0x81}

    def modes(t_from: float, t_to: float) -> set[int]:
        return {
            f.data[2]
            for f in frames
            if (f.arbitration_id >> 8) & 0x3FFFF == 0xFF22 and t_from < f.timestamp - t0 < t_to
        }

    assert int(Mode.DEGRADED) not in modes(5.0, 30.0)  # recorded own frames are not a clone's
    assert modes(50.0, 55.0) == {int(Mode.DEGRADED)}  # the violation, at once and held


def navgw(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "gateway.cli.main", *args],
        capture_output=True,
        text=True,
        check=False,
    )


def replay_cli(
    run_dir: Path, can_log: Path, out: Path, *extra: str
) -> subprocess.CompletedProcess[str]:
    return navgw(
        "replay", "--can", str(can_log), "--nmea", str(run_dir / "gnss.nmea"), "--out", str(out),
        *extra,
    )  # fmt: skip


def test_cli_exit_status_and_messages(run_dir: Path, tmp_path: Path) -> None:
    ok = replay_cli(run_dir, run_dir / "imu.log", tmp_path / "o.log")
    assert ok.returncode == 0, ok.stderr
    assert "IMU:" in ok.stderr and "x real time" in ok.stderr
    # no --config: zero lever arms, said once, as navgw run says it
    assert ok.stderr.count("antenna_lever_arm_m is zero") == 1, ok.stderr
    missing = replay_cli(run_dir, tmp_path / "nope.log", tmp_path / "o.log")
    assert missing.returncode == 2
    assert f"{tmp_path / 'nope.log'}: CAN log not found or not a file" in missing.stderr
    bad_cfg = tmp_path / "bad.toml"
    bad_cfg.write_text("[vehicle]\nantenna_lever_arm = [0, 0, -3]\n")
    bad = replay_cli(run_dir, run_dir / "imu.log", tmp_path / "o.log", "--config", str(bad_cfg))
    assert bad.returncode == 2
    assert (
        "unknown key vehicle.antenna_lever_arm: expected one of antenna_lever_arm_m" in bad.stderr
    )


@pytest.mark.parametrize("damage", ["empty", "garbage", "binary", "swapped"])
def test_unreadable_logs_exit_2_naming_what_was_expected(
    run_dir: Path, tmp_path: Path, damage: str
) -> None:
    """SPEC 5: non-zero with a clear message on unreadable input (it exited 0, 0 frames)."""
    can_log, nmea_log = tmp_path / "imu.log", tmp_path / "gnss.nmea"
    if damage == "swapped":
        can_log.write_bytes((run_dir / "gnss.nmea").read_bytes())
        nmea_log.write_bytes((run_dir / "imu.log").read_bytes())
    else:
        junk = {
            "empty": b"",
            "garbage": b"hello world\nthis is not a log\n" * 50,
            "binary": bytes(range(256)) * 40,
        }[damage]
        can_log.write_bytes(junk)
        nmea_log.write_bytes(junk)
    result = navgw(
        "replay", "--can", str(can_log), "--nmea", str(nmea_log), "--out", str(tmp_path / "o.log")
    )
    assert result.returncode == 2, result.stderr
    last = result.stderr.strip().splitlines()[-2:]
    assert f"{can_log}: no IMU sample" in last[0] and "expected candump -L" in last[0]
    assert f"{nmea_log}: no GNSS fix" in last[1] and "expected NMEA 0183" in last[1]
    assert max(len(line) for line in result.stderr.splitlines()) < 400
