"""The gateway's output through the real can-utils on vcan: canplayer, candump, cantools."""

from __future__ import annotations

import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import IO

import pytest

import dbc
from drivers.logs.candump import read_candump
from tests.n2k_check import decode_log
from tests.vcan.conftest import candump_argv

pytestmark = pytest.mark.live


def _first_seconds(sim_run: Path, tmp_path: Path, seconds: float) -> Path:
    """The gateway's output for the first ``seconds`` of the run, as a candump log."""
    full = sim_run / "gateway.log"
    frames = list(read_candump(full))
    lines = full.read_text().splitlines(keepends=True)
    cut = tmp_path / "out.log"
    t0 = frames[0].timestamp
    cut.write_text(
        "".join(line for line, f in zip(lines, frames, strict=True) if f.timestamp - t0 <= seconds)
    )
    return cut


def _wait_for_line(stream: IO[str], needle: str, timeout_s: float) -> list[str]:
    """Lines read from ``stream`` until one contains ``needle`` (a reader thread)."""
    found: list[str] = []
    done = threading.Event()

    def read() -> None:
        for line in stream:
            found.append(line)
            if needle in line:
                done.set()
                return

    threading.Thread(target=read, daemon=True).start()
    assert done.wait(timeout_s), f"no {needle!r} within {timeout_s} s: {found[-3:]}"
    return found


def test_canplayer_output_recorded_by_candump_decodes_the_same(
    vcan0: str, sim_run: Path, tmp_path: Path, candump: Path
) -> None:
    out = _first_seconds(sim_run, tmp_path, seconds=20.0)
    subprocess.run(["canplayer", "-I", str(out), f"{vcan0}=can0"], check=True, timeout=120)
    time.sleep(0.5)
    sent = [(f.arbitration_id, bytes(f.data)) for f in read_candump(out)]
    seen = [(f.arbitration_id, bytes(f.data)) for f in read_candump(candump)]
    assert seen == sent  # every frame, in order, bit for bit, through the kernel
    decoded = decode_log(candump)
    assert sum(m.id == "attitude" for m in decoded) > 500
    assert sum(m.id == "gnssPositionData" for m in decoded) > 100  # fast packets reassembled


def test_candump_piped_into_cantools_decode_reads_the_gateway_frames(
    vcan0: str, sim_run: Path, tmp_path: Path
) -> None:
    # cantools decodes a few hundred lines a second in the emulated guest: a short excerpt,
    # paced by canplayer (-t -g 15: a frame every 15 ms), and a large socket buffer for candump
    # (the emulator can starve it for a while), so that no frame is dropped
    out = _first_seconds(sim_run, tmp_path, seconds=3.0)
    expected = sum(m.id == "attitude" for m in decode_log(out))
    # candump | tee | cantools decode: tee keeps what candump printed, to compare line for line
    raw = tmp_path / "candump.txt"
    dump = subprocess.Popen(candump_argv(vcan0, "-d"), stdout=subprocess.PIPE)
    tee = subprocess.Popen(["tee", str(raw)], stdin=dump.stdout, stdout=subprocess.PIPE)
    assert dump.stdout is not None
    dump.stdout.close()
    decode = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "cantools",
            "decode",
            "--single-line",
            "-m",
            "0x03FFFF00",
            str(dbc.path(dbc.OUTPUT_DBC)),
        ],
        stdin=tee.stdout,
        stdout=subprocess.PIPE,
        text=True,
    )
    assert tee.stdout is not None and decode.stdout is not None
    tee.stdout.close()
    # the pipeline is up (python starts slowly in the emulated guest) once a probe comes out
    stop_probing = threading.Event()

    def probe() -> None:
        while not stop_probing.wait(0.5):
            subprocess.run(["cansend", vcan0, "18FF221C#FE5F000000000000"], check=False)

    threading.Thread(target=probe, daemon=True).start()
    try:
        _wait_for_line(decode.stdout, "NAVGW_STATUS(", timeout_s=90)
    finally:
        stop_probing.set()
    subprocess.run(
        ["canplayer", "-t", "-g", "15", "-I", str(out), f"{vcan0}=can0"], check=True, timeout=120
    )
    time.sleep(2.0)
    dump.terminate()
    text, _ = decode.communicate(timeout=60)
    printed = raw.read_text()
    assert "DROPCOUNT" not in printed, "the kernel dropped frames for candump: the guest is starved"
    assert "ADDRESS_CLAIM(" in text
    attitude = [line for line in text.splitlines() if "ATTITUDE(" in line]
    assert len(attitude) == printed.count(" 0DF1191C ") == expected > 100  # all, at 50 Hz
    assert "YAW:" in attitude[-1] and "ROLL:" in attitude[-1] and "rad" in attitude[-1]
    assert "NAVGW_GYRO_BIAS(" in text and "POSITION_RAPID_UPDATE(" in text
    assert "GNSS_POSITION_DATA_FP(" in text  # fast-packet frames labelled too
