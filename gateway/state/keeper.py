"""The warm start as the shells use it: read the store once, seed the engine, save.

:class:`StateKeeper` is what the live service and replay hold: :meth:`StateKeeper.load` at
start (a missing file is a cold start; an unusable one is ONE warning naming the file, what
was wrong and what was expected, then a cold start, never a failure), the fusion core's
``warm_start`` callback (:meth:`StateKeeper.warm_start`: the learned state of the IMU's
temperature band, its sigmas grown by age and temperature change), and saving
(:meth:`StateKeeper.snapshot` in the loop, :meth:`StateKeeper.write` wherever blocking I/O
may run; :meth:`StateKeeper.save` both).

What is saved: the running engine's biases with the sigmas it states for them
(:meth:`gateway.estimation.solution.LearningEstimator.learned_state`), in the band of the
IMU's last temperature, axis by axis only where better than what is stored
(:func:`gateway.state.store.merged`); and the last position and heading. The position and
heading are shown by ``navgw state show`` and are not used to start the engines: a parked
vehicle may have been towed or turned, a prior that may be wrong cannot be sent within its
stated accuracy, and the engines find the heading from the first course over ground (or
HDT) within seconds of driving off anyway.

The IMU mounting (issue 17): the service's live estimate, once every axis is determined, is
kept in the store against the configured mounting it was made with (:meth:`StateKeeper.
snapshot`); with ``[calibration] apply`` a start puts it in effect instead of the configured
one (:func:`effective_start`, the one place that decides, for the service and replay),
never while running: a change of mounting would jump roll and pitch on the bus. The biases
are stored in body axes, so they belong to the mounting IN EFFECT when they were learned
(the store's identity): a start that applies another mounting starts them cold, and keeps
the mounting estimate, which is checked against the configured mounting instead.
"""

from __future__ import annotations

import dataclasses
import logging
import math
from dataclasses import dataclass
from pathlib import Path

from gateway.calibration.mounting import AXES, CalibrationConfig
from gateway.config.gateway_config import GatewayConfig
from gateway.estimation.temperature import TEMP_RANGE_C, plausible
from gateway.fusion.fusion_core import FusionCore, learned_text
from gateway.fusion.rest_check import WarmSeed
from gateway.state.store import (
    STATE_FILE,
    BandEntry,
    Biases,
    BiasGrowth,
    Identity,
    LastPose,
    Mounting,
    StoredState,
    StoreError,
    Vec3,
    angles_text,
    merged,
    mounting_text,
    read_state,
    same_setting,
    seed_for,
    write_state,
)

log = logging.getLogger(__name__)

SECONDS_PER_DAY = 86400.0
#: A stored mounting is applied only with every axis's 1-sigma within navgw calibrate's limit
#: of a determined axis (deg).
MAX_APPLIED_SIGMA_DEG = CalibrationConfig.max_sigma_deg
#: A new live estimate replaces the stored one when its largest 1-sigma is at most this
#: fraction of the stored one's: the mounting applied at the next start, and with it the
#: biases learned under it, does not change for an estimate that is no better.
MORE_PRECISE = 0.8
#: ... or when some axis is further from the stored one than this many of their combined
#: 1-sigma: the IMU has moved (or the store's estimate was wrong), and the new one is true.
MOVED_SIGMAS = 3.0


