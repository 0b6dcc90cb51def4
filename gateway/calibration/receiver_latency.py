"""The receiver's latency on a host clock that does not follow UTC, from one recorded drive.

On such a host the epochs are placed by their receive time less ``[gnss]
receiver_latency_s`` (:mod:`gateway.estimation.epoch_clock`), so its error puts every GNSS
position and velocity that far off in time: the speed times it on the position. The EKF
learns it as a state (EPOCH: the velocity's and the position's columns are the antenna's
acceleration and velocity) wherever the vehicle speeds up, slows down and turns; the
observer has no such state and states the configured 1-sigma instead, which unmeasured
(0.1 s) puts it beyond RTK class above 0.5 m/s (DEGRADED). An EKF fed the drive gives the
latency to configure and its 1-sigma, so that the observer, and the EKF's start, have it
measured. (`field` seed 635, a 120 ms receiver on a host 30 s off UTC, configured at the
default 50 ms: 145.6 ms learnt, 2.8 ms 1-sigma, where the simulator's least delay was 146.)

Fed IMU samples and GNSS fixes in time order, like the engines.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from drivers.samples import GnssFix, ImuSample
from gateway.estimation.ekf.ekf_config import EkfConfig
from gateway.estimation.ekf.ekf_engine import EPOCH_WALK_S2_PER_S, EkfEngine
from gateway.estimation.epoch_clock import DELAY_WINDOW_S

#: The latency counts as measured within this 1-sigma, s: 10 ms at 5 m/s is the 5 cm of the
#: position's 1-sigma that NAVIGATING allows the epoch time
#: (:data:`gateway.estimation.solution.NAVIGATING_POSITION_SHARE_M`).
MAX_LATENCY_SIGMA_S = 0.01
#: 1-sigma of the latency placement from one drive to the next, s: the least receive delay
#: the epochs are placed by walks with the host clock's drift over its window (3 ms over
#: :data:`DELAY_WINDOW_S`, the EKF's model of it).
PLACEMENT_SIGMA_S = math.sqrt(EPOCH_WALK_S2_PER_S * DELAY_WINDOW_S)
#: What a drive needs for the latency: the antenna's velocity and acceleration changing.
LATENCY_DRIVE = (
    "drive at working speed with RTK fixed, speeding up, slowing down and turning (they "
    "show the receiver latency)"
)


@dataclass(frozen=True)
class LatencyResult:
    """What the drive showed of the epochs' timing: whether the host clock followed UTC
    (None: no date in the NMEA), and on one that did not, the latency to configure, s, its
    1-sigma over the drive, and the 1-sigma to configure with it (the drive's and the
    placement's, :data:`PLACEMENT_SIGMA_S`); None before the EKF ran."""

    host_follows_utc: bool | None
    configured_s: float  # the config's latency, s
    latency_s: float | None = None
    sigma_s: float | None = None

    @property
    def needed(self) -> bool:
        """The epochs are placed by receive time (the host clock not found following UTC),
        so the latency matters."""
        return self.host_follows_utc is not True

    @property
    def determined(self) -> bool:
        """Measured within :data:`MAX_LATENCY_SIGMA_S` (or not needed)."""
        return not self.needed or (self.sigma_s is not None and self.sigma_s <= MAX_LATENCY_SIGMA_S)

    @property
    def config_sigma_s(self) -> float | None:
        """``receiver_latency_sigma_s`` to configure with :attr:`latency_s`."""
        if self.sigma_s is None:
            return None
        return math.hypot(self.sigma_s, PLACEMENT_SIGMA_S)


class LatencyEstimator:
    """An EKF on the drive with the config's timing, read for its EPOCH state at the end;
    once its clock finds the host following UTC, only the clock is fed (nothing to learn)."""

    def __init__(self, ekf: EkfConfig) -> None:
        self._ekf = EkfEngine(ekf)
        self._configured_s = ekf.receiver_latency_s  # what the EPOCH state is learnt against

    def imu(self, sample: ImuSample) -> None:
        if not self._ekf.clock.host_follows_utc:
            self._ekf.imu(sample)

    def gnss(self, fix: GnssFix) -> None:
        if self._ekf.clock.host_follows_utc:
            self._ekf.clock.epoch_time(fix)
        else:
            self._ekf.gnss(fix)

    def result(self) -> LatencyResult:
        """The epochs' timing as learnt so far."""
        follows = self._ekf.clock.host_follows_utc
        learnt = self._ekf.epoch_time_error()
        if follows is True or learnt is None:
            return LatencyResult(follows, self._configured_s)
        error_s, sigma_s = learnt
        return LatencyResult(follows, self._configured_s, self._configured_s + error_s, sigma_s)
