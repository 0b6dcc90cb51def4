"""Tereshkov (2015) virtual-platform observer with gyro and accelerometer bias observers.

Discrete form of ALGORITHMS.md section 1. The state is the DCM C = C_b^p (body to "virtual
platform", the NED frame up to the attitude error), the gyro bias estimate and the
accelerometer bias estimate. Per IMU sample :meth:`TereshkovObserver.propagate` does

    w_b = w_meas - bg_hat,  f_b = f_meas - ba_hat
    C   = exp(-[w_p dt]x) C exp([w_b dt]x)                  eq. (1)
    f_p = C f_b                                             eq. (2)
    bg_hat[x,y] += (C^T w_p)[x,y] / tau_g * dt              eq. (11)
    ba_hat[x,y] += g w_b[z] (C^T w_p)[x,y] / omega_a * dt   eq. (12)

and per GNSS epoch :meth:`TereshkovObserver.correct_tilt` sets the horizontal control rate
w_p = -k x e, k = [0, 0, -1/(tau g)], from e = f_gnss - mean(f_p) (eq. 3). The heading channel
sets the vertical component of w_p (:meth:`set_heading_rate`), so the DCM stays the single
attitude state; the bias equations use the horizontal part of w_p only, since the z-gyro bias
belongs to the heading channel (seed 001).

Integration: exp([w_b dt]x) to second order (error < 1e-8 rad per sample at farm rates),
exp(-[w_p dt]x) exact (Rodrigues), computed once per control-rate change; C is projected back
onto SO(3) (SVD polar factor) every ``ORTHONORMALISE_EVERY`` samples. The hot path is plain
Python floats: numpy costs about 1 us per call on 3x3 arrays.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from drivers.units import GRAVITY_MPS2
from gateway.estimation.attitude import (
    Mat9,
    dcm_mul,
    exp_so3_2nd,
    exp_so3_9,
    from_mat9,
    orthonormalise,
    to_mat9,
)

Array = npt.NDArray[np.float64]
Float3 = tuple[float, float, float]

#: Samples between re-orthonormalisations of C (about 1.2 s at 204.8 Hz).
ORTHONORMALISE_EVERY = 256


class TereshkovObserver:
    """Attitude C_b^p plus x/y gyro and accelerometer bias observers (seed 000, eqs. 1-12).

    ``learn`` switches the bias equations (11), (12) on or off; the engine sets it from its
    gates. The z components of the bias estimates are owned by the heading channel and set
    with :meth:`set_gyro_bias_z`; the accelerometer z bias is not observable here and stays 0.
    """

    def __init__(
        self,
        tau_s: float,
        tau_g_s: float,
        omega_a_rps: float,
        c_bp: npt.ArrayLike,
        g_mps2: float = GRAVITY_MPS2,
    ) -> None:
        self.tau_s = tau_s
        self.tau_g_s = tau_g_s
        self.omega_a_rps = omega_a_rps
        self.g_mps2 = g_mps2
        self.learn = False
        self.learn_accel = True  # eq. (12); off where a filter learns the x/y accel biases
        self._c: Mat9 = to_mat9(c_bp)
        self._bg_rps = [0.0, 0.0, 0.0]
        self._ba_mps2 = [0.0, 0.0, 0.0]
        self._w_p_rps: Float3 = (0.0, 0.0, 0.0)  # control rate, platform (NED) frame
        self._exp_w_p: Mat9 | None = None  # exp(-[w_p dt]x) for _exp_dt, None when w_p = 0
        self._exp_dt = 0.0
        self._n_since_ortho = 0
        self.w_b_rps: Float3 = (0.0, 0.0, 0.0)  # last bias-corrected rate, body

    # ----------------------------------------------------------------------- prediction

    def propagate(self, w_meas: Float3, f_meas: Float3, dt: float) -> Float3:
        """One IMU sample: update C and (if ``learn``) the biases; return f_p (3,), m/s^2."""
        bg = self._bg_rps
        ba = self._ba_mps2
        wx = w_meas[0] - bg[0]
        wy = w_meas[1] - bg[1]
        wz = w_meas[2] - bg[2]
        fx = f_meas[0] - ba[0]
        fy = f_meas[1] - ba[1]
        fz = f_meas[2] - ba[2]
        c = dcm_mul(self._c, exp_so3_2nd(wx * dt, wy * dt, wz * dt))
        w_p = self._w_p_rps
        if w_p[0] or w_p[1] or w_p[2]:
            if self._exp_w_p is None or dt != self._exp_dt:
                self._exp_w_p = exp_so3_9(-w_p[0] * dt, -w_p[1] * dt, -w_p[2] * dt)
                self._exp_dt = dt
            c = dcm_mul(self._exp_w_p, c)
        self._n_since_ortho += 1
        if self._n_since_ortho >= ORTHONORMALISE_EVERY:
            c = to_mat9(orthonormalise(from_mat9(c)))
            self._n_since_ortho = 0
        self._c = c
        c00, c01, c02, c10, c11, c12, c20, c21, c22 = c
        if self.learn:
            self._learn(w_p, wz, dt)
        self.w_b_rps = (wx, wy, wz)
        return (
            c00 * fx + c01 * fy + c02 * fz,
            c10 * fx + c11 * fy + c12 * fz,
            c20 * fx + c21 * fy + c22 * fz,
        )

    def _learn(self, w_p: Float3, wz: float, dt: float) -> None:
        """Eqs. (11), (12) over ``dt``: w_p seen in the body frame, horizontal control only."""
        c = self._c
        wpb_x = c[0] * w_p[0] + c[3] * w_p[1]  # (C^T w_p)[x]
        wpb_y = c[1] * w_p[0] + c[4] * w_p[1]  # (C^T w_p)[y]
        k_g = dt / self.tau_g_s
        k_a = self.g_mps2 * wz * dt / self.omega_a_rps
        bg, ba = self._bg_rps, self._ba_mps2
        bg[0] += k_g * wpb_x
        bg[1] += k_g * wpb_y
        if self.learn_accel:
            ba[0] += k_a * wpb_x
            ba[1] += k_a * wpb_y

    # ---------------------------------------------------------------------- corrections

    def apply_control(self, duration_s: float) -> None:
        """The current control rate over ``duration_s`` at once (C and, if learning, eqs.
        11-12 with the last z rate): the rest of an epoch's correction when the next epoch
        replaces its rate before its period is over."""
        w_p = self._w_p_rps
        if not (w_p[0] or w_p[1] or w_p[2]) or duration_s <= 0.0:
            return
        d = duration_s
        self._c = dcm_mul(exp_so3_9(-w_p[0] * d, -w_p[1] * d, -w_p[2] * d), self._c)
        if self.learn:
            self._learn(w_p, self.w_b_rps[2], d)

    def correct_tilt(self, e_n_mps2: float, e_e_mps2: float) -> None:
        """Eq. (3): horizontal control rate from e = f_gnss - mean(f_p), NED, m/s^2.

        w_p = -k x e with k = [0, 0, -1/(tau g)] gives w_p = [-e_E, e_N, 0] / (tau g): a tilt
        error theta (platform vs NED) produces w_p = theta / tau, which C then removes.
        """
        kg = 1.0 / (self.tau_s * self.g_mps2)
        self._set_w_p((-e_e_mps2 * kg, e_n_mps2 * kg, self._w_p_rps[2]))

    def set_heading_rate(self, w_pz_rps: float) -> None:
        """Vertical control rate from the heading channel (yaw decreases by w_pz dt)."""
        self._set_w_p((self._w_p_rps[0], self._w_p_rps[1], w_pz_rps))

    def open_tilt_loop(self) -> None:
        """No GNSS acceleration this interval: horizontal control rate 0 (open loop)."""
        self._set_w_p((0.0, 0.0, self._w_p_rps[2]))

    def rotate_about_vertical(self, dpsi_rad: float) -> None:
        """C <- Rz(dpsi) C: a direct heading change (alignment), tilt untouched."""
        self._c = dcm_mul(exp_so3_9(0.0, 0.0, dpsi_rad), self._c)

    def rotate(self, phi_rad: Float3) -> None:
        """C <- exp([phi]x) C: a small rotation in the platform (NED) frame (a re-levelling)."""
        self._c = dcm_mul(exp_so3_9(*phi_rad), self._c)

    def set_biases(self, bg_rps: Float3, ba_mps2: Float3) -> None:
        """Both bias estimates at once (a warm start), used from the next sample on."""
        self._bg_rps = [float(bg_rps[0]), float(bg_rps[1]), float(bg_rps[2])]
        self._ba_mps2 = [float(ba_mps2[0]), float(ba_mps2[1]), float(ba_mps2[2])]

    def add_accel_bias_xy(self, dbx_mps2: float, dby_mps2: float) -> None:
        """A correction of the x/y accelerometer bias estimate (the accel-bias filter's)."""
        self._ba_mps2[0] += dbx_mps2
        self._ba_mps2[1] += dby_mps2

    def set_accel_bias_z(self, ba_z_mps2: float) -> None:
        """The z accelerometer bias estimate (the engine's height loop), used from the next
        sample on."""
        self._ba_mps2[2] = ba_z_mps2

    def set_gyro_bias_z(self, bg_z_rps: float) -> None:
        """The heading channel's z-gyro bias estimate, used from the next sample on."""
        self._bg_rps[2] = bg_z_rps

    def _set_w_p(self, w_p_rps: Float3) -> None:
        if w_p_rps != self._w_p_rps:
            self._w_p_rps = w_p_rps
            self._exp_w_p = None

    # ------------------------------------------------------------------------- read-out

    @property
    def c_bp9(self) -> Mat9:
        """C_b^p as 9 row-major floats (hot-path form)."""
        return self._c

    @property
    def c_bp(self) -> Array:
        """C_b^p, shape (3, 3)."""
        return from_mat9(self._c)

    @property
    def w_p_rps(self) -> Float3:
        """Current control rate, platform frame, rad/s."""
        return self._w_p_rps

    @property
    def bg_hat_rps(self) -> Float3:
        """Gyro bias estimate, body FRD, rad/s."""
        bg = self._bg_rps
        return (bg[0], bg[1], bg[2])

    @property
    def ba_hat_mps2(self) -> Float3:
        """Accelerometer bias estimate, body FRD, m/s^2."""
        ba = self._ba_mps2
        return (ba[0], ba[1], ba[2])
