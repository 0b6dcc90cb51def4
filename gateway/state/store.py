"""The learned-state file: its schema, strict reading, atomic writing, and the bias model.

One JSON file (``learned_state.json`` in ``[state] directory``), human readable, that a
gateway writes every ``save_interval_s`` and at a clean stop and reads at start:

- ``schema_version`` (:data:`SCHEMA_VERSION`), ``written_s`` (host clock, UTC s);
- ``identity``: what the biases belong to (:class:`Identity`): the IMU bridge's source
  address, the gateway's NAME identity number, the IMU mounting and both lever arms;
- ``bands``: per IMU temperature band, the gyro (rad/s) and accelerometer (m/s^2) bias
  estimates with their 1-sigma per body axis, as of ``t_s`` at ``temp_c``
  (:class:`BandEntry`);
- ``last``: the last reference-point position and heading (shown, not used: see
  :mod:`gateway.state.keeper`);
- ``rest``: the last stretch the vehicle stood still (:class:`gateway.fusion.rest_check.
  RestRecord`: where, and the IMU's mean specific force and rate there), which a warm start
  must find again before it uses the biases; or null (optional in schema 1 like ``mounting``:
  a file without it reads as none, and its biases are then not used);
- ``mounting``: the service's live IMU mounting estimate, once determined (:class:`Mounting`),
  with the configured mounting it was made against (``base_rpy_deg``); or null. The field was
  optional in schema 1 from the start, so ``base_rpy_deg`` came without a new version: a
  mounting entry without it (nothing wrote one) reads as none, and a navgw that does not know
  the key reads the rest of the file as before.

Reading is strict: anything but a complete, finite, physically possible state of this
schema is a :class:`StoreError` whose message says what was wrong and what was expected,
and the caller starts cold. Writing is atomic: a temporary file in the same directory,
written, flushed and fsync'ed, renamed over the old one, the directory fsync'ed; a crash at
any point leaves the old file or the new one, never a mix.

A stored sigma is the honest 1-sigma when it was stored; :class:`BiasGrowth` grows it by
what the IMU does since: the in-run bias wander (the datasheet's bias stability as a
Gauss-Markov process: its change over dt has the variance 2 sigma^2 (1 - exp(-dt / T)), a
random walk at first, bounded by the process's own spread) and the temperature change
(the temperature coefficient times the difference), never below the stored sigma.
"""

from __future__ import annotations

import json
import math
import os
import tempfile
from collections.abc import Iterable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from drivers.units import DEG_TO_RAD, GRAVITY_MPS2, MG_MPS2
from gateway.calibration.mounting import AXES
from gateway.config.gateway_config import GatewayConfig
from gateway.estimation.ekf.ekf_config import GM_ALLAN_FLOOR
from gateway.estimation.solution import LearnedState
from gateway.estimation.temperature import TEMP_RANGE_C
from gateway.fusion.rest_check import RestRecord

Vec3 = tuple[float, float, float]

SCHEMA_VERSION = 1
STATE_FILE = "learned_state.json"
#: Two stored angles (deg) or lever arms (m) closer than this are the same setting.
SAME_SETTING = 1e-6
#: Biases beyond these are not an ADIS16334's (initial bias error a few deg/s, some 10 mg):
#: a stored value this large is corruption, not learning.
MAX_GYRO_BIAS_RPS = 5.0 * DEG_TO_RAD
MAX_ACCEL_BIAS_MPS2 = 1.0
MAX_GYRO_SIGMA_RPS = 10.0 * DEG_TO_RAD
MAX_ACCEL_SIGMA_MPS2 = 2.0
#: Earth rate, rad/s: the engines leave it in the gyro bias they learn, in the body axes of
#: the heading they learned at; another heading at the next start moves it by up to this.
EARTH_RATE_RPS = 7.292115e-5


class StoreError(ValueError):
    """A stored state that is not used; the message says what is wrong and what was expected."""


