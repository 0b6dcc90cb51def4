"""Live latency: IMU frame in to 127257 out, on the running ``navgw run`` service.

Run (root: it routes a multicast group to loopback and uses SCHED_FIFO)::

    .venv/bin/python benchmarks/latency.py --seconds 30 --json latency.json
    .venv/bin/python benchmarks/latency.py --quick                   # 4 loaded cases, 10 s each
    .venv/bin/python benchmarks/latency.py --cases '819-*-load-*' --target both

Cases: {204, 819} (IMU at 204.8 Hz, DEC=2, or 819.2 Hz, DEC=0) x {quiet, traffic} (no other
frames, or 1,900 frames/s of unrelated ISOBUS-like frames: other PGNs and source addresses,
evenly spaced) x {idle, load} (no competing CPU load, or ``stress-ng --cpu N``, N = nproc, at
normal priority; N bounded python busy loops without stress-ng) x {normal, rt} (the service at
normal priority, or under ``chrt -f 50``). Names read ``819-traffic-load-rt``; ``--cases`` takes
comma-separated shell patterns.

Each case starts ``navgw run --config X`` (as ``python -m gateway.cli.main``, from the tree this
script is in, so that a ``git archive`` copy measures its own code) as a subprocess on
python-can ``udp_multicast`` (a group of its own routed to ``lo``, a random port per case
given as ``CAN_CONFIG``, as ``tests/test_service_e2e.py`` does) and plays a simulated run
into it in real time with :class:`gateway.demo.playback.SyncedPlayback`: the IMU bridge's frames
on the bus and the NMEA sentences on a pty, so that the service aligns and navigates as on a
vehicle (the run rests 5 s, then drives; the service navigates from about 9 s). The first
``--warmup`` seconds are not measured; then ``--seconds`` are.

What is measured. Every frame on the group (IMU frames, the service's output, the unrelated
traffic) is also received by a monitor socket in this process, stamped by the kernel on
arrival (``SO_TIMESTAMPNS``, the stamp the service's own socket sees for the same frame, as a
SocketCAN hardware stamp would be). The latency of an output instant is the arrival of the
127257 frame minus the arrival of the IMU_ACCEL frame that triggered it: IMU_ACCEL completes
a sample, and the scheduler sends 127257 with the first sample at or after each 20 ms grid
point of *sample time*. The triggering samples are found without trusting arrival order:
the monitor's frames go through the project's own :class:`drivers.imu_can.ImuDecoder` with
the service's config, which gives each sample the time the service gives it, and the grid
rule picks the trigger of each slot; each 127257 is matched to its slot by its SID
(:func:`match_outputs`). This stays right when the service falls more than one IMU period
behind (a later sample has arrived before the output, counted as ``overtaken``: "the most
recent IMU_ACCEL before it" would under-state the latency) and when a stall delivers several
samples at once. Included: the service's wake-up, ``recvmsg`` and msgpack unpack, the IMU
decoder, the engine, the solution and the encoding of 127257 (the scheduler encodes and
sends it first), ``sendto``, and one loopback hop to the monitor. Not included: the inbound
hop (both sockets get the IMU frame at the same time).

Baselines reported beside it: ``hop`` is the udp_multicast one-way latency, from the
harness's ``send()`` call (before msgpack packing) to the kernel stamp of the same frame at
the monitor (15 us p50 on the development machine; ../shared/NOTES.md's 94 us is user space
to user space); ``--target echo`` runs a trivial python-can process instead of the
service that sends a frame back for every IMU_ACCEL (blocking ``recv``/``send``), the floor
of any Python process on this bus. Also per case: frames sent and received, 127257 frames
missing against the 50 Hz grid (slots with a trigger in the window but no frame), the IMU
samples lost as the service reports them (NAVGW_STATUS byte 6, SPEC 4: lost in the last
second; summed over STATUS frames 1 s apart), the mode seen, and the service's CPU use. For
the why of slow cases (JSON): datagrams the service's sockets dropped (``/proc/net/udp``),
the host's steal time, IMU frames the harness sent late (``harness_stalls``), how late the
monitor thread got frames after their kernel stamp, and the five slowest outputs with that
delay for their trigger (a trigger the monitor also got late points at the host, not the
service). ``--profile DIR`` records the service with py-spy over each window.

The harness (IMU bridge, other ECUs, monitor) runs at SCHED_FIFO ``--harness-priority`` (40)
when root: above the competing load, which must not disturb the frames it stands in for, and
below the service's 50, because on a vehicle those frames come from hardware and cost the
ECU no CPU time (at 60 the harness's own work, ~20 % of a core with the traffic, delayed the
real-time service and added ~0.3 ms to its p99 on 2 cores). The service, the load and the
echo baseline are started with their own policy (``chrt -o 0`` or ``chrt -f 50``), never the
harness's. Stamps are the kernel's, so a late monitor thread does not change a figure.
Everything is bounded in time and cleaned up on any exit (service, traffic, load, and the
multicast route if added here).
"""

from __future__ import annotations