class StateKeeper:
    """The learned-state file of one configuration (module docstring)."""

    def __init__(self, config: GatewayConfig, directory: str | Path | None = None) -> None:
        """``directory``: where the file is (default: ``[state] directory``)."""
        state = config.state
        self.directory = Path(directory if directory is not None else state.directory)
        self.path = self.directory / STATE_FILE
        self.identity = Identity.from_config(config)
        self.growth = BiasGrowth.from_config(config)
        self.band_width_c = state.temperature_band_c
        self.max_age_s = state.max_age_days * SECONDS_PER_DAY
        self.stored: StoredState | None = None  # usable state: read, and saved since
        self.mounting: Mounting | None = None  # the mounting estimate kept: read, or learned
        self.problem: str | None = None  # why the file read at start is not used
        self.usable_directory = True
        self.saves = 0  # files written

    # --- start --------------------------------------------------------------------------

    def load(self) -> StoredState | None:
        """Read the file; the state if it is usable for this configuration, else None (with
        one warning saying why, or an info line when there is none)."""
        return self.take(self.read())

    def read(self) -> StoredState | None:
        """The file as it is, of whatever identity; None if there is none (an info line) or
        it is unusable (one warning, and :attr:`problem`, saying why)."""
        if not self.directory.is_dir():
            self.usable_directory = False
            self.problem = f"{self.directory} is not a directory"
            log.warning(
                "learned state not kept: %s (systemd's StateDirectory=navgw makes it; or set "
                "[state] directory, or enabled = false): cold start",
                self.problem,
            )
            return None
        try:
            return read_state(self.path)
        except FileNotFoundError:
            log.info("no learned state in %s: cold start", self.path)
        except StoreError as err:
            self._reject(str(err))
        except OSError as err:
            self._reject(f"cannot be read ({err.strerror})")
        except Exception as err:  # never fatal: a warm start is worth no failed start
            self._reject(f"cannot be used ({err!r})")
        return None

    def take(
        self, state: StoredState | None, applied: Mounting | None = None
    ) -> StoredState | None:
        """Start from ``state`` (:meth:`read`'s) with ``applied`` in effect if given (else
        the configured mounting): the state if its biases are usable, else None with one
        warning. Biases learned under another mounting are not (a cold start for them), but
        the mounting estimate is kept: the next save writes the mounting in effect."""
        if applied is not None:
            self.identity = dataclasses.replace(self.identity, imu_mounting_rpy_deg=applied.rpy_deg)
        if state is None:
            return None
        if problem := state.identity.mismatch_but_mounting(self.identity):
            self._reject(f"another IMU or configuration: {problem}")
            return None
        self.mounting = state.mounting
        if not same_setting(
            state.identity.imu_mounting_rpy_deg, self.identity.imu_mounting_rpy_deg
        ):
            self._cold_biases(state.identity.imu_mounting_rpy_deg)
            return None
        self.stored = dataclasses.replace(state, identity=self.identity)
        return self.stored

    def _cold_biases(self, learned_under: Vec3) -> None:
        self.problem = (
            f"biases learned under another IMU mounting ({angles_text(learned_under)} deg; "
            f"{angles_text(self.identity.imu_mounting_rpy_deg)} deg in effect)"
        )
        log.warning(
            "learned state %s: %s: cold start for the biases (the mounting estimate is kept)",
            self.path,
            self.problem,
        )

    def _reject(self, reason: str) -> None:
        self.problem = reason
        log.warning(
            "learned state %s ignored: %s; cold start (the file is replaced at the next save)",
            self.path,
            reason,
        )

    def warm_start(self, temp_c: float, t_s: float) -> WarmSeed | None:
        """The fusion core's callback: the learned state for the IMU at ``temp_c`` at ``t_s``
        (host clock) with the rest to check it against, or None (cold start; a warning says
        why when a store was there)."""
        state = self.stored
        if state is None:
            return None
        try:
            if not plausible(temp_c):
                raise StoreError(
                    f"the IMU reports {temp_c} degC: expected a temperature in "
                    f"[{TEMP_RANGE_C[0]:g}, {TEMP_RANGE_C[1]:g}] degC"
                )
            learned, entry = seed_for(
                state, temp_c, t_s, self.growth, self.band_width_c, self.max_age_s
            )
        except StoreError as err:
            self._reject(str(err))
            return None
        except Exception as err:  # never fatal (this runs inside the fusion core)
            self._reject(f"cannot be used ({err!r})")
            return None
        age_s = t_s - entry.t_s
        age = f"{age_s / 3600.0:.1f} h" if age_s >= 0.0 else "an unknown time (clock went back)"
        log.info(
            "learned state %s: biases of %.1f degC, %s old, grown to %s; used once checked at "
            "rest where the vehicle stopped", self.path, entry.temp_c, age, learned_text(learned),
        )  # fmt: skip
        return WarmSeed(learned, state.rest)

    # --- saving -------------------------------------------------------------------------

    def snapshot(
        self, core: FusionCore, force: bool = False, mounting: Mounting | None = None
    ) -> StoredState | None:
        """The state to write now (kept in memory), or None: nothing better learned (unless
        ``force``: a clean stop writes the last position even so), no temperature or no
        biases yet, or no usable directory. ``mounting``: the live estimate, determined,
        against :attr:`base_rpy_deg`; kept if it replaces the stored one (:func:`replaces`)."""
        learned = core.engine.learned_state()
        temp_c = core.imu_temp_c
        if not self.usable_directory or learned is None or temp_c is None:
            return None
        if not (learned.is_valid() and plausible(temp_c)):
            return None
        sol = core.solution()
        entry = BandEntry(
            temp_c=temp_c,
            t_s=sol.t,
            engine="ekf" if sol.is_ekf else "observer",
            gyro_rps=Biases(learned.bias_g_rps, learned.sigma_g_rps),
            accel_mps2=Biases(learned.bias_a_mps2, learned.sigma_a_mps2),
        )
        state, improved = merged(self.stored, self.identity, entry, self.growth, self.band_width_c)
        if sol.lat_deg is not None and sol.lon_deg is not None and sol.alt_m is not None:
            heading = None if sol.yaw_rad is None else math.degrees(sol.yaw_rad) % 360.0
            state = dataclasses.replace(
                state, last=LastPose(sol.t, sol.lat_deg, sol.lon_deg, sol.alt_m, heading)
            )
        kept = self._kept_mounting(mounting)
        rest = core.rest.record() if core.rest is not None else None
        new_rest = rest is not None and rest != state.rest
        if not (improved or kept is not self.mounting or new_rest or force):
            return None
        self.stored = dataclasses.replace(
            state, mounting=kept, rest=rest if rest is not None else state.rest
        )
        self.mounting = kept
        return self.stored

    def _kept_mounting(self, new: Mounting | None) -> Mounting | None:
        """The mounting estimate to store: ``new`` if it replaces the stored one (a warning
        if it does for being off it), else the stored one."""
        old = self.mounting
        if new is None or not replaces(new, old):
            return old
        if old is not None and _moved(new, old):
            log.warning(
                "IMU mounting estimate %s deg is off the stored %s deg beyond their 1-sigma: "
                "has the IMU moved? Stored in its place (after re-mounting it: navgw state clear)",
                angles_text(new.rpy_deg),
                angles_text(old.rpy_deg),
            )
        return new

    def write(self, state: StoredState) -> bool:
        """Write ``state`` (blocking: fsync); False with a warning if it cannot be."""
        try:
            write_state(self.path, state)
        except (OSError, ValueError) as err:
            log.warning("learned state not saved to %s: %s", self.path, err)
            return False
        self.saves += 1
        return True

    def save(self, core: FusionCore, force: bool = False, mounting: Mounting | None = None) -> bool:
        """:meth:`snapshot` and :meth:`write` at once; True if a file was written."""
        try:
            state = self.snapshot(core, force, mounting)
        except Exception as err:  # never fatal: a stop or a replay must end cleanly
            log.warning("learned state not saved to %s: %r", self.path, err)
            return False
        return state is not None and self.write(state)


