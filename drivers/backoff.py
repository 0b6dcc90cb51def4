"""Retry delays for devices that come and go (a CAN interface down, a USB receiver unplugged)."""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass
class Backoff:
    """Retry delays: ``initial_s``, doubling up to ``max_s``; :meth:`reset` after a success."""

    initial_s: float = 0.5
    max_s: float = 10.0
    _next_s: float = field(default=0.0, init=False)

    def next(self) -> float:
        """The delay before the next attempt."""
        self._next_s = min(self.max_s, 2.0 * self._next_s) if self._next_s else self.initial_s
        return self._next_s

    def reset(self) -> None:
        """Start again from ``initial_s``."""
        self._next_s = 0.0
