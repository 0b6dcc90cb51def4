"""The mean specific force of a stop, for as long as nothing says the vehicle moved.

Standing still, the vehicle's attitude is constant, so its tilt is the mean specific force
less the accelerometer bias, known the better the longer the stop (1/sqrt(n) of the spread of
the epochs' means), while a gyro-propagated attitude only gathers the gyro's angular random
walk. The mean holds only while the attitude does: :class:`RestWindow` collects the mean of
each epoch interval of a stop and starts again when

- the reference point has moved more than :data:`CREEP_M` over the window (GNSS velocity
  integrated; creeping over bumps at 0.1 m/s pitches the body by ~0.25 deg/s, below any rate
  test that the gyro noise allows at one epoch), or
- the body has turned, by the gyro: over the last 1, 2 or 5 s (:data:`SPANS`), the
  rotation about x or y less the window's own mean rate (the residual gyro bias, unknown at
  a cold start) beyond :data:`ROTATION_SIGMAS` of the ARW over the span (a front loader or
  a hitch lifting pitches the body by 0.3-1 deg in a few seconds).

The first :data:`SETTLE_S` of a stop are left out (the last of the braking, the suspension
settling), the mean covers at most :data:`MEMORY_S` (a slow change, a tank filled, is
followed with that lag) and leaves out its last :data:`LAG_S` (a drive-off shows in the GNSS
speed only after it began: a gentle start at 0.3 m/s^2 reaches the 0.1 m/s of the rest test
after 0.3-0.6 s, and the receiver's latency comes on top).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

from drivers.samples import Float3
from drivers.units import DEG_TO_RAD, GRAVITY_MPS2

SETTLE_S = 1.0
MEMORY_S = 20.0
LAG_S = 1.0
#: Reference-point displacement over the window that ends it (m): 3.5 sigma of 2 cm/s RTK
#: velocity noise integrated at 10 Hz over 20 s (0.028 m); noisier fixes end it sooner.
CREEP_M = 0.1
#: Detrended rotation beyond this many sigma of the gyro ARW over the span ends the window.
ROTATION_SIGMAS = 5.0
#: ... plus this much (rad): the engine vibration's gyro part and the sample granularity.
ROTATION_FLOOR_RAD = 0.02 * DEG_TO_RAD

#: Spans of the rotation test, epochs back from now (1, 2, 5 s at 10 Hz; the whole window
#: when shorter).
SPANS = (10, 20, 50)

#: Sums of one chunk: f_b x, y, z and f_b^2 x, y, each times the chunk's duration, the
#: duration, and 1 (the count; 0 for the start of a window).
_N = 7


@dataclass(frozen=True)
class RestLevel:
    """The mean body specific force of the stop, as the epochs gave it (the engine's has its
    accelerometer bias estimate taken out), m/s^2, and the 1-sigma of the tilt it gives, rad,
    from the spread of the epochs' means."""

    f_b_mps2: Float3
    sigma_tilt_rad: float