# ==================================================================== the IMU mounting


def replaces(new: Mounting, old: Mounting | None) -> bool:
    """Whether a determined live estimate takes the stored one's place: none stored, one
    against another configured mounting, a clearly more precise one (:data:`MORE_PRECISE`),
    or one the IMU has moved away from (:data:`MOVED_SIGMAS`)."""
    return (
        old is None
        or not same_setting(new.base_rpy_deg, old.base_rpy_deg)
        or max(new.sigma_deg) <= MORE_PRECISE * max(old.sigma_deg)
        or _moved(new, old)
    )


def _moved(new: Mounting, old: Mounting) -> bool:
    """Some axis of ``new`` is off ``old`` beyond :data:`MOVED_SIGMAS` combined 1-sigma."""
    return any(
        abs((a - b + 180.0) % 360.0 - 180.0) > MOVED_SIGMAS * math.hypot(sa, sb)
        for a, b, sa, sb in zip(new.rpy_deg, old.rpy_deg, new.sigma_deg, old.sigma_deg, strict=True)
    )


def mounting_problem(config: GatewayConfig, state: StoredState) -> str | None:
    """Why the mounting estimate in ``state`` may not be put in effect with ``config`` (None:
    it may): none stored, the store of another IMU or configuration (the mounting aside:
    the one in effect may be an applied one), estimated against another configured
    mounting, or an axis not determined (1-sigma above :data:`MAX_APPLIED_SIGMA_DEG`)."""
    m = state.mounting
    if m is None:
        return "no mounting estimate stored"
    if problem := state.identity.mismatch_but_mounting(Identity.from_config(config)):
        return f"the store is of another IMU or configuration: {problem}"
    configured, base = config.vehicle.imu_mounting_rpy_deg, m.base_rpy_deg
    if not same_setting(base, configured):
        return (
            f"it was estimated against [vehicle] imu_mounting_rpy_deg = {angles_text(base)}, "
            f"the config has {angles_text(configured)}"
        )
    loose = [
        f"{axis} {sigma:.3f}"
        for axis, sigma in zip(AXES, m.sigma_deg, strict=True)
        if sigma > MAX_APPLIED_SIGMA_DEG
    ]
    if loose:
        return f"not determined: 1-sigma {', '.join(loose)} deg, above {MAX_APPLIED_SIGMA_DEG:g}"
    return None