import argparse
import contextlib
import ctypes
import dataclasses
import fnmatch
import gc
import hashlib
import itertools
import json
import math
import os
import platform
import random
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import can
import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from drivers.imu_can import ImuDecoder  # noqa: E402
from drivers.samples import ImuSample  # noqa: E402
from gateway.config.driver_settings import imu_config  # noqa: E402
from gateway.config.gateway_config import load_config  # noqa: E402
from gateway.demo.playback import SyncedPlayback  # noqa: E402
from sim_bus.scenarios import generate, scenario_from_toml  # noqa: E402
from sim_bus.truth import Truth  # noqa: E402
from tests.notify_socket import NotifySocket  # noqa: E402

#: A group of its own (not the e2e test's 239.74.163.2), routed to lo for the run.
GROUP = "239.74.163.57"
PORTS = (44000, 44999)
RATES = {"204": 2, "819": 0}  # case token -> DEC (819.2 Hz / 2^DEC)
TRAFFIC_FPS = 1900.0
RT_PRIORITY = 50
HARNESS_PRIORITY = 40  # above the load, below the service's RT_PRIORITY
OUTPUT_HZ = 50.0  # 127257, SPEC 4 default
GRID_TOLERANCE = 1e-6  # as gateway.isobus.output_scheduler
SID_MODULO = 253  # as gateway.isobus.output_scheduler
MATCH_WINDOW = 25  # 127257 frames (0.5 s) over which a slot offset is settled
TARGET_P99_MS = 1.0
START_LEAD_S = 0.5  # READY -> first frame
TAIL_S = 0.6  # played after the window, so the last slots are answered

PGN_ATTITUDE = 127257
PGN_STATUS = 0xFF22
PGN_CLAIM = 0xEE00
ECHO_ID = 0x18FFEE1D  # the echo baseline's reply (proprietary B, SA 0x1D)
#: PGNs the service sends (SPEC 4) and the claim: the monitor keeps these and the IMU frames.
GATEWAY_PGNS = frozenset(
    {127257, 127251, 127250, 129025, 129026, 129029, 0xFF20, 0xFF21, PGN_STATUS, PGN_CLAIM, 0xEA00}
)
#: Unrelated traffic: (priority, PGN) of tractor ECUs; PDU1 ones get a random destination.
NOISE_PGNS = (
    (3, 0xF004),  # EEC1 engine speed
    (6, 0xFEF1),  # CCVS vehicle speed
    (6, 0xFE48),  # wheel-based speed and distance
    (6, 0xFE49),  # ground-based speed and distance
    (3, 0xFE45),  # rear hitch
    (3, 0xFE43),  # rear PTO
    (6, 0xFEEE),  # engine temperature
    (3, 0xCB00),  # ISOBUS process data (PDU1)
    (5, 0xE600),  # VT to ECU (PDU1)
    (5, 0xE700),  # ECU to VT (PDU1)
)


def pgn_of(can_id: int) -> int:
    """PGN of a 29-bit id (PDU1: destination cleared)."""
    pgn = (can_id >> 8) & 0x3FFFF
    return pgn & 0x3FF00 if (pgn >> 8) & 0xFF < 0xF0 else pgn


# --- cases --------------------------------------------------------------------------------


@dataclass(frozen=True)
class Case:
    rate: str  # "204" | "819"
    traffic: bool
    load: bool
    rt: bool
    target: str = "navgw"  # or "echo"

    @property
    def name(self) -> str:
        return "-".join(
            (
                self.rate,
                "traffic" if self.traffic else "quiet",
                "load" if self.load else "idle",
                "rt" if self.rt else "normal",
            )
        )

    @property
    def label(self) -> str:
        return self.name if self.target == "navgw" else f"{self.name} (echo)"

    @property
    def hz(self) -> float:
        return 819.2 / 2 ** RATES[self.rate]


ALL_CASES = [
    Case(rate, traffic, load, rt)
    for rate, traffic, load, rt in itertools.product(
        RATES, (False, True), (False, True), (False, True)
    )
]
QUICK_CASES = "*-traffic-load-*"


def select_cases(patterns: str, target: str) -> list[Case]:
    """Cases whose names match any of the comma-separated patterns, per target."""
    pats = [p.strip() for p in patterns.split(",") if p.strip()]
    chosen = [c for c in ALL_CASES if any(fnmatch.fnmatchcase(c.name, p) for p in pats)]
    if not chosen:
        names = ", ".join(c.name for c in ALL_CASES)
        raise SystemExit(f"--cases {patterns!r} matches no case; cases are: {names}")
    targets = ("navgw", "echo") if target == "both" else (target,)
    return [dataclasses.replace(c, target=t) for c in chosen for t in targets]


# --- processes and clean-up ---------------------------------------------------------------

_PR_SET_PDEATHSIG = 1


def _die_with_parent() -> None:
    """In a child before exec: SIGKILL when the benchmark dies, whatever the reason."""
    with contextlib.suppress(OSError, AttributeError):
        ctypes.CDLL(None, use_errno=True).prctl(_PR_SET_PDEATHSIG, signal.SIGKILL)