class RestWindow:
    """The epochs of one stop (see the module docstring): the engine calls :meth:`epoch` at
    each epoch at rest with the mean specific force since the last one, :meth:`stop` at any
    other. Nothing per IMU sample."""

    def __init__(self, gyro_arw_rps_per_sqrt_s: float, accel_psd_m2_per_s3: float = 0.0) -> None:
        self._arw = gyro_arw_rps_per_sqrt_s
        self._q_a = accel_psd_m2_per_s3
        self._since_s: float | None = None  # first epoch of the stop
        self._t_epoch_s: float | None = None  # last epoch at rest
        self._disp_ne_m = (0.0, 0.0)  # reference-point displacement since the stop began
        # one per epoch since the settling: IMU time at its end, its sums, and the body
        # rotation x, y and the displacement N, E since the stop began, at that time
        self._chunks: deque[tuple[float, tuple[float, ...], float, float, float, float]] = deque()
        self._n_used = 0  # the oldest chunks, older than LAG_S: summed in _total
        self._total = [0.0] * _N

    def set_noise(self, gyro_arw_rps_per_sqrt_s: float, accel_psd_m2_per_s3: float) -> None:
        """The IMU's white noise (the gyro's ARW, the accelerometer's PSD with the engine's
        vibration), as measured or configured."""
        self._arw, self._q_a = gyro_arw_rps_per_sqrt_s, accel_psd_m2_per_s3

    def stop(self) -> None:
        """Not at rest: the window is over."""
        self._since_s = self._t_epoch_s = None
        self._restart()
        self._disp_ne_m = (0.0, 0.0)

    def _restart(self) -> None:
        self._chunks.clear()
        self._n_used = 0
        self._total = [0.0] * _N

    def epoch(
        self,
        t_e: float,
        t_imu_s: float,
        f_b_mps2: Float3 | None,
        rotation_xy_rad: tuple[float, float],
        v_ref_ne_mps: tuple[float, float],
    ) -> RestLevel | None:
        """An epoch at rest at ``t_e``. ``f_b_mps2``: the mean body specific force of the IMU
        samples since the last call, up to ``t_imu_s`` (None: no samples, or none before);
        ``rotation_xy_rad``: the integral of the bias-corrected body rate x, y up to
        ``t_imu_s`` (any origin); ``v_ref_ne_mps``: the reference point's GNSS velocity.
        Returns the stop's mean, or None while it is too short or has just restarted."""
        if self._since_s is None:
            self._since_s = t_e
        if self._t_epoch_s is not None:
            dt = t_e - self._t_epoch_s
            d = self._disp_ne_m
            self._disp_ne_m = (d[0] + v_ref_ne_mps[0] * dt, d[1] + v_ref_ne_mps[1] * dt)
        self._t_epoch_s = t_e
        chunks = self._chunks
        if not chunks:
            if t_e - self._since_s >= SETTLE_S:  # the window's start (no sums of its own)
                chunks.append((t_imu_s, (0.0,) * _N, *rotation_xy_rad, *self._disp_ne_m))
            return None
        d_s = t_imu_s - chunks[-1][0]
        if f_b_mps2 is None or d_s <= 0.0:
            return None
        fx, fy, fz = f_b_mps2
        sums = (fx * d_s, fy * d_s, fz * d_s, fx * fx * d_s, fy * fy * d_s, d_s, 1.0)
        chunks.append((t_imu_s, sums, *rotation_xy_rad, *self._disp_ne_m))
        if self._moved():
            self._restart()
            chunks.append((t_imu_s, (0.0,) * _N, *rotation_xy_rad, *self._disp_ne_m))
            return None
        total = self._total
        while self._n_used < len(chunks) and chunks[self._n_used][0] <= t_imu_s - LAG_S:
            for i, x in enumerate(chunks[self._n_used][1]):
                total[i] += x
            self._n_used += 1
        while self._n_used > 1 and chunks[1][0] < t_imu_s - LAG_S - MEMORY_S:
            for i, x in enumerate(chunks.popleft()[1]):
                total[i] -= x
            self._n_used -= 1
        w, n_chunks = total[5], total[6]
        if n_chunks < 2.0:
            return None
        mean = (total[0] / w, total[1] / w, total[2] / w)
        var_h = max(total[3] / w - mean[0] ** 2, total[4] / w - mean[1] ** 2, 0.0)
        # the spread of a few epochs' means is itself a guess (two of them: chi-square with
        # one degree of freedom, near zero one time in four): never below what the white
        # noise leaves in a mean over the window (levelled on 0.2 s by a spread that said
        # 0.04 deg, pitch went 0.3 deg off at a stop on a 9 deg slope, 0.12 stated)
        var_mean = max(var_h / n_chunks, self._q_a / w)
        return RestLevel(mean, math.sqrt(var_mean) / GRAVITY_MPS2)

    def _moved(self) -> bool:
        """Has the reference point moved, or the body turned, over the window (docstring)?
        The rotation is tested over the spans that end now and begin :data:`SPANS` epochs
        back (the whole window when it is shorter, where the detrended rotation is zero: a
        window too short to tell a rotation from the gyro's bias)."""
        chunks = self._chunks
        t1, _, rx1, ry1, dn1, de1 = chunks[-1]
        t0, _, rx0, ry0, dn0, de0 = chunks[0]
        if math.hypot(dn1 - dn0, de1 - de0) > CREEP_M:
            return True
        window_s = t1 - t0
        if window_s <= 0.0:
            return False
        mx, my = (rx1 - rx0) / window_s, (ry1 - ry0) / window_s
        for k in SPANS:
            if k >= len(chunks):
                k = len(chunks) - 1
            t, _, rx, ry, _, _ = chunks[-1 - k]
            dt = t1 - t
            if dt <= 0.0:
                continue
            dev = math.hypot(rx1 - rx - mx * dt, ry1 - ry - my * dt)
            if dev > ROTATION_SIGMAS * self._arw * math.sqrt(dt) + ROTATION_FLOOR_RAD:
                return True
        return False
