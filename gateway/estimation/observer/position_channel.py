"""Reference-point horizontal position channel of the observer engine: each fix weighed by its
quality.

The product's own extension of seed 000 (the paper uses no positions; docs/ACCURACY.md,
"Position channel"). The engine dead-reckons the reference point on the GNSS-reset velocity
(or, in an outage, on the inertial velocity under the wheeled-vehicle constraints) and this
channel decides how much of each fix's horizontal position residual to take. Per axis (north,
east) a two-state Kalman filter in plain floats:

- ``p``: the engine's position; its error grows between fixes with the dead-reckoning noise;
- ``b``: the error of the receiver's current solution, first-order Gauss-Markov
  (``correlation_s``) plus a small white part (:mod:`gateway.estimation.gnss_error`, the
  model the EKF's fix-error states use too). Averaging a minute of float fixes then does
  not pretend to remove their error, and when RTK fixed returns the carried variance is
  still large: the first fixed epochs get a gain near 1.

A new fix quality is a new receiver solution with an independent error: ``b`` restarts.

Not the height: GNSS gives no vertical velocity, so the height is a double integrator that
only its loop holds. Weighed like this during a float spell (0.4 m vertical sigma, small
gains) it drifted 60 m; the engine keeps its fixed critically damped height loop (whose mean
correction on RTK fixed heights is the z accelerometer bias it learns). The channel only
keeps the height's variance for the engine's glitch gate: it grows with dead reckoning as
the horizontal does, and the loop pulls it to the fixes' over its transient
(:data:`HEIGHT_SETTLE_S`): after a float spell or an outage the first RTK heights are
metres or decimetres off, and the next few still are while the loop settles.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from drivers.samples import FixQuality
from gateway.estimation.gnss_error import split_fix_variance

#: Time constant of the height error's variance once fixes are taken again: the height
#: loop's (critically damped, 0.3 s) transient after a step, with its velocity kick. Taken
#: as collapsing to the fix's at once, the second RTK epoch after a 20 s outage was 0.52 m
#: off against a 0.28 m gate, and 2 s of fixes were rejected (gnss-outage seed 2).
HEIGHT_SETTLE_S = 0.5


@dataclass(slots=True)
class _Axis:
    """One axis: covariance of (position error, fix error) and the fix-error estimate, m."""

    p_pp: float = 0.0
    p_pb: float = 0.0
    p_bb: float = 0.0
    b_m: float = 0.0

    def predict(self, q_m2: float, decay: float, var_b_m2: float) -> None:
        """Dead reckoning adds ``q_m2``; the fix error decays towards its prior variance."""
        self.p_pp += q_m2
        self.p_pb *= decay
        self.p_bb = decay * decay * self.p_bb + (1.0 - decay * decay) * var_b_m2
        self.b_m *= decay

    def new_solution(self, var_b_m2: float) -> None:
        """A new receiver solution: its error is independent of everything so far."""
        self.p_bb, self.p_pb, self.b_m = var_b_m2, 0.0, 0.0

    def update(self, dz_m: float, var_w_m2: float) -> float:
        """Fuse a residual ``dz_m`` = fix - position; returns the position correction."""
        r = dz_m - self.b_m
        a = self.p_pp + self.p_pb
        c = self.p_pb + self.p_bb
        s = a + c + var_w_m2
        k_p, k_b = a / s, c / s
        self.p_pp -= k_p * a
        self.p_pb -= k_p * c
        self.p_bb -= k_b * c
        self.b_m += k_b * r
        return k_p * r

    def innovation_var_m2(self, var_w_m2: float) -> float:
        """Variance of the next residual: position, fix error and white part."""
        return self.p_pp + 2.0 * self.p_pb + self.p_bb + var_w_m2


class PositionChannel:
    """Kalman weights for the fixes' horizontal positions, north/east (module text)."""

    def __init__(self, correlation_s: float, white_share: float) -> None:
        """``correlation_s``: correlation time of a fix error; ``white_share``: the share of
        a fix's sigma that is white from epoch to epoch (the rest wanders)."""
        self._correlation_s = correlation_s
        self._white_share = white_share
        self._axes = (_Axis(), _Axis())
        self._quality: FixQuality | None = None
        self._var_b = [0.0, 0.0]
        self._var_w = [0.0, 0.0]
        self._var_d = 0.0  # the fix's height variance
        self._var_height = 0.0  # the engine's height error variance
        self._interval_s = 0.0  # of the last prediction

    def set_fix(
        self, quality: FixQuality, sigma_ned_m: tuple[float, float, float], seen_share: float
    ) -> None:
        """The sigma of the fix about to be used (north, east weighed, down for the gate) and
        the white share its receiver's track shows (:func:`split_fix_variance`); a new
        quality restarts the fix error."""
        for i in range(2):
            self._var_w[i], self._var_b[i] = split_fix_variance(
                sigma_ned_m[i], self._white_share, seen_share
            )
        self._var_d = sigma_ned_m[2] * sigma_ned_m[2]
        if quality != self._quality:
            self._quality = quality
            for i in range(2):
                self._axes[i].new_solution(self._var_b[i])

    def predict(self, interval_s: float, sigma_h_m: float) -> None:
        """Over ``interval_s`` of dead reckoning whose position error grew by ``sigma_h_m``
        (1-sigma, per horizontal axis)."""
        if interval_s <= 0.0:
            return
        decay = math.exp(-interval_s / self._correlation_s)
        q = sigma_h_m * sigma_h_m
        for i in range(2):
            self._axes[i].predict(q, decay, self._var_b[i])
        self._var_height += q
        self._interval_s = interval_s

    def update(self, dz_ne_m: list[float]) -> tuple[float, float]:
        """Fuse the residuals fix - position (north, east); returns the position corrections."""
        ax = self._axes
        self.height_taken()
        return (
            ax[0].update(dz_ne_m[0], self._var_w[0]),
            ax[1].update(dz_ne_m[1], self._var_w[1]),
        )

    def reset(self) -> None:
        """The position was set to the fix: its error is the fix's (white + wander)."""
        for i in range(2):
            a = self._axes[i]
            a.p_pp = self._var_b[i] + self._var_w[i]
            a.p_pb = -self._var_b[i]
            a.p_bb = self._var_b[i]
            a.b_m = 0.0
        self.height_taken()

    @property
    def interval_s(self) -> float:
        """The last prediction's interval: the receiver's epoch interval, s."""
        return self._interval_s

    def height_taken(self) -> None:
        """The height loop took the fix: its error settles towards the fix's."""
        settle = math.exp(-self._interval_s / HEIGHT_SETTLE_S)
        self._var_height = self._var_d + max(0.0, self._var_height - self._var_d) * settle

    def horizontal_innovation_m(self, dz_ne_m: list[float]) -> float:
        """Horizontal length of the innovation of the residuals fix - position (north, east):
        the residual less the fix error the channel carries (a DGNSS spell's metre, once
        learnt, is no surprise), what :meth:`horizontal_innovation_sigma_m` describes."""
        ax = self._axes
        return math.hypot(dz_ne_m[0] - ax[0].b_m, dz_ne_m[1] - ax[1].b_m)

    def horizontal_innovation_sigma_m(self) -> float:
        """1-sigma of the next horizontal residual (root sum of north and east)."""
        ax = self._axes
        return math.sqrt(
            ax[0].innovation_var_m2(self._var_w[0]) + ax[1].innovation_var_m2(self._var_w[1])
        )

    def vertical_innovation_sigma_m(self) -> float:
        """1-sigma of the next height residual: the height's error and the fix's."""
        return math.sqrt(self._var_height + self._var_d)

    def sigma_ne_m(self) -> tuple[float, float]:
        """Position 1-sigma north, east of the engine's reference point."""
        ax = self._axes
        return (math.sqrt(ax[0].p_pp), math.sqrt(ax[1].p_pp))
