"""The configured engine, built: the one place both engine classes are imported together."""

from __future__ import annotations

from gateway.config.gateway_config import GatewayConfig
from gateway.estimation.ekf.ekf_config import EkfConfig
from gateway.estimation.ekf.ekf_engine import EkfEngine
from gateway.estimation.observer.observer_engine import ObserverEngine
from gateway.estimation.solution import Estimator


def make_engine(config: GatewayConfig) -> Estimator:
    """The estimator ``config`` selects, tuned by it."""
    settings = config.engine_settings()
    if isinstance(settings, EkfConfig):
        return EkfEngine(settings)
    return ObserverEngine(settings)
