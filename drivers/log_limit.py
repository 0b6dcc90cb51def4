"""Warnings at a sane rate: bad input and recurring events are logged, not flooded.

A log line per malformed frame would fill an ECU's journal (a babbling node sends thousands a
second) and cost the loop its deadline. :class:`LogLimiter` logs the first event of each kind,
then at most one per ``interval_s`` with the number suppressed since. Time is the caller's:
input time (frame or sentence stamps) in the decoders and engines, so replay logs what the
live service logged; the monotonic clock in the service.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Hashable
from dataclasses import dataclass, field

from drivers.errors import ErrorPolicy, InputError

LOG_INTERVAL_S = 10.0  # at most one warning per kind per this long


@dataclass
class _Kind:
    last_t: float = -math.inf
    suppressed: int = 0


@dataclass
class LogLimiter:
    """At most one warning per kind per ``interval_s`` of the caller's clock."""

    logger: logging.Logger
    interval_s: float = LOG_INTERVAL_S
    _kinds: dict[Hashable, _Kind] = field(default_factory=dict)

    def warning(self, t: float, text: str, kind: Hashable = None) -> bool:
        """Log ``text`` now, or count it if a warning of ``kind`` was logged less than
        ``interval_s`` before ``t`` (a non-finite or earlier ``t`` logs: the clock was reset).
        Returns whether it was logged."""
        state = self._kinds.setdefault(kind, _Kind())
        if math.isfinite(t) and state.last_t <= t < state.last_t + self.interval_s:
            state.suppressed += 1
            return False
        more = f" ({state.suppressed} more since the last report)" if state.suppressed else ""
        self.logger.warning("%s%s", text, more)
        state.last_t, state.suppressed = t, 0
        return True


@dataclass
class BadInput:
    """Input a decoder cannot use, handled under the caller's :class:`ErrorPolicy`: raised as
    :class:`InputError`, logged at a limited rate (one line per kind per ``interval_s``), or
    skipped quietly. The caller counts it either way."""

    logger: logging.Logger
    policy: ErrorPolicy = ErrorPolicy.LOG
    interval_s: float = LOG_INTERVAL_S
    _log: LogLimiter = field(init=False)

    def __post_init__(self) -> None:
        self._log = LogLimiter(self.logger, self.interval_s)

    def bad(self, t: float, kind: Hashable, where: str, what: str, expected: str) -> None:
        """Unusable input at ``where`` (input time ``t``): ``what`` was wrong, what was
        ``expected``; it is dropped."""
        if self.policy is ErrorPolicy.RAISE:
            raise InputError(what, where, expected)
        if self.policy is ErrorPolicy.LOG:
            self._log.warning(t, f"{where}: {what}; expected {expected}", kind)

    def note(self, t: float, kind: Hashable, text: str) -> None:
        """Something worth a warning that is not an error (input accepted, data lost)."""
        if self.policy is not ErrorPolicy.IGNORE:
            self._log.warning(t, text, kind)