@dataclass(frozen=True)
class EffectiveStart:
    """What a start takes from the learned state: the config to run with (the stored
    mounting in ``vehicle.imu_mounting_rpy_deg`` when it is applied), the keeper of the
    learned state built for it (None: none kept), the mounting applied (None: the
    configured one is in effect) and the line logged about it (None: apply is off)."""

    config: GatewayConfig
    keeper: StateKeeper | None
    applied: Mounting | None
    message: str | None


def effective_start(config: GatewayConfig, directory: str | Path | None) -> EffectiveStart:
    """Read the learned state in ``directory`` (None: none is kept) and decide, with
    ``[calibration] apply``, which IMU mounting is in effect for the whole run: the stored
    estimate if :func:`mounting_problem` finds none, else the configured one; one line
    logged about it (:func:`_log_start`). Never fatal."""
    keeper = StateKeeper(config, directory) if directory is not None else None
    state = keeper.read() if keeper is not None else None
    problem = _apply_problem(config, keeper, state)
    applied = state.mounting if state is not None and problem is None else None
    if keeper is not None:
        keeper.take(state, applied)
    message = _log_start(config, applied, problem)
    if applied is not None:
        # its roll/pitch 1-sigma goes into the accuracy sent: the estimate is not exact
        vehicle = dataclasses.replace(
            config.vehicle,
            imu_mounting_rpy_deg=applied.rpy_deg,
            imu_mounting_sigma_deg=max(applied.sigma_deg[0], applied.sigma_deg[1]),
        )
        config = dataclasses.replace(config, vehicle=vehicle)
    return EffectiveStart(config, keeper, applied, message)


def _log_start(config: GatewayConfig, applied: Mounting | None, problem: str | None) -> str | None:
    """The line logged: INFO when ``applied``, a WARNING naming ``problem`` when apply was
    asked in vain; None (nothing logged) when apply is off."""
    if applied is not None:
        line = (
            f"IMU mounting from the learned state applied: {mounting_text(applied)} "
            f"(estimated against the configured {angles_text(applied.base_rpy_deg)})"
        )
        log.info("%s", line)
        return line
    if not config.calibration.apply:
        return None
    configured = angles_text(config.vehicle.imu_mounting_rpy_deg)
    line = (
        f"IMU mounting from the learned state not applied: {problem}; the configured "
        f"[vehicle] imu_mounting_rpy_deg = {configured} is in effect"
    )
    log.warning("%s", line)
    return line


def _apply_problem(
    config: GatewayConfig, keeper: StateKeeper | None, state: StoredState | None
) -> str | None:
    """Why no stored mounting is applied at this start (None: it is)."""
    if not config.calibration.apply:
        return "[calibration] apply is off"
    if keeper is None:
        return "no learned state is kept (the service needs [state] enabled, replay --state-dir)"
    if state is None:
        return (
            f"the learned state is unusable: {keeper.problem}"
            if keeper.problem
            else ("no learned state stored yet")
        )
    return mounting_problem(config, state)
