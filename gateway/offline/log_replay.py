"""Replay (SPEC 5): recorded logs through the live fusion code, output frames to a log.

The clock is the logs' host clock: each output frame is stamped with the time of the input
that triggered it, so the same input always gives byte-identical output. The core runs on
that clock less the steps it took (:mod:`drivers.host_clock`); the stamps are put back on it.

With a ``state_dir`` the replay is a start of the gateway that has been running before: the
learned state there seeds the engine (as the live service's does, by the IMU temperature of
the first IMU_AUX and the log's clock) and what the engine learned is saved there at the
end, so a recording continuing another replays as the service would have run it. Without
one, every replay starts cold and touches no file but its output.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path

import can

from drivers.host_clock import HostClock
from drivers.logs.candump import CandumpWriter
from drivers.nmea import NmeaCounters
from drivers.samples import ImuCounters, ImuSample
from gateway.config.driver_settings import imu_config
from gateway.config.gateway_config import GatewayConfig
from gateway.fusion.fusion_core import NOTHING, FusionCore, FusionStats
from gateway.offline.log_inputs import Input, LogInputs
from gateway.state.keeper import effective_start

#: Wraps the input iterator, e.g. in a progress bar; gets the CAN log's size in bytes.
Progress = Callable[[Iterable[Input], LogInputs], Iterator[Input]]


@dataclass(frozen=True)
class ReplaySummary:
    """What a replay read, wrote and counted."""

    stats: FusionStats
    imu: ImuCounters
    gnss: NmeaCounters
    bad_can_lines: int
    bad_nmea_lines: int
    log_span_s: float
    wall_s: float
    warm_start: bool = False  # the engine started from the learned state of ``state_dir``
    state_saved: bool = False  # what it learned was saved there

    @property
    def speedup(self) -> float:
        """Log time over wall time."""
        return self.log_span_s / self.wall_s if self.wall_s > 0 else float("inf")


def replay(
    can_log: str | Path,
    nmea_log: str | Path,
    out_log: str | Path,
    config: GatewayConfig | None = None,
    progress: Progress | None = None,
    state_dir: str | Path | None = None,
) -> ReplaySummary:
    """Run the logs through the fusion core and write every output frame (candump -L);
    ``state_dir``: start from the learned state there and save to it at the end (made if
    missing)."""
    config = config or GatewayConfig()
    if state_dir is not None:
        Path(state_dir).mkdir(parents=True, exist_ok=True)
    # the IMU mounting in effect first: the decoder turns the samples by it
    start = effective_start(config, state_dir)
    config, keeper = start.config, start.keeper
    inputs = LogInputs(can_log, nmea_log, imu_config(config))
    warm_start = keeper.warm_start if keeper is not None and keeper.stored else None
    core = FusionCore.from_config(
        config, inputs.imu_lost, warm_start=warm_start, track_rest=keeper is not None
    )
    # the recorded gateway's own frames are no one else's (its claims, and from its address)
    inputs.own_name, inputs.own_address = core.claimer.name, config.isobus.preferred_address
    stream: Iterable[Input] = progress(inputs, inputs) if progress else inputs
    t_first = t_last = None
    host_clock = inputs.imu_decoder.host_clock
    wall = time.perf_counter()
    with CandumpWriter(out_log, config.isobus.channel or config.imu.channel) as writer:
        write_all, on_input, on_imu = writer.write_all, core.on_input, core.on_imu
        for item in stream:
            if t_first is None:
                t_first = item.t
                write_all(core.start(item.t))
            t_last = item.t
            # IMU samples straight to on_imu: on_input would dispatch them there, per sample
            frames = on_imu(item) if type(item) is ImuSample else on_input(item)
            if frames is not NOTHING:  # most IMU samples send nothing
                write_all(_on_host_time(frames, host_clock) if host_clock.steps else frames)
    wall = time.perf_counter() - wall
    saved = keeper is not None and keeper.save(core, force=True)
    return ReplaySummary(
        stats=core.stats,
        imu=inputs.imu_decoder.counters,
        gnss=inputs.nmea_decoder.counters,
        bad_can_lines=inputs.bad_can_lines,
        bad_nmea_lines=inputs.bad_nmea_lines,
        log_span_s=(t_last - t_first) if t_first is not None and t_last is not None else 0.0,
        wall_s=wall,
        warm_start=core.warm_started,
        state_saved=saved,
    )


def _on_host_time(frames: Iterable[can.Message], clock: HostClock) -> Iterator[can.Message]:
    """``frames`` stamped on core time, stamped again on the logs' host clock."""
    for msg in frames:
        msg.timestamp = clock.host(msg.timestamp)
        yield msg


def unreadable(s: ReplaySummary, can_log: str | Path, nmea_log: str | Path) -> str | None:
    """What could not be read (SPEC 5: exit non-zero), None if both logs gave their data."""
    missing = []
    if s.stats.imu_samples == 0:
        missing.append(
            f"{can_log}: no IMU sample ({s.imu.frames} IMU bridge frames, {s.imu.ignored} other "
            f"frames, {s.bad_can_lines} malformed lines); expected candump -L lines of the "
            "bridge's IMU_GYRO/IMU_ACCEL frames (SPEC 1, 3)"
        )
    if s.stats.gnss_fixes == 0:
        missing.append(
            f"{nmea_log}: no GNSS fix ({s.gnss.sentences_ok} valid sentences, "
            f"{s.gnss.checksum_errors} bad checksums, {s.gnss.skipped_bytes} junk bytes, "
            f"{s.bad_nmea_lines} malformed lines); expected NMEA 0183 GGA/RMC lines (SPEC 2, 3)"
        )
    return "\n  ".join(missing) or None
