"""Driver settings from a gateway config: the one place the config's keys reach the drivers."""

from __future__ import annotations

from drivers.imu_can import ImuCanConfig, ImuCanIds
from gateway.config.gateway_config import GatewayConfig
from gateway.estimation.attitude import dcm_from_rpy_deg


def imu_config(config: GatewayConfig) -> ImuCanConfig:
    """The IMU driver settings of a gateway config (bridge address, mounting, stuck axes)."""
    c_b_imu = dcm_from_rpy_deg(config.vehicle.imu_mounting_rpy_deg)
    return ImuCanConfig(
        ids=ImuCanIds.for_source_address(config.imu.bridge_source_address),
        c_b_imu=tuple(tuple(float(x) for x in row) for row in c_b_imu),
        stuck_samples=config.imu.stuck_samples,
    )
