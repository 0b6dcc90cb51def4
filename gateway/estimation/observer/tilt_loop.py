"""The tilt loop's control (eq. 3): the paper's first order, or the product's second order.

Seed 000 corrects the platform with w_p = -k x e, k = [0, 0, -1/(tau g)]: each epoch turns it
by e T / (g tau), a first-order loop. Its tilt error has three parts (docs/ACCURACY.md, "The
floors of roll/pitch"): the gyro's ARW through the loop, ARW^2 tau / 2; a gyro bias error held
as b_g tau; and the GNSS velocity noise, sigma_v / (g tau), since e is a velocity *difference*
and its sum telescopes to one velocity error. The last grows as tau shrinks, so the paper's
loop cannot be made faster than about 4 s with RTK's 2 cm/s without passing that noise on.

The product's extension (``[observer] second_order_tilt_loop``) low-passes e before it is
applied, e_f' = (4 / tau) (e - e_f): the loop is then second order and critically damped
(natural frequency 2 / tau). A constant tilt or bias error is taken out as before (the steady
state is the same, b_g tau), but white velocity noise reaches the tilt through the low-pass:
its variance is that of the first-order loop times 2 T / tau (T the epoch period), so the loop
can be faster; the gyro's ARW costs q 5 tau / 8 instead of q tau / 2. White accelerometer
noise (VRW, the engine's broadband vibration) is white on e itself, not a difference:
S_a / (2 g^2 tau) in either loop. With ARW q, velocity noise density S_v = sigma_v^2 T and
the accelerometer's S_a, the second order's tilt variance

    q 5 tau / 8  +  2 S_v / (g^2 tau^3)  +  S_a / (2 g^2 tau)

is least where q 5 tau^4 / 8 - S_a tau^2 / (2 g^2) - 6 S_v / g^2 = 0, a quadratic in tau^2:
1.85 s with the datasheet's 2 deg/rt-h and RTK's 2 cm/s at 10 Hz; with the config's
0.2 m/s^2 of engine vibration 2.6 s, 3.1 s for float's 4 cm/s, 4.4 s for single point's
10 cm/s, 3.7 s for a 1 Hz RTK receiver. The loop takes that optimum for the fix it has and
the IMU noise as measured (:meth:`TiltLoop.set_imu_noise`), never faster than ``tau_s`` (2 s)
nor slower than 4 ``tau_s`` (a gyro bias error's steady tilt, b_g tau, grows with it).

The low-pass is kept as an owed velocity residual, so that every e is applied in full in the
end (its integral is what telescopes): each epoch adds e T to it, and the control over the
next period applies the share 1 - exp(-4 P / tau) of it. While the loop is open (a glitch, a
gap, the period over) what is owed waits: the next difference spans the open interval, and a
velocity error one epoch made is taken back by the next before most of it is applied (the
first epochs of a reversing start, taken as still, sent the tilt 0.28 deg off when what was
owed was applied at once as the loop opened: ``tests/test_course_hold.py``).
"""

from __future__ import annotations

import math

from drivers.units import GRAVITY_MPS2

#: The low-pass's rate times tau: 4 makes the second-order loop critically damped.
CRITICAL_DAMPING = 4.0
#: The slowest the second-order loop is made, as a multiple of ``tau_s``.
MAX_TAU_FACTOR = 4.0


