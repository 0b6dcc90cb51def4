"""A short simulated run replayed to an output log: what the monitor and plot tests read."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from gateway.config.gateway_config import load_config
from gateway.offline.log_replay import replay
from sim_bus.scenarios import SCENARIOS, generate

SEED = 3


@dataclass(frozen=True)
class OutputRun:
    """The simulator's files (``imu.log``, ``gnss.nmea``, ``truth.npz``) and ``out.log``."""

    directory: Path

    @property
    def log(self) -> Path:
        return self.directory / "out.log"

    @property
    def truth(self) -> Path:
        return self.directory / "truth.npz"


def make_output_run(directory: Path) -> OutputRun:
    """Simulate the ``short`` scenario (~2 min) and replay it with its vehicle's config."""
    generate(SCENARIOS["short"], directory, seed=SEED)
    run = OutputRun(directory)
    replay(
        directory / "imu.log",
        directory / "gnss.nmea",
        run.log,
        load_config(directory / "navgw.toml"),
    )
    return run


def last_data(log: Path, pgn: int) -> bytes:
    """The data of the last frame of ``pgn`` in ``log`` (read without the DBC)."""
    from drivers.logs.candump import read_candump

    data = b""
    for msg in read_candump(log):
        if (msg.arbitration_id >> 8) & 0x3FFFF == pgn:
            data = bytes(msg.data)
    return data


def expected_text(log: Path) -> dict[str, str]:
    """What the monitor must show for the last frames of ``log``, worked out by hand from
    SPEC 4's layouts (struct, not the DBC): gyro biases 1e-4 deg/s, latitude 1e-7 deg,
    NAVGW_STATUS's estimator flags."""
    import struct

    gx, gy, gz = struct.unpack_from("<3h", last_data(log, 0xFF20), 2)
    (lat,) = struct.unpack_from("<i", last_data(log, 129025), 0)
    estimator = last_data(log, 0xFF22)[5]  # NAVGW_STATUS byte 5: convergence bits 0-2
    converged = ", ".join(
        f"{what} {'converged' if estimator >> bit & 1 else 'learning'}"
        for bit, what in enumerate(("gyro x/y", "gyro z", "accel x/y"))
    )
    return {
        "converged": converged,
        "gyro": f"x {gx * 1e-4:+.4f}  y {gy * 1e-4:+.4f}  z {gz * 1e-4:+.4f}",
        "gyro x": f"{gx * 1e-4:+.4f}",
        "latitude": f"latitude  {lat * 1e-7:.7f} deg",
    }
