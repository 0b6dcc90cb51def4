"""Independent reading of the gateway's output: candump logs decoded by the nmea2000 package.

The package embeds canboat's PGN database, so these checks do not share code or DBC with
the encoders under test.
"""

from __future__ import annotations

import bisect
import itertools
import math
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt
from nmea2000 import NMEA2000Decoder

import dbc
from drivers.logs.candump import read_candump
from gateway.demo.accuracy import attitude_error_rad, truth_at
from gateway.estimation.ekf.ekf_config import EkfConfig
from gateway.estimation.observer.observer_config import ObserverConfig
from sim_bus.truth import Truth


@dataclass
class Decoded:
    """One decoded NMEA 2000 message: time of its (last) frame, canboat id, field values."""

    t: float
    pgn: int
    id: str
    fields: dict[str, object]


def decode_log(path: str | Path) -> list[Decoded]:
    """Every message of a candump log that canboat's database knows (fast packets joined)."""
    decoder = NMEA2000Decoder()
    out = []
    for frame in read_candump(path):
        message = decoder.decode(frame)
        if message is not None:
            fields = {f.id: f.value for f in message.fields}
            out.append(Decoded(frame.timestamp, message.PGN, message.id, fields))
    return out


def attitude_errors_deg(
    messages: list[Decoded], truth: Truth, after_s: float
) -> npt.NDArray[np.float64]:
    """(n, 3) roll, pitch, yaw errors in degrees of 127257 frames later than ``after_s``
    (the truth interpolated with its yaw unwrapped: a frame between two truth samples either
    side of +-180 deg is compared with a heading near 180 deg, not with their mean near 0)."""
    rows = [m for m in messages if m.id == "attitude" and m.t - truth.t[0] > after_s]
    est = np.array(
        [[m.fields["roll"], m.fields["pitch"], m.fields["yaw"]] for m in rows], dtype=float
    )
    true = truth_at(truth, np.array([m.t for m in rows])).rpy_rad
    return np.degrees(attitude_error_rad(est, true))


def position_errors_m(
    messages: list[Decoded], truth: Truth, after_s: float
) -> npt.NDArray[np.float64]:
    """Horizontal errors (m) of 129025 reference-point positions later than ``after_s``."""
    from gateway.estimation.geodesy import horizontal_ned

    rows = [m for m in messages if m.id == "positionRapidUpdate" and m.t - truth.t[0] > after_s]
    lat_lon = np.array([[m.fields["latitude"], m.fields["longitude"]] for m in rows], dtype=float)
    ne = horizontal_ned(lat_lon.reshape(-1, 2), truth.origin_lla)
    true = truth_at(truth, np.array([m.t for m in rows])).pos_ned_m
    return np.hypot(*(ne - true[:, :2]).T)


@dataclass(frozen=True)
class Plausible:
    """How far from the truth a decoded frame may be before it is absurd, not just inaccurate.

    These are gross-error bounds, far outside what a working gateway outputs at any time
    (alignment included) and far inside what a wrong frame shows (a position at the antipode,
    a roll off by 8 deg); the tests' RMS bounds check accuracy. Each frame is compared with
    the truth anywhere in ``[t - lag_s, t + lead_s]`` of its time stamp ``t``: a live frame is
    stamped when it is received, after the input it was computed from (more so on a loaded
    machine, and ``speed`` times more in a faster-than-real-time test).
    """

    position_m: float = 5.0  # reference point horizontal, from the truth track
    altitude_m: float = 10.0  # 129029, ellipsoidal height
    tilt_deg: float = 3.0  # roll and pitch
    heading_deg: float = 10.0  # yaw (127257), heading (127250), once available
    rate_dps: float = 5.0  # 127251
    sog_mps: float = 1.0  # 129026
    lag_s: float = 0.5
    lead_s: float = 0.05


#: Physical ranges of the fields :func:`implausible_frames` reads, per canboat message id.
_RANGES: dict[str, dict[str, tuple[float, float]]] = {
    "attitude": {"roll": (-math.pi, math.pi), "pitch": (-math.pi / 2, math.pi / 2),
                 "yaw": (-math.pi, 2 * math.pi)},
    "rateOfTurn": {"rate": (-math.pi, math.pi)},
    "vesselHeading": {"heading": (0.0, 2 * math.pi)},
    "positionRapidUpdate": {"latitude": (-90.0, 90.0), "longitude": (-180.0, 180.0)},
    "gnssPositionData": {"latitude": (-90.0, 90.0), "longitude": (-180.0, 180.0),
                         "altitude": (-1000.0, 10000.0)},
    "cogSogRapidUpdate": {"cog": (0.0, 2 * math.pi), "sog": (0.0, 50.0)},
}  # fmt: skip


