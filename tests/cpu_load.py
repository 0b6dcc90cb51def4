"""A competing CPU load for the live-path tests: started and stopped by the test run itself.

``NAVGW_TEST_CPU_LOAD=N`` makes ``tests/conftest.py`` run N CPU hogs for the whole pytest
session (``scripts/test`` runs the ``live`` tests a second time so). The hogs are
``stress-ng --cpu N`` (the Debian package ``stress-ng``; ``.ci/run`` installs it) or, where it
is absent, N Python busy loops in their own processes. Either way the load is bounded three
times over, so that nothing outlives the run:

- stopped at the end of the session (also after a failure or Ctrl-C): SIGTERM to each hog's
  process group, SIGKILL if one is still there after :data:`STOP_GRACE_S`, and checked gone;
- each hog gets SIGTERM from the kernel if the process that started it dies (SIGKILL included,
  ``PR_SET_PDEATHSIG``);
- each hog ends by itself after ``timeout_s`` (``stress-ng --timeout``, the loop's deadline).

As a command it runs another command under the load (``scripts/test`` does so for the vcan
VM)::

    python -m tests.cpu_load 2 --timeout 900 -- bash ../shared/tools/vcan-vm/run.sh
"""

from __future__ import annotations

import argparse
import contextlib
import ctypes
import os
import shutil
import signal
import subprocess
import sys
import time
from types import TracebackType

#: The environment variable the test session reads: the number of CPU hogs (0: none).
ENV_LOAD = "NAVGW_TEST_CPU_LOAD"
#: Optional: the hogs' own time limit, seconds (they are stopped earlier at the session's end).
ENV_TIMEOUT = "NAVGW_TEST_CPU_LOAD_S"
DEFAULT_TIMEOUT_S = 900  # well above a loaded live pass (~3 min), well under CI's limit
STOP_GRACE_S = 5.0

_PR_SET_PDEATHSIG = 1
_BUSY_LOOP = (
    "import sys, time\n"
    "end = time.monotonic() + float(sys.argv[1])\n"
    "while time.monotonic() < end:\n"
    "    pass\n"
)


def _die_with_parent() -> None:
    """In the child before exec: SIGTERM when the parent dies (Linux; elsewhere nothing)."""
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(_PR_SET_PDEATHSIG, signal.SIGTERM)
    except (OSError, AttributeError):
        pass


def _signal_group(pgid: int, signum: int) -> None:
    with contextlib.suppress(ProcessLookupError):
        os.killpg(pgid, signum)


