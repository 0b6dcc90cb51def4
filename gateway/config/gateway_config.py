"""The service configuration (TOML): every section, its defaults, and the engine it builds.

SPEC 5 fixes ``[vehicle]``; the other sections are the product's own. Defaults live here
once (output rates come from the scheduler's SPEC 4 table); ``navgw config --example``
prints them with their comments. Lever arms and GNSS timing are given once, in
``[vehicle]`` and ``[gnss]``, and handed to whichever engine runs.
"""

from __future__ import annotations

import dataclasses
import logging
from collections.abc import Iterable
from dataclasses import dataclass, field
from enum import Enum
from pathlib import Path
from typing import Any

from drivers.axis_checks import STUCK_SAMPLES
from gateway.config.config_schema import (
    ConfigError,
    from_table,
    in_range,
    load_toml,
    source_comments,
)
from gateway.estimation.ekf.ekf_config import EkfConfig
from gateway.estimation.epoch_clock import RECEIVE_EPOCH_SIGMA_S, EpochTime
from gateway.estimation.observer.observer_config import ObserverConfig
from gateway.isobus.address_claim import DeviceClass, NameFunction
from gateway.isobus.device_info import (
    DEFAULT_LOAD_EQUIVALENCY,
    DEFAULT_MODEL_ID,
    DEFAULT_PRODUCT_CODE,
    text_problem,
)
from gateway.isobus.j1939 import DEFAULT_MANUFACTURER_CODE, DEFAULT_SOURCE_ADDRESS, Pgn
from gateway.isobus.output_scheduler import DEFAULT_RATES_HZ, MAX_RATE_HZ

log = logging.getLogger(__name__)

Vec3 = tuple[float, float, float]


def _doc(text: str, **extra: Any) -> dict[str, Any]:
    """Field metadata: the comment ``navgw config --example`` prints beside the key."""
    return {"doc": text, **extra}


@dataclass(frozen=True)
class VehicleSection:
    """[vehicle], SPEC 5: where the sensors sit relative to the reference point."""

    antenna_lever_arm_m: Vec3 = field(
        default=(0.0, 0.0, 0.0), metadata=_doc("antenna relative to the reference point, body FRD")
    )
    imu_lever_arm_m: Vec3 = field(
        default=(0.0, 0.0, 0.0), metadata=_doc("IMU relative to the reference point, body FRD")
    )
    imu_mounting_rpy_deg: Vec3 = field(
        default=(0.0, 0.0, 0.0),
        metadata=_doc("IMU axes in the body frame: v_b = Rz(yaw) Ry(pitch) Rx(roll) v_imu"),
    )
    imu_mounting_sigma_deg: float = field(
        default=0.0,
        metadata=_doc(
            "1-sigma of that mounting's roll and pitch, added to the roll/pitch accuracy sent "
            "(NAVGW_STATUS); 0: exact. [calibration] apply sets the applied estimate's",
            **in_range(0.0, 10.0),
        ),
    )


class Engine(Enum):
    """Which estimator runs."""

    OBSERVER = "observer"
    EKF = "ekf"


@dataclass(frozen=True)
class EstimatorSection:
    """[estimator]: the engine; its tuning is in [observer] or [ekf]."""

    engine: Engine = field(
        default=Engine.OBSERVER,
        metadata=_doc('"observer" (Tereshkov bias observer) or "ekf" (GNSS/INS EKF, Gu et al.)'),
    )


