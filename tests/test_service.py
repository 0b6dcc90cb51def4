"""The live service's parts on real python-can buses: reader, echo, inbox, reopen, CLI errors."""

from __future__ import annotations

import asyncio
import itertools
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import can
import pytest

from drivers.errors import BusError
from drivers.frame_reader import FrameReader
from drivers.samples import ImuAux, ImuSample
from gateway.cli.main import build_parser, main
from gateway.config.config_schema import ConfigError
from gateway.config.gateway_config import GatewayConfig, ImuSection, example_toml
from gateway.estimation.solution import Mode
from gateway.isobus.j1939 import Pgn, can_id
from gateway.service.bus_links import BusPlan, EchoFilter, claim_filters, is_bus_down
from gateway.service.live_loop import GatewayService, Inbox
from gateway.service.timebase import TimeBase
from tests.multicast import GROUP, until_stamped_on_arrival

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
    async def main() -> tuple[list[int], int, int, BaseException | None]:
        ch = channel()
        with (
            can.Bus(interface="virtual", channel=ch) as rx,
            can.Bus(interface="virtual", channel=ch) as tx,
        ):
            async with FrameReader(rx, max_frames=4) as reader:
                for i in range(10):
                    tx.send(frame(i))
                await asyncio.sleep(0.3)  # the notifier thread delivers all ten
                pending = reader.pending
                got = [(await reader.__anext__()).data[0] for _ in range(4)]
                rx.shutdown()  # the interface goes away under the reader
                try:
                    await asyncio.wait_for(reader.__anext__(), 3.0)
                except BusError as exc:
                    return got, reader.dropped, pending, exc
        return got, -1, pending, None

    got, dropped, pending, error = asyncio.run(main())
    assert got == [6, 7, 8, 9] and dropped == 6 and pending == 4  # the newest frames are kept
    assert isinstance(error, BusError) and "failed" in str(error)


@pytest.mark.parametrize("interface", ["virtual", "udp_multicast"])
def test_reader_sheds_stale_frames_from_its_buffer_and_socket_in_order(
    interface: str, request: pytest.FixtureRequest
) -> None:
    """``shed`` drops the frames stamped before a time but those wanted, from the buffer
    and (udp_multicast: read in the loop) from the socket up to the first newer frame."""
    ch = GROUP if interface == "udp_multicast" else channel()
    if interface == "udp_multicast":
        request.getfixturevalue("multicast_port")
    claim_id = can_id(Pgn.ADDRESS_CLAIM, 0x40, 6)

    async def main() -> tuple[list[int], list[int], int]:
        with (
            can.Bus(interface=interface, channel=ch) as rx,
            can.Bus(interface=interface, channel=ch) as tx,
        ):
            if interface == "udp_multicast":
                until_stamped_on_arrival(tx, rx)
            async with FrameReader(rx) as reader:
                # the loop is held up: nothing is read while these arrive
                for i in range(10):
                    tx.send(frame(i, claim_id if i == 4 else 0x0CFF1080))
                time.sleep(0.05)
                before = time.time()
                time.sleep(0.01)
                for i in range(10, 13):
                    tx.send(frame(i))
                if interface == "virtual":  # the notifier's thread hands them to the loop
                    await asyncio.sleep(0.5)
                else:
                    time.sleep(0.1)  # in the socket, unread
                dropped = reader.shed(before, keep=lambda m: m.arbitration_id == claim_id)
                left = [(await asyncio.wait_for(reader.__anext__(), 1.0)).data[0] for _ in range(4)]
                return [m.data[0] for m in dropped], left, reader.dropped

    dropped, left, overflowed = asyncio.run(main())
    assert dropped == [0, 1, 2, 3, 5, 6, 7, 8, 9]
    assert left == [4, 10, 11, 12] and overflowed == 0