class TiltLoop:
    """The horizontal control rate's e, per epoch, and the loop's noise figures."""

    def __init__(self, tau_s: float, second_order: bool) -> None:
        self.tau_s = tau_s  # the paper's loop: its tau; second order: the fastest it goes
        self.second_order = second_order
        self.tau_now_s = tau_s  # the loop's time constant for the fixes it now takes
        self._q = 0.0  # gyro white noise density (ARW^2), rad^2/s
        self._s_a = 0.0  # accelerometer white noise density, (m/s^2)^2/Hz
        self._owed_ne = (0.0, 0.0)  # velocity residual not yet applied, NED, m/s

    def set_imu_noise(self, arw_rad_per_sqrt_s: float, accel_psd: float) -> None:
        """The IMU's white noise (as measured where it is more than the datasheet's)."""
        self._q = arw_rad_per_sqrt_s**2
        self._s_a = accel_psd

    def optimal_tau_s(self, sigma_v_mps: float, period_s: float) -> float:
        """The second-order loop's least-variance tau for this velocity noise, bounded to
        [tau_s, MAX_TAU_FACTOR tau_s] (module docstring)."""
        g2 = GRAVITY_MPS2 * GRAVITY_MPS2
        a = 5.0 * self._q / 8.0
        b = self._s_a / (2.0 * g2)
        c = 6.0 * sigma_v_mps * sigma_v_mps * period_s / g2
        longest = MAX_TAU_FACTOR * self.tau_s
        if a <= 0.0:
            return longest
        tau = math.sqrt((b + math.sqrt(b * b + 4.0 * a * c)) / (2.0 * a))
        return min(max(tau, self.tau_s), longest)

    def control(
        self,
        e_ne_mps2: tuple[float, float],
        interval_s: float,
        period_s: float,
        sigma_v_mps: float,
    ) -> tuple[float, float]:
        """The e to hold over the coming ``period_s`` for an epoch's e over ``interval_s``
        (longer than the period when epochs between were rejected), m/s^2, for a loop whose
        gain is 1 / (tau_s g). ``sigma_v_mps``: the fix's velocity 1-sigma per axis."""
        e_n, e_e = e_ne_mps2
        if not self.second_order:
            scale = interval_s / period_s
            return e_n * scale, e_e * scale
        self.tau_now_s = self.optimal_tau_s(sigma_v_mps, period_s)
        q_n = self._owed_ne[0] + e_n * interval_s
        q_e = self._owed_ne[1] + e_e * interval_s
        share = 1.0 - math.exp(-CRITICAL_DAMPING * period_s / self.tau_now_s)
        self._owed_ne = (q_n * (1.0 - share), q_e * (1.0 - share))
        scale = share * self.tau_s / (self.tau_now_s * period_s)
        return q_n * scale, q_e * scale

    def clear(self) -> None:
        """Nothing owed: the platform was levelled anew, the old residual no longer holds."""
        self._owed_ne = (0.0, 0.0)

    def rotate_about_vertical(self, dpsi_rad: float) -> None:
        """The platform was turned about the vertical: the owed residual turns with it."""
        c, s = math.cos(dpsi_rad), math.sin(dpsi_rad)
        q_n, q_e = self._owed_ne
        self._owed_ne = (c * q_n - s * q_e, s * q_n + c * q_e)

    def noise_tilt_var(self) -> float:
        """Steady tilt variance from the IMU's white noise, rad^2: gyro q tau / 2 (second
        order q 5 tau / 8) and accelerometer S_a / (2 g^2 tau)."""
        tau = self.tau_now_s
        share = 5.0 / 8.0 if self.second_order else 0.5
        return self._q * tau * share + self._s_a / (2.0 * GRAVITY_MPS2 * GRAVITY_MPS2 * tau)

    def velocity_tilt_sigma(self, sigma_v_mps: float, epoch_s: float) -> float:
        """Tilt 1-sigma from white GNSS velocity noise, rad: sigma_v / (g tau), second order
        times sqrt(2 T / tau) (T the epoch period; never more than the first order's)."""
        tau = self.tau_now_s
        first = sigma_v_mps / (GRAVITY_MPS2 * tau)
        if not self.second_order:
            return first
        return first * math.sqrt(min(1.0, 2.0 * epoch_s / tau))

    def decay(self, left: float, held: float, dt_s: float) -> tuple[float, float]:
        """A tilt error ``left`` on the platform (any unit), ``held`` of it in the low-pass,
        ``dt_s`` later with the loop closed: first order left exp(-t / tau); second order
        the critically damped response exp(A t) = exp(-2t/tau) (I + (A + 2/tau) t) of
        A = [[0, -1/tau], [4/tau, -4/tau]], from rest (1 + 2t/tau) exp(-2t/tau)."""
        x = dt_s / self.tau_now_s
        if not self.second_order:
            return left * math.exp(-x), 0.0
        k = math.exp(-2.0 * x)
        return k * ((1.0 + 2.0 * x) * left - x * held), k * (
            4.0 * x * left + (1.0 - 2.0 * x) * held
        )