@dataclass(frozen=True)
class ImuSection:
    """[imu]: the CAN bus of the ADIS16334 bridge (SPEC 1) and the IMU's datasheet figures."""

    interface: str = field(default="socketcan", metadata=_doc("python-can interface"))
    channel: str = field(default="can0", metadata=_doc("python-can channel"))
    bridge_source_address: int = field(
        default=0x80, metadata=_doc("source address of the bridge's frames", **in_range(0, 253))
    )
    # the IMU's figures, used by both engines (ADIS16334 datasheet values)
    gyro_arw_deg_per_sqrt_h: float = field(
        default=2.0,
        metadata=_doc("gyro angular random walk", **in_range(1e-6, 1e3)),
    )
    accel_vrw_mps_per_sqrt_h: float = field(
        default=0.12,
        metadata=_doc("accelerometer velocity random walk", **in_range(1e-6, 1e3)),
    )
    gyro_bias_stability_dps: float = field(
        default=0.007,
        metadata=_doc("gyro in-run bias stability (Allan floor)", **in_range(1e-9, 10.0)),
    )
    accel_bias_stability_mg: float = field(
        default=0.1,
        metadata=_doc("accelerometer in-run bias stability (Allan floor)", **in_range(1e-9, 1e3)),
    )
    bias_correlation_time_s: float = field(
        default=100.0,
        metadata=_doc("Gauss-Markov time of the in-run biases", **in_range(1e-3, 1e6)),
    )
    # bias change with temperature: the engines' bias walks grow by tempco x the temperature's
    # rate, and a stored bias's sigma by tempco x the temperature's change (warm start)
    gyro_bias_tempco_dps_per_c: float = field(
        default=0.01,
        metadata=_doc(
            "gyro bias temperature coefficient, deg/s per degC (ADIS1633x-class datasheet; "
            "the engines' bias walks follow a warm-up by it, up to ten times the class's)",
            **in_range(0.0, 0.1),
        ),
    )
    accel_bias_tempco_mg_per_c: float = field(
        default=0.1,
        metadata=_doc(
            "accelerometer bias temperature coefficient, mg per degC (ADIS1633x-class "
            "datasheet; up to twenty times the class's)",
            **in_range(0.0, 2.0),
        ),
    )
    imu_fault_s: float = field(
        default=1.0,
        metadata=_doc(
            "invalid or saturated IMU samples this long: FAULT", **in_range(1e-3, 3600.0)
        ),
    )
    stuck_samples: int = field(
        default=STUCK_SAMPLES,
        metadata=_doc(
            "an axis's output unchanged this many samples running: stuck, FAULT"
            " (0: off, for a source without noise)",
            **in_range(0, 1_000_000),
        ),
    )


@dataclass(frozen=True)
class GnssSection:
    """[gnss]: the receiver's serial port (SPEC 2) and how its epochs line up with IMU time."""

    port: str = field(default="/dev/ttyUSB0", metadata=_doc("serial device of the receiver"))
    baudrate: int = field(default=115200, metadata=_doc("8N1", **in_range(1200, 4_000_000)))
    epoch_time: EpochTime = field(
        default=EpochTime.AUTO,
        metadata=_doc(
            "auto: NMEA UTC when the receive delays say the host clock follows UTC"
            " (0-0.5 s), else receive; utc (PPS/NTP host) or receive (free clock) to force"
        ),
    )
    receiver_latency_s: float = field(
        default=0.05,
        metadata=_doc(
            "least delay from an epoch to the receipt of its last sentence (receive mode;"
            " navgw calibrate measures it)",
            **in_range(0.0, 1.0),
        ),
    )
    receiver_latency_sigma_s: float = field(
        default=RECEIVE_EPOCH_SIGMA_S,
        metadata=_doc(
            "1-sigma of receiver_latency_s (receive mode); the default: not measured. The"
            " observer says DEGRADED while speed x this is beyond 5 cm; the EKF learns it;"
            " navgw calibrate gives it with the latency",
            **in_range(0.001, 0.5),
        ),
    )


