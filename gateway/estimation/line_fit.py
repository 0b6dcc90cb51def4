"""Weighted least-squares line y = a + b x by running sums, for estimators that fit one as
their data come: a heading's drift against time (the z-gyro bias), a pitch error against
roll (the mounting's coupling)."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(slots=True)
class LineSums:
    """Sums of the points' weights w and of w x, w x^2, w y, w x y."""

    n: int = 0
    w: float = 0.0
    wx: float = 0.0
    wxx: float = 0.0
    wy: float = 0.0
    wxy: float = 0.0

    def add(self, weight: float, x: float, y: float) -> None:
        """One point."""
        self.n += 1
        self.w += weight
        self.wx += weight * x
        self.wxx += weight * x * x
        self.wy += weight * y
        self.wxy += weight * x * y

    @property
    def det(self) -> float:
        """w sum(w x^2) - sum(w x)^2: zero without a spread of x, else positive."""
        return self.w * self.wxx - self.wx * self.wx

    def line(self) -> tuple[float, float]:
        """Intercept a and slope b; ``det`` must be positive. With weights 1 / sigma^2 of
        independent errors, the slope's variance is w / det."""
        b = (self.w * self.wxy - self.wx * self.wy) / self.det
        return (self.wy - b * self.wx) / self.w, b
