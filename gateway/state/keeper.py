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
"""

from __future__ import annotations

import logging
import math
from pathlib import Path

from gateway.config.gateway_config import GatewayConfig
from gateway.estimation.solution import LearnedState
from gateway.fusion.fusion_core import FusionCore, learned_text
from gateway.state.store import (
    STATE_FILE,
    TEMP_RANGE_C,
    BandEntry,
    Biases,
    BiasGrowth,
    Identity,
    LastPose,
    StoredState,
    StoreError,
    merged,
    read_state,
    seed_for,
    write_state,
)

log = logging.getLogger(__name__)

SECONDS_PER_DAY = 86400.0


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
        self.problem: str | None = None  # why the file read at start is not used
        self.usable_directory = True
        self.saves = 0  # files written

    # --- start --------------------------------------------------------------------------

    def load(self) -> StoredState | None:
        """Read the file; the state if it is usable for this configuration, else None (with
        one warning saying why, or an info line when there is none)."""
        if not self.directory.is_dir():
            self.usable_directory = False
            log.warning(
                "learned state not kept: %s is not a directory (systemd's StateDirectory=navgw "
                "makes it; or set [state] directory, or enabled = false): cold start",
                self.directory,
            )
            return None
        try:
            state = read_state(self.path)
            if problem := state.identity.mismatch(self.identity):
                raise StoreError(f"another IMU or configuration: {problem}")
        except FileNotFoundError:
            log.info("no learned state in %s: cold start", self.path)
            return None
        except StoreError as err:
            self._reject(str(err))
            return None
        except OSError as err:
            self._reject(f"cannot be read ({err.strerror})")
            return None
        except Exception as err:  # never fatal: a warm start is worth no failed start
            self._reject(f"cannot be used ({err!r})")
            return None
        self.stored = StoredState(
            self.identity, state.bands, state.written_s, state.last, state.mounting
        )
        return self.stored

    def _reject(self, reason: str) -> None:
        self.problem = reason
        log.warning(
            "learned state %s ignored: %s; cold start (the file is replaced at the next save)",
            self.path,
            reason,
        )

    def warm_start(self, temp_c: float, t_s: float) -> LearnedState | None:
        """The fusion core's callback: the learned state for the IMU at ``temp_c`` at ``t_s``
        (host clock), or None (cold start; a warning says why when a store was there)."""
        state = self.stored
        if state is None:
            return None
        try:
            if not _plausible(temp_c):
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
            "learned state %s: biases of %.1f degC, %s old, grown to %s",
            self.path, entry.temp_c, age, learned_text(learned),
        )  # fmt: skip
        return learned

    # --- saving -------------------------------------------------------------------------

    def snapshot(self, core: FusionCore, force: bool = False) -> StoredState | None:
        """The state to write now (kept in memory), or None: nothing better learned (unless
        ``force``: a clean stop writes the last position even so), no temperature or no
        biases yet, or no usable directory."""
        learned = core.engine.learned_state()
        temp_c = core.imu_temp_c
        if not self.usable_directory or learned is None or temp_c is None:
            return None
        if not (learned.is_valid() and _plausible(temp_c)):
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
            last = LastPose(sol.t, sol.lat_deg, sol.lon_deg, sol.alt_m, heading)
            state = StoredState(state.identity, state.bands, state.written_s, last, state.mounting)
        if not (improved or force):
            return None
        self.stored = state
        return state

    def write(self, state: StoredState) -> bool:
        """Write ``state`` (blocking: fsync); False with a warning if it cannot be."""
        try:
            write_state(self.path, state)
        except (OSError, ValueError) as err:
            log.warning("learned state not saved to %s: %s", self.path, err)
            return False
        self.saves += 1
        return True

    def save(self, core: FusionCore, force: bool = False) -> bool:
        """:meth:`snapshot` and :meth:`write` at once; True if a file was written."""
        try:
            state = self.snapshot(core, force)
        except Exception as err:  # never fatal: a stop or a replay must end cleanly
            log.warning("learned state not saved to %s: %r", self.path, err)
            return False
        return state is not None and self.write(state)


def _plausible(temp_c: float) -> bool:
    """A temperature the IMU can have (TEMP_OUT garbage is not a band)."""
    return math.isfinite(temp_c) and TEMP_RANGE_C[0] <= temp_c <= TEMP_RANGE_C[1]