_SLACK = 1e-3  # a range's ends as encoded (yaw -pi, heading 2 pi) decode a hair outside


def _number(value: object) -> float | None:
    """The field as a float, None if the frame says "not available"; NaN if not a number."""
    if value is None:
        return None
    if isinstance(value, int | float) and not isinstance(value, bool):
        return float(value)
    return math.nan


#: NAVGW_STATUS (PGN 0xFF22), byte 2 mode: DEGRADED (4) or FAULT (5) excuse inaccuracy.
STATUS_PGN = 0xFF22
NAVIGATING = 2
COASTING = 3
DEGRADED = 4
#: A position sent NAVIGATING (RTK fixed: 1-2 cm) farther off than this is wrong, not
#: inaccurate: a 1 Hz receiver's fix propagated over its second was 14 cm off at worst.
NAVIGATING_POSITION_M = 0.2


def status_modes(path: str | Path) -> list[tuple[float, int]]:
    """(time, mode byte) of every NAVGW_STATUS frame of a candump log, any source address."""
    return [
        (float(f.timestamp), f.data[2])
        for f in read_candump(path)
        if (f.arbitration_id >> 8) & 0x3FFFF == STATUS_PGN and len(f.data) > 2
    ]


def settled(modes: list[tuple[float, int]]) -> list[tuple[float, int]]:
    """:func:`status_modes` from the first NAVIGATING on: before it the engine aligns, then
    says DEGRADED while the course brings its heading within NAVIGATING's 0.5 deg 1-sigma
    (a course at the 1.5 m/s of alignment is 0.76 deg: one to two seconds)."""
    first = next((i for i, (_, mode) in enumerate(modes) if mode == NAVIGATING), len(modes))
    return modes[first:]


def _degraded_near(status: list[tuple[float, int]]) -> Callable[[float], bool]:
    """Whether a NAVGW_STATUS within 0.1 s of a time says DEGRADED or FAULT (SPEC 4: a value
    may be off while STATUS says so, from the same instant)."""
    told = np.array([t for t, mode in status if mode >= DEGRADED])
    return lambda t: bool(len(told)) and bool(np.min(np.abs(told - t)) <= 0.1)


def stated_sigma_deg(log: str | Path) -> list[tuple[float, float | None]]:
    """(time, SIGMA_TILT deg or None when not available) of every NAVGW_STATUS frame,
    decoded by cantools with the project's DBC."""
    status = dbc.load(dbc.OUTPUT_DBC).get_message_by_name("NAVGW_STATUS")
    out = []
    for frame in read_candump(log):
        if (frame.arbitration_id >> 8) & 0x3FFFF == STATUS_PGN:
            values = status.decode(bytes(frame.data), decode_choices=False)
            assert isinstance(values, dict)
            sigma = values["SIGMA_TILT"]
            out.append((float(frame.timestamp), sigma if isinstance(sigma, float) else None))
    return out


#: SIGMA_TILT's resolution (0.01 deg) on a 3 m lever arm, m, and then some: a STATUS frame's
#: tilt share of the reference point is known to this from its bytes.
SHARE_RESOLUTION_M = 0.001


def status_tilt_shares_m(
    log: str | Path, lever_arm_ant_m: tuple[float, float, float]
) -> list[tuple[float, int, float | None]]:
    """(time, mode, |l_ant| x SIGMA_TILT in m or None when not available) of every
    NAVGW_STATUS frame: the tilt's share of the reference point's 1-sigma that NAVIGATING
    holds within the guard's ``navigating_position_sigma_m``."""
    arm_m = math.hypot(*lever_arm_ant_m)
    return [
        (t, mode, None if sigma is None else arm_m * math.radians(sigma))
        for (t, mode), (_, sigma) in zip(status_modes(log), stated_sigma_deg(log), strict=True)
    ]


@dataclass(frozen=True)
class StatedTilt:
    """One 127257 frame's roll and pitch (rad), with the SIGMA_TILT (deg, None: not
    available) of the last NAVGW_STATUS before it."""

    t: float
    roll_rad: float
    pitch_rad: float
    sigma_deg: float | None


