"""Is the antenna's height above the reference point the configured one? The drive tells.

Both engines take the antenna lever arm (SPEC 5) as given: the antenna's velocity is the
reference point's plus ``w x r_ant``. With a 3 m mast left out of the config (the default is
zero) the rocking of the cab on bumps moves the antenna sideways by roll rate times 3 m, which
the engines read as specific force: on the `short` run the observer's pitch went 2 deg off
with 0.46 stated, the EKF's 0.4 with 0.08 (docs/ROBUSTNESS.md).

The reference point is on the ground (SPEC 4: e.g. the rear-axle centre on the ground), where
a wheeled vehicle rolls: it does not move sideways when the cab rocks. So the antenna's
lateral (body y) velocity follows the body rates by its lever arm alone,

    v_lat = y_b . v_ant = v_lat_ref + w_z r_x - w_x r_z,

and a least-squares fit of its changes over ``LAG_S`` on the rates' changes (a slope's
crabbing and the heading's slow error drop out) gives the antenna's height -r_z with its
1-sigma; r_x is fitted alongside but not judged (a reference point ahead of the rear axle
rightly moves sideways in turns). Changes over half a second, not from epoch to epoch: a
rocking cab's rate (0.3-1 Hz) barely changes in 0.1 s while the gyro's noise in each
epoch's mean does, and noise in the rates shrinks the fit towards zero (by a quarter on
`short` from one epoch to the next). What noise is left is measured (the samples' scatter
about each epoch's mean) and taken out of the fit; with too little rocking beside it (smooth
ground) nothing is judged. The configured lever arm stays out of
the fit for the same reason: subtracting ``w x r_ant`` with measured rates put their noise
on both sides. Once the height differs from the configured one by more than ``SIGMAS`` of
its 1-sigma plus ``TOLERANCE_M`` (the roll centre of a vehicle on its tyres is near, not
on, the ground), :attr:`LeverArmCheck.off` is set, latched (the config does not change
while the service runs), and the core sends DEGRADED. On smooth ground there is no roll
rate to judge by, and no lever-arm error to fear from it either.

The rates are the IMU's own, each epoch's the mean over the 0.1 s before it (a comparison,
three sums and a count per sample; their bias drops out of the changes); not the solutions' attitude
differenced, which holds the engine's tilt corrections, made from the same GNSS velocities.
"""

from __future__ import annotations

import logging
import math
from collections import deque
from dataclasses import dataclass

from drivers.samples import Float3, GnssFix
from gateway.estimation.solution import Solution

log = logging.getLogger(__name__)

#: The height counts as off beyond this many of its 1-sigmas ...
SIGMAS = 5.0
#: ... plus this, m: the roll centre of a vehicle on its tyres is near, not on, the ground.
TOLERANCE_M = 1.0
#: Epochs judged only when moving at least this fast (m/s): a slower fix's course is noisy.
MIN_SPEED_MPS = 1.0
#: The rates of an epoch: their mean over this long before it (s), where the velocity is:
#: at 10 Hz the whole interval; a 1 Hz receiver's whole second averaged the rocking away
#: and centred it half a second early (a 3 m mast measured 2.2 m).
RATE_WINDOW_S = 0.1
#: Changes are taken over at least this long (s) ...
LAG_S = 0.5
#: ... and at most this long: across a longer gap the slow terms no longer drop out.
MAX_LAG_S = 1.5
#: The fit is made only while the gyro's noise is at most this share of the roll rate's
#: changes (its scatter within each epoch's samples says how much; taken out of the fit, an
#: over-estimate of it can magnify the height by 1 / (1 - this) at most).
MAX_NOISE_SHARE = 0.2
#: A lateral velocity change beyond this (m/s) is a glitch, not the lever arm.
MAX_DV_MPS = 1.0
#: Overlapping changes share their ends: the residuals' scatter understates the 1-sigma by
#: up to this factor.
OVERLAP_INFLATION = math.sqrt(2.0)
#: The fit is judged from this many changes on (10 s of driving at 10 Hz): a few rows can
#: fit each other exactly (a slope's start put 19 m +/- 0 on 10).
MIN_CHANGES = 100
#: The fit is looked at this often (s of fix time).
CHECK_INTERVAL_S = 1.0


@dataclass(frozen=True, slots=True)
class LeverArmFit:
    """The antenna's height above the reference point as the drive shows it (m, -r_z),
    its 1-sigma, and the configured one."""

    height_m: float
    sigma_m: float
    configured_m: float
    changes: int

    @property
    def ratio(self) -> float:
        """The error over the bound it is judged by: off beyond 1."""
        error = abs(self.height_m - self.configured_m)
        return error / (SIGMAS * self.sigma_m + TOLERANCE_M)

    def text(self) -> str:
        """E.g. ``2.98 +/- 0.05 m above the reference point, configured 0.00 m``."""
        return (
            f"{self.height_m:.2f} +/- {self.sigma_m:.2f} m above the reference point, "
            f"configured {self.configured_m:.2f} m"
        )


