"""The live service's parts on real python-can buses: reader, echo, inbox, reopen, CLI errors."""

from __future__ import annotations

import asyncio
import itertools
import subprocess
import sys
import time
from pathlib import Path

import can
import pytest

from drivers.canbus import FrameReader
from drivers.errors import BusError
from drivers.samples import ImuAux
from gateway.canbus import BusPlan, EchoFilter, claim_filters, is_bus_down
from gateway.cli import build_parser, main
from gateway.config import GatewayConfig, ImuSection, example_toml
from gateway.config_schema import ConfigError
from gateway.j1939 import Pgn, can_id
from gateway.service import GatewayService, Inbox

REPO = Path(__file__).resolve().parents[1]
_channels = itertools.count()


def channel() -> str:
    return f"svc{next(_channels)}"


def frame(i: int, arbitration_id: int = 0x0CFF1080) -> can.Message:
    return can.Message(arbitration_id=arbitration_id, data=bytes([i % 256] * 8))


# python-can's notifier thread re-raises a receive error after reporting it to the listener
THREAD_ERROR = pytest.mark.filterwarnings("ignore::pytest.PytestUnhandledThreadExceptionWarning")


@THREAD_ERROR
def test_reader_drops_oldest_when_full_and_ends_with_bus_error() -> None:
    async def main() -> tuple[list[int], int, BaseException | None]:
        ch = channel()
        with (
            can.Bus(interface="virtual", channel=ch) as rx,
            can.Bus(interface="virtual", channel=ch) as tx,
        ):
            async with FrameReader(rx, max_frames=4) as reader:
                for i in range(10):
                    tx.send(frame(i))
                await asyncio.sleep(0.3)  # the notifier thread delivers all ten
                got = [(await reader.__anext__()).data[0] for _ in range(4)]
                rx.shutdown()  # the interface goes away under the reader
                try:
                    await asyncio.wait_for(reader.__anext__(), 3.0)
                except BusError as exc:
                    return got, reader.dropped, exc
        return got, -1, None

    got, dropped, error = asyncio.run(main())
    assert got == [6, 7, 8, 9] and dropped == 6  # the newest frames are kept
    assert isinstance(error, BusError) and "failed" in str(error)


def test_claim_filters_pass_claims_and_requests_only() -> None:
    ch = channel()
    with (
        can.Bus(interface="virtual", channel=ch) as rx,
        can.Bus(interface="virtual", channel=ch) as tx,
    ):
        rx.set_filters(claim_filters())
        for pgn, dest in ((Pgn.ADDRESS_CLAIM, 255), (Pgn.ISO_REQUEST, 0x1C), (Pgn.ATTITUDE, 255)):
            tx.send(can.Message(arbitration_id=can_id(pgn, 0x33, 6, dest), data=b"\0" * 8))
        got = [rx.recv(0.2) for _ in range(3)]
    pgns = [None if m is None else (m.arbitration_id >> 16) & 0xFF for m in got]
    assert pgns == [0xEE, 0xEA, None]


def test_echo_filter_drops_one_copy_per_frame_sent() -> None:
    echo = EchoFilter(window_s=1.0)
    request = can.Message(arbitration_id=can_id(Pgn.ISO_REQUEST, 254, 6), data=b"\x00\xee\x00")
    echo.sent(request, 100.0)
    assert echo.is_echo(request, 100.001)  # our own copy
    assert not echo.is_echo(request, 100.002)  # the same frame again: another node's
    echo.sent(request, 100.0)
    assert not echo.is_echo(request, 101.5)  # too late to be our echo
    echo.sent(frame(1, can_id(Pgn.ATTITUDE, 0x1C, 2)), 100.0)  # not receivable: not kept
    assert not echo.is_echo(frame(1, can_id(Pgn.ATTITUDE, 0x1C, 2)), 100.0)