def stated_tilts(log: str | Path) -> Iterator[StatedTilt]:
    """Every 127257 frame of a candump log that has roll and pitch, with its stated accuracy."""
    status = stated_sigma_deg(log)
    times = [t for t, _ in status]
    for m in decode_log(log):
        roll, pitch = _number(m.fields.get("roll")), _number(m.fields.get("pitch"))
        if m.id == "attitude" and roll is not None and pitch is not None:
            i = bisect.bisect_right(times, m.t) - 1
            yield StatedTilt(m.t, roll, pitch, status[i][1] if i >= 0 else None)


def tilt_off_deg(
    truth: Truth, t: float, lag_s: float, roll_rad: float, pitch_rad: float
) -> tuple[float, float]:
    """How far (deg) a roll and pitch sent at ``t`` are from the truth at its nearest within
    ``[t - lag_s, t]``, the truth linear between its samples."""
    lo, hi = np.searchsorted(truth.t, [t - lag_s, t], side="right")
    ends = (t - lag_s, t)
    roll_off, pitch_off = (
        float(np.degrees(np.min(np.abs(v - np.append(
            truth.rpy_rad[lo:hi, k], np.interp(ends, truth.t, truth.rpy_rad[:, k]))))))
        for k, v in enumerate((roll_rad, pitch_rad))
    )  # fmt: skip
    return roll_off, pitch_off


def tilt_beyond_stated(
    log: str | Path, truth: Truth, lag_s: float = 0.0, margin_deg: float = 0.1
) -> tuple[int, list[str]]:
    """The never-lie check of roll and pitch: the attitude frames (127257) that state an
    accuracy, and one line for each whose roll or pitch is farther than ``margin_deg`` + 3
    sigma from the truth everywhere in ``[t - lag_s, t]`` (a live frame is stamped when
    received), the truth linear between its samples. A frame within 0.1 s of a STATUS
    saying DEGRADED or FAULT, or after one stating no accuracy, claims none and is not
    counted. (The truth's last sample at or before t, instead of its value at t, put up to
    one sample period, 4.9 ms, between them: 0.2 deg of a body pitching 40 deg/s on rough
    ground at 6 m/s, frames "beyond" that were not.)"""
    excused = _degraded_near(status_modes(log))
    checked, beyond = 0, []
    for f in stated_tilts(log):
        if f.sigma_deg is None or excused(f.t):
            continue
        checked += 1
        off = tilt_off_deg(truth, f.t, lag_s, f.roll_rad, f.pitch_rad)
        if max(off) > margin_deg + 3.0 * f.sigma_deg:
            beyond.append(f"t={f.t - truth.t[0]:.3f} s roll/pitch {off[0]:.2f}/{off[1]:.2f} "
                          f"deg off, {f.sigma_deg:.2f} deg stated")  # fmt: skip
    return checked, beyond


def heading_beyond_navigating(
    log: str | Path, truth: Truth, margin_deg: float = 0.1
) -> tuple[int, list[str]]:
    """The never-lie check of the heading: the bus states no heading accuracy, so a mode
    short of DEGRADED states it within the engines' ``navigating_heading_sigma_deg``. The
    127257 frames sent without a NAVGW_STATUS saying DEGRADED or FAULT within 0.1 s, and
    one line for each whose yaw is farther than ``margin_deg`` + 3 of that sigma from the
    truth."""
    sigma_deg = ObserverConfig().navigating_heading_sigma_deg
    assert EkfConfig().navigating_heading_sigma_deg == sigma_deg
    excused = _degraded_near(status_modes(log))
    rows = [
        m
        for m in decode_log(log)
        if m.id == "attitude" and _number(m.fields.get("yaw")) is not None and not excused(m.t)
    ]
    if not rows:
        return 0, []
    errors = attitude_errors_deg(rows, truth, after_s=-math.inf)[:, 2]
    beyond = [
        f"t={m.t - truth.t[0]:.3f} s heading {e:.2f} deg off"
        for m, e in zip(rows, errors, strict=True)
        if abs(e) > margin_deg + 3.0 * sigma_deg
    ]
    return len(rows), beyond