def test_a_reader_held_up_once_sheds_the_stale_frames_and_one_behind_again_its_backlog(
    multicast_port: int,
) -> None:
    """The service's shedding of IMU frames read MAX_SAMPLE_AGE_S late (udp_multicast, read
    in the loop and stamped on arrival as SocketCAN): the first time, only those as stale
    (the core would drop no other); again within SHED_AGAIN_S, the whole backlog. The service
    clock runs at a tenth of the wall clock, so the ages are whole seconds of wall time."""
    config = GatewayConfig(imu=ImuSection(interface="udp_multicast", channel=GROUP))
    service = GatewayService(config, timebase=TimeBase(speed=0.1))
    link = service.links[0]

    async def main() -> list[int]:
        shed = []
        with link.spec.open() as rx, can.Bus(interface="udp_multicast", channel=GROUP) as tx:
            until_stamped_on_arrival(tx, rx)
            async with FrameReader(rx) as reader:
                link.bus, link.reader, link.host_stamps = rx, reader, True

                def send(first: int, end: int) -> None:
                    for i in range(first, end):
                        tx.send(frame(i))

                async def read_one() -> None:
                    msg = await asyncio.wait_for(reader.__anext__(), 1.0)
                    service._on_frame(link, msg)
                    shed.append(service.stats.frames_shed)

                send(0, 10)
                time.sleep(1.5)  # the loop held up: 0-9 are 0.15 s of service time old
                send(10, 20)
                await read_one()  # 0 read late: 0-9 shed, 10-19 kept
                time.sleep(1.2)  # held up again: 10-19 stale now
                send(20, 25)
                await read_one()  # 10 read late again: the backlog shed, 20-24 with it
                with pytest.raises(TimeoutError):  # nothing left behind
                    await asyncio.wait_for(reader.__anext__(), 0.5)
        return shed

    assert asyncio.run(main()) == [10, 10 + 10 + 5]
    assert service.imu_decoder.counters.frames == 0  # none was decoded


def test_claim_filters_pass_claims_requests_and_frames_from_our_address() -> None:
    ch = channel()
    with (
        can.Bus(interface="virtual", channel=ch) as rx,
        can.Bus(interface="virtual", channel=ch) as tx,
    ):
        for address, passed in ((None, ["EE33", "EA33"]), (0x1C, ["EE33", "EA33", "F11C"])):
            rx.set_filters(claim_filters(address))
            for pgn, source in (
                (Pgn.ADDRESS_CLAIM, 0x33),
                (Pgn.ISO_REQUEST, 0x33),
                (Pgn.ATTITUDE, 0x33),
                (Pgn.ATTITUDE, 0x1C),
            ):
                tx.send(can.Message(arbitration_id=can_id(pgn, source, 6, 0x1C), data=bytes(8)))
            tx.send(can.Message(arbitration_id=0x1C, is_extended_id=False, data=bytes(8)))
            got = []
            while (msg := rx.recv(0.2)) is not None:
                got.append(
                    f"{(msg.arbitration_id >> 16) & 0xFF:02X}{msg.arbitration_id & 0xFF:02X}"
                )
            assert got == passed


def test_echo_filter_drops_one_copy_per_frame_sent() -> None:
    echo = EchoFilter(window_s=1.0)
    request = can.Message(arbitration_id=can_id(Pgn.ISO_REQUEST, 254, 6), data=b"\x00\xee\x00")
    echo.sent(request, 100.0)
    assert echo.is_echo(request, 100.001)  # our own copy
    assert not echo.is_echo(request, 100.002)  # the same frame again: another node's
    echo.sent(request, 100.0)
    assert not echo.is_echo(request, 101.5)  # too late to be our echo
    attitude = frame(1, can_id(Pgn.ATTITUDE, 0x1C, 2))  # from our address: it comes back too
    echo.sent(attitude, 102.0)
    echo.sent(attitude, 102.5)
    assert echo.is_echo(attitude, 102.6) and echo.is_echo(attitude, 102.6)
    assert not echo.is_echo(attitude, 102.6)
    for i in range(3000):  # 3 s of output, read behind a backlog: told by arrival time
        echo.sent(frame(i, can_id(Pgn.ATTITUDE, 0x1C, 2)), 103.0 + i * 0.001)
    assert echo.is_echo(frame(0, can_id(Pgn.ATTITUDE, 0x1C, 2)), 103.0005)
    local = frame(2, can_id(Pgn.ATTITUDE, 0x1C, 2))
    local.is_rx = False  # socketcan: sent from this host, by another socket (a local tool)
    assert not echo.is_echo(local, 110.0)  # not ours: we never sent it
    assert echo.echoes == 4


def test_inbox_drops_the_oldest_input_and_counts() -> None:
    async def main() -> tuple[list[int], int]:
        inbox = Inbox(maxsize=3)
        for i in range(5):
            inbox.offer(ImuAux(t=float(i), temp_c=25.0, supply_v=5.0, diag_stat=0, smpl_prd=1))
        return [int((await inbox.get()).t) for _ in range(3)], inbox.overloads

    assert asyncio.run(main()) == ([2, 3, 4], 2)


