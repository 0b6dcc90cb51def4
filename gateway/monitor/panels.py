"""The monitor's text, from a :class:`~gateway.monitor.bus_state.BusState`: pure functions, so
that what a person reads is tested without a terminal.

Everything is in words and units: the DBC's value names (``RTK_FIXED``) become ``RTK fixed``,
angles are degrees, "not available" is ``n/a``. No PGN number is needed to read it.
"""

from __future__ import annotations

from drivers.units import RAD_TO_DEG
from gateway.monitor.bus_state import BusState, NavSource
from gateway.readback.frame_decoder import Value

NA = "n/a"
_ACRONYMS = frozenset({"GNSS", "DGNSS", "RTK", "PPS", "IMU", "EKF", "GPS", "SBAS"})
#: NAVGW_STATUS health flags: signal -> (text when set, text when clear; "" says nothing).
HEALTH_FLAGS = {
    "IMU_OK": ("IMU ok", "IMU NOT OK"),
    "GNSS_OK": ("GNSS ok", "GNSS NOT OK"),
    "ADDRESS_CLAIMED": ("address claimed", "address NOT claimed"),
    "STATIONARY": ("stationary", "moving"),
    "REVERSING": ("reversing", ""),
    "IMU_ALARM": ("IMU ALARM (a DIAG_STAT flag is set)", ""),
}
ESTIMATOR_FLAGS = {
    "GYRO_XY_CONVERGED": "gyro x/y",
    "GYRO_Z_CONVERGED": "gyro z",
    "ACCEL_XY_CONVERGED": "accel x/y",
}


def words(value: Value) -> str:
    """A DBC value name in words (``RTK_FIXED`` -> ``RTK fixed``); ``n/a`` for None."""
    if value is None:
        return NA
    if not isinstance(value, str):
        return str(value)
    return " ".join(w if w in _ACRONYMS else w.lower() for w in value.split("_"))


def _num(value: float | None, spec: str, unit: str = "") -> str:
    return f"{value:{spec}}{unit}" if value is not None else NA


def _deg(value: float | None, spec: str = "+8.2f") -> str:
    return _num(value * RAD_TO_DEG if value is not None else None, spec, " deg")


def mode_text(src: NavSource | None) -> str:
    """``NAVIGATING``, ``FAULT``, ...; ``no status`` before the first NAVGW_STATUS."""
    mode = src.value("NAVGW_STATUS", "MODE") if src is not None else None
    return str(mode) if mode is not None else "no status"


def status_text(src: NavSource | None) -> str:
    """Fix quality, health flags in words, IMU samples lost, tilt sigma."""
    if src is None or not src.is_navgw:
        return "no NAVGW_STATUS from this source"
    value = src.value
    fix = words(value("NAVGW_STATUS", "FIX_QUALITY"))
    health = [
        on if value("NAVGW_STATUS", flag) else off for flag, (on, off) in HEALTH_FLAGS.items()
    ]
    engine = "EKF" if value("NAVGW_STATUS", "ENGINE_EKF") else "observer"
    lost = value("NAVGW_STATUS", "IMU_SAMPLES_LOST")
    return "\n".join(
        [
            f"fix       {fix}",
            f"health    {', '.join(h for h in health if h)}",
            f"engine    {engine}",
            f"IMU lost  {lost} samples in the last second (most: {src.most_imu_lost})",
            f"tilt 1σ   {_num(src.number('NAVGW_STATUS', 'SIGMA_TILT'), '.2f', ' deg')}",
        ]
    )