class Children:
    """Processes started here, each in its own process group; ended on exit, by their id."""

    def __init__(self) -> None:
        self.procs: list[subprocess.Popen[Any]] = []

    def start(self, cmd: Sequence[str], **kwargs: Any) -> subprocess.Popen[Any]:
        proc = subprocess.Popen(
            list(cmd), start_new_session=True, preexec_fn=_die_with_parent, **kwargs
        )
        self.procs.append(proc)
        return proc

    def stop(self, proc: subprocess.Popen[Any], grace_s: float = 5.0) -> int | None:
        """SIGTERM to the process group, SIGKILL after ``grace_s``; the exit status."""
        if proc.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(proc.pid, signal.SIGTERM)
            try:
                proc.wait(grace_s)
            except subprocess.TimeoutExpired:
                with contextlib.suppress(ProcessLookupError):
                    os.killpg(proc.pid, signal.SIGKILL)
                proc.wait()
        with contextlib.suppress(ProcessLookupError, PermissionError):
            os.killpg(proc.pid, signal.SIGKILL)  # workers left behind (stress-ng's)
        if proc in self.procs:
            self.procs.remove(proc)
        return proc.returncode

    def stop_all(self) -> None:
        for proc in list(self.procs):
            self.stop(proc, grace_s=2.0)


def _ip(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(["ip", *args], capture_output=True, text=True, check=False)


def _lo_multicast() -> bool:
    return "MULTICAST" in _ip("link", "show", "lo").stdout


def _other_multicast_routes_on_lo(group: str) -> bool:
    """Whether someone else (the e2e test) routes a multicast group to lo too."""
    for line in _ip("route", "show", "dev", "lo").stdout.splitlines():
        dest = line.split()[0].split("/")[0] if line.split() else ""
        if dest != group and dest.count(".") == 3 and 224 <= int(dest.split(".")[0]) <= 239:
            return True
    return False


@contextlib.contextmanager
def multicast_route(group: str) -> Iterator[None]:
    """Route ``group`` to lo and enable multicast on lo (../shared/NOTES.md); undo after.

    lo's MULTICAST flag is shared with anything else on the host (the e2e test): it is turned
    off after the run only if it was off before and no other multicast route uses lo.
    """
    if shutil.which("ip") is None or os.geteuid() != 0:
        raise SystemExit(
            f"needs root and iproute2: udp_multicast across processes needs "
            f"'ip link set lo multicast on; ip route add {group}/32 dev lo'"
        )
    set_multicast = not _lo_multicast()
    if set_multicast and _ip("link", "set", "lo", "multicast", "on").returncode:
        raise SystemExit("cannot enable multicast on lo")
    added = _ip("route", "add", f"{group}/32", "dev", "lo")
    if added.returncode and "File exists" not in added.stderr:
        raise SystemExit(f"cannot route {group} to lo: {added.stderr.strip()}")
    try:
        yield
    finally:
        if added.returncode == 0:
            _ip("route", "del", f"{group}/32", "dev", "lo")
        if set_multicast and not _other_multicast_routes_on_lo(group):
            _ip("link", "set", "lo", "multicast", "off")


def ensure_multicast_on_lo() -> None:
    """Before each case: something else may have turned lo's MULTICAST flag off meanwhile."""
    if not _lo_multicast():
        print("  (lo had lost its MULTICAST flag: set again)", flush=True)
        _ip("link", "set", "lo", "multicast", "on")


def set_fifo(priority: int) -> None:
    """This thread (and threads it starts later) at SCHED_FIFO ``priority``; 0: normal."""
    if priority > 0:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
    else:
        os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))


def snapshot(pid: int) -> dict[str, float]:
    """Counters read at both ends of the window: the service's CPU time and the datagrams its
    UDP sockets dropped (receive buffer full, /proc/net/udp), the host's steal time."""
    tick = os.sysconf("SC_CLK_TCK")
    out = {"wall": time.time()}
    with contextlib.suppress(OSError, IndexError, ValueError):
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
        out["cpu_s"] = (int(fields[11]) + int(fields[12])) / tick
    with contextlib.suppress(OSError, IndexError, ValueError):
        cpu = Path("/proc/stat").read_text().split("\n", 1)[0].split()
        out["steal_s"] = int(cpu[8]) / tick
    with contextlib.suppress(OSError):
        inodes = set()
        for fd in Path(f"/proc/{pid}/fd").iterdir():
            with contextlib.suppress(OSError):
                link = os.readlink(fd)
                if link.startswith("socket:["):
                    inodes.add(link[8:-1])
        drops = 0
        for table in ("/proc/net/udp", "/proc/net/udp6"):
            for line in Path(table).read_text().splitlines()[1:]:
                f = line.split()
                if len(f) > 12 and f[9] in inodes:
                    drops += int(f[-1])
        out["socket_drops"] = drops
    return out


def deltas(a: dict[str, float], b: dict[str, float]) -> dict[str, Any]:
    """Service CPU %, its socket drops and the host's steal time over the window."""
    wall = b["wall"] - a["wall"]

    def d(key: str) -> float | None:
        return b[key] - a[key] if key in a and key in b else None

    cpu, steal, drops = d("cpu_s"), d("steal_s"), d("socket_drops")
    return {
        "service_cpu_percent": None if cpu is None else round(100 * cpu / wall, 1),
        "service_socket_drops": None if drops is None else int(drops),
        "host_steal_ms": None if steal is None else round(1e3 * steal),
    }