def test_a_loop_behind_its_imu_input_does_not_report_the_imu_silent() -> None:
    """IMU samples waiting for the core are not an IMU silence: the tick reports FAULT only
    once nothing is pending (a backlog on a busy host is shed, and DEGRADED, not FAULT)."""
    ch = channel()
    dt = 1 / 204.8

    def sample(t: float) -> ImuSample:
        return ImuSample(t=t, dt=dt, w_ib_b=(0, 0, 0), f_ib_b=(0, 0, -9.81), seq=0)

    def statuses(peer: can.BusABC) -> list[Mode]:
        """The modes of the NAVGW_STATUS frames waiting at ``peer``."""
        status_id = can_id(Pgn.NAVGW_STATUS, 0x1C, 6)
        frames = iter(lambda: peer.recv(0), None)
        return [Mode(m.data[2]) for m in frames if m.arbitration_id == status_id]

    async def main() -> tuple[list[Mode], list[Mode]]:
        service = GatewayService(GatewayConfig(imu=ImuSection(interface="virtual", channel=ch)))
        with (
            can.Bus(interface="virtual", channel=ch) as bus,
            can.Bus(interface="virtual", channel=ch) as peer,
        ):
            service.isobus.bus = bus
            for msg in service.core.start(0.0):  # the claim, as the service's ISOBUS opens
                bus.send(msg)
            service.tick(0.2)  # our claim (after a random wait of at most 153 ms)
            service.tick(0.5)  # uncontested for 250 ms
            assert service.core.claimer.claimed
            for k in range(205):  # a second of samples: the core reports them
                service.process(sample(0.5 + k * dt))
            while peer.recv(0) is not None:
                pass
            service.inbox.offer(sample(1.5 + dt))  # read, not yet taken by the core
            service.tick(2.0)
            during = statuses(peer)
            await service.inbox.get()  # the core takes it (or drops it as stale)
            service.tick(2.05)
            return during, statuses(peer)

    assert asyncio.run(main()) == ([], [Mode.FAULT])


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


async def until(condition: Callable[[], object], timeout_s: float = 3.0) -> None:
    """Wait for ``condition`` (polled every 20 ms); fail after ``timeout_s``."""
    deadline = time.monotonic() + timeout_s
    while not condition():
        assert time.monotonic() < deadline, "timed out"
        await asyncio.sleep(0.02)


def claim(source: int, name: int) -> can.Message:
    return can.Message(
        arbitration_id=can_id(Pgn.ADDRESS_CLAIM, source, 6), data=name.to_bytes(8, "little")
    )


@pytest.mark.live
def test_service_on_an_echoing_bus_tells_its_echo_from_a_clone(multicast_port: int) -> None:
    """udp_multicast gives the service its own frames back, also through the filter on its
    address: none counts as a clone; another node's claim with our NAME and frames from our
    address do, and the filter follows our address when a lower NAME takes 0x1C."""
    config = GatewayConfig(imu=ImuSection(interface="udp_multicast", channel=GROUP))
    status = frame(3, can_id(Pgn.NAVGW_STATUS, 0x1C, 6))

    async def main() -> None:
        service = GatewayService(config)
        claimer = service.core.claimer
        with can.Bus(interface="udp_multicast", channel=GROUP) as peer:
            running = asyncio.create_task(service.run())
            try:
                await until(lambda: claimer.claimed)
                await asyncio.sleep(1.0)  # NAVGW_STATUS (FAULT: no IMU) at 10 Hz, echoed
                assert service.echo.echoes >= 8
                assert claimer.name_conflicts == claimer.spoofed_frames == 0
                peer.send(status)  # another node sends as us
                await until(lambda: claimer.spoofed_frames == 1)
                peer.send(claim(0x40, claimer.name))  # a clone of us
                await until(lambda: claimer.name_conflicts == 1)
                assert claimer.conflict(service.timebase.now())
                line = service.status_line()
                assert "1 claims with our NAME" in line and "1 frames from our address" in line
                assert line.startswith("fault,"), line  # what STATUS says: no IMU
                peer.send(claim(0x1C, claimer.name - 1))  # a lower NAME takes 0x1C
                await until(lambda: claimer.claimed and claimer.address == 0x81)
                echoes = service.echo.echoes
                await asyncio.sleep(0.5)
                assert service.echo.echoes >= echoes + 4  # ours from 0x81 pass the new filter
                peer.send(status)  # 0x1C is the other node's now
                peer.send(frame(3, can_id(Pgn.NAVGW_STATUS, 0x81, 6)))
                await until(lambda: claimer.spoofed_frames == 2)
                await asyncio.sleep(0.2)
                assert (claimer.spoofed_frames, claimer.name_conflicts) == (2, 1)
            finally:
                service.request_stop()
                assert await running == 0

    asyncio.run(main())


def navgw(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "gateway.cli.main", *args],
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
        build_parser([command]).parse_args([command, "--help"])
    assert exit_.value.code == 0 and "usage: navgw " + command in capsys.readouterr().out