@dataclass(frozen=True)
class IsobusSection:
    """[isobus]: the output bus, the ISO 11783-5 NAME it claims with, its product information."""

    interface: str | None = field(
        default=None, metadata=_doc("python-can interface; unset: [imu]'s")
    )
    channel: str | None = field(default=None, metadata=_doc("python-can channel; unset: [imu]'s"))
    preferred_address: int = field(
        default=DEFAULT_SOURCE_ADDRESS, metadata=_doc("claimed first", **in_range(0, 253))
    )
    identity_number: int = field(
        default=1, metadata=_doc("NAME identity (serial number)", **in_range(0, (1 << 21) - 1))
    )
    manufacturer_code: int = field(
        default=DEFAULT_MANUFACTURER_CODE,
        metadata=_doc("NAME and proprietary-frame manufacturer code", **in_range(0, 2047)),
    )
    ecu_instance: int = field(default=0, metadata=_doc("NAME ECU instance", **in_range(0, 7)))
    function_instance: int = field(
        default=0, metadata=_doc("NAME function instance", **in_range(0, 31))
    )
    device_function: int = field(
        default=NameFunction.OWNSHIP_POSITION_GNSS,
        metadata=_doc("NAME function (145: Ownship Position (GNSS))", **in_range(0, 255)),
    )
    device_class: int = field(
        default=DeviceClass.NAVIGATION,
        metadata=_doc("NAME device class / vehicle system (60: Navigation)", **in_range(0, 127)),
    )
    product_code: int = field(
        default=DEFAULT_PRODUCT_CODE,
        metadata=_doc("PGN 126996 product code (the manufacturer's)", **in_range(0, 65532)),
    )
    model_id: str = field(
        default=DEFAULT_MODEL_ID,
        metadata=_doc("PGN 126996 model id, ASCII, at most 32 characters", check=text_problem),
    )
    model_version: str = field(
        default="",
        metadata=_doc("PGN 126996 model (hardware) version, ASCII, <= 32", check=text_problem),
    )
    load_equivalency: int = field(
        default=DEFAULT_LOAD_EQUIVALENCY,
        metadata=_doc("PGN 126996 current drawn from the bus, x 50 mA", **in_range(0, 252)),
    )


#: [output] key of each SPEC 4 PGN.
OUTPUT_KEYS: dict[str, Pgn] = {
    "attitude_hz": Pgn.ATTITUDE,
    "rate_of_turn_hz": Pgn.RATE_OF_TURN,
    "vessel_heading_hz": Pgn.VESSEL_HEADING,
    "position_rapid_hz": Pgn.POSITION_RAPID_UPDATE,
    "cog_sog_rapid_hz": Pgn.COG_SOG_RAPID_UPDATE,
    "gnss_position_hz": Pgn.GNSS_POSITION_DATA,
    "gyro_bias_hz": Pgn.NAVGW_GYRO_BIAS,
    "accel_bias_hz": Pgn.NAVGW_ACCEL_BIAS,
    "status_hz": Pgn.NAVGW_STATUS,
}


def _rate(key: str) -> Any:
    pgn = OUTPUT_KEYS[key]
    return field(
        default=DEFAULT_RATES_HZ[pgn],
        metadata=_doc(f"PGN {int(pgn)}, 0 = off", **in_range(0.0, MAX_RATE_HZ)),
    )


@dataclass(frozen=True)
class OutputSection:
    """[output]: rate of each SPEC 4 frame, Hz."""

    attitude_hz: float = _rate("attitude_hz")
    rate_of_turn_hz: float = _rate("rate_of_turn_hz")
    vessel_heading_hz: float = _rate("vessel_heading_hz")
    position_rapid_hz: float = _rate("position_rapid_hz")
    cog_sog_rapid_hz: float = _rate("cog_sog_rapid_hz")
    gnss_position_hz: float = _rate("gnss_position_hz")
    gyro_bias_hz: float = _rate("gyro_bias_hz")
    accel_bias_hz: float = _rate("accel_bias_hz")
    status_hz: float = _rate("status_hz")

    def rates_hz(self) -> dict[Pgn, float]:
        """Rates keyed by PGN, as the scheduler takes them."""
        return {pgn: getattr(self, key) for key, pgn in OUTPUT_KEYS.items()}


@dataclass(frozen=True)
class RecordingSection:
    """[recording]: optional recording of the inputs in the SPEC 3 log formats."""

    enabled: bool = field(default=False, metadata=_doc("record IMU frames and NMEA sentences"))
    directory: str = field(default="/var/lib/navgw/recordings", metadata=_doc("where"))
    max_file_mb: float = field(
        default=100.0,
        metadata=_doc("rotate a log at this size", **in_range(0.1, 1e5)),
    )
    keep_files: int = field(
        default=20, metadata=_doc("oldest logs beyond this many are deleted", **in_range(1, 10_000))
    )


