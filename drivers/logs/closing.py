"""Context-manager behaviour for the log readers, writers and players: one ``close()``."""

from __future__ import annotations

from types import TracebackType
from typing import TypeVar

_C = TypeVar("_C", bound="Closing")


class Closing:
    """``with obj:`` closes ``obj`` at the end; subclasses define an idempotent ``close()``."""

    def close(self) -> None:
        """Release what the object holds; safe to call twice."""
        raise NotImplementedError

    def __enter__(self: _C) -> _C:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()
