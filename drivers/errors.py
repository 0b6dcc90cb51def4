"""Errors raised by the drivers: one small hierarchy, messages that say what, where, expected."""

from __future__ import annotations

from enum import Enum


class DriverError(Exception):
    """Base of every error a driver raises (bus failure, unreadable input, bad config)."""


class InputError(DriverError):
    """Input that cannot be used: ``what`` was wrong, ``where`` it was, what was ``expected``."""

    def __init__(self, what: str, where: str, expected: str) -> None:
        self.what = what
        self.where = where
        self.expected = expected
        super().__init__(f"{where}: {what}; expected {expected}")


class BusError(DriverError):
    """The CAN bus (or the interface under it) failed while a driver was reading it."""


class ErrorPolicy(Enum):
    """What a decoder does with input it cannot use (pynmeagps' quitonerror, by name)."""

    RAISE = "raise"  # stop at the first: InputError (strict tools, tests)
    LOG = "log"  # count, warn at a limited rate, skip (the service and replay: the default)
    IGNORE = "ignore"  # count and skip quietly (fuzzing, bulk re-processing)
