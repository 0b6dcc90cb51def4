"""Farm-field vehicle truth: swaths, headland turns, reversing and stops on tilted, bumpy terrain.

The path is planned in the horizontal plane as pieces along the travelled distance U (m):
straight swaths, quarter turns whose curvature rises and falls with a smooth cosine ramp (a
clothoid-like transition, so yaw rate and yaw acceleration are continuous), headland straights
and reversing straights. Heading psi(U) is exact; the horizontal position is integrated along U
by fourth-order Hermite quadrature and interpolated with the same cubic. The speed profile U(t)
is a sequence of rests, cruises and speed ramps whose acceleration is a sin^2 pulse (peak =
``accel_max_mps2``, continuous jerk). Height, roll and pitch follow the analytic terrain of
:mod:`sim_bus.terrain` under the reference point (body z along the terrain normal, body x the
heading projected onto the terrain), then pitched about its own y axis by the chassis's pitch
on its tyres against the ground (``chassis_pitch_deg``, and ``implement_lift_deg`` more over
each headland: a rear implement lifted as the pass ends and lowered as the next begins, over
``implement_lift_s``); the reference point's track is the terrain's.
Velocity, acceleration, body rate and its derivative come from the chain rule with exact
terrain derivatives, so the truth is self-consistent to rounding.

Frames: NED navigation frame, body FRD, attitude ZYX roll/pitch/yaw with yaw from true north,
g = [0, 0, +9.80665] m/s^2 in NED, specific force f = a - g. While reversing, the body keeps its
heading and the velocity points along -x_b.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Literal

import numpy as np
import numpy.typing as npt

from gateway.estimation.attitude import dcm_from_rpy_array
from gateway.estimation.geodesy import ned_to_lla
from sim_bus.terrain import Terrain, random_bumps
from sim_bus.truth import Truth

Array = npt.NDArray[np.float64]

G_NED_MPS2 = np.array([0.0, 0.0, 9.80665])
IMU_PERIOD_S = 4.0 / 819.2  # ADIS16334 at DEC = 2: 204.8 Hz
_NODE_SPACING_M = 0.05  # Hermite position nodes along the path: error ~1e-10 m


@dataclass(frozen=True)
class VehicleConfig:
    """Field run and terrain. Angles in degrees at this edge, everything else SI.

    Passes are straight swaths of ``swath_length_m``, the first heading ``swath_heading_deg``
    (from true north, clockwise), the next ones alternately opposite and offset
    ``swath_spacing_m`` to the side of ``first_turn``; the headland turns therefore alternate
    right and left. A headland turn is two quarter turns (``turn_radius_m``, curvature ramps of
    ``turn_transition_m``) joined by a straight; when the spacing is narrower than the two
    quarter turns, or ``reverse_at_headland`` is set, the joining piece is a fishtail: drive on
    ``reverse_length_m`` past, stop, reverse, stop, then turn into the next swath.

    The side slope is the terrain's cross-track gradient (right of ``swath_heading_deg`` up
    positive); it varies between its minimum and maximum over ``side_slope_wavelength_m``
    across the field. As on a real hillside, passes driven in opposite directions see it on
    opposite sides, so the roll sign alternates from pass to pass (a min/max of opposite signs
    makes a ridge or valley instead). ``seed`` of :func:`simulate_vehicle` draws the bumps.
    """

    origin_lla: tuple[float, float, float] = (52.2, 10.5, 80.0)  # deg, deg, m (ellipsoidal)
    swath_heading_deg: float = 0.0
    swath_length_m: float = 200.0
    swath_spacing_m: float = 18.0
    n_passes: int = 6
    work_speeds_mps: tuple[float, ...] = (3.0,)  # per pass, repeated cyclically
    first_turn: Literal["right", "left"] = "right"
    turn_radius_m: float = 6.0
    turn_transition_m: float = 3.0  # length of each curvature ramp of a quarter turn
    turn_speed_mps: float = 2.0
    reverse_at_headland: bool = False
    reverse_length_m: float = 3.0  # forward overshoot before reversing, m
    reverse_speed_mps: float = 1.0
    reverse_stop_s: float = 2.0  # rest before and after reversing
    accel_max_mps2: float = 0.8  # peak of every speed ramp
    start_stop_s: float = 40.0  # rest at the start (alignment)
    mid_stop_pass: int | None = None  # pass index with a rest half-way along it
    mid_stop_s: float = 0.0
    end_stop_s: float = 5.0
    side_slope_min_deg: float = 2.0
    side_slope_max_deg: float = 4.0
    side_slope_wavelength_m: float = 150.0
    along_slope_deg: float = 0.0  # along the first swath heading, uphill positive
    bump_amplitude_m: float = 0.01  # per plane wave; rms height = amplitude * sqrt(count / 2)
    bump_wavelength_min_m: float = 4.0
    bump_wavelength_max_m: float = 12.0
    bump_count: int = 8
    antenna_lever_arm_m: tuple[float, float, float] = (0.3, 0.0, -3.0)  # body FRD
    imu_lever_arm_m: tuple[float, float, float] = (0.5, 0.1, -1.0)  # body FRD
    chassis_pitch_deg: float = 0.0  # the chassis's pitch against its track, nose up, working
    implement_lift_deg: float = 0.0  # ... and more with the implement lifted at headlands
    implement_lift_s: float = 2.0  # the hitch's lift or lowering
    # The ground of another run (a restart where that run stopped: sim_bus.scenarios.
    # continuation): its terrain's swath heading and bump seed (None: this run's own), and
    # where this run's origin lies in that terrain's frame (north, east, m).
    terrain_heading_deg: float | None = None
    terrain_seed: int | None = None
    terrain_origin_ne_m: tuple[float, float] = (0.0, 0.0)

    def terrain(self, seed: int) -> Terrain:
        """The terrain of this field; ``seed`` draws the bumps (unless ``terrain_seed``)."""
        amp, k, phase = random_bumps(
            self.bump_amplitude_m,
            self.bump_wavelength_min_m,
            self.bump_wavelength_max_m,
            self.bump_count,
            seed if self.terrain_seed is None else self.terrain_seed,
        )
        heading_deg = self.swath_heading_deg
        if self.terrain_heading_deg is not None:
            heading_deg = self.terrain_heading_deg
        return Terrain(
            swath_heading_rad=math.radians(heading_deg),
            side_grad_min=math.tan(math.radians(self.side_slope_min_deg)),
            side_grad_max=math.tan(math.radians(self.side_slope_max_deg)),
            side_wavelength_m=self.side_slope_wavelength_m,
            along_grad=math.tan(math.radians(self.along_slope_deg)),
            bump_amplitude_m=amp,
            bump_wavenumber_rad_per_m=k,
            bump_phase_rad=phase,
        )


@dataclass(frozen=True)
class _Piece:
    """Path piece: curvature goes from kappa0 to kappa1 (1/m, right turn positive) by a cosine
    ramp over length_m (constant if equal), driven at speed_mps, direction +1 forward or -1
    reverse; stop_after_s: rest after the piece (None: drive on)."""

    length_m: float
    kappa0_per_m: float
    kappa1_per_m: float
    speed_mps: float
    direction: int = 1
    stop_after_s: float | None = None
    work: bool = False  # a pass (the implement down), not a headland piece

    def heading(self, u: Array) -> tuple[Array, Array, Array]:
        """Heading change psi - psi_start (rad), curvature (1/m), dcurvature/du (1/m^2) at u."""
        return _ramp(u, self.length_m, self.kappa0_per_m, self.kappa1_per_m)


def _ramp(
    u: Array, length: Array | float, k0: Array | float, k1: Array | float
) -> tuple[Array, Array, Array]:
    """Cosine curvature ramp k0 -> k1 over length: heading change, curvature, its derivative."""
    dk = np.subtract(k1, k0)
    x = np.pi * u / length
    psi = k0 * u + dk * (0.5 * u - length / (2.0 * np.pi) * np.sin(x))
    return (
        psi,
        k0 + 0.5 * dk * (1.0 - np.cos(x)),
        dk * np.pi / (2.0 * np.asarray(length)) * np.sin(x),
    )


def _quarter_turn(cfg: VehicleConfig, sign: float) -> list[_Piece]:
    """A 90 degree turn (sign +1 right, -1 left): ramp in, arc, ramp out, at turn speed."""
    kappa = sign / cfg.turn_radius_m
    arc_m = 0.5 * np.pi * cfg.turn_radius_m - cfg.turn_transition_m
    if arc_m <= 0.0 or cfg.turn_transition_m <= 0.0:
        raise ValueError(
            f"turn_transition_m={cfg.turn_transition_m} must be in (0, pi/2 * turn_radius_m)"
        )
    v = cfg.turn_speed_mps
    return [
        _Piece(cfg.turn_transition_m, 0.0, kappa, v),
        _Piece(arc_m, kappa, kappa, v),
        _Piece(cfg.turn_transition_m, kappa, 0.0, v),
    ]


def _quarter_turn_offset_m(cfg: VehicleConfig) -> float:
    """Sideways displacement of a quarter turn (equal to its forward one by symmetry)."""
    return float(_Path.build(_quarter_turn(cfg, 1.0), 0.0).node_p_m[-1, 1])


def _plan_pieces(cfg: VehicleConfig) -> list[_Piece]:
    """Passes and headland turns as one list of pieces, stops marked on the piece before."""
    if cfg.n_passes < 1:
        raise ValueError(f"n_passes={cfg.n_passes}, expected at least 1")
    gap_m = cfg.swath_spacing_m - 2.0 * _quarter_turn_offset_m(cfg)
    reversing = cfg.reverse_at_headland or gap_m < 0.0
    if reversing and cfg.reverse_length_m <= 0.0:
        raise ValueError(f"reverse_length_m={cfg.reverse_length_m}, expected > 0 when reversing")
    first_sign = 1.0 if cfg.first_turn == "right" else -1.0
    pieces: list[_Piece] = []
    for k in range(cfg.n_passes):
        v = cfg.work_speeds_mps[k % len(cfg.work_speeds_mps)]
        if k == cfg.mid_stop_pass:
            half = 0.5 * cfg.swath_length_m
            pieces += [_Piece(half, 0.0, 0.0, v, stop_after_s=cfg.mid_stop_s, work=True)]
            pieces += [_Piece(half, 0.0, 0.0, v, work=True)]
        else:
            pieces.append(_Piece(cfg.swath_length_m, 0.0, 0.0, v, work=True))
        if k == cfg.n_passes - 1:
            break
        sign = first_sign * (-1.0) ** k
        pieces += _quarter_turn(cfg, sign)
        if reversing:
            forward_m = max(gap_m, 0.0) + cfg.reverse_length_m
            v_turn, v_rev, rest = cfg.turn_speed_mps, cfg.reverse_speed_mps, cfg.reverse_stop_s
            pieces.append(_Piece(forward_m, 0.0, 0.0, v_turn, stop_after_s=rest))
            pieces.append(_Piece(forward_m - gap_m, 0.0, 0.0, v_rev, -1, stop_after_s=rest))
        elif gap_m > 0.0:
            pieces.append(_Piece(gap_m, 0.0, 0.0, cfg.turn_speed_mps))
        pieces += _quarter_turn(cfg, sign)
    pieces[-1] = replace(pieces[-1], stop_after_s=cfg.end_stop_s)
    return pieces


@dataclass(frozen=True)
class _Phases:
    """Speed profile as consecutive phases: start time s, duration s, start distance m, start
    speed m/s, speed change m/s (sin^2 acceleration pulse), rest flag; arrays (n_phases,)."""

    t_start_s: Array
    duration_s: Array
    u_start_m: Array
    v0_mps: Array
    dv_mps: Array
    at_rest: npt.NDArray[np.bool_]

    def evaluate(self, t_s: Array) -> tuple[Array, Array, Array, npt.NDArray[np.bool_]]:
        """Distance U (m), speed dU/dt (m/s), acceleration (m/s^2) and rest flag at times t_s."""
        i = np.clip(np.searchsorted(self.t_start_s, t_s, side="right") - 1, 0, len(self.v0_mps) - 1)
        T, v0, dv = self.duration_s[i], self.v0_mps[i], self.dv_mps[i]
        tau = np.clip(t_s - self.t_start_s[i], 0.0, T)
        x = 2.0 * np.pi * tau / T
        u = (
            self.u_start_m[i]
            + v0 * tau
            + dv * (tau**2 / (2.0 * T) + T * (np.cos(x) - 1.0) / (4.0 * np.pi**2))
        )
        return (
            u,
            v0 + dv * (tau / T - np.sin(x) / (2.0 * np.pi)),
            dv / T * (1.0 - np.cos(x)),
            self.at_rest[i],
        )


def _speed_phases(cfg: VehicleConfig, pieces: list[_Piece]) -> _Phases:
    """Rests, cruises and ramps; a speed change happens inside the faster of two neighbours."""
    rows: list[tuple[float, float, float, bool]] = []  # duration, v0, dv, at rest
    if cfg.start_stop_s > 0.0:
        rows.append((cfg.start_stop_s, 0.0, 0.0, True))
    leg: list[_Piece] = []
    for piece in pieces:
        leg.append(piece)
        if piece.stop_after_s is None:
            continue
        spans: list[list[float]] = []  # [length, speed] with equal speeds merged
        for p in leg:
            if spans and spans[-1][1] == p.speed_mps:
                spans[-1][0] += p.length_m
            else:
                spans.append([p.length_m, p.speed_mps])
        speeds = [0.0] + [s[1] for s in spans] + [0.0]
        for j, (length, v) in enumerate(spans):
            v_prev, v_next = speeds[j], speeds[j + 2]
            ramp_in = 2.0 * (v - v_prev) / cfg.accel_max_mps2 if v > v_prev else 0.0
            ramp_out = 2.0 * (v - v_next) / cfg.accel_max_mps2 if v > v_next else 0.0
            cruise_m = length - 0.5 * (v + v_prev) * ramp_in - 0.5 * (v + v_next) * ramp_out
            if cruise_m < 0.0:
                raise ValueError(
                    f"a {length:.1f} m stretch at {v} m/s is too short for its speed ramps "
                    f"at accel_max_mps2={cfg.accel_max_mps2}; lengthen it or lower the speed"
                )
            rows += [(ramp_in, v_prev, v - v_prev, False), (cruise_m / v, v, 0.0, False)]
            rows.append((ramp_out, v, v_next - v, False))
        rows.append((piece.stop_after_s, 0.0, 0.0, True))
        leg = []
    rows = [r for r in rows if r[0] > 1e-9]
    duration = np.array([r[0] for r in rows])
    v0 = np.array([r[1] for r in rows])
    dv = np.array([r[2] for r in rows])
    distance = v0 * duration + 0.5 * dv * duration
    return _Phases(
        t_start_s=np.concatenate(([0.0], np.cumsum(duration)[:-1])),
        duration_s=duration,
        u_start_m=np.concatenate(([0.0], np.cumsum(distance)[:-1])),
        v0_mps=v0,
        dv_mps=dv,
        at_rest=np.array([r[3] for r in rows]),
    )


@dataclass(frozen=True)
class _Path:
    """Horizontal path along the travelled distance U: pieces and Hermite position nodes.

    Each Hermite interval lies inside one piece, so a reversing cusp (where dp/dU flips sign)
    is a node and never interpolated across.
    """

    pieces: list[_Piece]
    u_start_m: Array  # (n_pieces,)
    psi_start_rad: Array  # (n_pieces,)
    node_u_m: Array  # (n_intervals,) left end of each interval
    node_h_m: Array  # (n_intervals,)
    node_p_m: Array  # (n_intervals + 1, 2) north, east at the interval ends
    node_dp: Array  # (n_intervals, 2, 2) dp/dU at the left and right end, per interval

    @classmethod
    def build(cls, pieces: list[_Piece], psi0_rad: float) -> _Path:
        """Integrate dp/dU = direction (cos psi, sin psi) by corrected trapezoids (4th order)."""
        lengths = np.array([p.length_m for p in pieces])
        turns = np.array([0.5 * (p.kappa0_per_m + p.kappa1_per_m) * p.length_m for p in pieces])
        u_start = np.concatenate(([0.0], np.cumsum(lengths)[:-1]))
        psi_start = psi0_rad + np.concatenate(([0.0], np.cumsum(turns)[:-1]))
        u_left, h, dp_ends, dp2_ends = [], [], [], []
        for p, u0, psi0 in zip(pieces, u_start, psi_start, strict=True):
            u = np.linspace(0.0, p.length_m, max(2, math.ceil(p.length_m / _NODE_SPACING_M) + 1))
            dpsi, kappa, _ = p.heading(u)
            psi = psi0 + dpsi
            tangent = p.direction * np.stack((np.cos(psi), np.sin(psi)), axis=1)
            normal = p.direction * kappa[:, None] * np.stack((-np.sin(psi), np.cos(psi)), axis=1)
            u_left.append(u0 + u[:-1])
            h.append(np.diff(u))
            dp_ends.append(np.stack((tangent[:-1], tangent[1:]), axis=1))
            dp2_ends.append(np.stack((normal[:-1], normal[1:]), axis=1))
        hh = np.concatenate(h)[:, None]
        dp, dp2 = np.concatenate(dp_ends), np.concatenate(dp2_ends)
        step = 0.5 * hh * (dp[:, 0] + dp[:, 1]) + hh**2 / 12.0 * (dp2[:, 0] - dp2[:, 1])
        nodes = np.concatenate((np.zeros((1, 2)), np.cumsum(step, axis=0)))
        return cls(pieces, u_start, psi_start, np.concatenate(u_left), hh[:, 0], nodes, dp)

    @property
    def length_m(self) -> float:
        """Total travelled distance, m."""
        return float(self.u_start_m[-1] + self.pieces[-1].length_m)

    def position(self, u_m: Array) -> Array:
        """Horizontal position (n, 2) north, east, m at travelled distances u_m (n,)."""
        i = np.clip(
            np.searchsorted(self.node_u_m, u_m, side="right") - 1, 0, len(self.node_h_m) - 1
        )
        h = self.node_h_m[i][:, None]
        s = np.clip((u_m - self.node_u_m[i])[:, None] / h, 0.0, 1.0)
        h00, h10 = 2 * s**3 - 3 * s**2 + 1, s**3 - 2 * s**2 + s
        h01, h11 = -2 * s**3 + 3 * s**2, s**3 - s**2
        return (
            h00 * self.node_p_m[i]
            + h10 * h * self.node_dp[i, 0]
            + h01 * self.node_p_m[i + 1]
            + h11 * h * self.node_dp[i, 1]
        )

    def heading(self, u_m: Array) -> tuple[Array, Array, Array, Array]:
        """Heading rad, curvature 1/m, dcurvature/dU 1/m^2 and direction (+1/-1) at u_m (n,)."""
        i = np.clip(np.searchsorted(self.u_start_m, u_m, side="right") - 1, 0, len(self.pieces) - 1)
        length = np.array([p.length_m for p in self.pieces])[i]
        k0 = np.array([p.kappa0_per_m for p in self.pieces])[i]
        k1 = np.array([p.kappa1_per_m for p in self.pieces])[i]
        dpsi, kappa, dkappa = _ramp(np.clip(u_m - self.u_start_m[i], 0.0, length), length, k0, k1)
        direction = np.array([p.direction for p in self.pieces], dtype=float)[i]
        return self.psi_start_rad[i] + dpsi, kappa, dkappa, direction


def simulate_vehicle(
    cfg: VehicleConfig, t0_s: float, dt_s: float = IMU_PERIOD_S, seed: int = 0
) -> Truth:
    """Truth of the whole run sampled every dt_s from t0_s (UTC host clock, s).

    ``seed`` draws the terrain bumps; everything else follows from ``cfg``. The run ends after
    the final rest; bias columns are zero (the IMU model fills them).
    """
    pieces = _plan_pieces(cfg)
    path = _Path.build(pieces, math.radians(cfg.swath_heading_deg))
    phases = _speed_phases(cfg, pieces)
    t_end = float(phases.t_start_s[-1] + phases.duration_s[-1])
    t_rel = np.arange(math.floor(t_end / dt_s + 1e-9) + 1, dtype=np.float64) * np.float64(dt_s)
    u, speed, accel, at_rest = phases.evaluate(t_rel)

    # Horizontal motion: v = d U' t, a = d (U'' t + U' psi' n).
    psi, kappa, dkappa, direction = path.heading(u)
    psi_dot = kappa * speed
    psi_ddot = dkappa * speed**2 + kappa * accel
    tangent = np.stack((np.cos(psi), np.sin(psi)), axis=1)
    normal = np.stack((-np.sin(psi), np.cos(psi)), axis=1)
    x_h = path.position(u)
    v_h = (direction * speed)[:, None] * tangent
    a_h = direction[:, None] * (accel[:, None] * tangent + (speed * psi_dot)[:, None] * normal)

    # Vertical motion on the terrain, D = -h(x_h) (h of the terrain's frame, 0 at the origin
    # when that frame is another run's: this run's origin is already at that height).
    terrain = cfg.terrain(seed)
    shift = np.asarray(cfg.terrain_origin_ne_m, dtype=float)
    terr = terrain.derivatives(x_h + shift)
    if shift.any():
        terr = replace(terr, h_m=terr.h_m - terrain.derivatives(shift[None, :]).h_m[0])
    hv = np.einsum("nij,nj->ni", terr.hess, v_h)
    ha = np.einsum("nij,nj->ni", terr.hess, a_h)
    tvv = np.einsum("nijk,ni,nj->nk", terr.third, v_h, v_h)
    pos = np.column_stack((x_h, -terr.h_m))
    vel = np.column_stack((v_h, -np.sum(terr.grad * v_h, axis=1)))
    acc = np.column_stack((a_h, -np.sum(v_h * hv + terr.grad * a_h, axis=1)))

    # Slopes along (g_a) and right-across (g_c) the heading, and their time derivatives.
    def dot(a: Array, b: Array) -> Array:
        return np.sum(a * b, axis=1)

    g_a, g_c = dot(terr.grad, tangent), dot(terr.grad, normal)
    g_a1 = dot(tangent, hv) + psi_dot * g_c
    g_c1 = dot(normal, hv) - psi_dot * g_a
    g_a2 = dot(tvv, tangent) + dot(tangent, ha) + psi_dot * dot(normal, hv) + psi_ddot * g_c
    g_a2 += psi_dot * g_c1
    g_c2 = dot(tvv, normal) + dot(normal, ha) - psi_dot * dot(tangent, hv) - psi_ddot * g_a
    g_c2 -= psi_dot * g_a1

    # Pitch: tan(theta) = g_a; roll: tan(phi) = q = -g_c cos(theta) (body z on the normal).
    theta = np.arctan(g_a)
    theta1 = g_a1 / (1.0 + g_a**2)
    theta2 = g_a2 / (1.0 + g_a**2) - 2.0 * g_a * g_a1**2 / (1.0 + g_a**2) ** 2
    ct, st = np.cos(theta), np.sin(theta)
    q = -g_c * ct
    q1 = -g_c1 * ct + g_c * st * theta1
    q2 = -g_c2 * ct + 2.0 * g_c1 * st * theta1 + g_c * (ct * theta1**2 + st * theta2)
    phi = np.arctan(q)
    phi1 = q1 / (1.0 + q**2)
    phi2 = q2 / (1.0 + q**2) - 2.0 * q * q1**2 / (1.0 + q**2) ** 2
    cf, sf = np.cos(phi), np.sin(phi)

    # Body rate from ZYX Euler rates, and its time derivative.
    w_ib_b = np.column_stack(
        (
            phi1 - psi_dot * st,
            theta1 * cf + psi_dot * sf * ct,
            -theta1 * sf + psi_dot * cf * ct,
        )
    )
    dw_ib_b = np.column_stack(
        (
            phi2 - psi_ddot * st - psi_dot * ct * theta1,
            theta2 * cf
            - theta1 * sf * phi1
            + psi_ddot * sf * ct
            + psi_dot * (cf * ct * phi1 - sf * st * theta1),
            -theta2 * sf
            - theta1 * cf * phi1
            + psi_ddot * cf * ct
            - psi_dot * (sf * ct * phi1 + cf * st * theta1),
        )
    )
    rpy = np.column_stack((phi, theta, (psi + np.pi) % (2.0 * np.pi) - np.pi))
    c_bn = dcm_from_rpy_array(rpy)
    if cfg.chassis_pitch_deg or cfg.implement_lift_deg:
        pitch = _chassis_pitch(cfg, path, u, t_rel)
        c_bn, w_ib_b, dw_ib_b = _pitch_chassis(c_bn, w_ib_b, dw_ib_b, *pitch)
        rpy = np.column_stack(
            (
                np.arctan2(c_bn[:, 2, 1], c_bn[:, 2, 2]),
                -np.arcsin(np.clip(c_bn[:, 2, 0], -1.0, 1.0)),
                np.arctan2(c_bn[:, 1, 0], c_bn[:, 0, 0]),
            )
        )

    lever_arm_ant = np.asarray(cfg.antenna_lever_arm_m, dtype=float)
    lever_arm_imu = np.asarray(cfg.imu_lever_arm_m, dtype=float)
    f_ib_b_ref = np.einsum("nji,nj->ni", c_bn, acc - G_NED_MPS2)
    w_x_l_imu = np.cross(w_ib_b, lever_arm_imu)
    f_ib_b_imu = f_ib_b_ref + np.cross(dw_ib_b, lever_arm_imu) + np.cross(w_ib_b, w_x_l_imu)
    pos_ant = pos + c_bn @ lever_arm_ant
    vel_ant = vel + np.einsum("nij,nj->ni", c_bn, np.cross(w_ib_b, lever_arm_ant))

    origin = np.asarray(cfg.origin_lla, dtype=float)
    n = len(t_rel)
    return Truth(
        t=t0_s + t_rel,
        pos_ned_m=pos,
        lla=ned_to_lla(pos, origin),
        vel_ned_mps=vel,
        rpy_rad=rpy,
        w_ib_b=w_ib_b,
        f_ib_b_imu=f_ib_b_imu,
        pos_ant_ned_m=pos_ant,
        lla_ant=ned_to_lla(pos_ant, origin),
        vel_ant_ned_mps=vel_ant,
        reversing=(direction < 0.0) & ~at_rest,
        stationary=at_rest,
        bias_g_rps=np.zeros((n, 3)),
        bias_a_mps2=np.zeros((n, 3)),
        origin_lla=origin,
        antenna_lever_arm_m=lever_arm_ant,
        imu_lever_arm_m=lever_arm_imu,
        dt_s=dt_s,
    )


def _chassis_pitch(
    cfg: VehicleConfig, path: _Path, u_m: Array, t_s: Array
) -> tuple[Array, Array, Array]:
    """The chassis's pitch against its track (rad) and its first and second time derivatives
    at times ``t_s`` (travelled distance ``u_m``): ``chassis_pitch_deg``, and
    ``implement_lift_deg`` more from the end of each pass to the start of the next, each
    change over ``implement_lift_s`` from the time the pass ends or begins, its rate a sin^2
    pulse (as the speed ramps': continuous angular acceleration)."""
    c = np.full(len(t_s), math.radians(cfg.chassis_pitch_deg))
    c1, c2 = np.zeros_like(c), np.zeros_like(c)
    lift, ramp = math.radians(cfg.implement_lift_deg), cfg.implement_lift_s
    if lift and not ramp > 0.0:
        raise ValueError(
            f"implement_lift_s={ramp} with implement_lift_deg={cfg.implement_lift_deg}: "
            "expected the lift's duration, s > 0"
        )
    work = [p.work for p in path.pieces]
    for k in range(1, len(work)):
        if work[k] == work[k - 1]:
            continue
        t0 = t_s[min(int(np.searchsorted(u_m, path.u_start_m[k])), len(t_s) - 1)]
        step = lift if work[k - 1] else -lift  # lifted as a pass ends, lowered as one begins
        x = 2.0 * np.pi * np.clip((t_s - t0) / ramp, 0.0, 1.0)
        c += step * (x - np.sin(x)) / (2.0 * np.pi)
        c1 += step / ramp * (1.0 - np.cos(x))
        c2 += step * 2.0 * np.pi / ramp**2 * np.sin(x)
    return c, c1, c2


def _pitch_chassis(
    c_bn: Array, w_b: Array, dw_b: Array, c: Array, c1: Array, c2: Array
) -> tuple[Array, Array, Array]:
    """Attitude, body rate and its derivative of a body pitched by ``c`` (rad, with its time
    derivatives ``c1``, ``c2``) about its own y axis: C <- C R_y(c),
    w <- R_y^T w + c' e_y, w' <- R_y^T w' - c' e_y x (R_y^T w) + c'' e_y."""
    zero = np.zeros_like(c)
    r_y = dcm_from_rpy_array(np.column_stack((zero, c, zero)))
    w_new = np.einsum("nji,nj->ni", r_y, w_b)
    dw_new = np.einsum("nji,nj->ni", r_y, dw_b)
    dw_new -= np.cross(c1[:, None] * np.array([0.0, 1.0, 0.0]), w_new)
    w_new[:, 1] += c1
    dw_new[:, 1] += c2
    return c_bn @ r_y, w_new, dw_new


VEHICLE_PRESETS: dict[str, VehicleConfig] = {
    # ~15 min: nine 250 m swaths at varying speed, 18 m apart, U-turns both ways, gentle side
    # slopes, a 40 s alignment rest and a 20 s stop half-way along the fourth pass.
    "field": VehicleConfig(
        swath_heading_deg=20.0,
        swath_length_m=250.0,
        swath_spacing_m=18.0,
        n_passes=9,
        work_speeds_mps=(3.0, 3.5, 2.5, 3.0, 3.3, 2.8),
        start_stop_s=40.0,
        mid_stop_pass=3,
        mid_stop_s=20.0,
        side_slope_min_deg=2.0,
        side_slope_max_deg=4.0,
        side_slope_wavelength_m=100.0,
        along_slope_deg=0.5,
    ),
    # Steep hillside: 5-8 deg across the swaths; the roll sign flips with every pass.
    "hillside": VehicleConfig(
        swath_heading_deg=90.0,
        swath_length_m=150.0,
        swath_spacing_m=18.0,
        n_passes=6,
        work_speeds_mps=(2.5, 2.2),
        first_turn="left",
        turn_speed_mps=1.5,
        start_stop_s=40.0,
        side_slope_min_deg=5.0,
        side_slope_max_deg=8.0,
        side_slope_wavelength_m=120.0,
        along_slope_deg=1.5,
    ),
    # Narrow 6 m swaths: every headland turn is a fishtail with a reverse of about 12 m.
    "headland-reversing": VehicleConfig(
        swath_heading_deg=-45.0,
        swath_length_m=120.0,
        swath_spacing_m=6.0,
        n_passes=6,
        work_speeds_mps=(2.5,),
        turn_radius_m=5.0,
        turn_transition_m=2.0,
        turn_speed_mps=1.5,
        reverse_at_headland=True,
        reverse_length_m=3.0,
        reverse_speed_mps=1.0,
        start_stop_s=30.0,
    ),
    # ~2 min for tests and the demo: 30 s rest, three 50 m passes, a right and a left U-turn.
    "short": VehicleConfig(
        swath_length_m=50.0,
        n_passes=3,
        work_speeds_mps=(3.0, 2.5),
        start_stop_s=30.0,
    ),
}
