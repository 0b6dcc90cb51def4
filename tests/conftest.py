"""Session-wide test setup: the ``live`` marker on other files' tests, and the CPU load.

``live`` (registered in pyproject.toml) marks the tests that run the gateway's live path in
real time, or faster on a scaled clock, so that the host's scheduling reaches what they
check. ``scripts/test`` runs them a second time under a competing CPU load:

    NAVGW_TEST_CPU_LOAD=2 .venv/bin/python -m pytest -m live

The modules that are live as a whole say so themselves (``pytestmark``): test_service_e2e.py,
test_demo.py and tests/vcan/. Single live tests in other modules are listed in
:data:`LIVE_TESTS`.

A test in which an engine raised fails (:func:`no_engine_fault`): the core keeps the
gateway going past it (``FusionCore._engine_raised``), which must not keep a bug from the
tests.

``NAVGW_TEST_CPU_LOAD=N`` runs N CPU hogs (:mod:`tests.cpu_load`: stress-ng, or Python busy
loops where it is absent) from the start of the session to its end, failures and Ctrl-C
included; the header of the run says which.
"""

from __future__ import annotations

import atexit
import logging
from collections.abc import Iterator

import pytest

from tests.cpu_load import CpuLoad, from_environment
from tests.multicast import multicast_port  # noqa: F401 - a fixture for every test module

#: Live tests in modules that are not live as a whole (node ids relative to the rootdir).
LIVE_TESTS = frozenset(
    {
        # the service object runs on a virtual bus in real time; its bus is shut under it
        "tests/test_service.py::test_service_reopens_a_bus_that_goes_away_and_claims_again",
        # the service's frame reader and its notifier thread, timed by a sleep
        "tests/test_service.py::test_reader_drops_oldest_when_full_and_ends_with_bus_error",
        "tests/test_service.py::test_reader_sheds_stale_frames_from_its_buffer_and_socket_in_order",
        "tests/test_service.py::"
        "test_a_reader_held_up_once_sheds_the_stale_frames_and_one_behind_again_its_backlog",
        # `navgw run` as a subprocess: READY, WATCHDOG every 0.2 s (< 0.45 s apart), STOPPING
        "tests/test_sdnotify.py::test_missing_devices_ready_watchdog_status_then_clean_stop",
    }
)

_load: CpuLoad | None = None


@pytest.fixture(autouse=True)
def no_engine_fault(caplog: pytest.LogCaptureFixture) -> Iterator[None]:
    """Fails the test if the fusion core caught an engine that raised in it (a test that
    injects one clears ``caplog`` once it has looked)."""
    yield
    raised = [
        r.getMessage()
        for r in caplog.get_records("call")
        if r.name == "gateway.fusion.fusion_core" and r.levelno >= logging.ERROR
    ]
    assert not raised, raised


@pytest.hookimpl(tryfirst=True)  # before -m selects on the marker
def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Mark :data:`LIVE_TESTS` ``live``; a listed test its module no longer has is an error."""
    modules = {}
    for item in items:
        file, _, name = item.nodeid.partition("::")
        if isinstance(item, pytest.Function):
            modules[file] = item.module
        if item.nodeid in LIVE_TESTS or f"{file}::{name.split('[')[0]}" in LIVE_TESTS:
            item.add_marker(pytest.mark.live)
    gone = [
        node for node in sorted(LIVE_TESTS)
        if (file := node.split("::")[0]) in modules
        and not hasattr(modules[file], node.split("::")[1])
    ]  # fmt: skip
    if gone:
        raise pytest.UsageError(f"tests/conftest.py LIVE_TESTS names tests that are gone: {gone}")


def _stop_load() -> list[str]:
    global _load
    load, _load = _load, None
    return load.stop() if load is not None else []


def pytest_configure(config: pytest.Config) -> None:
    """Read NAVGW_TEST_CPU_LOAD (a malformed value stops the run before it starts)."""
    global _load
    try:
        _load = from_environment()
    except ValueError as exc:
        raise pytest.UsageError(str(exc)) from None


@pytest.hookimpl(tryfirst=True)  # before the terminal reporter writes the header
def pytest_sessionstart(session: pytest.Session) -> None:
    """Start the CPU load NAVGW_TEST_CPU_LOAD asks for, for the whole session."""
    if _load is not None and not session.config.option.collectonly:
        _load.start()
        atexit.register(_stop_load)  # a backstop; sessionfinish stops it


def pytest_report_header(config: pytest.Config) -> str:
    return f"CPU load: {_load.description if _load is not None else 'none'}"


def pytest_sessionfinish(session: pytest.Session, exitstatus: int) -> None:
    """Stop the load (pytest calls this after failures and interrupts too)."""
    load = _load
    killed = _stop_load()
    reporter = session.config.pluginmanager.get_plugin("terminalreporter")
    if load is not None and load.started and reporter is not None:
        text = f"CPU load ({load.description}) stopped after {load.ran_s:.0f} s"
        reporter.write_line(text + (f"; had to SIGKILL {', '.join(killed)}" if killed else ""))