# --- children: unrelated traffic, echo baseline, CPU load ---------------------------------


def noise_child(port: int, fps: float, seconds: float, seed: int) -> None:
    """Send ``fps`` unrelated frames per second, evenly spaced, for ``seconds``."""
    rng = random.Random(seed)
    addresses = [a for a in range(0x00, 0xF8) if a not in (0x1C, 0x1D, 0x80)]
    period = 1.0 / fps
    with can.Bus(interface="udp_multicast", channel=GROUP, port=port) as bus:
        start = time.monotonic()
        for k in itertools.count():
            due = start + k * period
            if due - start > seconds:
                break
            delay = due - time.monotonic()
            if delay > 0:
                time.sleep(delay)
            prio, pgn = rng.choice(NOISE_PGNS)
            if pgn >> 8 < 0xF0:
                pgn |= rng.choice(addresses)
            can_id = prio << 26 | pgn << 8 | rng.choice(addresses)
            bus.send(can.Message(arbitration_id=can_id, data=rng.randbytes(8)))


def echo_child(port: int, accel_id: int, seconds: float) -> None:
    """The floor: answer every IMU_ACCEL with one frame (its payload, ECHO_ID), at once."""
    signal.signal(signal.SIGTERM, lambda _s, _f: sys.exit(0))
    with can.Bus(interface="udp_multicast", channel=GROUP, port=port) as bus:
        path = os.environ.get("NOTIFY_SOCKET")
        if path:
            with socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM) as s:
                s.sendto(b"READY=1", path)
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            msg = bus.recv(0.2)
            if msg is not None and msg.arbitration_id == accel_id:
                bus.send(can.Message(arbitration_id=ECHO_ID, data=msg.data))


def load_command(workers: int, seconds: float) -> list[str]:
    """stress-ng if installed, else ``workers`` bounded python busy loops (in one group)."""
    timeout = max(1, math.ceil(seconds))
    if shutil.which("stress-ng"):
        return ["stress-ng", "--cpu", str(workers), "--timeout", f"{timeout}s", "--quiet"]
    loop = f"import time\\ne=time.time()+{timeout}\\nwhile time.time()<e: pass"
    busy = f"{sys.executable} -c \"$(printf '{loop}')\""
    return ["sh", "-c", " & ".join([busy] * workers) + " & wait"]


# --- the run ------------------------------------------------------------------------------


@dataclass
class Options:
    seconds: float
    warmup: float
    workers: int
    harness_priority: int
    workdir: Path
    profile_dir: Path | None = None


@dataclass
class Capture:
    """What the monitor socket and the harness saw during one case."""

    #: kept frames: (kernel arrival stamp, id, data, time the monitor thread got it)
    frames: list[tuple[float, int, bytes, float]] = field(default_factory=list)
    noise_rx: int = 0
    sends: list[tuple[float, float, int]] = field(default_factory=list)  # IMU_ACCEL sent
    imu_sent: int = 0


class Monitor:
    """A udp_multicast socket on the group in a thread: keeps IMU and gateway frames."""

    def __init__(self, port: int, bridge_sa: int, capture: Capture) -> None:
        self.bus = can.Bus(interface="udp_multicast", channel=GROUP, port=port)
        sock = getattr(getattr(self.bus, "_multicast", None), "_socket", None)
        if sock is not None:  # a big receive buffer: the stamps are the kernel's anyway
            with contextlib.suppress(OSError):
                sock.setsockopt(socket.SOL_SOCKET, 33, 8 << 20)  # SO_RCVBUFFORCE
        self.bridge_sa, self.capture = bridge_sa, capture
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="monitor", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        keep, frames, cap = GATEWAY_PGNS, self.capture.frames, self.capture
        while not self._stop.is_set():
            msg = self.bus.recv(0.1)
            if msg is None:
                continue
            i = msg.arbitration_id
            if i & 0xFF == self.bridge_sa or i == ECHO_ID or pgn_of(i) in keep:
                frames.append((msg.timestamp, i, bytes(msg.data), time.time()))
            else:
                cap.noise_rx += 1

    def close(self) -> None:
        self._stop.set()
        self._thread.join(2.0)
        self.bus.shutdown()


def scenario_dir(rate: str, needed_s: float, workdir: Path) -> Path:
    """A simulated run at ``rate``: 5 s at rest, then driving, at least ``needed_s`` long."""
    out = workdir / f"run-{rate}"
    if (out / "truth.npz").exists():
        return out
    for passes in itertools.count(3):
        table = {
            "base": "short",
            "vehicle": {"start_stop_s": 5.0, "n_passes": passes, "swath_length_m": 100.0},
            "imu": {"dec": RATES[rate]},
        }
        run = generate(scenario_from_toml(table), out, seed=1)
        if run.duration_s >= needed_s:
            return out
    raise AssertionError("unreachable")


def write_config(path: Path, run_dir: Path, device: str) -> Path:
    """The service's config: the run's lever arms, the bus, the pty (as the e2e test)."""
    truth = Truth.load(run_dir / "truth.npz")
    lever = {
        k: [float(v) for v in getattr(truth, k)] for k in ("antenna_lever_arm_m", "imu_lever_arm_m")
    }
    path.write_text(
        "[vehicle]\n"
        + "".join(f"{k} = {v}\n" for k, v in lever.items())
        + f'[imu]\ninterface = "udp_multicast"\nchannel = "{GROUP}"\n'
        + f'[gnss]\nport = "{device}"\nreceiver_latency_s = 0.065\n'
    )
    return path


