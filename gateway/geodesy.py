"""WGS-84 conversions between geodetic coordinates and a local NED frame around an origin.

Exact (through ECEF), vectorised over leading dimensions: a field of a few km needs no
flat-earth approximation, and one pair of functions serves the simulator and the gateway.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

Array = npt.NDArray[np.float64]

A_M = 6378137.0  # WGS-84 semi-major axis
F = 1.0 / 298.257223563  # WGS-84 flattening
E2 = F * (2.0 - F)  # first eccentricity squared


def lla_to_ecef(lla: npt.ArrayLike) -> Array:
    """Latitude deg, longitude deg, ellipsoidal height m, shape (..., 3) -> ECEF m."""
    lla = np.asarray(lla, dtype=float)
    lat, lon, h = np.radians(lla[..., 0]), np.radians(lla[..., 1]), lla[..., 2]
    n = A_M / np.sqrt(1.0 - E2 * np.sin(lat) ** 2)
    return np.stack(
        (
            (n + h) * np.cos(lat) * np.cos(lon),
            (n + h) * np.cos(lat) * np.sin(lon),
            (n * (1.0 - E2) + h) * np.sin(lat),
        ),
        axis=-1,
    )


def ecef_to_lla(xyz: npt.ArrayLike) -> Array:
    """ECEF m, shape (..., 3) -> latitude deg, longitude deg, ellipsoidal height m.

    Bowring's closed form followed by two fixed-point refinements: well below 1 um in height
    and 1e-12 deg anywhere near the Earth's surface.
    """
    xyz = np.asarray(xyz, dtype=float)
    x, y, z = xyz[..., 0], xyz[..., 1], xyz[..., 2]
    lon = np.arctan2(y, x)
    p = np.hypot(x, y)
    b = A_M * (1.0 - F)
    ep2 = (A_M**2 - b**2) / b**2
    theta = np.arctan2(z * A_M, p * b)
    lat = np.arctan2(z + ep2 * b * np.sin(theta) ** 3, p - E2 * A_M * np.cos(theta) ** 3)
    for _ in range(2):
        n = A_M / np.sqrt(1.0 - E2 * np.sin(lat) ** 2)
        h = p / np.cos(lat) - n
        lat = np.arctan2(z, p * (1.0 - E2 * n / (n + h)))
    n = A_M / np.sqrt(1.0 - E2 * np.sin(lat) ** 2)
    h = p / np.cos(lat) - n
    return np.stack((np.degrees(lat), np.degrees(lon), h), axis=-1)


def c_ecef_to_ned(origin_lla: npt.ArrayLike) -> Array:
    """Rotation matrix (3, 3) taking ECEF vectors into the NED frame at the origin."""
    lat, lon = np.radians(np.asarray(origin_lla, dtype=float)[:2])
    sl, cl, so, co = np.sin(lat), np.cos(lat), np.sin(lon), np.cos(lon)
    return np.array(
        [
            [-sl * co, -sl * so, cl],
            [-so, co, 0.0],
            [-cl * co, -cl * so, -sl],
        ]
    )


def lla_to_ned(lla: npt.ArrayLike, origin_lla: npt.ArrayLike) -> Array:
    """Geodetic (..., 3) -> NED m relative to ``origin_lla`` (lat deg, lon deg, height m)."""
    d = lla_to_ecef(lla) - lla_to_ecef(origin_lla)
    return d @ c_ecef_to_ned(origin_lla).T


def ned_to_lla(ned_m: npt.ArrayLike, origin_lla: npt.ArrayLike) -> Array:
    """NED m (..., 3) relative to ``origin_lla`` -> geodetic (lat deg, lon deg, height m)."""
    xyz = np.asarray(ned_m, dtype=float) @ c_ecef_to_ned(origin_lla) + lla_to_ecef(origin_lla)
    return ecef_to_lla(xyz)
