"""``navgw monitor``: the Textual app driven headless (``run_test``) over a replayed run's
output log and over a python-can ``virtual`` bus; its log source on a fake clock; its CLI."""

from __future__ import annotations

import asyncio
import itertools
import time
from collections.abc import Callable
from pathlib import Path

import can
import pytest
from textual.pilot import Pilot
from textual.widgets import DataTable, Static

from drivers.logs.candump import read_candump
from gateway.cli.main import main
from gateway.monitor.app import MonitorApp
from gateway.monitor.bus_state import BusState
from gateway.monitor.sources import BusSource, LogSource
from tests.output_run import OutputRun, expected_text, make_output_run

SIZE = (160, 50)


@pytest.fixture(scope="module")
def run(tmp_path_factory: pytest.TempPathFactory) -> OutputRun:
    return make_output_run(tmp_path_factory.mktemp("monitor-app"))


def text(app: MonitorApp, selector: str) -> str:
    return str(app.query_one(selector, Static).content)


def rows(app: MonitorApp, selector: str) -> list[list[str]]:
    table = app.query_one(selector, DataTable)
    return [[str(c) for c in table.get_row_at(i)] for i in range(table.row_count)]


async def until(pilot: Pilot[None], done: Callable[[], bool], timeout_s: float = 30.0) -> None:
    """Wait until ``done()``: as long as a busy host needs, not a fixed pause."""
    give_up = time.monotonic() + timeout_s
    while not done():
        assert time.monotonic() < give_up, f"not reached in {timeout_s} s"
        await pilot.pause(0.05)


def test_the_monitor_shows_a_recorded_run(run: OutputRun) -> None:
    expected = expected_text(run.log)

    async def scenario() -> None:
        app = MonitorApp(LogSource(run.log, speed=500.0))  # 125 s of log in 0.25 s
        async with app.run_test(size=SIZE) as pilot:
            await until(pilot, lambda: app.source.ended)
            end = f"END OF log {run.log} at 500x"
            await until(pilot, lambda: text(app, "#banner").startswith(end))  # redrawn
            assert text(app, "#mode") == "mode      NAVIGATING"
            assert "fix       RTK fixed" in text(app, "#status")
            assert expected["gyro"] in text(app, "#biases")
            assert expected["converged"] in text(app, "#biases")
            assert expected["latitude"] in text(app, "#motion")
            rates = rows(app, "#rates")
            assert ["attitude", "50.0", "50", "ok"] in rates
            assert ["navgw gyro bias", "1.0", "1", "ok"] in rates
            (claim,) = rows(app, "#claims")
            assert claim[:2] == ["0x1C", "navgw"] and claim[2].startswith("identity 1, ")
            assert text(app, "#spark-gyro-x-label") == f"gyro x {expected['gyro x']}"
            assert text(app, "#sources") == "sources: [0x1C navgw]"
            assert "unknown 0  malformed 0" in text(app, "#counters")
            await pilot.press("n")  # one source: it stays
            assert text(app, "#sources") == "sources: [0x1C navgw]"

    asyncio.run(scenario())


def test_the_monitor_on_a_virtual_bus_banners_an_idle_then_a_stopped_bus(run: OutputRun) -> None:
    channel = f"navgw-monitor-test-{id(run)}"
    frames = list(itertools.islice(read_candump(run.log), 600))  # the claim and ~0.5 s
    stall_s = 2.0
    idle = f"no frames received yet from virtual {channel}: is the bus up, is navgw running?"

    async def scenario() -> None:
        source = BusSource("virtual", channel)
        app = MonitorApp(source, BusState(stall_s=stall_s))
        with can.Bus(interface="virtual", channel=channel) as sender:
            async with app.run_test(size=SIZE) as pilot:
                await until(pilot, lambda: text(app, "#banner") == idle)
                for msg in frames:
                    sender.send(msg)
                sent_at = time.monotonic()
                await until(pilot, lambda: f"frames {len(frames)} " in text(app, "#counters"))
                if time.monotonic() - sent_at < stall_s:  # shown before the bus could stall
                    assert text(app, "#banner") == ""
                assert text(app, "#mode") in ("mode      INITIALISING", "mode      ALIGNING")
                assert rows(app, "#claims")[0][:2] == ["0x1C", "navgw"]
                await until(pilot, lambda: text(app, "#banner").startswith("NO FRAMES for "))
                assert time.monotonic() - sent_at >= stall_s  # not before the silence

    asyncio.run(scenario())


def test_a_log_source_follows_its_speed_and_stops_at_its_end(run: OutputRun) -> None:
    wall = [0.0]
    source = LogSource(run.log, speed=10.0, clock=lambda: wall[0])
    t0 = next(iter(read_candump(run.log))).timestamp
    first = source.poll(10_000)
    assert [m.timestamp for m in first] == [t0]  # only what is due at the start
    wall[0] = 0.1  # 1 s of log
    second = source.poll(10_000)
    assert second[-1].timestamp <= t0 + 1.0 < source._next.timestamp  # type: ignore[union-attr]
    assert source.now() == pytest.approx(t0 + 1.0)
    wall[0] = 0.2
    limited = source.poll(5)  # behind the log clock, now() is the last frame's time
    assert len(limited) == 5 and source.now() == limited[-1].timestamp < t0 + 2.0
    wall[0] = 1e6
    while source.poll(100_000):
        pass
    assert source.ended and source.bad_lines == 0
    assert source.now() == next(reversed(list(read_candump(run.log)))).timestamp


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--log", "nowhere.log"], "--log nowhere.log: No such file or directory; expected a "
         "readable candump -L log"),
        (["--log", "LOG", "--speed", "0"], "--speed 0.0: expected a number > 0"),
        (["--log", "LOG", "--channel", "can1"], "--log reads a file: give it without"),
        (["--speed", "2"], "--speed is for --log"),
        (["--log", "LOG", "--config", "nowhere.toml"], "nowhere.toml: cannot read config file"),
        (["--interface", "no-such-interface"], "cannot open CAN interface 'no-such-interface' "
         "channel 'can0': "),
    ],
)  # fmt: skip
def test_bad_options_say_what_and_exit_2(
    argv: list[str], message: str, run: OutputRun, capsys: pytest.CaptureFixture[str]
) -> None:
    argv = [str(run.log) if a == "LOG" else a for a in argv]
    assert main(["monitor", *argv]) == 2
    err = capsys.readouterr().err
    assert err.startswith("navgw monitor: ") and message in err
    assert "Traceback" not in err


def test_an_empty_log_is_shown_as_ended(tmp_path: Path) -> None:
    empty = tmp_path / "empty.log"
    empty.write_text("not a candump line\n")

    async def scenario() -> None:
        app = MonitorApp(LogSource(empty))
        async with app.run_test(size=SIZE) as pilot:
            await pilot.pause(0.2)
            assert text(app, "#banner").startswith("END OF log")
            assert text(app, "#mode") == "mode      no status"
            assert "frames 0 " in text(app, "#counters")

    asyncio.run(scenario())
