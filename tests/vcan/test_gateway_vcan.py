"""``navgw run`` on real SocketCAN with can-utils, as a user runs it on a Linux box.

One session, like a day in the field compressed into ~80 s: the IMU log is played onto
vcan0 by ``canplayer`` and the NMEA log onto a pty; the gateway reads both and sends on
vcan1 (a separate ISOBUS); ``candump -L`` records vcan1. During the run a competing
node's claim arrives by ``cansend``, then a request for address claim, then vcan1 goes
down and up again. The tests read what the recording and the gateway said.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import can
import numpy as np
import pytest

from gateway.playback import paced
from gateway.timebase import TimeBase
from sim_bus.canlog import CandumpWriter, read_candump
from sim_bus.nmea_player import NmeaPlayer
from sim_bus.nmealog import read_nmea_log
from sim_bus.truth import Truth
from tests.n2k_check import attitude_errors_deg, decode_log, position_errors_m
from tests.notify_socket import NotifySocket
from tests.vcan.conftest import candump_argv

REPO = Path(__file__).resolve().parents[2]
GYRO_ID = 0x0CFF1080
COMPETING_CLAIM = "18EEFF1C#0000000000000000"  # NAME 0 wins any contention for 0x1C
REQUEST_FOR_CLAIM = "18EAFFFE#00EE00"  # from the null address to all
# wall seconds after the first IMU frame (navigating from ~20 s of the 78 s run)
T_CONTEND, T_REQUEST, T_DOWN, T_UP = 35.0, 42.0, 50.0, 54.0


@dataclass
class Session:
    """What one run left behind."""

    truth: Truth
    recordings: list[Path]  # candump -L of vcan1, before and after the interface went down
    stderr: str
    returncode: int
    notify: list[str]
    events: dict[str, float] = field(default_factory=dict)  # wall time of each action
    log_minus_wall_s: float = 0.0  # log time of a wall-clock time is wall + this

    def frames(self) -> list[can.Message]:
        return [m for path in self.recordings for m in read_candump(path)]

    def in_log_time(self, path: Path, out: Path) -> Path:
        """A recording re-stamped from wall-clock time to the logs' (and truth's) time."""
        with CandumpWriter(out, "vcan1") as writer:
            for m in read_candump(path):
                m.timestamp += self.log_minus_wall_s
                writer.write(m)
        return out


def _ip(*args: str) -> None:
    subprocess.run(["ip", *args], check=True)


def _candump(channel: str, path: Path) -> subprocess.Popen[bytes]:
    return subprocess.Popen(candump_argv(channel, "-L"), stdout=path.open("w"))


@pytest.fixture(scope="module")
def session(vcan0: str, sim_run: Path, tmp_path_factory: pytest.TempPathFactory) -> Session:
    tmp = tmp_path_factory.mktemp("gateway-vcan")
    if not Path("/sys/class/net/vcan1").exists():
        _ip("link", "add", "dev", "vcan1", "type", "vcan")
    _ip("link", "set", "up", "vcan1")
    truth = Truth.load(sim_run / "truth.npz")
    lever = {
        k: [float(v) for v in getattr(truth, k)] for k in ("antenna_lever_arm_m", "imu_lever_arm_m")
    }
    recordings = [tmp / "vcan1-a.log", tmp / "vcan1-b.log"]
    notify = NotifySocket(tmp / "notify.sock")
    events: dict[str, float] = {}
    with _Pacer(list(read_nmea_log(sim_run / "gnss.nmea"))) as player:
        config = tmp / "navgw.toml"
        config.write_text(
            "[vehicle]\n" + "".join(f"{k} = {v}\n" for k, v in lever.items())
            + f'[imu]\ninterface = "socketcan"\nchannel = "{vcan0}"\n'
            + '[isobus]\ninterface = "socketcan"\nchannel = "vcan1"\n'
            + f'[gnss]\nport = "{player.device}"\nreceiver_latency_s = 0.065\n'
        )  # fmt: skip
        dump = _candump("vcan1", recordings[0])
        env = {**os.environ, "NOTIFY_SOCKET": str(notify.path)}
        gateway = subprocess.Popen(
            [sys.executable, "-m", "gateway.cli", "-v", "run", "--config", str(config)],
            cwd=REPO, env=env, stderr=subprocess.PIPE, text=True,
        )  # fmt: skip
        try:
            assert notify.wait_for("READY=1", 180.0), f"no READY=1, exit {gateway.poll()}"
            with can.Bus(interface="socketcan", channel=vcan0, can_filters=[
                {"can_id": GYRO_ID, "can_mask": 0x1FFFFFFF, "extended": True}
            ]) as rx:  # fmt: skip
                canplayer = subprocess.Popen(
                    ["canplayer", "-I", str(sim_run / "imu.log"), f"{vcan0}=can0"]
                )
                first = rx.recv(timeout=30.0)
            assert first is not None, "canplayer sent nothing"
            t0_log = next(iter(read_candump(sim_run / "imu.log"))).timestamp
            start = first.timestamp
            player.start(TimeBase(origin=t0_log, origin_wall=start))

            def at(name: str, seconds: float) -> None:
                time.sleep(max(0.0, start + seconds - time.time()))
                events[name] = time.time()

            at("contend", T_CONTEND)
            subprocess.run(["cansend", "vcan1", COMPETING_CLAIM], check=True)
            at("request", T_REQUEST)
            subprocess.run(["cansend", "vcan1", REQUEST_FOR_CLAIM], check=True)
            at("down", T_DOWN)
            dump.terminate()
            _ip("link", "set", "down", "vcan1")
            at("up", T_UP)
            _ip("link", "set", "up", "vcan1")
            dump = _candump("vcan1", recordings[1])
            canplayer.wait(timeout=180)
            time.sleep(1.0)
            gateway.send_signal(signal.SIGTERM)
            returncode = gateway.wait(timeout=30)
        finally:
            if gateway.poll() is None:
                gateway.kill()
            stderr = gateway.communicate()[1]
            dump.terminate()
            notify.wait_for("nothing more", 0.5)
            notify.close()
    notified = [line for _, line in notify.received]
    return Session(truth, recordings, stderr, returncode, notified, events, t0_log - start)


class _Pacer:
    """The NMEA log onto a pty, each line at its host time mapped through a TimeBase."""

    def __init__(self, lines: list[tuple[float | None, str]]) -> None:
        self._lines = lines
        self._stop = threading.Event()
        self._timebase: TimeBase | None = None
        self._go = threading.Event()
        self._player = NmeaPlayer(self._paced(), speed=float("inf"))

    def _paced(self) -> Iterator[tuple[float | None, str]]:
        self._go.wait()
        assert self._timebase is not None
        yield from paced(self._lines, lambda line: line[0], self._timebase, self._stop)

    @property
    def device(self) -> str:
        return str(self._player.device)

    def start(self, timebase: TimeBase) -> None:
        self._timebase = timebase
        self._go.set()

    def __enter__(self) -> _Pacer:
        self._player.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._go.set()
        self._player.stop()


def _from_gateway(session: Session) -> list[can.Message]:
    """Frames from the gateway's addresses, less the competing claim cansend put there."""
    return [
        m for m in session.frames()
        if (m.arbitration_id & 0xFF) in (0x1C, 0x80) and bytes(m.data) != bytes(8)
    ]  # fmt: skip


