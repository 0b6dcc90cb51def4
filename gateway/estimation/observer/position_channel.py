"""Reference-point horizontal position channel of the observer engine: each fix's position and
velocity weighed by its quality.

The product's own extension of seed 000 (the paper uses no positions; docs/ACCURACY.md,
"Position channel"). The engine dead-reckons the reference point on its inertial velocity
(in an outage under the wheeled-vehicle constraints) and this channel decides how much of
each fix's horizontal position and velocity residuals to take. Per axis (north, east) a
three-state Kalman filter in plain floats:

- ``p``: the engine's position error; it integrates the velocity error between fixes;
- ``v``: the engine's velocity error: it walks with the platform's acceleration error
  between fixes, and each fix's velocity measures it with the receiver's noise. Set to each
  fix's velocity instead, a 1 Hz receiver's 5 cm/s draw was in the position for a whole
  second (3 sigma: 15 cm); weighed, the positions' change tells it too;
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
    """One axis: covariance of (position error, velocity error, fix error) and the fix-error
    estimate; m, m/s. The position and velocity errors are fed back each epoch (their
    estimates are zero after it), the fix error is the receiver's and stays."""

    p_pp: float = 0.0
    p_pv: float = 0.0
    p_pb: float = 0.0
    p_vv: float = 0.0
    p_vb: float = 0.0
    p_bb: float = 0.0
    b_m: float = 0.0

    def predict(
        self, interval_s: float, q_acc: float, var_v_m2ps2: float, decay: float, var_b_m2: float
    ) -> None:
        """Dead reckoning over ``interval_s``: the position error integrates the velocity
        error, which walks with a white acceleration error of density ``q_acc`` (m^2/s^3)
        and steps by ``var_v_m2ps2``; the fix error decays towards its prior variance."""
        t = interval_s
        self.p_pp += t * (2.0 * self.p_pv + t * self.p_vv) + q_acc * t**3 / 3.0
        self.p_pv += t * self.p_vv + q_acc * t * t / 2.0
        self.p_pb = decay * (self.p_pb + t * self.p_vb)
        self.p_vv += q_acc * t + var_v_m2ps2
        self.p_vb *= decay
        self.p_bb = decay * decay * self.p_bb + (1.0 - decay * decay) * var_b_m2
        self.b_m *= decay

    def new_solution(self, var_b_m2: float) -> None:
        """A new receiver solution: its error is independent of everything so far."""
        self.p_bb, self.p_pb, self.p_vb, self.b_m = var_b_m2, 0.0, 0.0, 0.0

    def update(self, r: float, position: bool, var_m2: float) -> tuple[float, float]:
        """Fuse one measurement whose innovation is ``r``: of the position (with the fix's
        error) or of the velocity; returns the corrections (position, velocity)."""
        if position:
            a, c, e = self.p_pp + self.p_pb, self.p_pv + self.p_vb, self.p_pb + self.p_bb
            s = a + e + var_m2
        else:
            a, c, e = self.p_pv, self.p_vv, self.p_vb
            s = c + var_m2
        self.p_pp -= a * a / s
        self.p_pv -= a * c / s
        self.p_pb -= a * e / s
        self.p_vv -= c * c / s
        self.p_vb -= c * e / s
        self.p_bb -= e * e / s
        self.b_m += e / s * r
        return a / s * r, c / s * r

    def fuse(
        self, dz_m: float | None, dzv_mps: float | None, var_w_m2: float, var_v_m2ps2: float
    ) -> tuple[float, float]:
        """Fuse a position residual ``dz_m`` = fix - position and a velocity residual
        ``dzv_mps`` = fix - velocity (either None: not measured); returns the corrections
        (position, velocity)."""
        dp = dv = 0.0
        if dz_m is not None:
            dp, dv = self.update(dz_m - self.b_m, True, var_w_m2)
        if dzv_mps is not None:
            cp, cv = self.update(dzv_mps - dv, False, var_v_m2ps2)
            dp, dv = dp + cp, dv + cv
        return dp, dv

    def innovation_var_m2(self, var_w_m2: float) -> float:
        """Variance of the next residual: position, fix error and white part."""
        return self.p_pp + 2.0 * self.p_pb + self.p_bb + var_w_m2


class PositionChannel:
    """Kalman weights for the fixes' horizontal positions and velocities, north/east (module
    text)."""

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

    def predict(self, interval_s: float, q_acc: float, var_v_m2ps2: float) -> None:
        """Over ``interval_s`` of dead reckoning whose velocity error walks with a white
        acceleration error of density ``q_acc`` (m^2/s^3, per horizontal axis) and steps by
        ``var_v_m2ps2`` (what each epoch's lever arms put in)."""
        if interval_s <= 0.0:
            return
        decay = math.exp(-interval_s / self._correlation_s)
        grown = self._axes[0].p_pp
        for i in range(2):
            self._axes[i].predict(interval_s, q_acc, var_v_m2ps2, decay, self._var_b[i])
        self._var_height += self._axes[0].p_pp - grown
        self._interval_s = interval_s

    def update(
        self,
        dz_ne_m: list[float] | None,
        dzv_ne_mps: tuple[float, float] | None,
        var_v_m2ps2: float,
    ) -> tuple[tuple[float, float], tuple[float, float]]:
        """Fuse the residuals fix - engine of the position (north, east; None: not taken)
        and of the velocity (None: none measured, variance ``var_v_m2ps2``); returns the
        corrections of the position and of the velocity, north and east."""
        if dz_ne_m is not None:
            self.height_taken()
        n, e = (
            self._axes[i].fuse(
                None if dz_ne_m is None else dz_ne_m[i],
                None if dzv_ne_mps is None else dzv_ne_mps[i],
                self._var_w[i],
                var_v_m2ps2,
            )
            for i in range(2)
        )
        return (n[0], e[0]), (n[1], e[1])

    def reset(self, var_v_m2ps2: float | None = None) -> None:
        """The position was set to the fix: its error is the fix's (white + wander); and the
        velocity to the fix's, of variance ``var_v_m2ps2`` (None: the velocity kept)."""
        for i in range(2):
            a = self._axes[i]
            a.p_pp = self._var_b[i] + self._var_w[i]
            a.p_pb = -self._var_b[i]
            a.p_bb = self._var_b[i]
            a.p_pv = 0.0
            if var_v_m2ps2 is not None:
                a.p_vv, a.p_vb = var_v_m2ps2, 0.0
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

    def sigma_h_after_m(self, interval_s: float, q_acc: float) -> float:
        """Horizontal 1-sigma (root sum of north and east) of the position error
        ``interval_s`` after the last epoch, its velocity error walking with ``q_acc``
        (m^2/s^3) meanwhile, m: what :meth:`predict` would make of it."""
        t = interval_s
        var = sum(a.p_pp + t * (2.0 * a.p_pv + t * a.p_vv) + q_acc * t**3 / 3.0 for a in self._axes)
        return math.sqrt(var)

    def sigma_v_ne_mps(self) -> tuple[float, float]:
        """Velocity 1-sigma north, east of the engine's reference point."""
        ax = self._axes
        return (math.sqrt(ax[0].p_vv), math.sqrt(ax[1].p_vv))