@dataclass(frozen=True)
class Identity:
    """What the learned biases belong to.

    The IMU: the bridge's CAN source address (SPEC 1 frames carry no serial number, so an IMU
    swapped for another behind the same bridge address is not recognised: ``navgw state
    clear`` after replacing it), and the gateway's NAME identity number (a store copied to
    another unit, e.g. with a cloned system image, is not its IMU's). The configuration that
    shapes the biases: the mounting rotation (biases are stored in body axes) and the lever
    arms (a wrong one is learned into the biases). The engine may differ: both use the IMU's
    biases.
    """

    bridge_source_address: int
    identity_number: int
    imu_mounting_rpy_deg: Vec3
    imu_lever_arm_m: Vec3
    antenna_lever_arm_m: Vec3

    @classmethod
    def from_config(cls, config: GatewayConfig) -> Identity:
        """The identity ``config`` describes."""
        v = config.vehicle
        return cls(
            bridge_source_address=config.imu.bridge_source_address,
            identity_number=config.isobus.identity_number,
            imu_mounting_rpy_deg=v.imu_mounting_rpy_deg,
            imu_lever_arm_m=v.imu_lever_arm_m,
            antenna_lever_arm_m=v.antenna_lever_arm_m,
        )

    def mismatch(self, expected: Identity) -> str | None:
        """What differs from ``expected`` (the config's), first field first; None if alike."""
        for name in self.__dataclass_fields__:
            mine, theirs = getattr(self, name), getattr(expected, name)
            same = mine == theirs if isinstance(mine, int) else same_setting(mine, theirs)
            if not same:
                return f"{name} is {_text(mine)} in the store, {_text(theirs)} in the config"
        return None

    def mismatch_but_mounting(self, expected: Identity) -> str | None:
        """:meth:`mismatch` on every field but the mounting: the biases are the IMU's in
        body axes, and only they depend on it."""
        mounting = expected.imu_mounting_rpy_deg
        return replace(self, imu_mounting_rpy_deg=mounting).mismatch(expected)


def same_setting(a: Vec3, b: Vec3) -> bool:
    """Two stored vectors of a setting (mounting deg, lever arm m) are the same one."""
    return all(abs(x - y) <= SAME_SETTING for x, y in zip(a, b, strict=True))


@dataclass(frozen=True)
class Biases:
    """One sensor's bias estimate and its 1-sigma per body axis (SI)."""

    bias: Vec3
    sigma: Vec3


@dataclass(frozen=True)
class BandEntry:
    """The biases learned at IMU temperature ``temp_c`` (degC), valid as of ``t_s`` (host
    clock, UTC s), by ``engine``."""

    temp_c: float
    t_s: float
    engine: str
    gyro_rps: Biases
    accel_mps2: Biases


@dataclass(frozen=True)
class LastPose:
    """The reference point's last position and heading (None: not known then)."""

    t_s: float
    lat_deg: float
    lon_deg: float
    alt_m: float
    heading_deg: float | None


@dataclass(frozen=True)
class Mounting:
    """An IMU mounting estimate: roll, pitch, yaw of the IMU axes in the body frame, deg, as
    ``[vehicle] imu_mounting_rpy_deg`` (the whole mounting, not a residual), with their
    1-sigma, deg; and ``base_rpy_deg``, the configured mounting it was estimated against
    (the samples were turned by it, or by a mounting applied on top of it): it is valid for
    that configuration only (:func:`gateway.state.keeper.mounting_problem`)."""

    rpy_deg: Vec3
    sigma_deg: Vec3
    base_rpy_deg: Vec3


@dataclass(frozen=True)
class StoredState:
    """The whole file."""

    identity: Identity
    bands: tuple[BandEntry, ...]  # ordered by temperature
    written_s: float
    last: LastPose | None = None
    mounting: Mounting | None = None
    rest: RestRecord | None = None


# =================================================================== the bias model