def test_gateway_output_on_vcan_decodes_to_the_truth(session: Session, tmp_path: Path) -> None:
    assert session.returncode == 0, session.stderr[-2000:]
    assert "Traceback" not in session.stderr
    messages = decode_log(session.in_log_time(session.recordings[0], tmp_path / "a.log"))
    err = attitude_errors_deg(messages, session.truth, after_s=22.0)
    assert len(err) > 40 * (T_DOWN - 25.0)
    rms = np.sqrt(np.mean(err**2, axis=0))
    assert rms[0] < 1.0 and rms[1] < 1.0 and rms[2] < 3.0, rms
    assert np.median(position_errors_m(messages, session.truth, after_s=22.0)) < 0.5


def test_a_lower_name_takes_our_address_and_we_move(session: Session) -> None:
    frames = _from_gateway(session)
    contend, down = session.events["contend"], session.events["down"]
    before = [m for m in frames if m.timestamp < contend]
    after = [m for m in frames if contend + 0.1 < m.timestamp < down]
    assert any(m.arbitration_id == 0x09F1131C for m in before)  # attitude from 0x1C
    assert not any(m.arbitration_id & 0xFF == 0x1C for m in after)  # silent at 0x1C ...
    assert any(m.arbitration_id == 0x18EEFF80 for m in after)  # ... claimed 128 ...
    assert any(m.arbitration_id == 0x09F11380 for m in after)  # ... and sends from there


def test_a_request_for_address_claim_is_answered(session: Session) -> None:
    t = session.events["request"]
    answers = [
        m for m in _from_gateway(session)
        if m.arbitration_id >> 8 & 0x3FFFF == 0x0EEFF and t <= m.timestamp < t + 1.0
    ]  # fmt: skip
    assert len(answers) == 1 and answers[0].arbitration_id == 0x18EEFF80


def test_interface_down_and_up_is_survived_and_sending_resumes(session: Session) -> None:
    assert session.returncode == 0
    assert "CAN" in session.stderr and "vcan1" in session.stderr
    resumed = [m for m in read_candump(session.recordings[1]) if m.arbitration_id >> 8 == 0x09F113]
    assert len(resumed) > 50  # attitude frames again after vcan1 came back
    assert any(line.startswith("STATUS=") for line in session.notify)
