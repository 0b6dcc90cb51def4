"""``navgw run`` on real SocketCAN with can-utils, as a user runs it on a Linux box.

One session, like a day in the field compressed into ~80 s: the IMU log is played onto
vcan0 by ``canplayer`` and the NMEA log onto a pty; the gateway reads both and sends on
vcan1 (a separate ISOBUS); ``candump -L`` records vcan1. During the run a competing
node's claim arrives by ``cansend``, then a request for address claim, then vcan1 goes
down and up again. The tests read what the recording and the gateway said.

A second, short session tests network management (issue 15): requests for 126996 (global)
and 126464 (to us), for unsupported PGNs (to us: NAK; global: none), competing claims with a
higher and a lower NAME, a node sending from our address, and a commanded address by BAM.
"""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from importlib import metadata
from pathlib import Path

import can
import numpy as np
import pytest
from nmea2000 import NMEA2000Decoder, NMEA2000Message

from drivers.logs.candump import CandumpWriter, read_candump
from drivers.logs.nmea_log import read_nmea_log
from gateway.demo.playback import paced
from gateway.estimation.solution import MAX_IMU_STEP_S
from gateway.service.timebase import TimeBase
from sim_bus.nmea_player import NmeaPlayer
from sim_bus.truth import Truth
from tests.n2k_check import (
    STATUS_PGN,
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
from tests.vcan.conftest import record_candump

REPO = Path(__file__).resolve().parents[2]
IMU_BRIDGE_SA = 0x80
GYRO_ID = 0x0CFF1000 | IMU_BRIDGE_SA
COMPETING_CLAIM = "18EEFF1C#0000000000000000"  # NAME 0 wins any contention for 0x1C
REQUEST_FOR_CLAIM = "18EAFFFE#00EE00"  # from the null address to all
# wall seconds after the first IMU frame (navigating from ~20 s of the 78 s run)
T_CONTEND, T_REQUEST, T_DOWN, T_UP = 35.0, 42.0, 50.0, 54.0
ALIGNED_S = 22.0  # log seconds: attitude and position are checked for accuracy from here
STEADY_S = 25.0  # ... and for their rate and gaps from here
#: The longest gap in attitude or position output while navigating, and the most a frame may
#: lag the truth it shows, wall seconds. A guidance controller wants no more than about
#: 0.25 s; the emulated guest runs Python ~10x slower than the ECU and is scheduled by an
#: emulator, which a host under load slows further.
MAX_GAP_S = 0.5
#: After a frame on the wire asks for it, the gateway acts within this, wall seconds.
REACTION_S = 0.1
#: ... or, on a guest that cannot keep up, before the winner of a contention may use the
#: address (ISO 11783-5: 250 ms after its claim), wall seconds (a slow guest's gateway went
#: on sending from 0x1C for 0.12 s: its loop had not yet read the claim).
CONTENTION_S = 0.25

pytestmark = pytest.mark.live


@dataclass
class Session:
    """What one run left behind."""

    truth: Truth
    recordings: list[Path]  # candump -L of vcan1, before and after the interface went down
    inputs: Path  # candump -L of vcan0: the IMU frames as canplayer put them on the bus
    stderr: str
    returncode: int
    notify: list[str]
    events: dict[str, float] = field(default_factory=dict)  # wall time of each action
    log_minus_wall_s: float = 0.0  # log time of a wall-clock time is wall + this

    def frames(self) -> list[can.Message]:
        return [m for path in self.recordings for m in _on_vcan1(path)]

    def in_log_time(self, path: Path, out: Path) -> Path:
        """A recording re-stamped from wall-clock time to the logs' (and truth's) time."""
        with CandumpWriter(out, "vcan1") as writer:
            for m in _on_vcan1(path):
                m.timestamp += self.log_minus_wall_s
                writer.write(m)
        return out


def _on_vcan1(path: Path) -> Iterator[can.Message]:
    """The frames on vcan1 in a recording (the second one records every interface)."""
    return (m for m in read_candump(path) if m.channel == "vcan1")


def _ip(*args: str) -> None:
    subprocess.run(["ip", *args], check=True)


def _candump_while_down(path: Path) -> subprocess.Popen[bytes]:
    """candump recording vcan1 from before it comes up again. The gateway reopens vcan1 and
    claims within milliseconds of its coming up; a socket bound to a down interface fails
    (ENETDOWN), so this one listens on all interfaces, less the IMU bridge's frames (source
    0x80) on vcan0; ``Session.frames`` keeps vcan1's."""
    return record_candump(f"any,{IMU_BRIDGE_SA:08X}~000000FF", path)


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
    inputs = tmp / "vcan0.log"
    notify = NotifySocket(tmp / "notify.sock")
    events: dict[str, float] = {}
    with _Pacer(list(read_nmea_log(sim_run / "gnss.nmea"))) as player:
        config = tmp / "navgw.toml"
        config.write_text(
            "[vehicle]\n" + "".join(f"{k} = {v}\n" for k, v in lever.items())
            + f'[imu]\ninterface = "socketcan"\nchannel = "{vcan0}"\n'
            + '[isobus]\ninterface = "socketcan"\nchannel = "vcan1"\n'
            + f'[gnss]\nport = "{player.device}"\nreceiver_latency_s = 0.065\n'
            + "receiver_latency_sigma_s = 0.01\n"  # the player's latency, measured
        )  # fmt: skip
        dump = record_candump("vcan1", recordings[0])
        dump_inputs = record_candump(vcan0, inputs)
        env = {**os.environ, "NOTIFY_SOCKET": str(notify.path)}
        gateway = subprocess.Popen(
            [sys.executable, "-m", "gateway.cli.main", "-v", "run", "--config", str(config)],
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
            dump = _candump_while_down(recordings[1])
            at("up", T_UP)
            _ip("link", "set", "up", "vcan1")
            canplayer.wait(timeout=180)
            time.sleep(1.0)
            gateway.send_signal(signal.SIGTERM)
            returncode = gateway.wait(timeout=30)
        finally:
            if gateway.poll() is None:
                gateway.kill()
            stderr = gateway.communicate()[1]
            for proc in (dump, dump_inputs):
                proc.terminate()
                proc.wait(timeout=10)  # its file complete before the tests read it
            notify.wait_for("nothing more", 0.5)
            notify.close()
    notified = [line for _, line in notify.received]
    return Session(truth, recordings, inputs, stderr, returncode, notified, events, t0_log - start)


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
        if (m.arbitration_id & 0xFF) in (0x1C, 0x81) and bytes(m.data) != bytes(8)
    ]  # fmt: skip


def test_gateway_output_on_vcan_decodes_to_the_truth(session: Session, tmp_path: Path) -> None:
    assert session.returncode == 0, session.stderr[-2000:]
    assert "Traceback" not in session.stderr
    names = ("a.log", "b.log")
    logs = [session.in_log_time(p, tmp_path / n) for p, n in zip(
        session.recordings, names, strict=True)]  # fmt: skip
    parts = [decode_log(log) for log in logs]
    for part, log in zip(parts, logs, strict=True):  # every frame, before and after vcan1 went down
        bad = implausible_frames(part, session.truth, Plausible(lag_s=MAX_GAP_S), status_modes(log))
        # ... and roll/pitch within the accuracy stated (at most 0.5 % beyond 3 sigma, by chance)
        checked, beyond = tilt_beyond_stated(log, session.truth, lag_s=MAX_GAP_S)
        said = f"beyond 0.1 deg + 3 stated sigma: {len(beyond)} of {checked} " + "\n".join(
            beyond[:10]
        )
        assert not bad, f"{len(bad)} implausible frames:\n" + "\n".join(bad[:20]) + f"\n{said}"
        assert len(beyond) <= 0.005 * checked, f"{said}\n{_said(session)}"
    if _overloaded(session):
        # The emulated guest, on a loaded host, could not keep up: the gateway shed what it got
        # too late, said DEGRADED, and sent nothing wrong (checked above); rate and accuracy
        # are for a gateway that keeps up. One that shed a few samples and bridged no gap
        # (not DEGRADED) is held to both below.
        return
    messages = parts[0]
    t0 = session.truth.t[0]
    start = t0 + STEADY_S
    end = session.events["down"] + session.log_minus_wall_s - 0.2
    # where canplayer stalled (the emulated guest starved), the gateway had nothing to send
    played = [m.timestamp + session.log_minus_wall_s for m in read_candump(session.inputs)]
    stalls = pauses(played, MAX_IMU_STEP_S)
    late = cadence_problems(messages, start, end, MAX_GAP_S, stalls)
    assert not late, f"{late}\ninput stalls {stalls[:10]}\n{_said(session)}"
    err = attitude_errors_deg(messages, session.truth, after_s=ALIGNED_S)
    rms = np.sqrt(np.mean(err**2, axis=0))
    assert rms[0] < 1.0 and rms[1] < 1.0 and rms[2] < 1.0, rms
    assert np.median(position_errors_m(messages, session.truth, after_s=ALIGNED_S)) < 0.5


def _overloaded(session: Session) -> bool:
    """The guest could not keep up: the gateway shed more than 1 % of the IMU input as stale
    (frames read, or samples reaching its core, MAX_SAMPLE_AGE_S after they arrived), by its
    last word. Then it bridged gaps and said DEGRADED, or FAULT while it could not align;
    that it sent nothing wrong meanwhile is checked whatever the load. A few samples shed
    one by one leave no gap: a gateway that kept up is held to rate and accuracy (a CI run
    shed 2)."""
    counts = {
        what: int(n) for n, what in re.findall(r"(\d+) stale IMU (samples|frames)", session.stderr)
    }  # the last of each: the stop line
    shed_frames = 2 * counts.get("samples", 0) + counts.get("frames", 0)
    return shed_frames > 0.01 * sum(1 for _ in read_candump(session.inputs))


def _said(session: Session) -> str:
    """What the gateway said (for a failure's message): its last STATUS and log lines."""
    status = [line for line in session.notify if line.startswith("STATUS=")][-3:]
    return "\n".join([*status, "stderr:", session.stderr[-3000:]])


def _on_the_wire(session: Session, frame: str, event: str) -> float:
    """candump's time stamp of the frame (``ID#DATA``) that ``cansend`` put on vcan1 at the
    time of ``event`` (the gateway may send the same frame: its own request at start)."""
    can_id, data = frame.split("#")
    times = [
        m.timestamp for m in read_candump(session.recordings[0])
        if m.arbitration_id == int(can_id, 16) and bytes(m.data) == bytes.fromhex(data)
        and m.timestamp >= session.events[event]
    ]  # fmt: skip
    assert times, (frame, event, session.events)
    return times[0]


def test_a_lower_name_takes_our_address_and_we_move(session: Session) -> None:
    frames = _from_gateway(session)
    contend, down = _on_the_wire(session, COMPETING_CLAIM, "contend"), session.events["down"]
    before = [m for m in frames if m.timestamp < contend]
    after = [m for m in frames if contend < m.timestamp < down]
    # sending from 0x1C before (attitude; at least the claim if the guest was overloaded)
    sent_before = {m.arbitration_id for m in before}
    assert 0x09F1131C in sent_before or (_overloaded(session) and 0x18EEFF1C in sent_before), _said(
        session
    )
    reaction = CONTENTION_S if _overloaded(session) else REACTION_S
    late = [f"{m.timestamp - contend:.3f} s {m.arbitration_id:08X}" for m in after
            if m.arbitration_id & 0xFF == 0x1C and m.timestamp > contend + reaction]  # fmt: skip
    assert not late, late[:10]  # silent at 0x1C ...
    # ... claimed 0x81, the first free address of 128-247 (0x80 is the IMU bridge's) ...
    assert any(m.arbitration_id == 0x18EEFF81 for m in after)
    assert any(m.arbitration_id & 0xFF == 0x81 and m.arbitration_id != 0x18EEFF81 for m in after)
    # ... and sends from there


def test_a_request_for_address_claim_is_answered(session: Session) -> None:
    t = _on_the_wire(session, REQUEST_FOR_CLAIM, "request")
    # within a second; an overloaded guest reads its bus late, so then before vcan1 goes
    # down (after it comes back up the gateway claims again, as it should)
    until = session.events["down"] if _overloaded(session) else t + 1.0
    answers = [
        m for m in _from_gateway(session)
        if m.arbitration_id >> 8 & 0x3FFFF == 0x0EEFF and t <= m.timestamp < until
    ]  # fmt: skip
    assert len(answers) == 1 and answers[0].arbitration_id == 0x18EEFF81


def test_interface_down_and_up_is_survived_and_sending_resumes(session: Session) -> None:
    assert session.returncode == 0
    assert "CAN" in session.stderr and "vcan1" in session.stderr
    after = [m for m in _on_vcan1(session.recordings[1]) if m.arbitration_id & 0xFF == 0x81]
    # after vcan1 came back: claimed again (0x1C stays the other node's), NAVGW_STATUS again
    assert 0x18EEFF81 in {m.arbitration_id for m in after}, _said(session)
    status = [m for m in after if (m.arbitration_id >> 8) & 0x3FFFF == STATUS_PGN]
    assert len(status) > 20, _said(session)
    # ... and the attitude, unless the guest could not keep up (then it says so in STATUS)
    resumed = [m for m in after if m.arbitration_id >> 8 == 0x09F113]
    assert len(resumed) > 50 or _overloaded(session), _said(session)
    assert any(line.startswith("STATUS=") for line in session.notify)


# --- network management on vcan (issue 15): a second, short session ------------------------
#
# The gateway alone on vcan1 (no IMU input: it claims, answers and sends NAVGW_STATUS FAULT),
# driven step by step: each ``cansend`` waits for the gateway's reaction on the bus, with a
# timeout a slow guest stays well within. ``candump -L`` records vcan1; the tests decode the
# recording with the nmea2000 package.

TOOL = 0x40
NM_STEP_TIMEOUT_S = 30.0  # the emulated guest answers in well under a second when unloaded
UNSUPPORTED_GLOBAL, UNSUPPORTED_TO_US = 130306, 130311  # wind data, environmental parameters
COMMANDED_TO = 0x30


@dataclass
class NetworkSession:
    """What the network-management run left behind."""

    recording: Path
    name: int  # the gateway's NAME
    marks: dict[str, float]  # wall time at which each step's frames were sent
    stderr: str
    returncode: int


def _cansend(*frames: str) -> None:
    for frame in frames:
        subprocess.run(["cansend", "vcan1", frame], check=True)


def _frame_text(can_id: int, data: bytes) -> str:
    return f"{can_id:08X}#{data.hex().upper()}"


def _request(pgn: int, destination: int) -> str:
    return _frame_text(0x18EA0000 | destination << 8 | TOOL, pgn.to_bytes(3, "little"))


def _commanded_bam(name: int, address: int) -> list[str]:
    payload = name.to_bytes(8, "little") + bytes([address])
    cm = bytes([32, 9, 0, 2, 0xFF]) + (65240).to_bytes(3, "little")
    dt = [bytes([1]) + payload[:7], bytes([2]) + payload[7:] + b"\xff" * 5]
    return [_frame_text(0x1CECFF00 | TOOL, cm), *(_frame_text(0x1CEBFF00 | TOOL, d) for d in dt)]


Test = Callable[[can.Message], bool]


def _id_is(can_id: int, data: bytes | None = None) -> Test:
    """A test for a frame with ``can_id`` (and ``data``, if given)."""
    return lambda m: m.arbitration_id == can_id and (data is None or bytes(m.data) == data)


class _Watch:
    """The gateway's frames on vcan1 as they come (python-can), to pace the steps."""

    def __init__(self) -> None:
        self.bus = can.Bus(interface="socketcan", channel="vcan1")
        self.seen: list[can.Message] = []

    def wait(self, what: str, test: Test, timeout: float = NM_STEP_TIMEOUT_S) -> can.Message:
        """The first frame from now on for which ``test(msg)`` is true."""
        end = time.monotonic() + timeout
        while (left := end - time.monotonic()) > 0:
            msg = self.bus.recv(min(left, 0.5))
            if msg is not None:
                self.seen.append(msg)
                if test(msg):
                    return msg
        raise AssertionError(f"no {what} within {timeout} s")


@pytest.fixture(scope="module")
def network_session(vcan0: str, tmp_path_factory: pytest.TempPathFactory) -> NetworkSession:
    from gateway.config.gateway_config import load_config
    from gateway.fusion.fusion_core import FusionCore

    tmp = tmp_path_factory.mktemp("gateway-vcan-nm")
    if not Path("/sys/class/net/vcan1").exists():
        _ip("link", "add", "dev", "vcan1", "type", "vcan")
    _ip("link", "set", "up", "vcan1")
    notify = NotifySocket(tmp / "notify.sock")
    recording = tmp / "vcan1.log"
    marks: dict[str, float] = {}
    with _Pacer([]) as player:  # a serial port that stays silent
        config = tmp / "navgw.toml"
        config.write_text(
            f'[imu]\ninterface = "socketcan"\nchannel = "{vcan0}"\n'
            '[isobus]\ninterface = "socketcan"\nchannel = "vcan1"\n'
            f'[gnss]\nport = "{player.device}"\n'
        )
        name = FusionCore.from_config(load_config(config)).claimer.name
        dump = record_candump("vcan1", recording)
        watch = _Watch()
        env = {**os.environ, "NOTIFY_SOCKET": str(notify.path)}
        gateway = subprocess.Popen(
            [sys.executable, "-m", "gateway.cli.main", "-v", "run", "--config", str(config)],
            cwd=REPO, env=env, stderr=subprocess.PIPE, text=True,
        )  # fmt: skip
        try:
            assert notify.wait_for("READY=1", 180.0), f"no READY=1, exit {gateway.poll()}"
            watch.wait("heartbeat from 0x1C", _id_is(0x1DF0111C), 60.0)

            def step(mark: str, frames: list[str], what: str, test: Test) -> None:
                marks[mark] = time.time()
                _cansend(*frames)
                watch.wait(what, test)

            ours = name.to_bytes(8, "little")
            step("product", [_request(126996, 0xFF)], "126996", _id_is(0x19F0141C))
            step("pgn_list", [_request(126464, 0x1C)], "126464 to the tool", _id_is(0x19EE401C))
            unsupported = [_request(UNSUPPORTED_GLOBAL, 0xFF), _request(UNSUPPORTED_TO_US, 0x1C)]
            step("unsupported", unsupported, "NAK", _id_is(0x18E8FF1C))
            higher = _frame_text(0x18EEFF1C, (name + 1).to_bytes(8, "little"))
            step("higher", [higher], "our defence of 0x1C", _id_is(0x18EEFF1C, ours))
            time.sleep(1.5)  # past the re-claim interval
            spoof = _frame_text(0x09F1131C, bytes(8))
            step("spoof", [spoof], "re-claim of 0x1C", _id_is(0x18EEFF1C, ours))
            bam = _commanded_bam(name, COMMANDED_TO)
            step("commanded", bam, "claim of 0x30", _id_is(0x18EEFF30, ours))
            watch.wait("NAVGW_STATUS from 0x30", _id_is(0x18FF2230))
            lower = _frame_text(0x18EEFF30, bytes(8))
            step("lower", [lower], "claim of 0x81", _id_is(0x18EEFF81, ours))
            time.sleep(1.0)
            marks["end"] = time.time()
            gateway.send_signal(signal.SIGTERM)
            returncode = gateway.wait(timeout=60)
        finally:
            watch.bus.shutdown()
            if gateway.poll() is None:
                gateway.kill()
            stderr = gateway.communicate()[1]
            dump.terminate()
            dump.wait(timeout=10)
            notify.close()
    return NetworkSession(recording, name, marks, stderr, returncode)


def _decoded(session: NetworkSession, pgn: int) -> list[NMEA2000Message]:
    """The messages of ``pgn`` in the recording, decoded by the nmea2000 package (each step
    asks once: the step's answer is all of them, whenever its last frame came)."""
    decoder = NMEA2000Decoder()
    messages = (decoder.decode(frame) for frame in read_candump(session.recording))
    return [m for m in messages if m is not None and pgn == m.PGN]


def _values(message: NMEA2000Message) -> dict[str, object]:
    return {f.id: f.value for f in message.fields}


def test_product_information_on_request_decodes_with_our_version(
    network_session: NetworkSession,
) -> None:
    assert network_session.returncode == 0, network_session.stderr[-2000:]
    assert "Traceback" not in network_session.stderr
    infos = _decoded(network_session, 126996)
    assert len(infos) == 1 and infos[0].source == 0x1C
    values = _values(infos[0])
    assert values["softwareVersionCode"] == metadata.version("navgw")
    assert values["modelSerialCode"] == "1" and values["modelId"] == "navgw GNSS/IMU gateway"


def test_pgn_list_on_a_request_to_us_goes_to_the_requester(
    network_session: NetworkSession,
) -> None:
    lists = _decoded(network_session, 126464)
    assert [m.destination for m in lists] == [TOOL, TOOL]
    transmit = lists[0]
    listed = [
        transmit.get_list_field_by_id(i, "pgn").value for i in range(transmit.get_list_field_size())
    ]
    assert _values(transmit)["functionCode"] == "Transmit PGN list"
    assert {126996, 126993, 127257, 129029, 59392} <= set(listed)


def test_unsupported_pgn_nak_only_when_addressed_to_us(network_session: NetworkSession) -> None:
    naks = _decoded(network_session, 59392)  # the global request got none
    assert [(_values(m)["control"], _values(m)["pgn"]) for m in naks] == [
        ("NAK", UNSUPPORTED_TO_US)
    ]


def test_competing_claims_violation_and_commanded_address(network_session: NetworkSession) -> None:
    s = network_session
    frames = list(read_candump(s.recording))
    ours = s.name.to_bytes(8, "little")

    def claims_from_us(start: str, end: str) -> list[int]:
        return [
            f.arbitration_id & 0xFF for f in frames
            if f.arbitration_id >> 8 == 0x18EEFF and bytes(f.data) == ours
            and s.marks[start] <= f.timestamp < s.marks[end]
        ]  # fmt: skip

    assert claims_from_us("higher", "spoof") == [0x1C]  # a higher NAME: we defend, once
    assert claims_from_us("spoof", "commanded") == [0x1C]  # a violation: we claim again
    assert claims_from_us("commanded", "lower") == [COMMANDED_TO]  # commanded: we move
    assert claims_from_us("lower", "end") == [0x81]  # a lower NAME: we move on (0x80 reserved)
    # nothing from an address once we have left it
    after_move = [f for f in frames if f.timestamp >= s.marks["commanded"] + 1.0]
    left = [f for f in after_move if f.arbitration_id & 0xFF == 0x1C]
    assert not left, [f"{f.arbitration_id:08X}" for f in left[:5]]
    after_loss = [
        f for f in frames
        if f.timestamp >= s.marks["lower"] + 1.0 and f.arbitration_id & 0xFF == COMMANDED_TO
    ]  # fmt: skip
    assert not after_loss
    assert any(f.arbitration_id & 0xFF == 0x81 and f.arbitration_id >> 8 != 0x18EEFF
               for f in frames if f.timestamp >= s.marks["lower"])  # fmt: skip
