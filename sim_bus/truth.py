"""Simulator truth: the vehicle's true motion at the IMU sample instants.

Stored as ``.npz`` with one array per column below (``save``/``load``). Row k is IMU
sample k; times are host-clock UTC seconds, the same clock as the logs.

=================  =======  ========================================================
column             shape    meaning
=================  =======  ========================================================
t                  (n,)     s, UTC; instant of IMU sample k
pos_ned_m          (n, 3)   reference point, NED relative to the origin, m
lla                (n, 3)   reference point latitude deg, longitude deg, ellipsoidal height m
vel_ned_mps        (n, 3)   reference point velocity, NED, m/s
rpy_rad            (n, 3)   roll, pitch, yaw (ZYX, yaw from true north), rad
w_ib_b             (n, 3)   true body angular rate, FRD, rad/s
f_ib_b_imu         (n, 3)   true specific force at the IMU location, FRD, m/s^2
pos_ant_ned_m      (n, 3)   antenna phase centre, NED, m
lla_ant            (n, 3)   antenna latitude deg, longitude deg, ellipsoidal height m
vel_ant_ned_mps    (n, 3)   antenna velocity, NED, m/s
reversing          (n,)     bool, vehicle moving backwards
stationary         (n,)     bool, vehicle at rest
bias_g_rps         (n, 3)   true gyro bias of the IMU model, body FRD, rad/s (0 if none)
bias_a_mps2        (n, 3)   true accelerometer bias of the IMU model, body FRD, m/s^2
=================  =======  ========================================================

Scalars stored alongside: ``origin_lla`` (3,), ``antenna_lever_arm_m`` (3,),
``imu_lever_arm_m`` (3,), ``dt_s`` (IMU sample period).
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields
from pathlib import Path

import numpy as np
import numpy.typing as npt

Array = npt.NDArray[np.float64]


@dataclass
class Truth:
    """Columns documented in the module docstring; all arrays share the first dimension."""

    t: Array
    pos_ned_m: Array
    lla: Array
    vel_ned_mps: Array
    rpy_rad: Array
    w_ib_b: Array
    f_ib_b_imu: Array
    pos_ant_ned_m: Array
    lla_ant: Array
    vel_ant_ned_mps: Array
    reversing: npt.NDArray[np.bool_]
    stationary: npt.NDArray[np.bool_]
    bias_g_rps: Array
    bias_a_mps2: Array
    origin_lla: Array = field(default_factory=lambda: np.zeros(3))
    antenna_lever_arm_m: Array = field(default_factory=lambda: np.zeros(3))
    imu_lever_arm_m: Array = field(default_factory=lambda: np.zeros(3))
    dt_s: float = 4.0 / 819.2

    def __len__(self) -> int:
        return len(self.t)

    def save(self, path: str | Path) -> None:
        """Write all columns and scalars to an uncompressed ``.npz`` file."""
        columns = {f.name: np.asarray(getattr(self, f.name)) for f in fields(self)}
        np.savez(Path(path), allow_pickle=False, **columns)

    @classmethod
    def load(cls, path: str | Path) -> Truth:
        """Read a file written by :meth:`save`."""
        with np.load(Path(path)) as z:
            kw = {f.name: z[f.name] for f in fields(cls)}
        kw["dt_s"] = float(kw["dt_s"])
        return cls(**kw)