@dataclass(frozen=True)
class StateSection:
    """[state]: what the gateway learned of its IMU, kept across starts (warm start)."""

    enabled: bool = field(
        default=True,
        metadata=_doc(
            "load the learned biases at start (used once checked at rest where the vehicle "
            "stopped), save them while running and at stop (see README, Warm start)"
        ),
    )
    directory: str = field(
        default="/var/lib/navgw",
        metadata=_doc("where (systemd StateDirectory=navgw); learned_state.json in it"),
    )
    save_interval_s: float = field(
        default=300.0,
        metadata=_doc("save this often while running (and at a clean stop)", **in_range(10.0, 1e5)),
    )
    temperature_band_c: float = field(
        default=10.0,
        metadata=_doc(
            "kept per IMU temperature band this wide, degC; none used beyond one band away",
            **in_range(1.0, 100.0),
        ),
    )
    max_age_days: float = field(
        default=30.0,
        metadata=_doc("learned biases older than this are not used", **in_range(0.001, 3650.0)),
    )


#: Sections with a plain dataclass, in the order the example prints them.
@dataclass(frozen=True)
class CalibrationSection:
    """[calibration]: the IMU mounting estimate of navgw calibrate on the live inputs; its use."""

    live: bool = field(
        default=True,
        metadata=_doc(
            "estimate the mounting while running: in the status and the log; kept in the "
            "learned state ([state] enabled) once every axis is determined"
        ),
    )
    report_interval_s: float = field(
        default=300.0,
        metadata=_doc("log the estimate this often", **in_range(10.0, 1e5)),
    )
    apply: bool = field(
        default=False,
        metadata=_doc(
            "at start, put the kept estimate in effect instead of [vehicle] "
            "imu_mounting_rpy_deg when it was determined against that one (needs [state] "
            "enabled; never changed while running; navgw state clear after re-mounting)"
        ),
    )


SECTIONS: dict[str, type] = {
    "vehicle": VehicleSection,
    "estimator": EstimatorSection,
    "imu": ImuSection,
    "gnss": GnssSection,
    "isobus": IsobusSection,
    "output": OutputSection,
    "recording": RecordingSection,
    "state": StateSection,
    "calibration": CalibrationSection,
}

#: Engine tuning sections; their shared fields come from [vehicle] and [gnss].
ENGINE_SECTIONS: dict[str, type] = {"observer": ObserverConfig, "ekf": EkfConfig}

#: Engine config fields that come from [vehicle] and [gnss] instead of [observer]/[ekf].
_SHARED = {
    "antenna_lever_arm_m": "vehicle",
    "imu_lever_arm_m": "vehicle",
    "imu_mounting_sigma_deg": "vehicle",
    "epoch_time": "gnss",
    "receiver_latency_s": "gnss",
    "receiver_latency_sigma_s": "gnss",
    "gyro_arw_deg_per_sqrt_h": "imu",
    "accel_vrw_mps_per_sqrt_h": "imu",
    "gyro_bias_stability_dps": "imu",
    "accel_bias_stability_mg": "imu",
    "bias_correlation_time_s": "imu",
    "imu_fault_s": "imu",
    "gyro_bias_tempco_dps_per_c": "imu",
    "accel_bias_tempco_mg_per_c": "imu",
}