@dataclass(frozen=True)
class BiasGrowth:
    """How a stored bias's 1-sigma grows with time and temperature (module docstring)."""

    gyro_wander_rps: float  # Gauss-Markov sigma of the in-run gyro bias
    accel_wander_mps2: float
    correlation_s: float
    gyro_tempco_rps_per_c: float
    accel_tempco_mps2_per_c: float

    @classmethod
    def from_config(cls, config: GatewayConfig) -> BiasGrowth:
        """[imu]'s bias stability (datasheet Allan floor / 0.6174), correlation time and
        temperature coefficients."""
        imu = config.imu
        return cls(
            gyro_wander_rps=imu.gyro_bias_stability_dps * DEG_TO_RAD / GM_ALLAN_FLOOR,
            accel_wander_mps2=imu.accel_bias_stability_mg * MG_MPS2 / GM_ALLAN_FLOOR,
            correlation_s=imu.bias_correlation_time_s,
            gyro_tempco_rps_per_c=imu.gyro_bias_tempco_dps_per_c * DEG_TO_RAD,
            accel_tempco_mps2_per_c=imu.accel_bias_tempco_mg_per_c * MG_MPS2,
        )

    def _grow(
        self, sigma: Vec3, wander: float, tempco: float, dt_s: float, dtemp_c: float, extra: float
    ) -> Vec3:
        """``dt_s`` < 0 (the clock went back: the real age is unknown) counts as forever."""
        share = 1.0 if dt_s < 0.0 else -math.expm1(-dt_s / self.correlation_s)
        add = 2.0 * wander**2 * share + (tempco * dtemp_c) ** 2 + extra**2
        return (
            math.sqrt(sigma[0] ** 2 + add),
            math.sqrt(sigma[1] ** 2 + add),
            math.sqrt(sigma[2] ** 2 + add),
        )

    def gyro(self, b: Biases, dt_s: float, dtemp_c: float, earth: bool = False) -> Biases:
        """Gyro biases ``dt_s`` and ``dtemp_c`` later (``earth``: at another heading too)."""
        extra = EARTH_RATE_RPS if earth else 0.0
        g = self._grow(
            b.sigma, self.gyro_wander_rps, self.gyro_tempco_rps_per_c, dt_s, dtemp_c, extra
        )
        return Biases(b.bias, g)

    def accel(self, b: Biases, dt_s: float, dtemp_c: float) -> Biases:
        """Accelerometer biases ``dt_s`` and ``dtemp_c`` later."""
        a = self._grow(
            b.sigma, self.accel_wander_mps2, self.accel_tempco_mps2_per_c, dt_s, dtemp_c, 0.0
        )
        return Biases(b.bias, a)


def band_of(temp_c: float, width_c: float) -> int:
    """Index of the temperature band of ``temp_c`` (bands of ``width_c`` from 0 degC)."""
    return math.floor(temp_c / width_c)


def seed_for(
    state: StoredState,
    temp_c: float,
    now_s: float,
    growth: BiasGrowth,
    band_width_c: float,
    max_age_s: float,
) -> tuple[LearnedState, BandEntry]:
    """The learned state to start from with the IMU at ``temp_c`` at ``now_s``: the entry of
    its temperature band, else the nearest within one band width; its sigmas grown by the
    time and temperature since (:class:`BiasGrowth`, Earth rate included). StoreError when
    no entry is that near, or the chosen one is older than ``max_age_s``."""
    if not state.bands:
        raise StoreError("no biases learned yet; expected at least one temperature band")
    same = [
        e for e in state.bands if band_of(e.temp_c, band_width_c) == band_of(temp_c, band_width_c)
    ]
    entry = min(same or state.bands, key=lambda e: abs(e.temp_c - temp_c))
    if not same and abs(entry.temp_c - temp_c) > band_width_c:
        learned = ", ".join(f"{e.temp_c:.1f}" for e in state.bands)
        raise StoreError(
            f"the IMU is at {temp_c:.1f} degC, its biases were learned at {learned} degC: "
            f"expected one within a {band_width_c:g} degC band"
        )
    age_s = now_s - entry.t_s
    if age_s > max_age_s:
        raise StoreError(
            f"the biases of {entry.temp_c:.1f} degC were learned {age_s / 86400.0:.1f} days "
            f"ago: expected at most {max_age_s / 86400.0:g} days (max_age_days)"
        )
    dtemp = abs(temp_c - entry.temp_c)
    g = growth.gyro(entry.gyro_rps, age_s, dtemp, earth=True)
    a = growth.accel(entry.accel_mps2, age_s, dtemp)
    return LearnedState(g.bias, g.sigma, a.bias, a.sigma), entry


