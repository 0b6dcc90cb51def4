"""Loosely coupled GNSS/INS error-state EKF: strapdown, error propagation, measurement models.

ALGORITHMS.md 3 (seed 002, Gu et al.) in the conventions of ALGORITHMS.md: NED navigation frame
around a local origin, body FRD, g = [0, 0, +9.80665] NED, specific force f = a - g. The
nominal state is the INS solution of the **IMU point** (the point whose specific force is
measured, so no lever-arm acceleration terms enter the mechanisation); lever arms to the
antenna and to the reference point appear only in the measurement models and the read-out.

Earth rate and transport rate are dropped (seed 002's F_pp, F_vp, F_phi_p, Coriolis terms):
7.3e-5 rad/s of Earth rate is an attitude drift of 0.004 deg/s, below the ADIS16334's gyro
noise (ARW 2 deg/sqrt(h) = 0.033 deg/s over 1 s) and well below its turn-on bias (0.1 deg/s),
which the filter estimates anyway; transport rate at 5 m/s is v/R = 8e-7 rad/s; the Coriolis
acceleration 2 w_ie v = 7e-4 m/s^2 at 5 m/s is below the accelerometer bias being estimated.
Gravity is constant over a field.

Error state (20, :data:`POS` ... :data:`EPOCH`), true = nominal + error, except attitude:
C_bn_true = (I + [phi]x) C_bn, phi a small rotation in NED. Continuous error dynamics

    d(dp)/dt = dv
    d(dv)/dt = -[f_n]x phi - C_bn dba - C_bn n_a
    d(phi)/dt = -C_bn dbg - C_bn n_g
    d(dba)/dt = w_ba,   d(dbg)/dt = w_bg   (random walks: see EkfTuning)
    d(db)/dt = -db / tau_fix + w_fix       (the receiver's position error, NED)
    d(dc)/dt = w_c                         (the chassis's pitch against its track)
    d(dtau)/dt = w_tau                     (the epochs' placement on the host clock)

The states db are the error of the receiver's current position solution, first-order
Gauss-Markov (:mod:`gateway.estimation.gnss_error`): RTK float and DGNSS errors wander over
tens of seconds; taken as white, a minute of them collapsed the position variance and the
filter followed the wander. The engine restarts them when the fix quality changes. The
chassis's pitch against its track (:mod:`gateway.estimation.chassis`) is what the
non-holonomic constraint's vertical row allows: the reference point moves along the track,
which the chassis, on its tyres, may pitch against. On a host clock that does not follow UTC
the epochs are placed by their arrival less the configured receiver latency, a constant
error tau (:mod:`gateway.estimation.epoch_clock`): a fix is then the antenna where it was
tau earlier, v tau along its track. Taken as white noise, 18 ms of it went into pitch through
the 3 m mast's lever arm (a position offset along the body x axis either way), 0.17 deg off
with 0.08 stated on rough ground; as a state it is told from pitch as the speed changes.

Measurement models return a :class:`Measurement` (z, H, R) as in pyins; :func:`correct`
does the algebra for any of them (sequential, NIS gate).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from functools import cache

import numpy as np
import numpy.typing as npt

from drivers.samples import Float3
from drivers.units import GRAVITY_MPS2, wrap_pi
from gateway.estimation.attitude import (
    Mat9,
    dcm_mul,
    exp_so3_2nd,
    exp_so3_9,
    from_mat9,
    orthonormalise,
    to_mat9,
)
from gateway.estimation.chassis import CHASSIS_PITCH_SIGMA_RAD, CHASSIS_PITCH_WANDER_S
from gateway.estimation.ekf.ekf_config import EkfTuning
from gateway.estimation.lever_arm import lever_arm_position_ned, lever_arm_velocity_ned

Array = npt.NDArray[np.float64]
Floats = Sequence[float] | Array  # a 3-vector as list, tuple or array

# --- error-state layout -------------------------------------------------------------------
POS = slice(0, 3)  # position error, NED, m
VEL = slice(3, 6)  # velocity error, NED, m/s
ATT = slice(6, 9)  # attitude error phi, NED, rad
BA = slice(9, 12)  # accelerometer bias error, body, m/s^2
BG = slice(12, 15)  # gyro bias error, body, rad/s
FIX = slice(15, 18)  # error of the receiver's position solution, NED, m
CHASSIS = 18  # the chassis's pitch against its track, rad
EPOCH = 19  # the epochs' placement error on the host clock (late: positive), s
N_STATES = 20

#: Low-pass time constant of the body rate used for lever-arm velocities at the current time:
#: one sample of ARW noise is 0.5 deg/s, 2.5 cm/s at a 3 m lever arm.
RATE_LP_TAU_S = 0.05
#: Samples between re-orthonormalisations of the DCM (second-order exp drifts O(dphi^3)).
ORTHO_EVERY = 256

_I3 = np.eye(3)
_I_N = np.eye(N_STATES)


@cache
def nis_gate(gate_sigma: float, dof: int) -> float:
    """Chi-square threshold with the tail probability of a ``gate_sigma`` normal event.

    Solves Q(dof/2, x/2) = erfc(gate_sigma / sqrt 2) for x by bisection, with the closed form
    of the chi-square survival function for integer and half-integer shapes (no scipy on
    the ECU; dof 1 gives gate_sigma^2 exactly).
    """
    tail = math.erfc(gate_sigma / math.sqrt(2.0))
    lo, hi = 0.0, 1.0
    while chi2_sf(hi, dof) > tail:
        hi *= 2.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if chi2_sf(mid, dof) > tail:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def chi2_sf(x: float, dof: int) -> float:
    """P(chi-square with ``dof`` degrees of freedom > x): the regularised upper incomplete
    gamma Q(dof/2, x/2) in closed form."""
    h = 0.5 * x
    if dof % 2 == 0:
        term, total = 1.0, 1.0
        for k in range(1, dof // 2):
            term *= h / k
            total += term
        return math.exp(-h) * total
    total = math.erfc(math.sqrt(h))
    term = math.sqrt(h) / math.gamma(1.5)
    for k in range(dof // 2):
        if k:
            term *= h / (k + 0.5)
        total += math.exp(-h) * term
    return total


@dataclass(frozen=True, slots=True)
class Measurement:
    """One measurement linearised about the nominal state: z = H dx + v, v ~ N(0, R).

    ``z`` shape (m,) innovation (measured minus predicted), ``h`` shape (m, 20), ``r`` (m, m);
    ``c`` (20, m), if any, the covariance of the error state with v where v is noise the
    state's own process noise shares (the gyro's white noise in a zero-rate update).
    """

    name: str
    z: Array
    h: Array
    r: Array
    c: Array | None = None


@dataclass(frozen=True, slots=True)
class Correction:
    """Outcome of :func:`correct`: normalised innovation squared and whether it passed."""

    name: str
    nis: float
    accepted: bool


def correct(p: Array, dx: Array, m: Measurement, gate_sigma: float) -> Correction:
    """Fuse ``m`` into the error state ``dx`` (20,) and covariance ``p`` (20, 20), in place.

    Sequential form: the innovation is taken relative to the error already estimated in this
    batch (z - H dx), so several measurements of one epoch share one feedback. Rejected if
    the normalised innovation squared exceeds :func:`nis_gate`. Covariance P - K S K^T =
    P - K (P H^T)^T, symmetrised: for the optimal gain it is the Joseph form's
    (I - KH) P (I - KH)^T + K R K^T exactly, at one 18 x m x 18 product instead of two
    18 x 18 x 18 ones (the Joseph form guards a suboptimal gain, and single precision; in
    double precision P stays positive definite on every run, tests/test_engine_ekf.py).
    """
    z = m.z - m.h @ dx
    ph = p @ m.h.T
    if m.c is None:
        s_inv = inverse_small(m.h @ ph + m.r)
    else:  # correlated noise: K = (P H^T + C) S^-1, S = H P H^T + H C + C^T H^T + R
        hc = m.h @ m.c
        s_inv = inverse_small(m.h @ ph + hc + hc.T + m.r)
        ph = ph + m.c
    nis = float(z @ s_inv @ z)
    if not nis <= nis_gate(gate_sigma, len(z)):
        return Correction(m.name, nis, False)
    k = ph @ s_inv
    dx += k @ z
    set_symmetrised(p, p - k @ ph.T)
    return Correction(m.name, nis, True)


def inverse_small(s: Array) -> Array:
    """Inverse of a symmetric positive definite (m, m), m <= 3, by its adjugate in floats
    (np.linalg.inv costs 4.7 us on a 3 x 3, mostly its checks; this 1 us)."""
    n = len(s)
    if n == 1:
        return np.array([[1.0 / s.item(0, 0)]])
    if n == 2:
        a, b, d = s.item(0, 0), s.item(0, 1), s.item(1, 1)
        det = a * d - b * b
        return np.array([[d / det, -b / det], [-b / det, a / det]])
    (a, b, c), (_, d, e), (_, _, f) = s.tolist()
    i00, i01, i02 = d * f - e * e, c * e - b * f, b * e - c * d
    i11, i12, i22 = a * f - c * c, b * c - a * e, a * d - b * b
    det = a * i00 + b * i01 + c * i02
    return np.array(
        [[i00 / det, i01 / det, i02 / det], [i01 / det, i11 / det, i12 / det],
         [i02 / det, i12 / det, i22 / det]]
    )  # fmt: skip


def set_symmetrised(p: Array, p_new: Array) -> None:
    """p <- (p_new + p_new^T) / 2 in place: rounding leaves the products slightly asymmetric."""
    np.add(p_new, p_new.T, out=p)
    p *= 0.5


# --- strapdown mechanisation ---------------------------------------------------------------


class Strapdown:
    """INS nominal state of the IMU point and the IMU-interval sums that drive :func:`predict`.

    Per sample (:meth:`propagate`, plain floats: this is the per-sample hot path): bias-
    corrected rate and specific force, velocity increment rotated to NED with the first-order
    rotation correction C (dv_b + dtheta x dv_b / 2), trapezoidal position, DCM update by the
    second-order exponential, periodic re-orthonormalisation.
    """

    def __init__(
        self,
        c_bn: npt.ArrayLike,
        p_ned_m: Sequence[float] = (0.0, 0.0, 0.0),
        v_ned_mps: Sequence[float] = (0.0, 0.0, 0.0),
    ) -> None:
        self.c_bn9: Mat9 = to_mat9(c_bn)
        self.p_ned_m = [float(x) for x in p_ned_m]
        self.v_ned_mps = [float(x) for x in v_ned_mps]
        self.bias_a_mps2 = [0.0, 0.0, 0.0]  # body FRD
        self.bias_g_rps = [0.0, 0.0, 0.0]  # body FRD
        self.w_b_rps = (0.0, 0.0, 0.0)  # last bias-corrected body rate
        self.w_b_lp_rps = (0.0, 0.0, 0.0)  # the same low-passed (RATE_LP_TAU_S): lever arms
        self._n = 0
        # sums over the current covariance interval
        self.sum_dt_s = 0.0
        self.sum_dv_ned_mps = [0.0, 0.0, 0.0]  # integral of f_n dt
        self.sum_c_dt = [0.0] * 9  # integral of C_bn dt, row major

    @property
    def c_bn(self) -> Array:
        """C_b^n, shape (3, 3)."""
        return from_mat9(self.c_bn9)

    def propagate(self, w_ib_b: Floats, f_ib_b: Floats, dt: float) -> None:
        """Advance the nominal state by one IMU sample (rates rad/s, specific force m/s^2)."""
        bg, ba = self.bias_g_rps, self.bias_a_mps2
        wx, wy, wz = w_ib_b[0] - bg[0], w_ib_b[1] - bg[1], w_ib_b[2] - bg[2]
        fx, fy, fz = f_ib_b[0] - ba[0], f_ib_b[1] - ba[1], f_ib_b[2] - ba[2]
        self.w_b_rps = (wx, wy, wz)
        a = dt / (RATE_LP_TAU_S + dt)
        lx, ly, lz = self.w_b_lp_rps
        self.w_b_lp_rps = (lx + a * (wx - lx), ly + a * (wy - ly), lz + a * (wz - lz))
        ax, ay, az = wx * dt, wy * dt, wz * dt
        dvx = (fx + 0.5 * (ay * fz - az * fy)) * dt
        dvy = (fy + 0.5 * (az * fx - ax * fz)) * dt
        dvz = (fz + 0.5 * (ax * fy - ay * fx)) * dt
        c = self.c_bn9
        c00, c01, c02, c10, c11, c12, c20, c21, c22 = c
        dvn = c00 * dvx + c01 * dvy + c02 * dvz
        dve = c10 * dvx + c11 * dvy + c12 * dvz
        dvd = c20 * dvx + c21 * dvy + c22 * dvz
        v, p = self.v_ned_mps, self.p_ned_m
        vn0, ve0, vd0 = v
        vn, ve, vd = vn0 + dvn, ve0 + dve, vd0 + dvd + GRAVITY_MPS2 * dt
        self.v_ned_mps = [vn, ve, vd]
        self.p_ned_m = [
            p[0] + 0.5 * (vn0 + vn) * dt,
            p[1] + 0.5 * (ve0 + ve) * dt,
            p[2] + 0.5 * (vd0 + vd) * dt,
        ]
        s = self.sum_dv_ned_mps
        self.sum_dv_ned_mps = [s[0] + dvn, s[1] + dve, s[2] + dvd]
        sc = self.sum_c_dt
        self.sum_c_dt = [
            sc[0] + c00 * dt, sc[1] + c01 * dt, sc[2] + c02 * dt,
            sc[3] + c10 * dt, sc[4] + c11 * dt, sc[5] + c12 * dt,
            sc[6] + c20 * dt, sc[7] + c21 * dt, sc[8] + c22 * dt,
        ]  # fmt: skip
        self.sum_dt_s += dt
        c = dcm_mul(c, exp_so3_2nd(ax, ay, az))
        self._n += 1
        if self._n % ORTHO_EVERY == 0:
            c = to_mat9(orthonormalise(from_mat9(c)))
        self.c_bn9 = c

    def take_interval(self) -> tuple[float, Array, Array]:
        """(T, integral of f_n dt (3,), integral of C_bn dt (3, 3)) since the last call."""
        out = (self.sum_dt_s, np.array(self.sum_dv_ned_mps), np.array(self.sum_c_dt).reshape(3, 3))
        self.sum_dt_s = 0.0
        self.sum_dv_ned_mps = [0.0, 0.0, 0.0]
        self.sum_c_dt = [0.0] * 9
        return out

    def inject(self, dx: Array, age_s: float = 0.0) -> Mat9:
        """Closed-loop feedback of the error estimate ``dx`` (20,) of a time ``age_s`` ago;
        returns the rotation.

        Position, velocity and biases add, the position with the velocity error's drift
        since (dv age_s); attitude is reset by the small rotation C <- exp([phi]x) C. The
        error state is then zero by definition (the caller drops dx); the reset Jacobian
        I - [phi/2]x of the covariance is taken as I (phi ~ mrad). In floats: four times a
        second or more, numpy's per-call cost was half of it.
        """
        d = dx.tolist()
        p, v, ba, bg = self.p_ned_m, self.v_ned_mps, self.bias_a_mps2, self.bias_g_rps
        for i in range(3):
            p[i] += d[i] + d[3 + i] * age_s
            v[i] += d[3 + i]
            ba[i] += d[9 + i]
            bg[i] += d[12 + i]
        rot9 = exp_so3_9(d[6], d[7], d[8])
        self.c_bn9 = dcm_mul(rot9, self.c_bn9)
        return rot9

    def rotate(self, rot: Array) -> None:
        """Turn the attitude by ``rot`` (3, 3) in NED: C <- rot C (alignment of heading)."""
        self.c_bn9 = to_mat9(rot @ self.c_bn)


# --- error-state propagation ---------------------------------------------------------------


def _flat(rows: slice, cols: slice) -> npt.NDArray[np.intp]:
    """Flat indices of the block (rows, cols) of an (20, 20) matrix."""
    return np.arange(N_STATES * N_STATES).reshape(N_STATES, N_STATES)[rows, cols]


#: Phi's blocks as :func:`transition_matrix` writes them: (p, phi), (v, phi), (p, ba),
#: (v, ba), (phi, bg), (p, bg), (v, bg); then the diagonals T I (p, v) and fix_decay I.
_PHI_BLOCKS = np.array(
    [_flat(POS, ATT), _flat(VEL, ATT), _flat(POS, BA), _flat(VEL, BA), _flat(ATT, BG),
     _flat(POS, BG), _flat(VEL, BG)]
)  # fmt: skip
_PHI_T = np.diagonal(_flat(POS, VEL)).copy()
_PHI_FIX = np.diagonal(_flat(FIX, FIX)).copy()


def transition_matrix(
    t_s: float, dv_f_ned_mps: Array, c_dt: Array, fix_decay: float = 1.0
) -> Array:
    """Phi (20, 20) over an interval T from the IMU sums of :meth:`Strapdown.take_interval`.

    A = F T with F averaged over the interval (f_n T = integral f_n dt, C T = integral C dt);
    A^4 = 0 (the chain bg -> phi -> v -> p is three long), so I + A + A^2/2 + A^3/6 is
    exp(A) exactly for the averaged F. Averaging F over a GNSS epoch interval (0.1 s at
    10 Hz, at most ``covariance_period_s``) instead of stepping it at every sample is checked
    in tests/test_ekf.py and by the `ekf-cov-every-sample` engine of benchmarks/accuracy.py.
    The fix-error states are uncoupled: they decay by ``fix_decay``, exp(-T / tau_fix).

    The blocks of the series, written out (with Fv = -[f_n T]x, G = -C T):
    I + A: T I (p, v), Fv (v, phi), G (v, ba), G (phi, bg); A^2 / 2: T Fv / 2 (p, phi),
    T G / 2 (p, ba), Fv G / 2 (v, bg); A^3 / 6: T Fv G / 6 (p, bg).
    """
    x, y, z = dv_f_ned_mps.tolist()
    fv = np.array(((0.0, z, -y), (-z, 0.0, x), (y, -x, 0.0)))  # -[f_n T]x
    g = -c_dt
    fv_g = fv @ g
    blocks = np.array((fv, fv, g, g, g, fv_g, fv_g))
    half_t = 0.5 * t_s
    blocks *= np.array((half_t, 1.0, half_t, 1.0, 1.0, t_s / 6.0, 0.5))[:, None, None]
    phi = _I_N.copy()
    phi.put(_PHI_BLOCKS, blocks)  # (one call for seven 3 x 3 blocks: 8 us -> 6.5 a step)
    phi.put(_PHI_T, t_s)
    phi.put(_PHI_FIX, fix_decay)
    return phi


def process_noise_psd(tuning: EkfTuning) -> Array:
    """Diagonal continuous process noise Q_c (20,) of the error state.

    White accel/gyro noise enters dv and phi through C_bn; being isotropic, C q I C^T = q I.
    The fix-error and epoch states' driving noise depends on the fix and the host clock: the
    engine sets it per epoch.
    """
    q = np.zeros(N_STATES)
    q[VEL] = tuning.q_accel_m2_per_s3
    q[ATT] = tuning.q_gyro_rad2_per_s
    q[BA] = tuning.q_bias_a_m2_per_s5
    q[BG] = tuning.q_bias_g_rad2_per_s3
    q[CHASSIS] = CHASSIS_PITCH_SIGMA_RAD**2 / CHASSIS_PITCH_WANDER_S
    return q


def predict(p: Array, phi: Array, q_c: Array, t_s: float) -> None:
    """P <- Phi P Phi^T + Q_d in place, Q_d = (Phi Q_c Phi^T + Q_c) T / 2 (trapezoid),
    computed as Phi (P + Q_c T / 2) Phi^T + Q_c T / 2 (the same, two products fewer)."""
    half_q = (0.5 * t_s) * q_c
    p.ravel()[:: N_STATES + 1] += half_q  # the diagonal (P is C-contiguous: a view)
    p_new = phi @ p @ phi.T
    p_new.ravel()[:: N_STATES + 1] += half_q
    set_symmetrised(p, p_new)


# --- measurement models --------------------------------------------------------------------
# Built from floats (once or twice an epoch each): numpy's per-call cost for 3-vectors was
# 8-11 us a model. Their Jacobians are checked against finite differences in tests/test_ekf.py.

_H_POSITION = np.zeros((3, N_STATES))
_H_POSITION[:, POS] = _I3
_H_POSITION[:, FIX] = _I3
_H_VELOCITY = np.zeros((3, N_STATES))
_H_VELOCITY[:, VEL] = _I3


def _minus_skew(x: float, y: float, z: float) -> tuple[Float3, Float3, Float3]:
    """-[v]x as rows, v = (x, y, z)."""
    return (0.0, z, -y), (-z, 0.0, x), (y, -x, 0.0)


def fuse_position(
    p_ned_m: Array,
    c_bn: Array,
    l_ant_b: Array,
    p_ant_meas_ned_m: Array,
    white_sigma_ned_m: Array,
    fix_error_ned_m: Array,
    v_ant_ned_mps: Array,
) -> Measurement:
    """Antenna position as the receiver reports it: p + C l + b, l = antenna relative to the
    IMU (body, m), b the receiver's position error (its wander; ``white_sigma_ned_m`` the
    rest), at the epoch's time as placed (the EPOCH estimate taken out): an error dtau
    there (s, late: positive) is the antenna's velocity ``v_ant_ned_mps`` times it back.

    Shapes (3,) except ``c_bn`` (3, 3). dz = dp - [C l]x phi + db - v_ant dtau.
    """
    cl_n, cl_e, cl_d = lever_arm_position_ned(to_mat9(c_bn), l_ant_b.tolist())
    h = _H_POSITION.copy()
    h[:, ATT] = _minus_skew(cl_n, cl_e, cl_d)
    vn, ve, vd = v_ant_ned_mps.tolist()
    h[:, EPOCH] = (-vn, -ve, -vd)
    (pn, pe, pd), (mn, me, md) = p_ned_m.tolist(), p_ant_meas_ned_m.tolist()
    bn, be, bd = fix_error_ned_m.tolist()
    z = np.array((mn - (pn + cl_n + bn), me - (pe + cl_e + be), md - (pd + cl_d + bd)))
    sn, se, sd = white_sigma_ned_m.tolist()
    r = np.array(((sn * sn, 0.0, 0.0), (0.0, se * se, 0.0), (0.0, 0.0, sd * sd)))
    return Measurement("position", z, h, r)


def fuse_velocity(
    v_ned_mps: Array,
    c_bn: Array,
    w_b_rps: Array,
    l_ant_b: Array,
    v_ant_meas_ne_mps: Array,
    sigma_mps: float,
    a_ant_ned_mps2: Array | None = None,
) -> Measurement:
    """Antenna horizontal velocity (north, east) from SOG/COG: v_ant = v + C (w x l).

    NMEA RMC/VTG carry no vertical velocity; the vertical channel is observed through height.
    dv_ant = dv - [C (w x l)]x phi + C [l]x dbg (the rate error is -dbg) - a_ant dtau: the
    velocity of the epoch's time as placed, the antenna's acceleration ``a_ant_ned_mps2``
    times its error back (as :func:`fuse_position`'s; None: no EPOCH column).
    ``v_ant_meas_ne_mps`` shape (2,).
    """
    c9 = to_mat9(c_bn)
    c0, c1, c2, c3, c4, c5, c6, c7, c8 = c9
    lx, ly, lz = l_ant_b.tolist()
    vl_n, vl_e, vl_d = lever_arm_velocity_ned(c9, w_b_rps.tolist(), (lx, ly, lz))
    h = _H_VELOCITY.copy()
    h[:, ATT] = _minus_skew(vl_n, vl_e, vl_d)
    # C [l]x, row i: (c_i1 lz - c_i2 ly, c_i2 lx - c_i0 lz, c_i0 ly - c_i1 lx)
    h[:, BG] = (
        (c1 * lz - c2 * ly, c2 * lx - c0 * lz, c0 * ly - c1 * lx),
        (c4 * lz - c5 * ly, c5 * lx - c3 * lz, c3 * ly - c4 * lx),
        (c7 * lz - c8 * ly, c8 * lx - c6 * lz, c6 * ly - c7 * lx),
    )
    if a_ant_ned_mps2 is not None:
        an, ae, ad = a_ant_ned_mps2.tolist()
        h[:, EPOCH] = (-an, -ae, -ad)
    vn, ve, _ = v_ned_mps.tolist()
    mn, me = v_ant_meas_ne_mps.tolist()
    z = np.array((mn - (vn + vl_n), me - (ve + vl_e)))
    var = sigma_mps * sigma_mps
    return Measurement("velocity", z, h[:2], np.array(((var, 0.0), (0.0, var))))


def fuse_nonholonomic(
    v_ned_mps: Array,
    c_bn: Array,
    w_b_rps: Array,
    l_ref_b: Array,
    sigma_mps: float,
    chassis_pitch_rad: float = 0.0,
) -> Measurement:
    """Zero lateral body velocity of the reference point (land vehicle), and vertical but
    for the chassis's pitch c against its track: v_z = v_x c.

    v_ref_b = C^T v + w x l, l = reference point relative to the IMU (body). Holds driving
    forwards, reversing (only the longitudinal component changes sign) and at rest.
    d(v_ref_b) = C^T dv + C^T [v]x phi + [l]x dbg; d(v_z - v_x c) adds -v_x dc (v_x c's
    own dependence on dv and phi is second order).
    """
    c0, c1, c2, c3, c4, c5, c6, c7, c8 = c_bn.ravel().tolist()
    vn, ve, vd = v_ned_mps.tolist()
    wx, wy, wz = w_b_rps.tolist()
    lx, ly, lz = l_ref_b.tolist()
    h = np.zeros((2, N_STATES))
    # rows y and z of C^T, of C^T [v]x (row i: column i of C times [v]x) and of [l]x
    h[:, VEL] = ((c1, c4, c7), (c2, c5, c8))
    h[:, ATT] = (
        (c4 * vd - c7 * ve, c7 * vn - c1 * vd, c1 * ve - c4 * vn),
        (c5 * vd - c8 * ve, c8 * vn - c2 * vd, c2 * ve - c5 * vn),
    )
    h[:, BG] = ((lz, 0.0, -lx), (-ly, lx, 0.0))
    v_x = c0 * vn + c3 * ve + c6 * vd + (wy * lz - wz * ly)
    h[1, CHASSIS] = -v_x
    v_y = c1 * vn + c4 * ve + c7 * vd + (wz * lx - wx * lz)
    v_z = c2 * vn + c5 * ve + c8 * vd + (wx * ly - wy * lx) - v_x * chassis_pitch_rad
    var = sigma_mps * sigma_mps
    return Measurement(
        "nonholonomic", np.array((-v_y, -v_z)), h, np.array(((var, 0.0), (0.0, var)))
    )


def heading_weights(c00: float, c10: float, c20: float) -> tuple[float, float]:
    """(h_N, h_E) of the true heading yaw = atan2(C10, C00) (body x's azimuth) against the
    attitude error: d(yaw) = phi_D + h_N phi_N + h_E phi_E, h = -C20 (C00, C10) / (C00^2 +
    C10^2). Plain floats: the engine takes it per epoch and per solution."""
    d = c00 * c00 + c10 * c10
    return -c20 * c00 / d, -c20 * c10 / d


def heading_row(c_bn: Array) -> Array:
    """H (1, N_STATES) of the true heading (:func:`heading_weights`)."""
    h = np.zeros((1, N_STATES))
    h_n, h_e = heading_weights(float(c_bn[0, 0]), float(c_bn[1, 0]), float(c_bn[2, 0]))
    h[0, ATT] = (h_n, h_e, 1.0)
    return h


def fuse_heading(c_bn: Array, heading_meas_rad: float, sigma_rad: float) -> Measurement:
    """True heading (HDT, dual antenna along body x), :func:`heading_row`."""
    z = np.array([wrap_pi(heading_meas_rad - math.atan2(float(c_bn[1, 0]), float(c_bn[0, 0])))])
    return Measurement("heading", z, heading_row(c_bn), np.array([[sigma_rad**2]]))


def fuse_zero_rate(
    c_bn: Array, mean_w_z_rps: float, span_s: float, q_gyro_rad2_per_s: float
) -> Measurement:
    """Zero-rate update at rest: the mean bias-corrected body z rate over the last
    ``span_s`` is the z-gyro bias error (measured b - estimated b) plus the mean of the
    gyro's white noise n over the span, variance q_gyro / span (Earth's rate is in the bias
    as it is while driving).

    That noise also turned the attitude error by -C n T over the span (phi' = -C db - C n),
    which P holds as process noise: their covariance, -q_gyro times C's z column, goes in
    as ``c``. So the update takes out the heading's drift of the stop, random walk and bias
    error alike (the vehicle has not turned), and P's heading variance the random walk's
    share with it. Without the update a stop left the z bias unobserved: the heading 4 deg
    off after 10 minutes (NAVIGATING); with it but as independent noise, held within
    0.2 deg while P's 1-sigma grew to 1.1 deg.
    """
    h = np.zeros((1, N_STATES))
    h[0, BG.start + 2] = 1.0
    c = np.zeros((N_STATES, 1))
    c[ATT, 0] = -q_gyro_rad2_per_s * c_bn[:, 2]
    r = np.array([[q_gyro_rad2_per_s / span_s]])
    return Measurement("zero rate", np.array([mean_w_z_rps]), h, r, c)


def attitude_error(c_bn_true: Array, c_bn_est: Array) -> Array:
    """phi (3,) with C_true = exp([phi]x) C_est: the filter's attitude error convention."""
    d = c_bn_true @ c_bn_est.T
    angle = math.acos(max(-1.0, min(1.0, 0.5 * (float(np.trace(d)) - 1.0))))
    axis = np.array([d[2, 1] - d[1, 2], d[0, 2] - d[2, 0], d[1, 0] - d[0, 1]])
    s = math.sin(angle)
    return 0.5 * axis if s < 1e-9 else 0.5 * angle / s * axis
