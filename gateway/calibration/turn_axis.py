"""The body's down axis in IMU axes: the axis a wheeled vehicle turns about.

On a plane, whatever its slope, a vehicle turns about the plane's normal, its own z axis:
w_b = (0, 0, r). The gyros read w = C^T w_b + b_g, so the mean rates of windows of a drive
lie on a line through the gyro bias b_g along n = C^T z_b, the body's z axis in the IMU's
axes. Its direction gives the mounting's roll and pitch (n is the last row of C), free of
the accelerometer bias, which no fit of specific force can tell from a mounting tilt.

The line is the principal axis of the windows' rates (a total least squares fit: the same
in any axes, unlike regressing x and y rates on the z rate, whose regressor carries the
x and y noise once the axes are tilted). Turns set the line's length; straights and stops
its bias point. What the fit cannot tell from a mounting: the terrain's own curvature
rotating the body about its x and y axes during a turn (bumps, a side slope that changes
across the field): a few tenths of a degree per U-turn on bumpy ground, averaging out over
turns both ways. Good enough to bring the samples near the body's axes, where an engine's
attitude takes over (:mod:`gateway.estimation.ins_tilt`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from drivers.samples import ImuSample
from gateway.estimation.solution import MAX_IMU_STEP_S

Array = npt.NDArray[np.float64]

#: Windows turning faster than this count as turns (right or left) in the turn tally.
TURN_RATE_RPS = math.radians(3.0)


@dataclass(frozen=True, slots=True)
class TurnAxis:
    """The fitted axis ``n_imu`` (3,), unit, z down, in the fit's axes, and the covariance
    ``tilt_cov_rad2`` (2, 2) of the mounting roll and pitch it gives (windows taken as
    independent)."""

    n_imu: Array
    tilt_cov_rad2: Array


class TurnAxisFit:
    """Window means of the gyro, their second moments, and the turns they contain."""

    def __init__(self, window_s: float = 1.0) -> None:
        self.window_s = window_s
        self.sums = np.zeros((4, 4))  # sum z z^T of z = (1, w_x, w_y, w_z) per window
        self.turned_right_rad = 0.0
        self.turned_left_rad = 0.0
        self._sum = [0.0, 0.0, 0.0]
        self._n = 0
        self._t0_s: float | None = None
        self._last_s: float | None = None

    def add(self, sample: ImuSample) -> None:
        """One IMU sample; a gap or a flagged sample drops the window it falls in."""
        t = sample.t
        last, self._last_s = self._last_s, t
        flagged = sample.alarm or sample.saturated or sample.stuck
        if flagged or last is None or t - last > MAX_IMU_STEP_S:
            self._restart(None)
            return
        if t <= last:
            return
        if self._t0_s is None:
            self._restart(last)
        w = sample.w_ib_b
        self._sum[0] += float(w[0])
        self._sum[1] += float(w[1])
        self._sum[2] += float(w[2])
        self._n += 1
        if self._t0_s is not None and t - self._t0_s >= self.window_s:
            self._close(t)

    def _restart(self, t0_s: float | None) -> None:
        self._sum = [0.0, 0.0, 0.0]
        self._n = 0
        self._t0_s = t0_s

    def _close(self, t_s: float) -> None:
        n = self._n
        w = (self._sum[0] / n, self._sum[1] / n, self._sum[2] / n)
        z = np.array((1.0, *w))
        self.sums += np.outer(z, z)
        turned = w[2] * (t_s - (self._t0_s or t_s))
        if w[2] > TURN_RATE_RPS:
            self.turned_right_rad += turned
        elif w[2] < -TURN_RATE_RPS:
            self.turned_left_rad -= turned
        self._restart(t_s)

    def fit(self) -> TurnAxis | None:
        """The turn axis, or None before the windows span any turning."""
        s = self.sums
        count = s[0, 0]
        if count < 3:
            return None
        mean = s[0, 1:] / count
        lam, vec = np.linalg.eigh(s[1:, 1:] / count - np.outer(mean, mean))
        if lam[2] <= 0.0:
            return None
        n = vec[:, 2] if vec[2, 2] > 0.0 else -vec[:, 2]
        # perturbation of the principal axis along the two others: lam_j lam_2 / (N gap^2)
        var = [lam[j] * lam[2] / (count * (lam[2] - lam[j]) ** 2) for j in (0, 1)]
        jac = _tilt_jacobian(n) @ vec[:, :2]  # d(roll, pitch) / d(along the two others)
        return TurnAxis(n, jac @ np.diag(var) @ jac.T)


def _tilt_jacobian(n: Array) -> Array:
    """d(roll, pitch) / dn, shape (2, 3), for roll = atan2(n_y, n_z), pitch = -asin(n_x)."""
    ny2nz2 = n[1] ** 2 + n[2] ** 2
    return np.array(
        [
            [0.0, n[2] / ny2nz2, -n[1] / ny2nz2],
            [-1.0 / math.sqrt(max(ny2nz2, 1e-12)), 0.0, 0.0],
        ]
    )