def position_beyond_mode(log: str | Path, truth: Truth) -> tuple[int, list[str]]:
    """The never-lie check of the reference point (129025): the bus states its accuracy
    through the mode. Of the positions sent without a NAVGW_STATUS saying DEGRADED or FAULT
    within 0.1 s, one line for each COASTING farther than 3 x ``coast_sigma_m`` (the
    1-sigma COASTING states) from the truth, or NAVIGATING farther than
    :data:`NAVIGATING_POSITION_M`; and how many were checked."""
    coast_sigma_m = ObserverConfig().coast_sigma_m
    assert EkfConfig().coast_sigma_m == coast_sigma_m
    status = status_modes(log)
    excused, times = _degraded_near(status), [t for t, _ in status]
    rows = [
        m
        for m in decode_log(log)
        if m.id == "positionRapidUpdate"
        and _number(m.fields.get("latitude")) is not None
        and not excused(m.t)
    ]
    if not rows:
        return 0, []
    errors = position_errors_m(rows, truth, after_s=-math.inf)
    beyond = []
    for m, e in zip(rows, errors, strict=True):
        i = bisect.bisect_right(times, m.t) - 1
        mode = status[i][1] if i >= 0 else None
        bound = 3.0 * coast_sigma_m if mode == COASTING else NAVIGATING_POSITION_M
        if e > bound:
            beyond.append(f"t={m.t - truth.t[0]:.3f} s position {e:.2f} m off, mode {mode}")
    return len(rows), beyond


def implausible_frames(
    messages: list[Decoded],
    truth: Truth,
    limits: Plausible = Plausible(),
    status: list[tuple[float, int]] | None = None,
) -> list[str]:
    """One line per navigation frame that is not a plausible reading of the truth.

    Checked: 127257 attitude, 127251 rate of turn, 127250 heading, 129025 and 129029
    positions (and 129029's height), 129026 speed over ground. A field that is "not
    available" is plausible; one that is not finite, outside its physical range, or farther
    from the truth than ``limits`` (everywhere in the frame's time window) is not. Frames
    outside the truth's time span are checked against its ends. With ``status`` (from
    :func:`status_modes`), a frame within 0.1 s of a NAVGW_STATUS saying DEGRADED or FAULT is
    held to range and finiteness only: SPEC 4 lets a value be off while STATUS says so.
    """
    from gateway.estimation.geodesy import horizontal_ned, lla_to_ned

    t_truth = truth.t
    yaw_rate = np.gradient(np.unwrap(truth.rpy_rad[:, 2]), t_truth)
    speed = np.hypot(truth.vel_ned_mps[:, 0], truth.vel_ned_mps[:, 1])
    out: list[str] = []

    def window(t: float) -> slice:
        lo, hi = np.searchsorted(t_truth, [t - limits.lag_s, t + limits.lead_s])
        lo = min(int(lo), len(t_truth) - 1)
        return slice(lo, max(int(hi), lo + 1))

    def angle_off_deg(value: float, true: npt.NDArray[np.float64]) -> float:
        return float(np.degrees(np.min(np.abs((value - true + np.pi) % (2 * np.pi) - np.pi))))

    excused = _degraded_near(status or [])

    def bad(m: Decoded, text: str) -> None:
        out.append(f"t={m.t - t_truth[0]:.3f} s {m.pgn} {m.id}: {text}")

    for m in messages:
        ranges = _RANGES.get(m.id, {})
        if not ranges:
            continue
        values = {k: _number(m.fields.get(k)) for k in ranges}
        broken = [
            f"{k}={v}" for k, v in values.items()
            if v is not None
            and not (math.isfinite(v) and ranges[k][0] - _SLACK <= v <= ranges[k][1] + _SLACK)
        ]  # fmt: skip
        if broken:
            bad(m, "out of range: " + ", ".join(broken))
            continue
        if excused(m.t):
            continue
        w = window(m.t)
        angles = {"attitude": ("roll", "pitch", "yaw"), "vesselHeading": (None, None, "heading")}
        if m.id in angles:
            for i, k in enumerate(angles[m.id]):
                v = values.get(k) if k else None
                limit = limits.tilt_deg if i < 2 else limits.heading_deg
                if v is not None and (off := angle_off_deg(v, truth.rpy_rad[w, i])) > limit:
                    bad(m, f"{k} {math.degrees(v):.2f} deg, {off:.2f} deg from the truth")
        elif m.id == "rateOfTurn":
            v = values["rate"]
            if v is not None:
                off = float(np.degrees(np.min(np.abs(v - yaw_rate[w]))))
                if off > limits.rate_dps:
                    bad(m, f"rate {math.degrees(v):.2f} deg/s, {off:.2f} deg/s from the truth")
        elif m.id == "cogSogRapidUpdate":
            v = values["sog"]
            if v is not None and (off := float(np.min(np.abs(v - speed[w])))) > limits.sog_mps:
                bad(m, f"SOG {v:.2f} m/s, {off:.2f} m/s from the truth")
        else:  # positions
            lat, lon = values["latitude"], values["longitude"]
            if (lat is None) != (lon is None):
                bad(m, f"latitude {lat}, longitude {lon}: half a position")
                continue
            if lat is None or lon is None:
                continue
            h = values.get("altitude")
            if h is None:
                ne = horizontal_ned((lat, lon), truth.origin_lla)
            else:
                ned = lla_to_ned((lat, lon, h), truth.origin_lla)
                ne = ned[:2]
            off = float(np.min(np.hypot(*(truth.pos_ned_m[w, :2] - ne).T)))
            if off > limits.position_m:
                bad(m, f"lat {lat:.7f} lon {lon:.7f}, {off:.1f} m from the truth track")
            elif h is not None:
                off_h = float(np.min(np.abs(truth.pos_ned_m[w, 2] - ned[2])))
                if off_h > limits.altitude_m:
                    bad(m, f"altitude {h:.2f} m, {off_h:.2f} m from the truth")
    return out