@dataclass(frozen=True)
class GatewayConfig:
    """The whole configuration, validated."""

    vehicle: VehicleSection = VehicleSection()
    estimator: EstimatorSection = EstimatorSection()
    imu: ImuSection = ImuSection()
    gnss: GnssSection = GnssSection()
    isobus: IsobusSection = IsobusSection()
    output: OutputSection = OutputSection()
    recording: RecordingSection = RecordingSection()
    state: StateSection = StateSection()
    calibration: CalibrationSection = CalibrationSection()
    observer: ObserverConfig = field(default_factory=ObserverConfig)
    ekf: EkfConfig = field(default_factory=EkfConfig)

    def shared(self, engine_cls: type) -> dict[str, Any]:
        """The settings of ``engine_cls`` given once in [vehicle], [gnss] and [imu] (any
        engine's own ignored)."""
        names = {f.name for f in dataclasses.fields(engine_cls)}
        return {
            key: getattr(getattr(self, section), key)
            for key, section in _SHARED.items()
            if key in names
        }

    def with_engine(self, engine: Engine) -> GatewayConfig:
        """This config with another engine (``--engine`` on the command line)."""
        return dataclasses.replace(self, estimator=EstimatorSection(engine=engine))

    def lever_arm_warning(self) -> str | None:
        """The warning of ``navgw run`` and ``navgw replay`` when the antenna lever arm is zero
        (None when it is set): zero is the default, so a forgotten [vehicle] or --config
        silently moves the reference point to the antenna."""
        if any(self.vehicle.antenna_lever_arm_m):
            return None
        return "[vehicle] antenna_lever_arm_m is zero: the reference point is the antenna"

    def engine_settings(self) -> ObserverConfig | EkfConfig:
        """The configured engine's tuning, with this config's geometry and timing."""
        if self.estimator.engine is Engine.EKF:
            return dataclasses.replace(self.ekf, **self.shared(EkfConfig))
        return dataclasses.replace(self.observer, **self.shared(ObserverConfig))


#: Keys of earlier releases, each with what took its place: ignored with a warning, so that
#: a config written by an older ``navgw config --example`` (every key) still starts the
#: service after an upgrade.
RETIRED_KEYS: dict[str, dict[str, str]] = {
    "observer": {
        "gyro_z_bias_walk_dps_per_sqrt_s": "the z-gyro bias's random walk is the in-run wander "
        "of gyro_bias_stability_dps and bias_correlation_time_s (since 2026-12-04)",
        "tau_heading_s": "the first heading reference after a gap is weighed by its sigma "
        "like any other (since 2026-12-06)",
    },
    "ekf": {
        "align_yaw_sigma_deg": "the first heading's 1-sigma is that of the courses it is "
        "taken from, the last second's above cog_min_speed_mps (since 2026-12-05)",
    },
}

#: Keys of earlier releases now in another section: (old section, key) -> new section. A
#: value given in the old place is taken in the new one (unless set there too), with a
#: warning, so that an older config keeps its meaning.
MOVED_KEYS: dict[tuple[str, str], str] = {
    # the IMU's datasheet figures, in [state] while only the warm start used them
    ("state", "gyro_bias_tempco_dps_per_c"): "imu",
    ("state", "accel_bias_tempco_mg_per_c"): "imu",
}


def _upgraded(table: dict[str, Any], where: str) -> dict[str, Any]:
    """``table`` less the :data:`RETIRED_KEYS` it sets and with the :data:`MOVED_KEYS` in
    their new place, each logged as a warning."""
    out = dict(table)
    for section, retired in RETIRED_KEYS.items():
        given = out.get(section)
        if isinstance(given, dict) and (old := sorted(set(given) & set(retired))):
            out[section] = {k: v for k, v in given.items() if k not in retired}
            for key in old:
                log.warning("%s: %s.%s is ignored: %s", where, section, key, retired[key])
    for (section, key), to in MOVED_KEYS.items():
        given, target = out.get(section), out.get(to, {})
        if not (isinstance(given, dict) and key in given and isinstance(target, dict)):
            continue
        out[section] = {k: v for k, v in given.items() if k != key}
        if key in target:
            log.warning("%s: %s.%s is ignored: %s.%s is set", where, section, key, to, key)
        else:
            out[to] = {**target, key: given[key]}
            log.warning(
                "%s: %s.%s is now %s.%s: taken from [%s]", where, section, key, to, key, section
            )
    return out


