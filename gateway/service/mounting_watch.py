"""The IMU mounting estimate of ``navgw calibrate``, running on the live inputs (issue 17).

The service feeds :class:`MountingWatch` every IMU sample and GNSS fix the fusion core gets,
in the same order, and reads a one-line summary for its status (sd_notify STATUS) and its
log. The estimate is reported, never applied: the samples keep the configured mounting
(``[vehicle] imu_mounting_rpy_deg``), and the line says what to paste once every axis is
determined. One pass only: when the configured mounting is far from the body's axes the
first estimate is coarse (``needs_rerun``, with its sigmas saying so), and ``navgw
calibrate`` on a recording of the drive runs the further passes.

About 13 us of CPU per IMU sample (an observer of its own, the turn-axis and forward-axis
sums) and 1.5 ms per summary, every ``interval_s``. It is a diagnostic: an exception inside
switches it off with one error in the log, and the service goes on.
"""

from __future__ import annotations

import logging

from drivers.samples import GnssFix, ImuSample
from gateway.calibration.mounting import (
    AXES,
    CalibrationConfig,
    MountingEstimator,
    MountingResult,
    total_mounting_rpy_deg,
)
from gateway.config.gateway_config import Engine, GatewayConfig
from gateway.estimation.observer.observer_config import ObserverConfig

log = logging.getLogger(__name__)


class MountingWatch:
    """The live mounting estimate: fed the core's inputs, summarised every ``interval_s``."""

    def __init__(self, config: GatewayConfig, interval_s: float) -> None:
        observer = config.with_engine(Engine.OBSERVER).engine_settings()
        assert isinstance(observer, ObserverConfig)
        self._configured = config.vehicle.imu_mounting_rpy_deg
        self._estimator: MountingEstimator | None = MountingEstimator(
            CalibrationConfig(observer=observer)
        )
        self.interval_s = interval_s
        self._next_s: float | None = None  # service time of the next summary
        self.summary = "mounting estimate: waiting for a drive"

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
            self.summary = self._text(est.result())
        except Exception:
            self._fail()
            return None
        return self.summary

    def _text(self, r: MountingResult) -> str:
        """Per axis the mounting (configured composed with the estimate) and its 1-sigma, the
        config line once all are determined, else what the drive still lacks."""
        if r.rpy_deg is None:
            missing = "; ".join(r.manoeuvres) or "more driving"
            return f"mounting estimate: none yet ({missing})"
        total = total_mounting_rpy_deg(self._configured, r.rpy_deg)
        axes = ", ".join(
            f"{axis} {angle:.2f}+/-{sigma:.2f}"
            for axis, angle, sigma in zip(AXES, total, r.sigma_deg, strict=True)
        )
        if r.needs_rerun:
            return f"mounting estimate (coarse: run navgw calibrate on a recording): {axes} deg"
        if not r.determined:
            return f"mounting estimate: {axes} deg; still missing: {'; '.join(r.manoeuvres)}"
        line = ", ".join(f"{a:.2f}" for a in total)
        return f"mounting estimate: {axes} deg; [vehicle] imu_mounting_rpy_deg = [{line}]"

    def _fail(self) -> None:
        log.exception("IMU mounting estimate failed; switched off (the gateway runs on)")
        self._estimator = None
        self.summary = "mounting estimate: off after an internal error"