def merged(
    state: StoredState | None,
    identity: Identity,
    entry: BandEntry,
    growth: BiasGrowth,
    band_width_c: float,
) -> tuple[StoredState, bool]:
    """``state`` with ``entry`` in its temperature band, axis by axis the better of the two:
    the stored value grown to the entry's time and temperature, or the entry's (smaller
    sigma wins; a tie keeps the stored). Also True if some axis of the entry was taken: a
    session that has learned nothing better (its first minutes) leaves the store as it is."""
    if state is None or state.identity != identity:
        return StoredState(identity, (entry,), entry.t_s), True
    band = band_of(entry.temp_c, band_width_c)
    same = [e for e in state.bands if band_of(e.temp_c, band_width_c) == band]
    others = [e for e in state.bands if band_of(e.temp_c, band_width_c) != band]
    gyro, accel = entry.gyro_rps, entry.accel_mps2
    taken = [True] * 6  # axes (gyro x, y, z, accel x, y, z) still the entry's
    for old in same:
        dt, dtemp = entry.t_s - old.t_s, abs(entry.temp_c - old.temp_c)
        gyro = _better(gyro, growth.gyro(old.gyro_rps, dt, dtemp), taken, 0)
        accel = _better(accel, growth.accel(old.accel_mps2, dt, dtemp), taken, 3)
    # who learned what is kept: "ekf+observer" when the axes come from both
    engines = {entry.engine} if any(taken) else set()
    if not all(taken):
        engines.update(name for old in same for name in old.engine.split("+"))
    engine = "+".join(sorted(engines))
    new = replace(entry, engine=engine, gyro_rps=gyro, accel_mps2=accel)
    bands = tuple(sorted([*others, new], key=lambda e: e.temp_c))
    return replace(state, bands=bands, written_s=entry.t_s), any(taken)


def _better(new: Biases, old: Biases, taken: list[bool], first: int) -> Biases:
    """Axis by axis the smaller sigma (``old`` on a tie); an axis from ``old`` clears its
    flag in ``taken`` (from index ``first``)."""
    bias, sigma = list(new.bias), list(new.sigma)
    for i in range(3):
        if old.sigma[i] <= sigma[i]:
            bias[i], sigma[i] = old.bias[i], old.sigma[i]
            taken[first + i] = False
    return Biases(_vec(bias), _vec(sigma))


def angles_text(v: Vec3) -> str:
    """'[0.43, -0.74, 0.94]': angles in deg as the config writes them, to 0.01 deg."""
    return "[" + ", ".join(f"{x:.2f}" for x in v) + "]"


def mounting_text(m: Mounting) -> str:
    """'roll 0.43+/-0.09, pitch -0.74+/-0.10, yaw 0.94+/-0.10 deg'."""
    axes = zip(AXES, m.rpy_deg, m.sigma_deg, strict=True)
    return ", ".join(f"{axis} {a:.2f}+/-{s:.2f}" for axis, a, s in axes) + " deg"


def _vec(v: Iterable[float]) -> Vec3:
    a, b, c = v
    return (float(a), float(b), float(c))


def _text(value: Any) -> str:
    if isinstance(value, tuple):
        return "[" + ", ".join(f"{x:g}" for x in value) + "]"
    return str(value)


# ============================================================================== JSON


def to_json(state: StoredState) -> dict[str, Any]:
    """The file's content (units in the key names: SI, degrees only for the mounting)."""
    ident = state.identity
    doc: dict[str, Any] = {
        "schema_version": SCHEMA_VERSION,
        "written_s": state.written_s,
        "identity": {
            "bridge_source_address": ident.bridge_source_address,
            "identity_number": ident.identity_number,
            "imu_mounting_rpy_deg": list(ident.imu_mounting_rpy_deg),
            "imu_lever_arm_m": list(ident.imu_lever_arm_m),
            "antenna_lever_arm_m": list(ident.antenna_lever_arm_m),
        },
        "bands": [
            {
                "temp_c": e.temp_c,
                "t_s": e.t_s,
                "engine": e.engine,
                "gyro_bias_rps": list(e.gyro_rps.bias),
                "gyro_sigma_rps": list(e.gyro_rps.sigma),
                "accel_bias_mps2": list(e.accel_mps2.bias),
                "accel_sigma_mps2": list(e.accel_mps2.sigma),
            }
            for e in state.bands
        ],
        "last": None,
        "mounting": None,
        "rest": None,
    }
    if state.last is not None:
        last = state.last
        doc["last"] = {
            "t_s": last.t_s,
            "lat_deg": last.lat_deg,
            "lon_deg": last.lon_deg,
            "alt_m": last.alt_m,
            "heading_deg": last.heading_deg,
        }
    if state.rest is not None:
        r = state.rest
        doc["rest"] = {
            "t_s": r.t_s,
            "lat_deg": r.lat_deg,
            "lon_deg": r.lon_deg,
            "sigma_m": r.sigma_m,
            "f_b_mps2": list(r.f_b_mps2),
            "w_b_rps": list(r.w_b_rps),
            "sigma_f_mps2": list(r.sigma_f_mps2),
            "sigma_w_rps": list(r.sigma_w_rps),
            "duration_s": r.duration_s,
        }
    if state.mounting is not None:
        doc["mounting"] = {
            "rpy_deg": list(state.mounting.rpy_deg),
            "sigma_deg": list(state.mounting.sigma_deg),
            "base_rpy_deg": list(state.mounting.base_rpy_deg),
        }
    return doc


