"""sd_notify: the service as a subprocess talks to a socket the test binds, as systemd would."""

from __future__ import annotations

import itertools
import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from gateway.service.sdnotify import SdNotifier
from tests.notify_socket import NotifySocket

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture
def notify(tmp_path: Path) -> Iterator[NotifySocket]:
    sock = NotifySocket(tmp_path / "notify.sock")
    yield sock
    sock.close()


def start_service(config: Path, notify: NotifySocket, **env: str) -> subprocess.Popen[str]:
    environ = {**os.environ, "NOTIFY_SOCKET": str(notify.path), "JOURNAL_STREAM": "8:1", **env}
    return subprocess.Popen(
        [sys.executable, "-m", "gateway.cli.main", "run", "--config", str(config)],
        cwd=REPO,
        env=environ,
        stderr=subprocess.PIPE,
        text=True,
    )


def test_notifier_sends_datagrams_and_is_silent_without_socket(notify: NotifySocket) -> None:
    SdNotifier({}).ready()  # no $NOTIFY_SOCKET: nothing happens, nothing raised
    n = SdNotifier({"NOTIFY_SOCKET": str(notify.path), "WATCHDOG_USEC": "400000"})
    assert n.watchdog_interval_s == pytest.approx(0.2)
    n.ready("starting")
    assert notify.wait_for("READY=1", 1.0) == "READY=1"
    assert ("STATUS=starting" in [line for _, line in notify.received]) is True
    other = {"NOTIFY_SOCKET": str(notify.path), "WATCHDOG_USEC": "400000", "WATCHDOG_PID": "1"}
    assert SdNotifier(other).watchdog_interval_s is None  # meant for another process
    n.close()
    n.close()


def test_missing_devices_ready_watchdog_status_then_clean_stop(
    tmp_path: Path, notify: NotifySocket
) -> None:
    """No serial device, no CAN interface: READY, WATCHDOG, STATUS 'waiting'; SIGTERM -> 0."""
    config = tmp_path / "navgw.toml"
    config.write_text(
        '[imu]\ninterface = "socketcan"\nchannel = "navgwtest0"\n'
        f'[gnss]\nport = "{tmp_path / "ttyNONE"}"\n'
    )
    proc = start_service(config, notify, WATCHDOG_USEC="400000")
    try:
        assert notify.wait_for("READY=1", 20.0), proc.stderr
        status = notify.wait_for("STATUS=", 5.0)
        assert status is not None
        assert "GNSS waiting for" in status and "ttyNONE" in status, status
        assert "CAN socketcan navgwtest0 waiting" in status, status
        notify.wait_for("(collect for a while)", 1.2)
        beats = notify.times("WATCHDOG=1")
        assert len(beats) >= 4, notify.received  # every 0.2 s while healthy
        assert max(b - a for a, b in itertools.pairwise(beats)) < 0.45
        assert proc.poll() is None  # still running, still waiting
        t_term = time.monotonic()
        proc.send_signal(signal.SIGTERM)
        assert notify.wait_for("STOPPING=1", 3.0) == "STOPPING=1"
        assert proc.wait(timeout=3.0) == 0
        assert time.monotonic() - t_term < 3.0
    finally:
        if proc.poll() is None:
            proc.kill()
        stderr = proc.communicate()[1]
    assert "WARNING drivers.gnss_serial: GNSS port" in stderr  # journald format: no timestamp
    assert "not available" in stderr and "navgwtest0" in stderr