def navgw_command() -> list[str]:
    """``navgw`` from the tree this script is in (cwd REPO), whatever the venv has installed."""
    return [sys.executable, "-m", "gateway.cli.main"]


def run_case(case: Case, opts: Options, children: Children) -> dict[str, Any]:
    """Run one case; returns its figures (see :func:`analyse`)."""
    ensure_multicast_on_lo()
    total_s = START_LEAD_S + opts.warmup + opts.seconds + TAIL_S
    run_dir = scenario_dir(case.rate, opts.warmup + opts.seconds + 10.0, opts.workdir)
    tmp = Path(tempfile.mkdtemp(prefix=f"{case.name}-", dir=opts.workdir))
    port = random.randrange(*PORTS)
    config_path = tmp / "navgw.toml"
    capture = Capture()
    notify = NotifySocket(tmp / "notify.sock")
    env = {
        **os.environ,
        "NOTIFY_SOCKET": str(notify.path),
        "CAN_CONFIG": json.dumps({"port": port}),
    }
    harness_rt = opts.harness_priority > 0
    normal = ["chrt", "-o", "0"] if harness_rt else []
    prio = ["chrt", "-f", str(RT_PRIORITY)] if case.rt else normal
    bound_s = total_s + 30.0  # children end by themselves after this
    stderr_path = tmp / "service.stderr"
    service: subprocess.Popen[Any] | None = None
    profile: subprocess.Popen[Any] | None = None
    loadavg = Path("/proc/loadavg").read_text().split()[0]
    set_fifo(opts.harness_priority)  # threads started below inherit it
    gc.collect()
    gc.disable()  # a collection over the monitor's growing list would stall the IMU player
    try:
        monitor = Monitor(port, 0x80, capture)
        tx = can.Bus(interface="udp_multicast", channel=GROUP, port=port)
        with contextlib.ExitStack() as stack:
            stack.callback(monitor.close)
            stack.callback(tx.shutdown)
            stack.callback(notify.close)
            pb = stack.enter_context(
                SyncedPlayback(
                    run_dir / "imu.log", run_dir / "gnss.nmea", tx, 1.0, total_s - START_LEAD_S
                )
            )
            cfg = load_config(write_config(config_path, run_dir, pb.device))
            ids = imu_config(cfg).ids
            _record_sends(tx, ids.accel, capture)
            if case.load:
                children.start(
                    normal + load_command(opts.workers, bound_s),
                    stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                )  # fmt: skip
            if case.traffic:
                children.start(
                    [sys.executable, __file__, "_noise", str(port), str(TRAFFIC_FPS),
                     str(bound_s), str(port)],  # seed: the port
                    stdout=subprocess.DEVNULL,
                )  # fmt: skip
            if case.target == "navgw":
                cmd = prio + navgw_command() + ["run", "--config", str(config_path)]
            else:
                cmd = prio + [sys.executable, __file__, "_echo", str(port), str(ids.accel),
                              str(bound_s)]  # fmt: skip
            with stderr_path.open("w") as err:
                service = children.start(cmd, cwd=REPO, env=env, stderr=err, stdout=err)
            if notify.wait_for("READY=1", 30.0) is None:
                raise RuntimeError(f"{case.label}: no READY=1 (exit {service.poll()})")
            stack.enter_context(_draining(notify))
            origin = time.time() + START_LEAD_S
            pb.start(origin)
            w0 = origin + opts.warmup
            w1 = w0 + opts.seconds
            _sleep_until(w0)
            before = snapshot(service.pid)
            if opts.profile_dir is not None and case.target == "navgw":
                profile = _start_profile(case, service.pid, opts, children)
            _sleep_until(w1)
            after = snapshot(service.pid)
            _sleep_until(w1 + TAIL_S)
            status = children.stop(service)
            if profile is not None:
                children.stop(profile, grace_s=30.0)
    finally:
        gc.enable()
        set_fifo(0)
        if service is not None and service.poll() is None:
            children.stop(service)
        children.stop_all()
    stderr = stderr_path.read_text(errors="replace")
    result = analyse(case, capture, cfg, w0, w1)
    result |= {
        "loadavg_1min_at_start": float(loadavg),
        "service_exit": status,
        **deltas(before, after),
        "traceback": "Traceback" in stderr,
        "service_warnings": [
            line for line in stderr.splitlines() if "WARNING" in line or "ERROR" in line
        ][:8],
    }
    return result


@contextlib.contextmanager
def _draining(notify: NotifySocket) -> Iterator[None]:
    """Keep reading sd_notify datagrams: a full queue makes the service's sd_notify fail."""
    stop = threading.Event()

    def drain() -> None:
        while not stop.is_set():
            notify.wait_for("\0", 0.2)

    thread = threading.Thread(target=drain, name="notify", daemon=True)
    thread.start()
    try:
        yield
    finally:
        stop.set()
        thread.join()


