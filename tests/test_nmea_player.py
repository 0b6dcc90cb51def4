"""NMEA player: lines reach a pyserial reader through a real pty, in order, across reopens."""

from __future__ import annotations

import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
import serial

from drivers.logs.nmea_log import write_nmea_log
from sim_bus.nmea_player import Detached, NmeaPlayer, play_nmea_lines

T0 = 1_700_000_000.0


def numbered(n: int, period_s: float) -> list[tuple[float | None, str]]:
    """n distinct sentences, one every period_s of host time."""
    return [(T0 + i * period_s, f"$GNTXT,01,01,02,line {i:05d}*00") for i in range(n)]


def read_lines(
    port: serial.Serial, n: int, until: str | None = None, deadline_s: float = 5.0
) -> list[str]:
    """Up to n whole lines, stopping after the line ``until`` or at the deadline."""
    out: list[str] = []
    end = time.monotonic() + deadline_s
    while len(out) < n and time.monotonic() < end and (not out or out[-1] != until):
        raw = port.readline()
        if raw:
            assert raw.endswith(b"\r\n")
            out.append(raw.decode("ascii").rstrip("\r\n"))
    return out


def test_every_line_in_order_as_fast_as_possible() -> None:
    lines = numbered(2000, 0.1)  # 200 s of log, 130 kB: more than a pty buffer holds
    with NmeaPlayer(lines, speed=float("inf")) as player:
        with serial.Serial(player.device, 115200, timeout=1.0) as port:
            got = read_lines(port, len(lines))
        assert player.wait(1.0)
    assert got == [s for _, s in lines]
    assert player.stats.sent == len(lines) and player.stats.dropped == 0


def test_real_time_pacing_with_speed_factor() -> None:
    lines = numbered(11, 0.5)  # 5 s of log at speed 10: 0.5 s
    arrivals = []
    with NmeaPlayer(lines, speed=10.0) as player, serial.Serial(player.device, timeout=1.0) as port:
        for _ in lines:
            assert port.readline()
            arrivals.append(time.monotonic())
    elapsed = arrivals[-1] - arrivals[0]
    assert 0.45 < elapsed < 1.2  # upper bound loose for a loaded machine


def test_reader_closes_and_reopens_mid_stream() -> None:
    lines = numbered(60, 0.05)  # 3 s at 20 Hz, real time
    with NmeaPlayer(lines, speed=2.0) as player:
        with serial.Serial(player.device, 115200, timeout=1.0) as port:
            first = read_lines(port, 10)
        time.sleep(0.5)  # ~10 lines due with nobody listening: dropped, like an unplugged cable
        with serial.Serial(player.device, 115200, timeout=1.0) as port:
            rest = read_lines(port, 60, until=lines[-1][1])
        assert player.wait(1.0)
    sent = [s for _, s in lines]
    assert first == sent[:10]
    k = sent.index(rest[0])
    assert k >= 15  # skipped the lines due while closed ...
    assert rest == sent[k:]  # ... and got every later one, whole and in order
    assert player.stats.sent + player.stats.dropped == len(lines)
    assert player.stats.dropped >= 5


def test_pause_mode_loses_nothing_across_a_reopen() -> None:
    lines = numbered(40, 0.05)
    with NmeaPlayer(lines, speed=2.0, detached=Detached.PAUSE) as player:
        with serial.Serial(player.device, 115200, timeout=1.0) as port:
            first = read_lines(port, 10)
        time.sleep(0.3)
        with serial.Serial(player.device, 115200, timeout=1.0) as port:
            rest = read_lines(port, 40, until=lines[-1][1])
    sent = [s for _, s in lines]
    assert first == sent[:10]
    # at most the lines written between the reader's last read and its close are flushed
    assert rest == sent[len(sent) - len(rest) :] and len(first) + len(rest) >= len(sent) - 2


def test_symlink_and_blocking_play_function(tmp_path: Path) -> None:
    link = tmp_path / "gnss0"
    lines = numbered(20, 0.01)
    got: list[str] = []
    readers: list[threading.Thread] = []

    def ready(device: str) -> None:
        assert link.resolve() == Path(device).resolve()
        port = serial.Serial(str(link), 115200, timeout=1.0)  # opened: playback starts

        def read() -> None:
            with port:
                got.extend(read_lines(port, len(lines)))

        readers.append(threading.Thread(target=read))
        readers[0].start()

    stats = play_nmea_lines(lines, speed=float("inf"), link=link, on_ready=ready, linger_s=10.0)
    readers[0].join()
    assert got == [s for _, s in lines] and stats.sent == 20
    assert not link.exists()


def test_command_line_prints_the_device(tmp_path: Path) -> None:
    log = tmp_path / "gnss.nmea"
    write_nmea_log(log, numbered(30, 0.1))
    proc = subprocess.Popen(
        [sys.executable, "-m", "sim_bus.nmea_player", str(log), "--speed", "10"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        cwd=Path(__file__).parent.parent,
    )
    try:
        assert proc.stdout is not None
        device = proc.stdout.readline().strip()
        assert device.startswith("/dev/")
        with serial.Serial(device, 115200, timeout=1.0) as port:
            got = read_lines(port, 30)
        assert len(got) == 30
        assert proc.wait(5.0) == 0
    finally:
        proc.kill()
        proc.wait()


def test_speed_must_be_positive() -> None:
    with pytest.raises(ValueError, match="speed"):
        NmeaPlayer([], speed=0.0)
