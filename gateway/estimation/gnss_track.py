"""Is the receiver's own track continuous? Tells a GNSS glitch from an engine that is off.

When an engine's position disagrees with the GNSS for several epochs, one of them is wrong.
A position glitch (multipath, a wrong fix) makes the receiver's track jump: its position
leaves where its own velocity was taking it. An engine that is off (after an outage, or
starved of epochs on a busy host) disagrees with a track that is continuous. The engines
reject positions beyond their gate for a long time (``position_reset_s``) only after a jump,
and reset to a continuous track after a few epochs (``reset_rejections``).

A solution can also leave its own velocity slowly, by less than a jump in any step (a
wrong fix as the geometry turns): the engine follows it, since each innovation is small.
Over ``DRIFT_WINDOW_S`` the misses add up; beyond their noise the track is ``drifting``, and
the engines reject its positions as they reject a glitch.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field

from gateway.estimation.gnss_error import POSITION_NOISE_MAX_STEP_S, PositionNoise

#: Epochs further apart than this are not compared (an outage: no continuity to judge).
MAX_STEP_S = 2.0
#: A wheeled vehicle's vertical acceleration on the ground (a crest at 4 m/s, 20 m radius).
MAX_VERTICAL_ACCEL_MPS2 = 1.0
#: The receiver's positions are compared with its own velocity over this long of driving: a
#: drift of the solution (multipath, a wrong fix as the geometry changes) that no one step
#: shows. Slow steps, jumps and gaps are not counted, and do not end the window.
DRIFT_WINDOW_S = 10.0
#: Steps older than this are dropped however little was driven since: a headland at walking
#: pace is over in 30 s, and a drift seen before a long stop says little about after it.
DRIFT_MAX_AGE_S = 30.0
#: A drift seen holds until its misses fall below this fraction of the bound: a drift near
#: the bound (2 cm/s) crosses it back and forth with the noise, and each time the engines
#: took the drifting fix again (field seed 3: 654 frames up to 49 cm off, NAVIGATING).
DRIFT_CLEAR_FRACTION = 0.5
#: Below this speed receivers hold or filter the course: no drift test there.
DRIFT_MIN_SPEED_MPS = 0.5


@dataclass
class GnssTrack:
    """The last antenna position and velocity the receiver gave (local NE, m, m/s)."""

    jump_sigma: float = 5.0  # a jump is beyond this many sigma of two independent positions
    #: plus this: epoch timing (20 ms at 4 m/s: 8 cm) and the receiver's smoothing. A fixed
    #: RTK track moves by millimetres more than its velocity says; a wrong ambiguity or
    #: multipath under a tree line moves it by decimetres (with 0.5 m, 0.3 m was no jump)
    jump_floor_m: float = 0.1
    jumped_at_s: float | None = None  # epoch time of the last jump
    rejecting_since_s: float | None = None  # epoch time the engine began to reject positions
    rejections: int = 0  # consecutive positions the engine rejected
    spell_jump_s: float | None = None  # the jump the run of rejections began with, if one
    taken_until_s: float | None = None  # a jumped track was taken: in doubt until then
    drifting: bool = False  # the last epoch's positions left the receiver's own velocity
    drift_m: float = 0.0  # by this much over the drift window
    _last: tuple[float, float, float, float, float, float] | None = None  # t, n, e, vn, ve, sigma
    _heights: tuple[tuple[float, float], ...] = ()  # (t, down m) of the last two epochs
    #: (t, dt, north, east, turn bound, noise variance) of each step's miss of its velocity
    _steps: deque[tuple[float, float, float, float, float, float]] = field(default_factory=deque)
    _window_s: float = 0.0  # the steps' dt summed at the last test: time driven in the window
    _quality: int | None = None  # the solution the window's steps belong to
    #: the white noise of its positions, from the short steps' misses
    noise: PositionNoise = field(default_factory=PositionNoise)

    def add(
        self, t_s: float, p_ne_m: tuple[float, float], v_ne_mps: tuple[float, float] | None,
        sigma_h_m: float, down_m: float | None = None, sigma_d_m: float = 0.0,
        quality: int | None = None,
    ) -> None:  # fmt: skip
        """Compare one epoch with where the last one's velocity (and its own) led, and the
        positions of the last ``DRIFT_WINDOW_S`` with that velocity's integral (the steps
        of one solution, ``quality``); and its height (``down_m``, 1-sigma ``sigma_d_m``)
        with the last two heights' trend."""
        self._add_height(t_s, down_m, sigma_d_m)
        vn, ve = v_ne_mps if v_ne_mps is not None else (math.nan, math.nan)
        last = self._last
        new_solution = quality != self._quality
        if new_solution:
            self._steps.clear()  # a new solution: its error is not the last one's
            self._quality = quality
        if last is not None and t_s < last[0]:
            # the receiver's UTC went back (a clock glitch): its epochs are not a track we
            # can follow; taken as continuous, the engines reset to positions 1 s old
            self.jumped_at_s = t_s
        elif (
            last is not None
            and 0.0 < t_s - last[0] <= MAX_STEP_S
            and math.isfinite(vn + ve + last[3] + last[4])
        ):
            dt = t_s - last[0]
            miss_n = p_ne_m[0] - (last[1] + 0.5 * (last[3] + vn) * dt)
            miss_e = p_ne_m[1] - (last[2] + 0.5 * (last[4] + ve) * dt)
            # the trapezoid's error in a turn is u dt (w dt)^2 / 12 (3 cm at 1 Hz, 3 m/s,
            # 0.33 rad/s); a quarter of the velocity change over the step bounds it
            dv_mps = math.hypot(vn - last[3], ve - last[4])
            speed_mps, speed_last_mps = math.hypot(vn, ve), math.hypot(last[3], last[4])
            curve_m = 0.25 * dv_mps * dt
            # the two positions' errors: a new solution's differs from the last one's (RTK
            # fixed after float: decimetres, no jump), one solution's barely
            sigma_step_m = math.hypot(sigma_h_m, last[5])
            bound_m = self.jump_sigma * sigma_step_m + self.jump_floor_m
            # Steps not added (a jump, a new solution, a slow step) leave the window as it
            # is: each step's miss is its own evidence, so a drift seen before a headland or
            # a glitch is still a drift after it (cleared, it took 8.5 s to see it again,
            # while both engines followed a fixed solution 49 cm off, NAVIGATING)
            jumped = math.hypot(miss_n, miss_e) > bound_m + curve_m
            if jumped:
                self.jumped_at_s = t_s
            one_solution = not jumped and not new_solution
            if one_solution and dt <= POSITION_NOISE_MAX_STEP_S:
                half = (0.5 * miss_n * miss_n, 0.5 * miss_e * miss_e)  # a miss: two white errors
                self.noise.add(quality, half, dt, 0.5 * max(sigma_h_m, last[5]) ** 2)
            if one_solution and min(speed_mps, speed_last_mps) >= DRIFT_MIN_SPEED_MPS:
                # the trapezoid's miss in the turn itself (twice), and the step's noise as
                # 1-sigma: a mast swaying near 1 Hz (omega 2 pi) moves the velocity by dv in
                # a step, and the trapezoid misses by dv dt (omega dt) / 12, at most a quarter
                # of dv dt (two samples 1 s apart miss their mean by decimetres either way)
                noise_m = dv_mps * dt * min(0.25, 0.5 * dt)
                turn_rad = math.atan2(last[3] * ve - last[4] * vn, last[3] * vn + last[4] * ve)
                turn_m = 0.5 * (speed_mps + speed_last_mps) * dt * turn_rad**2 / 6.0
                self._steps.append((t_s, dt, miss_n, miss_e, turn_m, noise_m * noise_m))
        self._last = (t_s, p_ne_m[0], p_ne_m[1], vn, ve, sigma_h_m)
        self._test_drift(t_s, sigma_h_m)

    def _test_drift(self, t_s: float, sigma_h_m: float) -> None:
        """Positions that leave the receiver's own (Doppler) velocity slowly, by less than a
        jump in any step: their misses add up over the window, where a working solution's
        (its wander over 10 s, its velocity's noise integrated) stay within centimetres. A
        fixed solution drifting 2 cm/s was followed 0.6 m, NAVIGATING, by both engines."""
        steps = self._steps
        window_s = sum(s[1] for s in steps)
        while steps and (window_s > DRIFT_WINDOW_S + 1e-6 or steps[0][0] <= t_s - DRIFT_MAX_AGE_S):
            window_s -= steps.popleft()[1]
        self._window_s = window_s if steps else 0.0
        drift_n = sum(s[2] for s in steps)
        drift_e = sum(s[3] for s in steps)
        turn_m = sum(s[4] for s in steps)
        sigma_m = math.sqrt(sigma_h_m * sigma_h_m + sum(s[5] for s in steps))
        self.drift_m = math.hypot(drift_n, drift_e)
        bound_m = self.jump_sigma * sigma_m + self.jump_floor_m + turn_m
        self.drifting = self.drift_m > bound_m * (DRIFT_CLEAR_FRACTION if self.drifting else 1.0)
        if self.drifting:
            self.jumped_at_s = t_s

    def drift_text(self, t_s: float) -> str:
        """The warning for positions rejected because the track drifts."""
        return (
            f"GNSS positions at t={t_s:.3f} left the receiver's own velocity by "
            f"{self.drift_m:.2f} m over the last {self._window_s:.1f} s driven (a drifting "
            "solution); positions not used"
        )

    def away_text(self, t_s: float) -> str:
        """The warning for a position rejected because the track has not jumped back."""
        return (
            f"GNSS position at t={t_s:.3f} is on a track that jumped at t="
            f"{self.spell_jump_s or 0.0:.3f} and has not jumped back; position not used"
        )

    def _add_height(self, t_s: float, down_m: float | None, sigma_d_m: float) -> None:
        """NMEA has no vertical velocity: the height is extrapolated from the last two. The
        second difference of three heights has sqrt(6) sigma of one; the vehicle's vertical
        acceleration (1 m/s^2 over a crest) adds a dt (dt + dt_prev) / 2: 1 cm at 10 Hz."""
        if down_m is None:
            self._heights = ()
            return
        h = self._heights
        if len(h) == 2:
            dt, dt_prev = t_s - h[1][0], h[1][0] - h[0][0]
            if 0.0 < dt <= MAX_STEP_S and 0.0 < dt_prev <= MAX_STEP_S:
                pred = h[1][1] + (h[1][1] - h[0][1]) * dt / dt_prev
                bound = self.jump_sigma * math.sqrt(6.0) * sigma_d_m + self.jump_floor_m
                if abs(down_m - pred) > bound + MAX_VERTICAL_ACCEL_MPS2 * dt * (dt + dt_prev) / 2:
                    self.jumped_at_s = t_s
        self._heights = (h[-1], (t_s, down_m)) if h else ((t_s, down_m),)

    def jumped_since(self, t_s: float) -> bool:
        """Did the track jump at or after ``t_s``?"""
        return self.jumped_at_s is not None and self.jumped_at_s >= t_s

    def rejected(self, t_s: float) -> None:
        """The engine rejected the position of epoch ``t_s``."""
        if self.rejecting_since_s is None:
            self.rejecting_since_s = t_s
            self.spell_jump_s = self.jumped_at_s if self.jumped_since(t_s) else None
        self.rejections += 1

    def accepted(self) -> None:
        """The engine used a position (or reset to one): the run of rejections ends."""
        self.rejecting_since_s, self.rejections, self.spell_jump_s = None, 0, None

    @property
    def away(self) -> bool:
        """Are the engine's rejections those of a track that jumped away and has not jumped
        back? Its positions are then the jumped track's however close the engine's dead
        reckoning (whose gate widens as it goes on) lets them come: 0.3 m off 12 s after
        the jump was inside the observer's gate, and it sent that, NAVIGATING."""
        return self.spell_jump_s is not None and self.jumped_at_s == self.spell_jump_s

    def reset_due(self, t_s: float, reset_rejections: int, position_reset_s: float) -> bool:
        """Should the engine take the GNSS position at ``t_s`` however far it is? After
        ``reset_rejections`` of a continuous track (the engine is off), or after
        ``position_reset_s`` of rejections that began with a jump (it moved for good). Never
        while the track drifts: a reset would take the drifting fix (field seed 3 sent 49 cm
        off, NAVIGATING); it comes once the drift has left the window."""
        since = self.rejecting_since_s
        if since is None or self.drifting:
            return False
        if not self.jumped_since(since):
            return self.rejections >= reset_rejections
        if t_s - since < position_reset_s:
            return False
        self.taken_until_s = t_s + position_reset_s
        return True

    def doubtful(self, t_s: float) -> bool:
        """Are the positions in doubt at ``t_s``: being rejected, or those of a jumped track
        taken less than ``position_reset_s`` ago? A wrong fix held past the rejections is
        taken as a new base station's would be; it may yet jump back (a 90 s wrong fix went
        out 31 cm off, NAVIGATING, for the 30 s after it was taken)."""
        until = self.taken_until_s
        return self.rejecting_since_s is not None or (until is not None and t_s < until)
