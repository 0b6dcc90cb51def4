"""The last line of defence before the bus: nothing physically implausible leaves the gateway.

Whatever an engine does (a numerical blow-up, a time-base fault, a bug), a guidance controller
steers on our frames. :class:`OutputGuard` checks every solution the scheduler is about to
encode against physics that hold for any farm vehicle, and withholds what fails: the field is
sent as "not available" (None in the :class:`~gateway.estimation.solution.Solution`), the mode
becomes
DEGRADED (FAULT when the attitude itself is absurd), the event is counted and logged at a
limited rate (solution time, so replay logs the same). Checks:

- every number finite; roll and pitch within ``max_tilt_deg`` (a wheeled vehicle beyond it has
  rolled over); rate of turn within the gyro's range; speed below ``max_speed_mps``; latitude,
  longitude and ellipsoidal height on the Earth's surface; bias estimates within their range;
- position continuous with the vehicle's motion: each position must lie within
  ``|v| dt + a_max dt^2 / 2 + jump_allowance_m`` of the last one sent, moved on by the last
  velocity sent. A position that is not is withheld; a new track is trusted again once it has
  been continuous with itself for ``settle_s`` (a real reset after an outage costs that long
  without position, an absurd spike never gets through). After ``stale_s`` without a position
  sent (an outage whose dead reckoning was withheld) nothing is left to be continuous with:
  the first ``settle_s`` of the new track are withheld the same way, but that is not an
  implausible output, so it is neither counted nor logged as one, and the mode is kept.

Roll and pitch go out only with a stated accuracy: while their 1-sigma is unknown or beyond
``max_tilt_sigma_deg`` (the most NAVGW_STATUS byte 7 can state, SPEC 4), they are "not
available", and so is the position: the reference point is the antenna minus C times its
lever arm, as unknown as the tilt (3 m of mast and 3 deg: 16 cm). That is normal operation
(an engine levelled on a moving window), not an implausible output: not counted, not logged,
the mode kept. NAVIGATING states an RTK fix's centimetres for the reference point: while
the tilt's share of its error, ``|l_ant| sigma_tilt``, is beyond ``navigating_position_sigma_m``
the mode is DEGRADED (the observer without a fix for the first 40 s of a cold start sent the
reference point 18 cm off, NAVIGATING, with the 2.55 deg its tilt stated on a 3 m mast).

It also makes the fix fields say what the position sent is (SPEC 4): while coasting the
position is dead reckoning (GGA quality 6; satellites, HDOP and age not available), and
without a position, no fix (0), not the last fix received.

Pure code with no clock of its own, like the engines: the live service and replay guard
identically.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from dataclasses import dataclass, replace
from enum import Enum

from drivers.log_limit import LogLimiter
from drivers.samples import FixQuality, Float3
from drivers.units import DEG_TO_RAD
from gateway.estimation.solution import NAVIGATING_POSITION_SHARE_M, Mode, Solution

log = logging.getLogger(__name__)

#: Metres per degree of latitude (mean; continuity tests need no better than 1 %).
M_PER_DEG = 111_195.0


@dataclass(frozen=True)
class GuardLimits:
    """Physical bounds of a farm vehicle and its sensors (SI unless the name says)."""

    max_tilt_deg: float = 60.0  # roll or pitch beyond which a wheeled vehicle has rolled over
    max_tilt_sigma_deg: float = 2.54  # largest roll/pitch 1-sigma STATUS states (SPEC 4)
    #: The tilt's share of the reference point's horizontal 1-sigma that NAVIGATING allows,
    #: m (:data:`~gateway.estimation.solution.NAVIGATING_POSITION_SHARE_M`).
    navigating_position_sigma_m: float = NAVIGATING_POSITION_SHARE_M
    max_rate_dps: float = 300.0  # ADIS16334 gyro range (SPEC 1)
    max_speed_mps: float = 40.0  # 144 km/h: no farm vehicle, no road transport either
    max_accel_mps2: float = 15.0  # 1.5 g, braking or a bump: bounds position change with time
    jump_allowance_m: float = 2.0  # GNSS corrections (float to fixed, end of an outage) may step
    settle_s: float = 1.0  # a new track must be continuous this long to be trusted
    stale_s: float = 10.0  # a track not continued for this long proves itself again
    min_alt_m: float = -500.0  # below the Dead Sea shore and any geoid/ellipsoid offset
    max_alt_m: float = 9000.0
    max_gyro_bias_dps: float = 10.0  # far beyond any MEMS gyro's turn-on bias
    max_accel_bias_mps2: float = 2.0  # 0.2 g


class Withheld(Enum):
    """What the guard replaced by "not available", one counter each."""

    ATTITUDE = "attitude"
    RATE = "rate of turn"
    POSITION = "position"
    VELOCITY = "velocity"
    BIAS = "bias estimates"
    SIGMA = "roll/pitch sigma"


@dataclass(slots=True)
class _Track:
    """A position and velocity sent (or a candidate track), local metres via degrees."""

    t: float
    lat_deg: float
    lon_deg: float
    vel_ne_mps: tuple[float, float]
    since_t: float  # start of this track's continuity


class OutputGuard:
    """``check(solution)`` returns the solution with implausible content withheld."""

    def __init__(
        self,
        limits: GuardLimits | None = None,
        warn_interval_s: float = 10.0,
        lever_arm_ant_m: Float3 = (0.0, 0.0, 0.0),
    ) -> None:
        """``lever_arm_ant_m``: the antenna from the reference point, body FRD, m (its length
        turns the tilt's sigma into the reference point's)."""
        self.limits = limits or GuardLimits()
        self._lever_arm_m = math.hypot(*lever_arm_ant_m)
        self.counts: dict[Withheld, int] = dict.fromkeys(Withheld, 0)
        self._track: _Track | None = None  # last position sent
        self._candidate: _Track | None = None  # a new track, not yet trusted
        self._log = LogLimiter(log, warn_interval_s)

    def forget_track(self) -> None:
        """The next position starts a new track (the engine was restarted)."""
        self._track = self._candidate = None

    @property
    def withheld(self) -> int:
        """Solutions' fields withheld so far, all kinds."""
        return sum(self.counts.values())

    def check(self, sol: Solution) -> Solution:
        """``sol`` with what fails the checks set to None and the mode lowered accordingly."""
        if sol.coasting and sol.fix_quality is not None:
            dead_reckoning = sol.lat_deg is not None
            sol = replace(
                sol,
                fix_quality=FixQuality.DEAD_RECKONING if dead_reckoning else FixQuality.NONE,
                num_sats=None,
                hdop=None,
                age_s=None,
            )
        lim = self.limits
        if sol.roll_rad is not None or sol.pitch_rad is not None or sol.lat_deg is not None:
            sigma = sol.sigma_tilt_rad
            if sigma is None or not sigma <= lim.max_tilt_sigma_deg * DEG_TO_RAD:
                sol = replace(
                    sol, roll_rad=None, pitch_rad=None, lat_deg=None, lon_deg=None, alt_m=None
                )
        if sol.mode is Mode.NAVIGATING and self._lever_arm_m > 0.0:
            sigma = sol.sigma_tilt_rad
            if sigma is None or not self._lever_arm_m * sigma <= lim.navigating_position_sigma_m:
                sol = replace(sol, mode=Mode.DEGRADED)
        changes: dict[str, object] = {}
        reasons: list[str] = []
        fault = False

        def withhold(kind: Withheld, why: str, **fields: object) -> None:
            if any(getattr(sol, name) is not None for name in fields):
                self.counts[kind] += 1
                reasons.append(f"{kind.value} ({why})")
                changes.update(fields)

        max_tilt = lim.max_tilt_deg * DEG_TO_RAD
        if (
            not _ok(sol.roll_rad, max_tilt)
            or not _ok(sol.pitch_rad, max_tilt)
            or (sol.yaw_rad is not None and not math.isfinite(sol.yaw_rad))
        ):
            fault = True
            withhold(
                Withheld.ATTITUDE,
                f"roll {_deg(sol.roll_rad)}, pitch {_deg(sol.pitch_rad)}, yaw "
                f"{_deg(sol.yaw_rad)} deg; expected finite, |roll|, |pitch| <= "
                f"{lim.max_tilt_deg:g} deg",
                roll_rad=None, pitch_rad=None, yaw_rad=None, yaw_rate_rps=None,
                lat_deg=None, lon_deg=None, alt_m=None, vel_ned_mps=None,
            )  # fmt: skip
        if not _ok(sol.yaw_rate_rps, lim.max_rate_dps * DEG_TO_RAD):
            withhold(
                Withheld.RATE,
                f"{_deg(sol.yaw_rate_rps)} deg/s; expected within +/-{lim.max_rate_dps:g}",
                yaw_rate_rps=None,
            )
        vel = sol.vel_ned_mps
        if vel is not None and not (
            math.isfinite(vel[0])
            and math.isfinite(vel[1])
            and math.isfinite(vel[2])
            and math.hypot(*vel) <= lim.max_speed_mps
        ):
            withhold(
                Withheld.VELOCITY,
                f"{vel}; expected finite, below {lim.max_speed_mps:g} m/s",
                vel_ned_mps=None, lat_deg=None, lon_deg=None, alt_m=None,
            )  # fmt: skip
        if "lat_deg" not in changes and not self._check_position(sol, withhold):
            sol = replace(sol, lat_deg=None, lon_deg=None, alt_m=None)
        if sol.sigma_tilt_rad is not None and not (
            math.isfinite(sol.sigma_tilt_rad) and sol.sigma_tilt_rad >= 0.0
        ):
            withhold(Withheld.SIGMA, f"{sol.sigma_tilt_rad}", sigma_tilt_rad=None)
        if not _vec_ok(sol.bias_g_rps, lim.max_gyro_bias_dps * DEG_TO_RAD) or not _vec_ok(
            sol.bias_a_mps2, lim.max_accel_bias_mps2
        ):
            withhold(
                Withheld.BIAS,
                "non-finite or beyond the sensor's range",
                bias_g_rps=None, bias_a_mps2=None,
            )  # fmt: skip
        if not changes:
            return sol
        mode = Mode.FAULT if fault else max(sol.mode, Mode.DEGRADED)
        why = "; ".join(reasons)
        self._log.warning(sol.t, f"implausible output withheld at t={sol.t:.3f}: {why}")
        return replace(sol, mode=mode, **changes)  # type: ignore[arg-type]

    def _check_position(self, sol: Solution, withhold: Callable[..., None]) -> bool:
        """Range and continuity of the reference point; updates the tracks. False: a new
        track after a stale one, still settling (withheld, but not implausible)."""
        lim = self.limits
        lat, lon, alt = sol.lat_deg, sol.lon_deg, sol.alt_m
        if lat is None or lon is None:
            return True
        if not (
            math.isfinite(lat)
            and math.isfinite(lon)
            and abs(lat) <= 90.0
            and abs(lon) <= 180.0
            and (alt is None or (math.isfinite(alt) and lim.min_alt_m <= alt <= lim.max_alt_m))
        ):
            withhold(
                Withheld.POSITION,
                f"lat {lat}, lon {lon}, height {alt} m; expected on the Earth's surface",
                lat_deg=None, lon_deg=None, alt_m=None, vel_ned_mps=None,
            )  # fmt: skip
            return True
        vel = sol.vel_ned_mps
        here = _Track(sol.t, lat, lon, (vel[0], vel[1]) if vel else (0.0, 0.0), sol.t)
        track = self._track
        if track is None or self._continues(track, here):  # the first position: range only
            self._track, self._candidate = here, None
            return True
        cand = self._candidate
        if cand is not None and self._continues(cand, here):
            here.since_t = cand.since_t
            if sol.t - cand.since_t >= lim.settle_s:
                self._track, self._candidate = here, None  # a new track, trusted from now
                return True
        self._candidate = here
        if sol.t - track.t > lim.stale_s:
            return False
        jump_m = _distance_m(track.lat_deg, track.lon_deg, lat, lon)
        withhold(
            Withheld.POSITION,
            f"{jump_m:.1f} m from the last position sent, moved on by its "
            f"velocity over {sol.t - track.t:.3f} s; expected a continuous track",
            lat_deg=None, lon_deg=None, alt_m=None,
        )  # fmt: skip
        return True

    def _continues(self, a: _Track, b: _Track) -> bool:
        """``b`` lies where ``a``'s motion can take the vehicle by ``b.t``."""
        dt = b.t - a.t
        lim = self.limits
        if not 0.0 <= dt <= lim.stale_s:
            return False
        vn, ve = a.vel_ne_mps
        moved_lat = a.lat_deg + vn * dt / M_PER_DEG
        moved_lon = a.lon_deg + ve * dt / (M_PER_DEG * max(math.cos(a.lat_deg * DEG_TO_RAD), 1e-6))
        bn, be = b.vel_ne_mps
        allowed = lim.jump_allowance_m + 0.5 * lim.max_accel_mps2 * dt * dt
        return (
            _distance_m(moved_lat, moved_lon, b.lat_deg, b.lon_deg) <= allowed
            and math.hypot(bn - vn, be - ve) <= lim.max_accel_mps2 * dt + lim.jump_allowance_m
            and math.hypot(bn, be) <= lim.max_speed_mps
        )


def _ok(x: float | None, limit: float) -> bool:
    return x is None or (math.isfinite(x) and abs(x) <= limit)


def _vec_ok(v: Float3 | None, limit: float) -> bool:
    """Every element finite and within +/-limit (None: nothing to check); NaN and inf fail
    ``<=``."""
    return v is None or (abs(v[0]) <= limit and abs(v[1]) <= limit and abs(v[2]) <= limit)


def _deg(x: float | None) -> str:
    return "n/a" if x is None else f"{x / DEG_TO_RAD:.1f}"


def _distance_m(lat_a: float, lon_a: float, lat_b: float, lon_b: float) -> float:
    """Horizontal distance, local flat-earth (continuity checks: metres to kilometres)."""
    dlon = (lon_b - lon_a + 180.0) % 360.0 - 180.0
    dn = (lat_b - lat_a) * M_PER_DEG
    de = dlon * M_PER_DEG * math.cos(0.5 * (lat_a + lat_b) * DEG_TO_RAD)
    return math.hypot(dn, de)
