"""Comparison engines for the accuracy benchmark, each behind the Estimator protocol.

- ``level``: no terrain compensation. Reference point = antenna - Rz(yaw) l_ant, i.e. the
  lever arm is removed as if the vehicle were level (what a receiver without an IMU does).
- ``mahony`` / ``madgwick``: gravity-referenced AHRS of the ``ahrs`` package fed the same
  IMU samples (Mahony with gyro-bias integral, k_I > 0; Madgwick without). They have no
  magnetometer and no GNSS acceleration, so roll/pitch is what they are judged on.
- ``observer-no-bias``: the observer with bias estimation switched off (a config flag, see
  :data:`ENGINES` in ``benchmarks/accuracy.py``).
- ``observer-first-order``: the observer with seed 000's first-order tilt loop at the
  paper's tau (the product's second-order loop off: ``gateway.estimation.observer.tilt_loop``).

All three tilt baselines run an
:class:`~gateway.estimation.observer.observer_engine.ObserverEngine` beside
them for what they lack: yaw (GNSS-course-referenced heading channel) and the GNSS-aided
reference-point track. Their solution is the observer's with roll/pitch replaced and the
reference point moved by (C_obs - C_base) l_ant, so the position difference between engines
is exactly the terrain-compensation difference.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np
import numpy.typing as npt

from drivers.samples import Float3, GnssFix, ImuSample
from drivers.units import DEG_TO_RAD
from gateway.estimation.attitude import dcm_from_rpy, roll_pitch_from_specific_force, rpy_from_dcm
from gateway.estimation.geodesy import ned_to_lla
from gateway.estimation.observer.observer_config import ObserverConfig
from gateway.estimation.observer.observer_engine import ObserverEngine
from gateway.estimation.solution import Convergence, Estimator, Solution

Array = npt.NDArray[np.float64]


class _TiltSwapEngine(ABC):
    """Observer navigation with another roll/pitch source (template: :meth:`_tilt`)."""

    def __init__(self, config: ObserverConfig) -> None:
        self._nav = ObserverEngine(config)
        self._l_ant_b = np.array(config.antenna_lever_arm_m, dtype=float)

    def imu(self, sample: ImuSample) -> None:
        """Feed the navigation observer and the tilt source."""
        self._nav.imu(sample)
        self._imu_tilt(sample)

    def gnss(self, fix: GnssFix) -> None:
        """GNSS goes to the navigation observer only (the tilt sources take none)."""
        self._nav.gnss(fix)

    def temperature(self, t_s: float, temp_c: float) -> None:
        """The IMU's temperature goes to the navigation observer (the tilt sources model
        no bias walk)."""
        self._nav.temperature(t_s, temp_c)

    def solution(self) -> Solution:
        """The observer's solution with this engine's roll/pitch and lever-arm projection."""
        sol = self._nav.solution()
        tilt = self._tilt()
        if tilt is None or sol.roll_rad is None or sol.pitch_rad is None:
            return sol
        roll, pitch, bias_g = tilt
        yaw = sol.yaw_rad if sol.yaw_rad is not None else 0.0
        lat, lon, alt = sol.lat_deg, sol.lon_deg, sol.alt_m
        if lat is not None and lon is not None and alt is not None:
            shift = (
                dcm_from_rpy(sol.roll_rad, sol.pitch_rad, yaw) - dcm_from_rpy(roll, pitch, yaw)
            ) @ self._l_ant_b
            lat, lon, alt = (float(x) for x in ned_to_lla(shift, (lat, lon, alt)))
        return replace(
            sol,
            roll_rad=roll,
            pitch_rad=pitch,
            lat_deg=lat,
            lon_deg=lon,
            alt_m=alt,
            bias_g_rps=bias_g,
            bias_a_mps2=None,
            sigma_tilt_rad=None,
            convergence=Convergence(),
        )

    @abstractmethod
    def _imu_tilt(self, sample: ImuSample) -> None:
        """Propagate the tilt source with one sample."""

    @abstractmethod
    def _tilt(self) -> tuple[float, float, Float3 | None] | None:
        """Roll, pitch (rad) and gyro bias estimate (3,) or None; None before alignment."""


class LevelEngine(_TiltSwapEngine):
    """No terrain compensation: roll = pitch = 0 in the lever-arm projection."""

    def _imu_tilt(self, sample: ImuSample) -> None:
        """Nothing to propagate."""

    def _tilt(self) -> tuple[float, float, Float3 | None]:
        return 0.0, 0.0, None


#: Seed 000's tilt time constant (section 4) for its first-order loop, s.
PAPER_TAU_S = 4.0


class AhrsEngine(_TiltSwapEngine):
    """Mahony or Madgwick from the ``ahrs`` package (imported lazily: a dev extra).

    Frames: the filters take an accelerometer that reads +g along the earth z axis at rest, so
    they get -f_b (gravity in body FRD) and their earth frame is NED; q.to_DCM() is C_b^n.
    They start from roll/pitch of the mean specific force over ``align_tilt_time_s``, like
    the observer. Gains (the filters' own parameters, chosen by the same physics as the
    observer's, not tuned on the runs):

    - Mahony: k_P = 1/tau (seed 000's first-order tilt loop, :data:`PAPER_TAU_S`),
      k_I = 1/(tau tau_g) (the bias loop of eq. 11: b' = theta / (tau tau_g)).
    - Madgwick: beta = sqrt(3/4) w_beta (Madgwick 2010, eq. 50) with w_beta the 3-sigma
      turn-on gyro bias of the IMU, 0.3 deg/s.
    """

    def __init__(self, kind: str, config: ObserverConfig) -> None:
        super().__init__(config)
        from ahrs.filters import Madgwick, Mahony

        self.kind = kind
        if kind == "mahony":
            self._filter: Mahony | Madgwick = Mahony(
                k_P=1.0 / PAPER_TAU_S, k_I=1.0 / (PAPER_TAU_S * config.tau_g_s)
            )
        elif kind == "madgwick":
            self._filter = Madgwick(gain=math.sqrt(0.75) * 0.3 * DEG_TO_RAD)
        else:
            raise ValueError(f"AHRS kind {kind!r}: expected 'mahony' or 'madgwick'")
        self._align_time_s = config.align_tilt_time_s
        self._align_f = np.zeros(3)
        self._align_n = 0
        self._align_t0_s: float | None = None
        self._q: Array | None = None

    def _imu_tilt(self, sample: ImuSample) -> None:
        """Align on the mean specific force, then one filter update per sample."""
        if self._q is None:
            if self._align_t0_s is None:
                self._align_t0_s = sample.t
            self._align_f += sample.f_ib_b
            self._align_n += 1
            if sample.t - self._align_t0_s >= self._align_time_s:
                roll, pitch = roll_pitch_from_specific_force(self._align_f / self._align_n)
                self._q = _quaternion_from_dcm(dcm_from_rpy(roll, pitch, 0.0))
            return
        self._q = self._filter.updateIMU(
            self._q, np.array(sample.w_ib_b), -np.array(sample.f_ib_b), dt=sample.dt
        )

    def _tilt(self) -> tuple[float, float, Float3 | None] | None:
        if self._q is None:
            return None
        from ahrs import Quaternion

        roll, pitch, _ = rpy_from_dcm(Quaternion(self._q).to_DCM())
        b = getattr(self._filter, "b", None)
        if b is None:
            return roll, pitch, None
        bx, by, bz = (float(x) for x in b)
        return roll, pitch, (bx, by, bz)


def _quaternion_from_dcm(c: Array) -> Array:
    """Unit quaternion [w, x, y, z] of a rotation matrix (3, 3) (Shepperd, w >= 0 branch)."""
    w = 0.5 * math.sqrt(max(0.0, 1.0 + c[0, 0] + c[1, 1] + c[2, 2]))
    return np.array(
        [
            w,
            (c[2, 1] - c[1, 2]) / (4 * w),
            (c[0, 2] - c[2, 0]) / (4 * w),
            (c[1, 0] - c[0, 1]) / (4 * w),
        ]
    )


# ================================================================ the engines compared


@dataclass(frozen=True)
class RunSetup:
    """What every engine is told about one run: the vehicle geometry (SPEC 5, body FRD, m).
    GNSS epochs are timed as the default config does (:mod:`gateway.estimation.epoch_clock`)."""

    antenna_lever_arm_m: tuple[float, float, float]
    imu_lever_arm_m: tuple[float, float, float]

    def observer_config(self, **overrides: object) -> ObserverConfig:
        """The paper-parameter observer config for this run, with ``overrides``."""
        cfg = ObserverConfig(
            antenna_lever_arm_m=self.antenna_lever_arm_m,
            imu_lever_arm_m=self.imu_lever_arm_m,
        )
        return replace(cfg, **overrides)  # type: ignore[arg-type]


def _ekf(setup: RunSetup, **overrides: float) -> Estimator:
    """The EKF, default config but the run's lever arms and ``overrides`` (e.g.
    ``covariance_period_s`` 0: the covariance propagated at every IMU sample)."""
    from gateway.estimation.ekf.ekf_config import EkfConfig
    from gateway.estimation.ekf.ekf_engine import EkfEngine

    return EkfEngine(
        EkfConfig(
            antenna_lever_arm_m=setup.antenna_lever_arm_m,
            imu_lever_arm_m=setup.imu_lever_arm_m,
            **overrides,  # type: ignore[arg-type]
        )
    )


#: Engine name -> factory. A new engine gains its columns in the benchmark by one line here.
ENGINES: dict[str, Callable[[RunSetup], Estimator]] = {
    "observer": lambda s: ObserverEngine(s.observer_config()),
    "observer-no-bias": lambda s: ObserverEngine(s.observer_config(estimate_biases=False)),
    "observer-eq12": lambda s: ObserverEngine(s.observer_config(accel_bias_filter=False)),
    "observer-first-order": lambda s: ObserverEngine(
        s.observer_config(second_order_tilt_loop=False, tau_s=PAPER_TAU_S)
    ),
    "level": lambda s: LevelEngine(s.observer_config()),
    "mahony": lambda s: AhrsEngine("mahony", s.observer_config()),
    "madgwick": lambda s: AhrsEngine("madgwick", s.observer_config()),
    "ekf": _ekf,
    "ekf-cov-every-sample": lambda s: _ekf(s, covariance_period_s=0.0),
}