class LeverArmCheck:
    """Fed each IMU sample's rates and each GNSS fix with the engine's solution after it;
    :attr:`off` once the drive has shown the antenna's height above the reference point off
    the configured one."""

    def __init__(self, antenna_lever_arm_m: Float3) -> None:
        self.configured_height_m = 0.0 - antenna_lever_arm_m[2]  # 0.0, not -0.0, for z = 0
        self.found: LeverArmFit | None = None  # the fit that showed it off
        # normal equations of d(v_lat) = a d(w_x) + b d(w_z): sums of xx, xz, zz, xy, zy, yy
        self._sums = [0.0] * 6
        self._n = 0
        self._noise = 0.0  # the x rate changes' noise variances, summed
        #: recent epochs: t, v_lat, mean w_x, w_z, and the variance of the w_x mean's noise
        self._recent: deque[tuple[float, float, float, float, float]] = deque()
        self._w_sum = [0.0, 0.0, 0.0]  # body x and z rates, x squared, since the last epoch
        self._w_n = 0  # and how many samples
        self._sum_from = -math.inf  # rates are summed from this sample time on
        self._t_epoch: float | None = None  # the last epoch's solution time
        self._next_t: float | None = None

    @property
    def off(self) -> bool:
        """The drive has shown the lever arm off (latched: the config does not change)."""
        return self.found is not None

    def imu(self, t: float, w_ib_b: Float3) -> None:
        """One IMU sample's time (s) and body rates (rad/s), summed over the last
        RATE_WINDOW_S before the next epoch is due."""
        if t < self._sum_from:
            return
        w_x = w_ib_b[0]
        s = self._w_sum
        s[0] += w_x
        s[1] += w_ib_b[2]
        s[2] += w_x * w_x
        self._w_n += 1

    def epoch(self, fix: GnssFix, sol: Solution) -> None:
        """One GNSS fix and the solution after it; every CHECK_INTERVAL_S, the verdict."""
        w_sum, n_w = self._w_sum, self._w_n
        self._w_sum, self._w_n = [0.0, 0.0, 0.0], 0
        if self._t_epoch is not None:  # the next epoch is due one interval on
            self._sum_from = 2.0 * sol.t - self._t_epoch - RATE_WINDOW_S
        self._t_epoch = sol.t
        roll, pitch, yaw, vel = sol.roll_rad, sol.pitch_rad, sol.yaw_rad, fix.vel_ne_mps
        if (
            roll is not None and pitch is not None and yaw is not None and n_w > 1
            and vel is not None and math.hypot(*vel) >= MIN_SPEED_MPS
        ):  # fmt: skip
            w_x, w_z = w_sum[0] / n_w, w_sum[1] / n_w
            # the mean's noise: the samples' scatter about it over n_w (n_w - 1) samples
            var_x = max(w_sum[2] - n_w * w_x * w_x, 0.0) / (n_w * (n_w - 1))
            v_lat = _along_body_y(vel, roll, pitch, yaw)
            self._judge((sol.t, v_lat, w_x, w_z, var_x))
        if self._next_t is not None and fix.t < self._next_t:
            return
        self._next_t = fix.t + CHECK_INTERVAL_S
        fit = self.fit()
        if fit is not None and fit.ratio > 1.0 and self.found is None:
            self.found = fit
            log.warning(
                "t=%.1f: the antenna lever arm in effect is off: the drive puts the antenna "
                "%s ([vehicle] antenna_lever_arm_m z is minus the height): roll and pitch "
                "sent may be off by it; NAVGW_STATUS degraded until the lever arm is set and "
                "the service restarted", fix.t, fit.text(),
            )  # fmt: skip

    def _judge(self, now: tuple[float, float, float, float, float]) -> None:
        """Add the change from the newest epoch at least LAG_S before ``now``."""
        recent, t = self._recent, now[0]
        while recent and t - recent[0][0] > MAX_LAG_S:
            recent.popleft()
        before = None
        for row in recent:
            if t - row[0] < LAG_S:
                break
            before = row
        recent.append(now)
        if before is None:
            return
        dy = now[1] - before[1]
        if abs(dy) > MAX_DV_MPS:
            return
        dx, dz = now[2] - before[2], now[3] - before[3]
        s = self._sums
        s[0] += dx * dx
        s[1] += dx * dz
        s[2] += dz * dz
        s[3] += dx * dy
        s[4] += dz * dy
        s[5] += dy * dy
        self._noise += now[4] + before[4]
        self._n += 1

    def fit(self) -> LeverArmFit | None:
        """The height and its 1-sigma from the drive so far; None before there is roll to
        judge by."""
        s, n = self._sums, self._n
        # the roll rate's own noise taken out of its sum of squares (it would shrink the fit;
        # the z rate's is left: it shrinks only the fit of r_x, nearly uncorrelated)
        xx, zz = s[0] - self._noise, s[2]
        det = xx * zz - s[1] * s[1]
        if n < MIN_CHANGES or xx < (1.0 - MAX_NOISE_SHARE) * s[0] or det <= 0.0:
            return None
        a = (s[3] * zz - s[4] * s[1]) / det  # d(v_lat) per d(w_x): -r_z, the height
        b = (s[4] * xx - s[3] * s[1]) / det
        # the residuals' sum of squares, of the changes as measured (their noise included)
        residual = (
            s[5] - 2.0 * (a * s[3] + b * s[4]) + a * a * s[0] + 2.0 * a * b * s[1] + b * b * zz
        )
        sigma = OVERLAP_INFLATION * math.sqrt(max(residual, 0.0) / (n - 2) * zz / det)
        if not math.isfinite(sigma):
            return None
        return LeverArmFit(a, sigma, self.configured_height_m, n)


def _along_body_y(vel_ne: tuple[float, float], roll: float, pitch: float, yaw: float) -> float:
    """A horizontal velocity (N, E, m/s) along body y: C_b^n's second column, Rz Ry Rx, in
    plain floats (numpy's per-call cost was 1.5 us an IMU sample at 10 Hz)."""
    sr, cr = math.sin(roll), math.cos(roll)
    sy, cy = math.sin(yaw), math.cos(yaw)
    sp_sr = math.sin(pitch) * sr
    return vel_ne[0] * (cy * sp_sr - sy * cr) + vel_ne[1] * (sy * sp_sr + cy * cr)
