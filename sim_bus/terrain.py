"""Analytic field terrain: a height field whose derivatives up to third order are exact.

The vehicle simulator tilts the body with the terrain normal and needs the rates and angular
accelerations of that tilt; with exact gradient, Hessian and third-derivative tensor the whole
truth is self-consistent to rounding, with no numerical differentiation.

Height h (m, up) over horizontal NED coordinates x = (north, east) is a sum of ridge functions
f(k . x):

- side slope across the swaths, whose gradient varies smoothly between a minimum and a maximum
  over a cross-track wavelength (a plane when both are equal; a ridge or valley when they
  differ in sign);
- a constant along-track slope;
- bumps: a few random plane waves of cm-dm amplitude and metre wavelength.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

Array = npt.NDArray[np.float64]


@dataclass(frozen=True)
class TerrainDerivatives:
    """Height and its derivatives at n horizontal points.

    h_m (n,), grad (n, 2) dimensionless, hess (n, 2, 2) 1/m, third (n, 2, 2, 2) 1/m^2, all with
    respect to (north, east).
    """

    h_m: Array
    grad: Array
    hess: Array
    third: Array


@dataclass(frozen=True)
class Terrain:
    """Sum of ridge functions over (north, east); see the module docstring.

    swath_heading_rad: along-track direction (from north, clockwise); cross-track is to its right.
    side_grad_min/max: cross-track gradient dh/dc extremes (tan of the slope angle).
    side_wavelength_m: cross-track period of the gradient variation.
    along_grad: along-track gradient dh/da.
    bump_amplitude_m (count,), bump_wavenumber_rad_per_m (count, 2), bump_phase_rad (count,):
    plane waves A sin(k . x + phase).
    """

    swath_heading_rad: float
    side_grad_min: float
    side_grad_max: float
    side_wavelength_m: float
    along_grad: float
    bump_amplitude_m: Array
    bump_wavenumber_rad_per_m: Array
    bump_phase_rad: Array

    def derivatives(self, x_ne_m: Array) -> TerrainDerivatives:
        """Exact h, gradient, Hessian and third derivatives at points x_ne_m (n, 2), m."""
        x = np.asarray(x_ne_m, dtype=float)
        n = x.shape[0]
        u_along = np.array([np.cos(self.swath_heading_rad), np.sin(self.swath_heading_rad)])
        u_cross = np.array([-u_along[1], u_along[0]])
        h = np.zeros(n)
        grad = np.zeros((n, 2))
        hess = np.zeros((n, 2, 2))
        third = np.zeros((n, 2, 2, 2))

        def add_ridge(k: Array, f: Array, f1: Array, f2: Array, f3: Array) -> None:
            """Add sum_j f_j(k_j . x) for k (m, 2), given f_j and its derivatives f1..f3 (n, m)."""
            m = k.shape[0]
            kk = np.einsum("mi,mj->mij", k, k).reshape(m, 4)
            kkk = np.einsum("mi,mj,mk->mijk", k, k, k).reshape(m, 8)
            h[:] += f.sum(axis=1)
            grad[:] += f1 @ k
            hess[:] += (f2 @ kk).reshape(n, 2, 2)
            third[:] += (f3 @ kkk).reshape(n, 2, 2, 2)

        # Side slope: dh/dc = mid + amp sin(q c), zero height at c = 0.
        mid = 0.5 * (self.side_grad_max + self.side_grad_min)
        amp = 0.5 * (self.side_grad_max - self.side_grad_min)
        q = 2.0 * np.pi / self.side_wavelength_m
        c = (x @ u_cross)[:, None]
        add_ridge(
            u_cross[None, :],
            mid * c - amp / q * (np.cos(q * c) - 1.0),
            mid + amp * np.sin(q * c),
            amp * q * np.cos(q * c),
            -amp * q**2 * np.sin(q * c),
        )
        h[:] += self.along_grad * (x @ u_along)
        grad[:] += self.along_grad * u_along
        if self.bump_amplitude_m.size:
            amp_b = self.bump_amplitude_m
            arg = x @ self.bump_wavenumber_rad_per_m.T + self.bump_phase_rad
            s, co = amp_b * np.sin(arg), amp_b * np.cos(arg)
            add_ridge(
                self.bump_wavenumber_rad_per_m, s - amp_b * np.sin(self.bump_phase_rad), co, -s, -co
            )
        return TerrainDerivatives(h, grad, hess, third)


def random_bumps(
    amplitude_m: float, wavelength_min_m: float, wavelength_max_m: float, count: int, seed: int
) -> tuple[Array, Array, Array]:
    """Plane-wave bumps: amplitudes (count,) m, wavenumbers (count, 2) rad/m, phases (count,).

    Each wave has the given amplitude, a wavelength drawn log-uniformly in the range, a uniform
    direction and phase; the sum has an rms height of amplitude_m * sqrt(count / 2).
    """
    rng = np.random.default_rng(seed)
    wavelength = np.exp(rng.uniform(np.log(wavelength_min_m), np.log(wavelength_max_m), count))
    direction = rng.uniform(0.0, 2.0 * np.pi, count)
    k = (2.0 * np.pi / wavelength)[:, None] * np.stack((np.cos(direction), np.sin(direction)), 1)
    return np.full(count, amplitude_m), k, rng.uniform(0.0, 2.0 * np.pi, count)