@dataclass(frozen=True)
class Cadence:
    """How a consumer saw one output over an interval (see :func:`cadence`)."""

    frames: int  # frames with the field available
    longest_gap_s: float  # the longest time without one, input pauses not counted
    active_s: float  # the interval's length less the input pauses in it


def cadence(
    messages: list[Decoded],
    msg_id: str,
    field: str,
    start: float,
    end: float,
    pauses: Sequence[tuple[float, float]] = (),
) -> Cadence:
    """The ``msg_id`` frames with ``field`` available stamped in ``[start, end]``, and the
    longest time in that interval without one (from ``start`` to the first, between two,
    from the last to ``end``).

    ``pauses``: intervals in which the gateway's inputs paused (a test's player stalled): no
    output can go on without its inputs, so their time counts neither in gaps nor in
    ``active_s``."""
    t = np.array(
        [m.t for m in messages
         if m.id == msg_id and start <= m.t <= end and m.fields.get(field) is not None]
    )  # fmt: skip
    edges = np.concatenate([[start], np.sort(t), [end]])

    def paused(a: float, b: float) -> float:
        return sum(max(0.0, min(b, p1) - max(a, p0)) for p0, p1 in pauses)

    gaps = [b - a - paused(a, b) for a, b in itertools.pairwise(edges)]
    return Cadence(len(t), float(max(gaps)), end - start - paused(start, end))


def pauses(times: Sequence[float], min_s: float) -> list[tuple[float, float]]:
    """The intervals longer than ``min_s`` between consecutive ``times`` (sorted)."""
    t = np.asarray(times, dtype=float)
    i = np.flatnonzero(np.diff(t) > min_s)
    return [(float(t[k]), float(t[k + 1])) for k in i]


#: The outputs a guidance controller steers by, each at 50 Hz by default: (message, field).
STEERING_OUTPUTS = (("attitude", "roll"), ("positionRapidUpdate", "latitude"))


def cadence_problems(
    messages: list[Decoded],
    start: float,
    end: float,
    max_gap_s: float,
    pauses: Sequence[tuple[float, float]] = (),
    rate_hz: float = 50.0,
    share: float = 0.95,
) -> list[str]:
    """What a guidance controller would miss in ``[start, end]``: each of
    :data:`STEERING_OUTPUTS` must come at ``share`` of ``rate_hz`` at least, never more than
    ``max_gap_s`` apart (see :func:`cadence` for ``pauses``)."""
    out = []
    for msg_id, field in STEERING_OUTPUTS:
        c = cadence(messages, msg_id, field, start, end, pauses)
        if c.frames < share * rate_hz * c.active_s:
            out.append(f"{msg_id}: {c.frames} frames in {c.active_s:.2f} s, expected "
                       f"{share * rate_hz * c.active_s:.0f} at least")  # fmt: skip
        if c.longest_gap_s > max_gap_s:
            out.append(f"{msg_id}: {c.longest_gap_s:.3f} s without one (at most {max_gap_s} s)")
    return out
