"""Is a dual-antenna heading (HDT) continuous with the gyro's turn? Tells its jumps.

A dual-antenna receiver that fixes its baseline's ambiguity wrongly (at a re-acquisition,
under a tree line) reports a heading off by degrees (a 19 cm cycle on a 1-2 m baseline:
5-10 deg), with its usual small noise. HDT is the heading channel's best reference, so the
observer followed it at once and sent yaw 5 deg off, NAVIGATING. The gyro cannot jump: the
HDT's offset from the gyro's own heading, ``d = psi_hat - psi_hdt + hc`` (``hc`` the heading
corrections applied, so ``psi_hat - hc`` is the gyro's integral), holds still for a working
receiver but for the two epochs' noise and what the gyro adds since (its noise, its z bias's
uncertainty, its scale factor in the turn). An HDT whose ``d`` has left the last accepted
one's by more is not used until it comes back; course over ground or the gyro carry the
heading meanwhile. The reference of ``d`` is kept across HDT dropouts (a wrong fix at a
re-acquisition is caught too) and dropped only when the gyro's integral is broken (an IMU
gap bridged, the heading set directly); epochs up to that moment are not judged (their
platform heading predates the break: at 20 Hz the epoch after the alignment still had the
heading before it, 20 deg off, and every HDT after was rejected).

What the gyro adds grows with time and turning (a headland turn: 1.8 deg of scale factor),
so after a long spell of rejections the HDT still off would pass the continuity test alone.
In a spell, an HDT must also agree with the heading held meanwhile (course over ground, the
gyro) within the heading channel's own sigma: the 5 deg HDT of field seed 1 passed the
continuity test after a headland and the yaw went 3.9 deg off.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from drivers.units import DEG_TO_RAD, SQRT_SECONDS_PER_HOUR, wrap_pi
from gateway.estimation.observer.observer_config import ObserverConfig

#: Beyond the noise: the HDT's timing against the IMU's (20 ms, as the position track's) in
#: a turn, and the receiver's own smoothing of its heading.
HDT_TIMING_S = 0.02
HDT_STEP_FLOOR_RAD = 0.5 * DEG_TO_RAD
#: The gyro's scale-factor error (MEMS, after factory calibration): in a 90 deg headland
#: turn during an HDT dropout the gyro's integral is 0.9 deg off the turn.
GYRO_SCALE_ERROR = 0.01


@dataclass
class HdtScreen:
    """The last accepted HDT's time, its offset ``d`` from the gyro's heading and the gyro's
    heading then (rad); HDTs rejected since the last accepted one."""

    cfg: ObserverConfig
    _ref: tuple[float, float, float] | None = None  # t, d, psi_hat - hc
    _whole_from_s: float = -math.inf  # the gyro's integral is whole after this time
    rejected: int = 0
    offset_rad: float = 0.0  # the last HDT's d less the reference's
    bound_rad: float = 0.0  # and what it was allowed

    def screen(
        self,
        t_s: float,
        psi_hat_rad: float,
        hdt_rad: float,
        hc_rad: float,
        z_bias_sigma_rps: float,
        sigma_psi_rad: float,
    ) -> bool:
        """Use the HDT of epoch ``t_s``? ``psi_hat_rad`` is the platform heading then (1-sigma
        ``sigma_psi_rad``), ``hc_rad`` the heading corrections applied up to then,
        ``z_bias_sigma_rps`` the z-gyro bias's 1-sigma (its error turns the gyro's heading
        by that much per second)."""
        if t_s <= self._whole_from_s:
            return True  # not judged: taken as ever
        cfg = self.cfg
        sigma_hdt = cfg.hdt_sigma_deg * DEG_TO_RAD
        d = wrap_pi(psi_hat_rad - hdt_rad + hc_rad)
        psi_gyro = psi_hat_rad - hc_rad
        ref = self._ref
        if ref is not None:
            t_ref, d_ref, psi_gyro_ref = ref
            dt = max(0.0, t_s - t_ref)
            arw = cfg.gyro_arw_deg_per_sqrt_h * DEG_TO_RAD / SQRT_SECONDS_PER_HOUR
            sigma = math.sqrt(2.0 * sigma_hdt**2 + arw**2 * dt + (z_bias_sigma_rps * dt) ** 2)
            turn = abs(wrap_pi(psi_gyro - psi_gyro_ref))
            bound = (
                cfg.glitch_sigma * sigma
                + HDT_STEP_FLOOR_RAD
                + (HDT_TIMING_S / dt if dt > 0.0 else 0.0) * turn
                + GYRO_SCALE_ERROR * turn
            )
            self.offset_rad, self.bound_rad = wrap_pi(d - d_ref), bound
            if self.rejected and abs(self.offset_rad) <= bound:  # a spell: agree with psi_hat
                self.offset_rad = wrap_pi(psi_hat_rad - hdt_rad)
                self.bound_rad = (
                    cfg.glitch_sigma * math.hypot(sigma_psi_rad, sigma_hdt) + HDT_STEP_FLOOR_RAD
                )
            if abs(self.offset_rad) > self.bound_rad:
                self.rejected += 1
                return False
        self._ref = (t_s, d, psi_gyro)
        self.rejected = 0
        return True

    def text(self, t_s: float) -> str:
        """The warning for an HDT not used."""
        return (
            f"HDT at t={t_s:.3f} is {-self.offset_rad / DEG_TO_RAD:+.2f} deg off the heading the "
            f"last HDT used and the gyro give (allowed {self.bound_rad / DEG_TO_RAD:.2f} deg; "
            f"{self.rejected} in a row): a jump of the dual-antenna solution, heading not used"
        )

    def restart(self, t_s: float) -> None:
        """The gyro's integral was broken at ``t_s`` (an IMU gap bridged, the heading set
        directly): the next HDT of a later epoch is taken as the new reference."""
        self._ref = None
        self._whole_from_s = t_s
