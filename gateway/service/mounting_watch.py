"""The IMU mounting estimate of ``navgw calibrate``, running on the live inputs (issue 17).

The service feeds :class:`MountingWatch` every IMU sample and GNSS fix the fusion core gets,
in the same order, and reads a one-line summary for its status (sd_notify STATUS) and its
log. The samples are turned by the mounting in effect: the configured one, or the one a
start applied from the learned state (:func:`gateway.state.keeper.effective_start`); the
estimate is the residual to it, reported composed with it, with the line to paste once
every axis is determined. Then it is also :attr:`MountingWatch.learned`, which the service
hands to the learned state, against the configured mounting; it never changes the mounting
of a running service. One pass only: when the mounting in effect is far from the body's
axes the first estimate is coarse (``needs_rerun``, with its sigmas saying so), and ``navgw
calibrate`` on a recording of the drive runs the further passes.

About 13 us of CPU per IMU sample (an observer of its own, the turn-axis and forward-axis
sums) and 1.5 ms per summary, every ``interval_s``. It is a diagnostic: an exception inside
switches it off with one error in the log, and the service goes on.
"""

from __future__ import annotations

import logging

from drivers.samples import GnssFix, ImuSample
from gateway.calibration.mounting import (
    CalibrationConfig,
    MountingEstimator,
    MountingResult,
    total_mounting_rpy_deg,
)
from gateway.config.gateway_config import Engine, GatewayConfig
from gateway.estimation.observer.observer_config import ObserverConfig
from gateway.state.store import Mounting, angles_text, mounting_text

log = logging.getLogger(__name__)


class MountingWatch:
    """The live mounting estimate: fed the core's inputs, summarised every ``interval_s``."""

    def __init__(
        self, config: GatewayConfig, interval_s: float, applied: Mounting | None = None
    ) -> None:
        """``config``: the one in effect; ``applied``: the stored mounting it has in effect
        (None: the configured one)."""
        observer = config.with_engine(Engine.OBSERVER).engine_settings()
        assert isinstance(observer, ObserverConfig)
        self._in_effect = config.vehicle.imu_mounting_rpy_deg
        self._base = applied.base_rpy_deg if applied is not None else self._in_effect
        self._applied = "" if applied is None else f" ({applied_text(applied)})"
        self._estimator: MountingEstimator | None = MountingEstimator(
            CalibrationConfig(observer=observer)
        )
        self.interval_s = interval_s
        self._next_s: float | None = None  # service time of the next summary
        self.summary = "mounting estimate: waiting for a drive" + self._applied
        self.learned: Mounting | None = None  # the last summary's, once every axis determined

    def feed(self, item: object) -> None:
        """One input, as the core gets it; anything but IMU samples and fixes is ignored."""
        est = self._estimator
        if est is None:
            return
        try:
            if isinstance(item, ImuSample):
                est.imu(item)
            elif isinstance(item, GnssFix):
                est.gnss(item)
        except Exception:
            self._fail()

    def update(self, now_s: float) -> str | None:
        """The summary at the first call, then once every ``interval_s`` (service time);
        None in between."""
        est = self._estimator
        if est is None:
            return None
        if self._next_s is not None and now_s < self._next_s:
            return None
        self._next_s = now_s + self.interval_s
        try:
            r = est.result()
            estimate = self._composed(r)
            self.summary = self._text(r, estimate) + self._applied
        except Exception:
            self._fail()
            return None
        if estimate is not None and r.determined:
            self.learned = estimate
        return self.summary

    def _composed(self, r: MountingResult) -> Mounting | None:
        """The whole mounting: the one in effect composed with the estimate, its 1-sigma,
        against the configured mounting; None before there is an estimate."""
        if r.rpy_deg is None:
            return None
        total = total_mounting_rpy_deg(self._in_effect, r.rpy_deg)
        return Mounting(total, r.sigma_deg, self._base)

    def _text(self, r: MountingResult, estimate: Mounting | None) -> str:
        """Per axis the whole mounting and its 1-sigma, the config line once all are
        determined, else what the drive still lacks."""
        if estimate is None:
            missing = "; ".join(r.manoeuvres) or "more driving"
            return f"mounting estimate: none yet ({missing})"
        axes = mounting_text(estimate)
        if r.needs_rerun:
            return f"mounting estimate (coarse: run navgw calibrate on a recording): {axes}"
        if not r.determined:
            return f"mounting estimate: {axes}; still missing: {'; '.join(r.manoeuvres)}"
        line = angles_text(estimate.rpy_deg)
        return f"mounting estimate: {axes}; [vehicle] imu_mounting_rpy_deg = {line}"

    def _fail(self) -> None:
        log.exception("IMU mounting estimate failed; switched off (the gateway runs on)")
        self._estimator = None
        self.summary = "mounting estimate: off after an internal error" + self._applied


def applied_text(applied: Mounting) -> str:
    """What the status line says of a mounting applied at start."""
    return f"mounting {angles_text(applied.rpy_deg)} deg applied from state"
