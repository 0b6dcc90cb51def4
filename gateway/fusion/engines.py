"""The configured engine, built: the one place both engine classes are imported together."""

from __future__ import annotations

from gateway.config.gateway_config import GatewayConfig
from gateway.estimation.ekf.ekf_config import EkfConfig
from gateway.estimation.ekf.ekf_engine import EkfEngine
from gateway.estimation.epoch_clock import EpochClock
from gateway.estimation.imu_noise import ImuNoiseMeter
from gateway.estimation.observer.observer_engine import ObserverEngine
from gateway.estimation.solution import LearningEstimator


def make_engine(
    config: GatewayConfig, clock: EpochClock | None = None, noise: ImuNoiseMeter | None = None
) -> LearningEstimator:
    """The estimator ``config`` selects, tuned by it; ``clock`` and ``noise`` shared if given
    (the fusion core keeps them across engine restarts: a restart on a loaded host must not
    forget that the host clock follows UTC and take late epochs for a clock offset, nor one
    on the move the IMU's noise measured at rest)."""
    settings = config.engine_settings()
    if isinstance(settings, EkfConfig):
        return EkfEngine(settings, clock, noise)
    return ObserverEngine(settings, clock, noise)


def epoch_clock(config: GatewayConfig) -> EpochClock:
    """The epoch clock of ``config``'s GNSS timing."""
    return EpochClock.of(config.gnss)
