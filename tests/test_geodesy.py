"""Geodesy round trips and hand-checked distances."""

import numpy as np
from numpy.testing import assert_allclose

from gateway.estimation.geodesy import (
    A_M,
    E2,
    LocalFrame,
    ecef_to_lla,
    horizontal_ned,
    lla_to_ecef,
    lla_to_ned,
    ned_to_lla,
)

ORIGIN = np.array([52.2, 10.5, 80.0])


def test_round_trip_ned_lla_over_a_field() -> None:
    rng = np.random.default_rng(1)
    ned = rng.uniform(-3000.0, 3000.0, size=(200, 3)) * [1, 1, 0.01]
    back = lla_to_ned(ned_to_lla(ned, ORIGIN), ORIGIN)
    assert_allclose(back, ned, atol=1e-6)


def test_ecef_round_trip_includes_poles_and_heights() -> None:
    lla = np.array([[89.9, -170.0, 1000.0], [-45.0, 0.0, -50.0], [0.0, 179.0, 0.0]])
    assert_allclose(ecef_to_lla(lla_to_ecef(lla)), lla, atol=1e-9)


def test_one_arcsecond_north_matches_meridian_radius() -> None:
    lat = np.radians(ORIGIN[0])
    m_radius = A_M * (1 - E2) / (1 - E2 * np.sin(lat) ** 2) ** 1.5
    ned = lla_to_ned(ORIGIN + [1 / 3600, 0.0, 0.0], ORIGIN)
    assert_allclose(ned[0], (m_radius + ORIGIN[2]) * np.radians(1 / 3600), rtol=1e-6)
    assert abs(ned[1]) < 1e-9
    assert abs(ned[2]) < 1e-3  # earth curvature over 31 m: 0.07 mm


def test_a_position_without_height_is_placed_at_the_ground_s_scale() -> None:
    """129025 has no height: a field 600 m up, points 250 m out, come back to the millimetre
    at the origin's height, where 0 m put them 2.4 cm short (the 1e-4 of 600 m / R)."""
    origin = np.array([-23.5, -47.5, 600.0])
    ned = np.array([[250.0, 0.0, 0.5], [0.0, -250.0, -1.0], [-180.0, 180.0, 0.0]])
    lat_lon = ned_to_lla(ned, origin)[:, :2]
    assert_allclose(horizontal_ned(lat_lon, origin), ned[:, :2], atol=1e-3)
    assert_allclose(horizontal_ned(lat_lon[0], origin), ned[0, :2], atol=1e-3)
    at_zero = lla_to_ned(np.column_stack([lat_lon, np.zeros(3)]), origin)[:, :2]
    assert float(np.max(np.abs(at_zero - ned[:, :2]))) > 0.02


def test_local_frame_scalar_path_equals_the_array_path() -> None:
    frame = LocalFrame(ORIGIN)
    rng = np.random.default_rng(2)
    for ned in rng.uniform(-5000.0, 5000.0, size=(50, 3)) * [1, 1, 0.02]:
        lla = ned_to_lla(ned, ORIGIN)
        assert_allclose(frame.to_lla(*ned)[:2], lla[:2], rtol=0, atol=1e-12)  # deg
        assert abs(frame.to_lla(*ned)[2] - lla[2]) < 1e-6  # m
        assert_allclose(frame.to_ned(*lla), ned, rtol=0, atol=1e-6)