def _record_sends(bus: can.BusABC, accel_id: int, capture: Capture) -> None:
    """Wrap ``bus.send``: (time before send, scheduled time, SEQ) of every IMU_ACCEL."""
    send = bus.send
    sends = capture.sends

    def timed_send(msg: can.Message, timeout: float | None = None) -> None:
        t = time.time()
        send(msg, timeout)
        capture.imu_sent += 1
        if msg.arbitration_id == accel_id:
            sends.append((t, msg.timestamp, msg.data[6]))

    setattr(bus, "send", timed_send)  # noqa: B010 (an instance attribute over the method)


def _sleep_until(t: float) -> None:
    while (left := t - time.time()) > 0:
        time.sleep(min(left, 0.5))


def _start_profile(
    case: Case, pid: int, opts: Options, children: Children
) -> subprocess.Popen[Any] | None:
    py_spy = shutil.which("py-spy") or str(Path(sys.executable).with_name("py-spy"))
    if not Path(py_spy).exists():
        print("  (py-spy not installed: no profile)", flush=True)
        return None
    assert opts.profile_dir is not None
    opts.profile_dir.mkdir(parents=True, exist_ok=True)
    out = opts.profile_dir / f"{case.name}.txt"
    return children.start(
        ["chrt", "-o", "0", py_spy, "record", "--pid", str(pid), "--rate", "1000",
         "--duration", str(math.ceil(opts.seconds)), "--format", "raw", "--nonblocking",
         "--output", str(out)],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
    )  # fmt: skip


# --- analysis -----------------------------------------------------------------------------


def percentiles_ms(x: np.ndarray) -> dict[str, float | None]:
    if len(x) == 0:
        return {"p50": None, "p99": None, "p99.9": None, "max": None}
    p = np.percentile(x, [50, 99, 99.9]) * 1e3
    return {
        "p50": round(float(p[0]), 3),
        "p99": round(float(p[1]), 3),
        "p99.9": round(float(p[2]), 3),
        "max": round(float(x.max()) * 1e3, 3),
    }


def triggers(frames: list[tuple[float, int, bytes, float]], cfg: Any) -> tuple[list[int], int]:
    """Indices into ``frames`` of the frames that completed a sample due a 127257 (the grid
    rule, on the sample times the project's decoder gives), and the samples it found lost."""
    decoder = ImuDecoder(imu_config(cfg))
    ids = decoder.config.ids
    imu = {ids.gyro, ids.accel, ids.aux}
    out: list[int] = []
    last_slot: int | None = None
    for n, (t, i, data, _) in enumerate(frames):
        if i not in imu:
            continue
        msg = can.Message(timestamp=t, arbitration_id=i, data=data, is_extended_id=True)
        for item in decoder.feed(msg):
            if isinstance(item, ImuSample):
                slot = math.floor(item.t * OUTPUT_HZ + GRID_TOLERANCE)
                if last_slot is None or slot > last_slot:
                    last_slot = slot
                    out.append(n)
    return out, decoder.counters.lost


def match_outputs(trig: np.ndarray, att: np.ndarray, sid: np.ndarray) -> np.ndarray:
    """Index into ``trig`` of the trigger of each 127257 arrival ``att`` (-1: none).

    Consecutive 127257 frames are ``(SID difference mod 253)`` slots apart (the SID advances
    once per output instant, and every instant of the default rates has a 127257), so
    ``k_m = K + c_m`` with ``c_m`` the cumulative SID steps; each arrival bounds ``k_m`` from
    above by the latest trigger that arrived before it (``L_m``), so ``K = min(L_m - c_m)``
    over a short window ahead (``MATCH_WINDOW`` frames): exact as long as one frame in that
    window is less than one slot (20 ms) late. A burst (the bridge, or the harness, stalled
    and several samples arrive at once) then maps each output to its own slot, where
    "latest trigger before it" would map two outputs to one.
    """
    if len(att) == 0:
        return np.zeros(0, dtype=int)
    upper = np.searchsorted(trig, att, side="left") - 1
    c = np.concatenate(([0], np.cumsum(np.diff(sid) % SID_MODULO)))
    r = upper - c
    pad = np.concatenate((r, np.full(MATCH_WINDOW - 1, np.iinfo(np.int64).max)))
    K = np.lib.stride_tricks.sliding_window_view(pad, MATCH_WINDOW).min(axis=1)
    k = K + c
    return np.where(k <= upper, k, -1)