def config_from_table(table: dict[str, Any], where: str = "config") -> GatewayConfig:
    """Validate a parsed TOML document; unknown tables and keys are errors that name them
    (but :data:`RETIRED_KEYS`, ignored, and :data:`MOVED_KEYS`, taken in their new place,
    each with a warning)."""
    table = _upgraded(table, where)
    unknown = sorted(set(table) - set(SECTIONS) - set(ENGINE_SECTIONS))
    if unknown:
        raise ConfigError(
            f"unknown section [{unknown[0]}] in {where}: expected one of "
            + ", ".join(f"[{s}]" for s in [*SECTIONS, *ENGINE_SECTIONS])
        )
    sections: dict[str, Any] = {
        name: from_table(cls, table.get(name, {}), name)
        for name, cls in {**SECTIONS, **ENGINE_SECTIONS}.items()
    }
    for name in ENGINE_SECTIONS:
        for key, value in table.get(name, {}).items():
            if key in _SHARED:
                raise ConfigError(f"{name}.{key}: set it once, in [{_SHARED[key]}] {key}")
            if problem := _engine_value_problem(key, getattr(sections[name], key)):
                raise ConfigError(f"{name}.{key} = {value!r}: expected {problem}")
    return GatewayConfig(**sections)


#: Engine tunings that may be zero (a noise term left out) or any value (a bearing).
_MAY_BE_ZERO = frozenset({"vibration_gyro_dps", "vibration_accel_mps2"})
_ANY_VALUE = frozenset({"ab_line_bearing_deg"})


def _engine_value_problem(key: str, value: object) -> str | None:
    """Every number of [observer] and [ekf] is a time constant, a noise, a rate, a speed, a
    gate or a count that the engines divide by or compare against: positive (tau_s = 0 passed
    the check, then replay died dividing by it)."""
    if key in _ANY_VALUE or isinstance(value, bool) or not isinstance(value, int | float):
        return None
    if key in _MAY_BE_ZERO:
        return None if value >= 0 else "a number >= 0"
    return None if value > 0 else "a number > 0"


def load_config(path: str | Path | None) -> GatewayConfig:
    """The config of a TOML file (None: all defaults); errors name the file and the key."""
    if path is None:
        return GatewayConfig()
    table = load_toml(path)  # its own errors name the file
    try:
        return config_from_table(table, str(path))
    except ConfigError as err:
        raise ConfigError(f"{path}: {err}") from None


def example_toml() -> str:
    """A complete, commented config with every default, as ``navgw config --example`` prints."""
    title = "navgw configuration (TOML). Every key is optional; shown are the defaults."
    return config_toml(GatewayConfig(), title, [*SECTIONS, *ENGINE_SECTIONS])


def config_toml(config: GatewayConfig, title: str, sections: Iterable[str]) -> str:
    """``sections`` of ``config`` as commented TOML: each key with its value and its meaning
    (``navgw config --example``; ``navgw sim`` writes a simulated vehicle's this way)."""
    lines = [f"# {title}"]
    for name in sections:
        table = getattr(config, name)
        lines += ["", f"[{name}]", f"# {_section_header(name, type(table))}"]
        comments = source_comments(type(table))
        for f in dataclasses.fields(table):
            if name in ENGINE_SECTIONS and f.name in _SHARED:
                continue
            value = getattr(table, f.name)
            comment = f.metadata.get("doc") or comments.get(f.name)
            text = hex(value) if "address" in f.name else _toml_value(value)
            line = f"{f.name} = {text}" if text is not None else f"# {f.name} = (unset)"
            lines.append(f"{line}  # {comment}" if comment else line)
    return "\n".join(lines) + "\n"


def _section_header(name: str, cls: type) -> str:
    """The line under ``[name]``: the section class's summary, or for an engine's tuning (whose
    class docstring is Sphinx markup) which engine it tunes and where its shared keys are."""
    if name not in ENGINE_SECTIONS:
        return (cls.__doc__ or "").strip().splitlines()[0]
    shared = " and ".join(f"[{section}]" for section in dict.fromkeys(_SHARED.values()))
    return (
        f'tuning of engine = "{name}"; its lever arms, GNSS timing and IMU figures are set '
        f"in {shared}"
    )


def _toml_value(value: Any) -> str | None:
    if value is None:
        return None
    if isinstance(value, Enum):
        return _toml_value(value.value)
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return f'"{value}"'
    if isinstance(value, tuple | list):
        return "[" + ", ".join(str(_toml_value(v)) for v in value) + "]"
    return repr(value)