class _Reader:
    """Typed access to a parsed document; every problem a StoreError naming the field."""

    def __init__(self, table: Any, where: str) -> None:
        if not isinstance(table, dict):
            raise StoreError(f"{where or 'the document'} is {_kind(table)}: expected an object")
        self.table, self.where = table, where

    def _path(self, key: str) -> str:
        return f"{self.where}.{key}" if self.where else key

    def raw(self, key: str) -> Any:
        if key not in self.table:
            raise StoreError(f"field {self._path(key)} is missing")
        return self.table[key]

    def sub(self, key: str) -> _Reader:
        return _Reader(self.raw(key), self._path(key))

    def number(self, key: str, lo: float = -math.inf, hi: float = math.inf) -> float:
        return _number(self.raw(key), self._path(key), lo, hi)

    def integer(self, key: str, lo: int, hi: int) -> int:
        value = self.raw(key)
        if isinstance(value, bool) or not isinstance(value, int) or not lo <= value <= hi:
            raise StoreError(f"{self._path(key)} = {value!r}: expected an integer in [{lo}, {hi}]")
        return value

    def vec3(self, key: str, lo: float = -math.inf, hi: float = math.inf) -> Vec3:
        value = self.raw(key)
        if not isinstance(value, list) or len(value) != 3:
            raise StoreError(f"{self._path(key)} = {value!r}: expected a list of 3 numbers")
        a, b, c = (_number(v, f"{self._path(key)}[{i}]", lo, hi) for i, v in enumerate(value))
        return (a, b, c)

    def text(self, key: str) -> str:
        value = self.raw(key)
        if not isinstance(value, str):
            raise StoreError(f"{self._path(key)} = {value!r}: expected a string")
        return value


def _kind(value: Any) -> str:
    kinds: dict[type, str] = {dict: "an object", list: "a list", str: "a string"}
    return kinds.get(type(value), repr(value))


def _number(value: Any, where: str, lo: float, hi: float) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise StoreError(f"{where} = {value!r}: expected a number")
    if not math.isfinite(value):
        raise StoreError(f"{where} = {value!r}: expected a finite number")
    if not lo <= value <= hi:
        raise StoreError(f"{where} = {value!r}: expected a value in [{lo:g}, {hi:g}]")
    return float(value)