def analyse(case: Case, cap: Capture, cfg: Any, w0: float, w1: float) -> dict[str, Any]:
    """Latency figures of one case, from the monitor's frames."""
    ids = imu_config(cfg).ids
    frames = cap.frames
    accel = [(t, d[6], got) for t, i, d, got in frames if i == ids.accel]
    accel_t = np.array([t for t, _, _ in accel])
    # udp_multicast one-way: harness send() -> kernel stamp at the monitor, in order
    hop = np.array(
        [a - s for (s, _, q), (a, r, _) in zip(cap.sends, accel, strict=False) if q == r]
    )
    late = np.array([s - sched for s, sched, _ in cap.sends])
    # kernel stamp -> the monitor thread has it: softirq delivery plus the monitor's wake-up
    delivery = np.array([got - t for t, _, got in accel if w0 <= t < w1])
    in_window = (accel_t >= w0) & (accel_t < w1)
    result: dict[str, Any] = {
        "case": case.label,
        "rate_hz": case.hz,
        "seconds": round(w1 - w0, 1),
        "imu_frames_sent": cap.imu_sent,
        "imu_accel_in_window": int(in_window.sum()),
        "noise_frames_received": cap.noise_rx,
        "hop_ms": percentiles_ms(hop),
        "harness_late_ms": percentiles_ms(late),  # IMU frames sent after their schedule
        "harness_stalls": int(np.sum(late > 1e-3)),  # sent > 1 ms late (a burst follows)
        "monitor_delivery_ms": percentiles_ms(delivery),
    }
    if case.target == "echo":
        last_by_seq: dict[int, float] = {}
        lat, answered = [], set()
        for t, i, d, _ in frames:
            if i == ids.accel:
                last_by_seq[d[6]] = t
            elif i == ECHO_ID and d[6] in last_by_seq:
                t_in = last_by_seq[d[6]]
                if w0 <= t_in < w1:
                    lat.append(t - t_in)
                    answered.add(t_in)
        result |= {
            "latency_ms": percentiles_ms(np.array(lat)),
            "expected": int(in_window.sum()),
            "received": len(lat),
            "missing": int(in_window.sum()) - len(answered),
        }
        return result
    trig_idx, lost_upstream = triggers(frames, cfg)
    trig = np.array([frames[n][0] for n in trig_idx])
    trig_delivery = np.array([frames[n][3] - frames[n][0] for n in trig_idx])
    gw = [(t, i, d) for t, i, d, _ in frames if i & 0xFF != 0x80 and i != ECHO_ID]
    outs = [(t, d[0]) for t, i, d in gw if pgn_of(i) == PGN_ATTITUDE]
    att = np.array([t for t, _ in outs])
    k = match_outputs(trig, att, np.array([sid for _, sid in outs], dtype=int))
    ok = k >= 0
    att, k = att[ok], k[ok]
    lat = att - trig[k]
    mine = (trig[k] >= w0) & (trig[k] < w1)
    expected = int(((trig >= w0) & (trig < w1)).sum())
    matched = np.unique(k[mine])
    # the naive rule (latest IMU_ACCEL before the output) disagrees when a later sample
    # arrived before the output: the service was more than one IMU period behind
    j = np.searchsorted(accel_t, att[mine], side="left") - 1
    overtaken = int(np.sum(accel_t[j] > trig[k[mine]] + 1e-9))
    status = [(t, d) for t, i, d in gw if pgn_of(i) == PGN_STATUS and w0 <= t < w1 + 1.0]
    lost, modes, mark = 0, [], -math.inf
    for t, d in status:
        modes.append(d[2])
        if t >= mark + 1.0 - 0.05:
            lost, mark = lost + d[6], t
    slow = np.argsort(lat[mine])[::-1][:5]
    result |= {
        "latency_ms": percentiles_ms(lat[mine]),
        "expected": expected,
        "received": int(mine.sum()),
        "missing": expected - len(matched),
        "duplicates": int(mine.sum()) - len(matched),
        "overtaken": overtaken,
        "gateway_frames_received": sum(1 for t, _, _ in gw if w0 <= t < w1),
        "imu_samples_lost": lost,
        "imu_samples_lost_max_per_s": max((d[6] for _, d in status), default=None),
        "imu_samples_lost_upstream": lost_upstream,  # gaps the monitor saw too (whole run)
        "navigating_fraction": round(modes.count(2) / len(modes), 3) if modes else None,
        # the slowest outputs: when, how late, and how late the monitor got their trigger
        "slowest": [
            {
                "at_s": round(float(trig[k[mine]][n] - w0), 3),
                "latency_ms": round(float(lat[mine][n]) * 1e3, 3),
                "trigger_delivery_ms": round(float(trig_delivery[k[mine]][n]) * 1e3, 3),
            }
            for n in slow
        ],
    }
    return result


# --- report -------------------------------------------------------------------------------


def table(results: list[dict[str, Any]]) -> str:
    head = (
        "| case | p50 ms | p99 ms | p99.9 ms | max ms | 127257 rx/expected (missing) "
        "| overtaken | IMU lost (socket drops) | hop p50/p99 ms | service CPU | load avg |\n"
        "|---|---|---|---|---|---|---|---|---|---|---|\n"
    )
    rows = []
    for r in results:
        lat, hop = r["latency_ms"], r["hop_ms"]
        p99 = lat["p99"]
        mark = "**" if p99 is not None and p99 > TARGET_P99_MS else ""
        cpu = r.get("service_cpu_percent")
        rows.append(
            f"| {r['case']} | {lat['p50']} | {mark}{p99}{mark} | {lat['p99.9']} | {lat['max']} "
            f"| {r['received']}/{r['expected']} ({r['missing']}) | {r.get('overtaken', '-')} "
            f"| {r.get('imu_samples_lost', '-')} ({r.get('service_socket_drops', '-')}) "
            f"| {hop['p50']}/{hop['p99']} | {'-' if cpu is None else f'{cpu:.0f} %'} "
            f"| {r.get('loadavg_1min_at_start', '-')} |"
        )
    return head + "\n".join(rows)


