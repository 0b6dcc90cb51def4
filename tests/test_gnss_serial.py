"""Serial reader on real pseudo-terminals: a real log played, a device vanishing and returning."""

from __future__ import annotations

import asyncio
import calendar
import logging
import math
import os
from collections.abc import Callable, Iterator
from dataclasses import replace
from pathlib import Path

import pytest

from drivers.gnss_serial import GnssSerialReader
from drivers.logs.nmea_log import read_nmea_log
from drivers.nmea import nmea_checksum, read_fixes_from_log
from drivers.samples import FixQuality, GnssFix
from sim_bus.nmea_player import Detached, NmeaPlayer

DAY = float(calendar.timegm((2024, 5, 1, 0, 0, 0)))


def epoch_bytes(second: int) -> list[bytes]:
    """The six sentences of one 1 Hz epoch at 12:00:<second> UTC on 2024-05-01."""
    tod = f"1200{second:02d}.00"
    bodies = [
        f"GNRMC,{tod},A,4807.0380,N,01131.0000,E,1.0,90.0,010524,,,R",
        "GNVTG,90.0,T,,M,1.0,N,1.9,K,R",
        f"GNGGA,{tod},4807.0380,N,01131.0000,E,4,20,0.6,500.0,M,47.0,M,1.0,0001",
        f"GNGST,{tod},0.5,0.02,0.01,30.0,0.011,0.012,0.020",
        f"GNZDA,{tod},01,05,2024,00,00",
        "GNHDT,45.0,T",
    ]
    return [f"${b}*{nmea_checksum(b):02X}\r\n".encode() for b in bodies]


def clock() -> Callable[[], float]:
    ticks: Iterator[float] = (2000.0 + i for i in range(1_000_000))
    return lambda: next(ticks)


async def until(condition: Callable[[], bool], timeout_s: float = 5.0) -> None:
    deadline = asyncio.get_running_loop().time() + timeout_s
    while not condition():
        assert asyncio.get_running_loop().time() < deadline, "timed out"
        await asyncio.sleep(0.005)


def new_device(link: Path) -> tuple[int, int]:
    """A pseudo-terminal whose slave side appears at ``link`` (like a udev symlink)."""
    master, slave = os.openpty()
    link.unlink(missing_ok=True)
    link.symlink_to(os.ttyname(slave))
    return master, slave


def test_reader_waits_for_the_device_and_survives_it_vanishing(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    link = tmp_path / "gnss0"
    reader = GnssSerialReader(str(link), clock=clock(), backoff_initial_s=0.01, backoff_max_s=0.04)
    got: list[GnssFix] = []

    async def consume() -> None:
        async for fix in reader.fixes():
            got.append(fix)

    async def scenario() -> None:
        task = asyncio.create_task(consume())
        await asyncio.sleep(0.15)  # missing at start: several retries, one log line
        assert not reader.connected
        master, slave = new_device(link)
        await until(lambda: reader.connected)
        for line in epoch_bytes(0) + epoch_bytes(1)[:1]:
            os.write(master, line)
        await until(lambda: len(got) == 1)
        os.close(master)  # the device vanishes: the pending epoch is flushed
        os.close(slave)
        link.unlink()
        await until(lambda: not reader.connected and len(got) == 2)
        await asyncio.sleep(0.15)
        master, slave = new_device(link)
        await until(lambda: reader.connected)
        for line in epoch_bytes(2) + epoch_bytes(3):
            os.write(master, line)
        await until(lambda: len(got) == 4)
        reader.close()
        await task
        os.close(master)
        os.close(slave)

    with caplog.at_level(logging.INFO, logger="drivers.gnss_serial"):
        asyncio.run(scenario())
    assert [f.t_utc for f in got] == [DAY + 43200 + s for s in range(4)]
    assert [f.quality for f in got] == [FixQuality.RTK_FIXED] * 4
    assert got[1].sigma_n_m is None and got[2].sigma_n_m == got[3].sigma_n_m == 0.011
    assert all(2000.0 <= f.t < 2100.0 for f in got)  # host time from the injected clock
    assert reader.decoder.counters.checksum_errors == 0 and not reader.connected
    assert [m.split(" (")[0] for m in caplog.messages] == [
        f"GNSS port {link} not available",
        f"GNSS port {link} connected at 115200 baud",
        f"GNSS port {link} lost; reconnecting",
        f"GNSS port {link} connected at 115200 baud",
    ]


def test_real_log_played_on_a_pty_gives_the_log_fixes() -> None:
    """sim_bus's NMEA player sends nmea-rtk.log through a pty: the same fixes as the log path."""
    path = Path(__file__).parent / "data" / "nmea" / "nmea-rtk.log"
    expected = [replace(f, t=0.0) for f in read_fixes_from_log(path)]
    player = NmeaPlayer(read_nmea_log(path), speed=math.inf, detached=Detached.PAUSE)
    reader = GnssSerialReader(player.start(), clock=clock())
    got: list[GnssFix] = []

    async def consume() -> None:
        async for fix in reader.fixes():
            got.append(replace(fix, t=0.0))
            if len(got) == len(expected):
                reader.close()

    try:
        asyncio.run(asyncio.wait_for(consume(), 10.0))
    finally:
        player.stop()
    assert len(got) == 122 and got == expected