def _group_alive(pgid: int) -> bool:
    try:
        os.killpg(pgid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


class CpuLoad:
    """``n`` CPU hogs from :meth:`start` to :meth:`stop` (a context manager too)."""

    def __init__(self, n: int, timeout_s: float = DEFAULT_TIMEOUT_S) -> None:
        if n < 0 or timeout_s <= 0:
            raise ValueError(f"CpuLoad(n={n}, timeout_s={timeout_s}): expected n >= 0, t > 0")
        self.n = n
        self.timeout_s = timeout_s
        self.procs: list[subprocess.Popen[bytes]] = []
        self.description = "none"
        self.started = self.stopped = 0.0

    def _spawn(self, argv: list[str]) -> subprocess.Popen[bytes]:
        proc = subprocess.Popen(
            argv,
            stdin=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            start_new_session=True,  # its own process group: stopped as one, not hit by Ctrl-C
            preexec_fn=_die_with_parent,  # safe: started before any thread of ours
        )
        self.procs.append(proc)
        return proc

    def start(self) -> CpuLoad:
        """Start the hogs; :attr:`description` says which."""
        if self.n == 0 or self.procs:
            return self
        seconds = max(1, round(self.timeout_s))
        self.started = time.monotonic()
        stress = shutil.which("stress-ng")
        if stress is not None:
            argv = [stress, "--cpu", str(self.n), "--timeout", f"{seconds}s", "--quiet"]
            proc = self._spawn(argv)
            time.sleep(0.2)
            if proc.poll() is None:
                self.description = f"stress-ng --cpu {self.n} --timeout {seconds}s"
                return self
            self.procs.clear()
            why = f"stress-ng exited at once with status {proc.returncode}"
        else:
            why = "stress-ng not installed"
        for _ in range(self.n):
            self._spawn([sys.executable, "-c", _BUSY_LOOP, str(seconds)])
        self.description = f"{self.n} Python busy loops of at most {seconds} s ({why})"
        return self

    def stop(self) -> list[str]:
        """Stop every hog and its children; the groups that needed SIGKILL (normally none).

        Raises RuntimeError if a process group is still there after SIGKILL.
        """
        killed: list[str] = []
        for proc in self.procs:
            pgid = proc.pid  # start_new_session: the group's id is the leader's pid
            _signal_group(pgid, signal.SIGTERM)
            deadline = time.monotonic() + STOP_GRACE_S
            while proc.poll() is None or _group_alive(pgid):
                if time.monotonic() > deadline:
                    killed.append(f"process group {pgid}")
                    _signal_group(pgid, signal.SIGKILL)
                    proc.wait(STOP_GRACE_S)
                    time.sleep(0.1)
                    if _group_alive(pgid):
                        raise RuntimeError(f"CPU load: process group {pgid} survived SIGKILL")
                    break
                time.sleep(0.02)
        if self.procs:
            self.stopped = time.monotonic()
        self.procs.clear()
        return killed

    @property
    def ran_s(self) -> float:
        """How long the load ran (after :meth:`stop`)."""
        return max(0.0, self.stopped - self.started)

    def __enter__(self) -> CpuLoad:
        return self.start()

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.stop()


def from_environment() -> CpuLoad | None:
    """The load ``NAVGW_TEST_CPU_LOAD`` asks for, None if none; ValueError if malformed."""
    raw = os.environ.get(ENV_LOAD, "").strip()
    if raw in ("", "0"):
        return None
    try:
        n = int(raw)
        timeout_s = float(os.environ.get(ENV_TIMEOUT, DEFAULT_TIMEOUT_S))
        return CpuLoad(n, timeout_s) if n else None
    except ValueError as exc:
        raise ValueError(
            f"{ENV_LOAD}={raw!r} {ENV_TIMEOUT}={os.environ.get(ENV_TIMEOUT)!r}: expected the "
            f"number of CPU hogs (an integer >= 0) and their time limit in seconds ({exc})"
        ) from None


def main(argv: list[str] | None = None) -> int:
    """Run a command under the load; its exit status."""
    argv = sys.argv[1:] if argv is None else argv
    split = argv.index("--") if "--" in argv else len(argv)
    parser = argparse.ArgumentParser(
        prog="python -m tests.cpu_load",
        usage="%(prog)s N [--timeout S] -- COMMAND [ARG...]",
        description="Run COMMAND under N CPU hogs; its exit status.",
    )
    parser.add_argument("n", type=int, help="number of CPU hogs")
    parser.add_argument("--timeout", type=float, default=DEFAULT_TIMEOUT_S,
                        help="the hogs' own time limit, s (default %(default)s)")  # fmt: skip
    args = parser.parse_args(argv[:split])
    command = argv[split + 1 :]
    if not command:
        parser.error("no command after --")
    load = CpuLoad(args.n, args.timeout)
    # the command, not this wrapper, gets Ctrl-C and a TERM: forward them, then stop the load
    child: subprocess.Popen[bytes] | None = None

    def forward(signum: int, _frame: object) -> None:
        if child is not None and child.poll() is None:
            child.send_signal(signum)

    signal.signal(signal.SIGTERM, forward)
    signal.signal(signal.SIGINT, forward)
    with load:
        print(f"CPU load: {load.description}", file=sys.stderr, flush=True)
        started = time.monotonic()
        child = subprocess.Popen(command)
        status = child.wait()
        print(f"CPU load: stopped after {time.monotonic() - started:.0f} s", file=sys.stderr)
    return status


if __name__ == "__main__":
    sys.exit(main())