def code_version() -> str:
    """git HEAD, plus a hash of the working tree's service code (others may be editing it):
    the decoder replicated here must be the one the service runs."""
    head = subprocess.run(
        ["git", "rev-parse", "--short", "HEAD"], cwd=REPO, capture_output=True, text=True
    ).stdout.strip()
    digest = hashlib.sha1()
    for path in sorted([*REPO.glob("gateway/*.py"), *REPO.glob("drivers/*.py")]):
        digest.update(path.read_bytes())
    return f"{head or '?'}+{digest.hexdigest()[:8]}"


def machine() -> dict[str, Any]:
    model = next(
        (
            line.split(":", 1)[1].strip()
            for line in Path("/proc/cpuinfo").read_text().splitlines()
            if line.startswith("model name")
        ),
        platform.processor(),
    )
    return {
        "date": time.strftime("%Y-%m-%d %H:%M %Z"),
        "nproc": os.cpu_count(),
        "cpu": model,
        "kernel": platform.release(),
        "python": platform.python_version(),
        "python_can": can.__version__,
        "loadavg_at_start": Path("/proc/loadavg").read_text().split()[:3],
        "load": "stress-ng" if shutil.which("stress-ng") else "python busy loops",
        "code": code_version(),
    }


def main(argv: Sequence[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    children_modes: dict[str, Callable[[list[str]], None]] = {
        "_noise": lambda a: noise_child(int(a[0]), float(a[1]), float(a[2]), int(a[3])),
        "_echo": lambda a: echo_child(int(a[0]), int(a[1]), float(a[2])),
    }
    if argv and argv[0] in children_modes:
        children_modes[argv[0]](argv[1:])
        return 0
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=30.0, help="measured seconds per case")
    parser.add_argument("--warmup", type=float, default=12.0, help="unmeasured start, s")
    parser.add_argument(
        "--cases", default="*", help="comma-separated patterns, e.g. '819-*-load-*' (default *)"
    )
    parser.add_argument(
        "--quick", action="store_true", help=f"cases {QUICK_CASES}, 10 s each (a smoke run)"
    )
    parser.add_argument(
        "--target", choices=("navgw", "echo", "both"), default="navgw",
        help="the service, the trivial echo baseline, or both",
    )  # fmt: skip
    parser.add_argument(
        "--load-workers", type=int, default=os.cpu_count() or 1,
        help="stress-ng --cpu workers (default: one per core)",
    )  # fmt: skip
    parser.add_argument(
        "--harness-priority", type=int, default=HARNESS_PRIORITY,
        help="SCHED_FIFO priority of the harness (0: normal)",
    )  # fmt: skip
    parser.add_argument("--json", type=Path, help="write the results here")
    parser.add_argument(
        "--profile", type=Path, metavar="DIR",
        help="py-spy record (raw) of the service over each window into DIR",
    )  # fmt: skip
    args = parser.parse_args(argv)
    if args.quick:
        args.cases, args.seconds = QUICK_CASES, min(args.seconds, 10.0)
    cases = select_cases(args.cases, args.target)
    children = Children()

    def terminate(signum: int, _frame: object) -> None:
        raise SystemExit(128 + signum)

    for sig in (signal.SIGTERM, signal.SIGHUP, signal.SIGINT):  # SIGINT: even in background
        signal.signal(sig, terminate)
    info = machine()
    print(
        f"{info['date']}: {info['nproc']} x {info['cpu']}, load average {info['loadavg_at_start']}"
        f"; {len(cases)} cases x {args.seconds:g} s (+{args.warmup:g} s warm-up)",
        flush=True,
    )
    results: list[dict[str, Any]] = []
    with (
        tempfile.TemporaryDirectory(prefix="navgw-latency-") as work,
        multicast_route(GROUP),
    ):
        try:
            opts = Options(
                args.seconds, args.warmup, args.load_workers, args.harness_priority,
                Path(work), args.profile,
            )  # fmt: skip
            for case in cases:
                if (code := code_version()) != info["code"]:
                    print(f"  WARNING: the service code changed during the run ({code})")
                r = run_case(case, opts, children) | {"code": code}
                results.append(r)
                lat = r["latency_ms"]
                print(
                    f"{r['case']:>28}: p50 {lat['p50']} p99 {lat['p99']} p99.9 {lat['p99.9']} "
                    f"max {lat['max']} ms; {r['received']}/{r['expected']} "
                    f"(missing {r['missing']}); lost {r.get('imu_samples_lost', '-')}; "
                    f"hop p50 {r['hop_ms']['p50']} ms; harness late max "
                    f"{r['harness_late_ms']['max']} ms; cpu {r.get('service_cpu_percent')} %"
                    + (f"; {r['service_warnings']}" if r.get("service_warnings") else ""),
                    flush=True,
                )
        finally:
            children.stop_all()
            if args.json is not None:
                args.json.write_text(
                    json.dumps(
                        {"machine": info, "args": sys.argv[1:], "results": results}, indent=1
                    )
                )
    print()
    print(table(results))
    return 0


if __name__ == "__main__":
    sys.exit(main())