def test_inbox_drops_the_oldest_input_and_counts() -> None:
    async def main() -> tuple[list[int], int]:
        inbox = Inbox(maxsize=3)
        for i in range(5):
            inbox.offer(ImuAux(t=float(i), temp_c=25.0, supply_v=5.0, diag_stat=0, smpl_prd=1))
        return [int((await inbox.get()).t) for _ in range(3)], inbox.overloads

    assert asyncio.run(main()) == ([2, 3, 4], 2)


def test_bus_down_errors_are_told_from_busy_ones() -> None:
    down = can.CanOperationError("Failed to transmit: Network is down", 100)
    assert is_bus_down(down)
    assert not is_bus_down(can.CanOperationError("Transmit buffer full"))


def test_bus_plan_shares_one_bus_unless_told_otherwise() -> None:
    assert BusPlan.from_config(GatewayConfig()).shared
    with pytest.raises(ConfigError, match=r"imu.interface = 'socketcann': not a python-can"):
        BusPlan.from_config(GatewayConfig(imu=ImuSection(interface="socketcann")))


@THREAD_ERROR
def test_service_reopens_a_bus_that_goes_away_and_claims_again(tmp_path: Path) -> None:
    """The interface disappears under the service: it reopens it and claims its address again."""
    ch = channel()
    config = GatewayConfig(imu=ImuSection(interface="virtual", channel=ch))

    async def main() -> tuple[int, int, int]:
        service = GatewayService(config)
        with can.Bus(interface="virtual", channel=ch) as peer:
            peer.set_filters(claim_filters())
            running = asyncio.create_task(service.run())
            claims = 0
            deadline = time.monotonic() + 6.0
            while claims < 2 and time.monotonic() < deadline:
                await asyncio.sleep(0.05)
                while (msg := peer.recv(0)) is not None:
                    claims += (msg.arbitration_id >> 16) & 0xFF == 0xEE
                if claims == 1 and service.links[0].reopens == 0 and service.links[0].bus:
                    service.links[0].bus.shutdown()  # interface gone
            assert service.healthy()
            service.request_stop()
            status = await running
        return claims, service.links[0].reopens, status

    claims, reopens, status = asyncio.run(main())
    assert (claims, reopens, status) == (2, 1, 0)


def navgw(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "gateway.cli", *args],
        capture_output=True,
        text=True,
        check=False,
        cwd=REPO,
    )


def test_run_rejects_bad_configs_naming_the_key(tmp_path: Path) -> None:
    bad = tmp_path / "bad.toml"
    bad.write_text("[gnss]\nbaud = 9600\n")
    result = navgw("run", "--config", str(bad))
    assert result.returncode == 2
    assert "unknown key gnss.baud" in result.stderr
    bad.write_text('[imu]\ninterface = "socketcann"\n')
    result = navgw("run", "--config", str(bad))
    assert result.returncode == 2 and "imu.interface = 'socketcann'" in result.stderr
    result = navgw("run", "--config", str(tmp_path / "missing.toml"))
    assert result.returncode == 2 and "cannot read config file" in result.stderr


def test_config_example_checks_clean(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["config", "--example"]) == 0
    example = capsys.readouterr().out
    assert example == example_toml()
    path = tmp_path / "navgw.toml"
    path.write_text(example)
    assert main(["config", "--check", str(path)]) == 0
    assert "ok (engine observer, IMU socketcan can0, ISOBUS same bus" in capsys.readouterr().out
    path.write_text('[isobus]\ninterface = "vcan"\n')
    assert main(["config", "--check", str(path)]) == 2
    assert "isobus.interface = 'vcan': not a python-can interface" in capsys.readouterr().err


@pytest.mark.parametrize("command", ["run", "demo", "config", "replay"])
def test_every_command_has_help(command: str, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exit_:
        build_parser().parse_args([command, "--help"])
    assert exit_.value.code == 0 and "usage: navgw " + command in capsys.readouterr().out