def from_json(doc: Any) -> StoredState:
    """A parsed document checked field by field (StoreError on the first problem)."""
    top = _Reader(doc, "")
    version = top.raw("schema_version")
    if version != SCHEMA_VERSION:
        raise StoreError(f"schema_version = {version!r}: expected {SCHEMA_VERSION}")
    ident = top.sub("identity")
    identity = Identity(
        bridge_source_address=ident.integer("bridge_source_address", 0, 253),
        identity_number=ident.integer("identity_number", 0, (1 << 21) - 1),
        imu_mounting_rpy_deg=ident.vec3("imu_mounting_rpy_deg", -360.0, 360.0),
        imu_lever_arm_m=ident.vec3("imu_lever_arm_m"),
        antenna_lever_arm_m=ident.vec3("antenna_lever_arm_m"),
    )
    bands_raw = top.raw("bands")
    if not isinstance(bands_raw, list):
        raise StoreError(f"bands is {_kind(bands_raw)}: expected a list")
    bands = []
    for i, item in enumerate(bands_raw):
        b = _Reader(item, f"bands[{i}]")
        bands.append(
            BandEntry(
                temp_c=b.number("temp_c", *TEMP_RANGE_C),
                t_s=b.number("t_s", 0.0),
                engine=b.text("engine"),
                gyro_rps=Biases(
                    b.vec3("gyro_bias_rps", -MAX_GYRO_BIAS_RPS, MAX_GYRO_BIAS_RPS),
                    _sigmas(b, "gyro_sigma_rps", MAX_GYRO_SIGMA_RPS),
                ),
                accel_mps2=Biases(
                    b.vec3("accel_bias_mps2", -MAX_ACCEL_BIAS_MPS2, MAX_ACCEL_BIAS_MPS2),
                    _sigmas(b, "accel_sigma_mps2", MAX_ACCEL_SIGMA_MPS2),
                ),
            )
        )
    last = None
    if top.raw("last") is not None:
        lr = top.sub("last")
        heading = lr.raw("heading_deg")
        last = LastPose(
            t_s=lr.number("t_s", 0.0),
            lat_deg=lr.number("lat_deg", -90.0, 90.0),
            lon_deg=lr.number("lon_deg", -180.0, 180.0),
            alt_m=lr.number("alt_m", -1e4, 1e5),
            heading_deg=None if heading is None else lr.number("heading_deg", 0.0, 360.0),
        )
    mounting = None
    if top.raw("mounting") is not None:
        mr = top.sub("mounting")
        rpy, sigma = mr.vec3("rpy_deg", -360.0, 360.0), mr.vec3("sigma_deg", 0.0, 360.0)
        if mr.table.get("base_rpy_deg") is not None:  # none: against an unknown mounting
            mounting = Mounting(rpy, sigma, mr.vec3("base_rpy_deg", -360.0, 360.0))
    rest = None
    if top.table.get("rest") is not None:
        rr = top.sub("rest")
        rest = RestRecord(
            t_s=rr.number("t_s", 0.0),
            lat_deg=rr.number("lat_deg", -90.0, 90.0),
            lon_deg=rr.number("lon_deg", -180.0, 180.0),
            sigma_m=rr.number("sigma_m", 0.0, 1e4),
            f_b_mps2=rr.vec3("f_b_mps2", -3.0 * GRAVITY_MPS2, 3.0 * GRAVITY_MPS2),
            w_b_rps=rr.vec3("w_b_rps", -MAX_GYRO_BIAS_RPS, MAX_GYRO_BIAS_RPS),
            sigma_f_mps2=rr.vec3("sigma_f_mps2", 0.0, GRAVITY_MPS2),
            sigma_w_rps=rr.vec3("sigma_w_rps", 0.0, MAX_GYRO_SIGMA_RPS),
            duration_s=rr.number("duration_s", 0.0),
        )
    return StoredState(
        identity=identity,
        bands=tuple(sorted(bands, key=lambda e: e.temp_c)),
        written_s=top.number("written_s", 0.0),
        last=last,
        mounting=mounting,
        rest=rest,
    )


def _sigmas(b: _Reader, key: str, hi: float) -> Vec3:
    sigma = b.vec3(key, 0.0, hi)
    if min(sigma) <= 0.0:
        raise StoreError(f"{b._path(key)} = {list(sigma)}: expected sigmas > 0")
    return sigma


# ============================================================================ files


def read_state(path: Path) -> StoredState:
    """The state in ``path``; FileNotFoundError if there is none, StoreError if unusable."""
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        raise StoreError("not a text file: expected JSON") from None
    if not text.strip():
        raise StoreError("the file is empty: expected a JSON object")
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as err:
        raise StoreError(f"not valid JSON ({err}): expected a JSON object") from None
    except RecursionError:
        raise StoreError("JSON nested too deep: expected the state's few levels") from None
    return from_json(doc)


def write_state(path: Path, state: StoredState) -> None:
    """Write ``state`` to ``path`` atomically (module docstring); OSError if it cannot be."""
    text = json.dumps(to_json(state), indent=2, allow_nan=False) + "\n"
    directory = path.parent
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=directory)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            f.write(text)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    fsync_directory(directory)


def fsync_directory(directory: Path) -> None:
    """Make a rename in ``directory`` durable (where the platform allows it)."""
    try:
        dir_fd = os.open(directory, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(dir_fd)
    except OSError:
        pass  # some file systems cannot fsync a directory; the rename is done anyway
    finally:
        os.close(dir_fd)


def leftover_temporaries(path: Path) -> list[Path]:
    """Temporary files an interrupted write left beside ``path`` (never read as state)."""
    return sorted(path.parent.glob(f".{path.name}.*.tmp"))