def motion_text(src: NavSource | None) -> str:
    """Attitude, yaw rate, reference point position, speed and course, satellites."""
    if src is None:
        return "no navigation frames"
    n = src.number
    method = words(src.value("GNSS_POSITION_DATA", "METHOD"))
    return "\n".join(
        [
            f"roll      {_deg(n('ATTITUDE', 'ROLL'))}",
            f"pitch     {_deg(n('ATTITUDE', 'PITCH'))}",
            f"heading   {_deg(n('VESSEL_HEADING', 'HEADING'), '8.2f')}",
            f"yaw rate  {_deg(n('RATE_OF_TURN', 'RATE'), '+8.3f')}/s",
            f"latitude  {_num(n('POSITION_RAPID_UPDATE', 'LATITUDE'), '.7f', ' deg')}",
            f"longitude {_num(n('POSITION_RAPID_UPDATE', 'LONGITUDE'), '.7f', ' deg')}",
            f"altitude  {_num(n('GNSS_POSITION_DATA', 'ALTITUDE'), '.2f', ' m')}",
            f"speed     {_num(n('COG_SOG_RAPID_UPDATE', 'SOG'), '.2f', ' m/s')}, course "
            f"{_deg(n('COG_SOG_RAPID_UPDATE', 'COG'), '.1f')}",
            f"position  {method}, {_num(n('GNSS_POSITION_DATA', 'NUMBER_OF_SVS'), '.0f')} "
            f"satellites, HDOP {_num(n('GNSS_POSITION_DATA', 'HDOP'), '.2f')}",
        ]
    )


def bias_text(src: NavSource | None) -> str:
    """Gyro and accelerometer bias estimates, and which have converged."""
    if src is None:
        return "no bias estimates"
    n = src.number
    gyro = "  ".join(
        f"{a} {_num(n('NAVGW_GYRO_BIAS', f'GYRO_BIAS_{a.upper()}'), '+.4f')}" for a in "xyz"
    )
    accel = "  ".join(
        f"{a} {_num(n('NAVGW_ACCEL_BIAS', f'ACCEL_BIAS_{a.upper()}'), '+.4f')}" for a in "xyz"
    )
    lines = [f"gyro deg/s    {gyro}", f"accel m/s^2   {accel}"]
    if src.is_navgw:
        state = [
            f"{label} {'converged' if src.value('NAVGW_STATUS', flag) else 'learning'}"
            for flag, label in ESTIMATOR_FLAGS.items()
        ]
        if src.value("NAVGW_STATUS", "BIAS_LEARNING_FROZEN"):
            state.append("learning FROZEN")
        lines.append(", ".join(state))
    return "\n".join(lines)


def rate_rows(src: NavSource | None, now: float) -> list[tuple[str, str, str, str]]:
    """Rows of the rate table: message, measured Hz, configured Hz, verdict. A message that
    is not periodic in SPEC 4 (a heartbeat, a claim) shows how many were received instead."""
    if src is None:
        return []
    return [
        (
            words(rate.name),
            _num(rate.measured_hz, ".1f")
            if rate.configured_hz is not None
            else f"{rate.received} received",
            _num(rate.configured_hz, "g") if rate.configured_hz is not None else "",
            rate.verdict,
        )
        for rate in src.rates(now)
    ]


def claim_rows(state: BusState) -> list[tuple[str, str, str]]:
    """Rows of the claims table: address, who (navgw or another node), the NAME in words."""
    rows = []
    for address, claim in sorted(state.claims.by_address.items()):
        source = state.sources.get(address)
        who = (
            "cannot claim"
            if claim.cannot_claim
            else "navgw"
            if source is not None and source.is_navgw
            else "other node"
        )
        rows.append((f"0x{address:02X}", who, claim.describe()))
    return rows


def sources_text(state: BusState) -> str:
    """The navigation sources heard and which is shown."""
    if not state.nav_sources:
        return "no navigation source heard"
    return "sources: " + "  ".join(
        f"{'[' if a == state.selected else ''}0x{a:02X}{' navgw' if s.is_navgw else ''}"
        f"{']' if a == state.selected else ''}"
        for a, s in state.nav_sources.items()
    )


def counters_text(state: BusState) -> str:
    """Frames read, decoded, unknown, malformed (with the last reason), other nodes' traffic."""
    s = state.decoder.stats
    ours = set(state.nav_sources)
    others = {a: c for a, c in state.frames_by_source.items() if a not in ours}
    text = (
        f"frames {s.frames}  messages {s.decoded}  unknown {s.unknown}  malformed {s.malformed}"
        f"  other nodes {len(others)} ({sum(others.values())} frames)"
    )
    return text + (f"\nlast malformed: {s.last_problem}" if s.last_problem else "")
