"""Errors raised by the drivers: one small hierarchy, messages that say what, where, expected."""

from __future__ import annotations


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
