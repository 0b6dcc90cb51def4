"""CPU cost of the output stage: encoders per frame and per PGN, one instant with every PGN
due, and the scheduler and encoders per IMU sample as the fusion core drives them.

Run: ``python benchmarks/output_encode.py``.

- per PGN: ``OutputEncoder.frames`` for one PGN, microseconds per call and per frame;
- output instant: all 9 PGNs due (15 frames), microseconds per instant;
- per IMU sample: 204.8 Hz solutions through ``OutputScheduler`` with the default rates, the
  way :class:`~gateway.fusion.fusion_core.FusionCore` drives it (``is_due`` every sample,
  ``frames`` when due, every frame taken). This is the "encode + scheduler" share of the
  "solution, guard, encode" row of ``benchmarks/replay_speed.py`` (issue 14 target: <= 3 us).
  Also the cost of ``frames`` called on every sample without the ``is_due`` gate (the
  not-due path). Frames are taken one by one and dropped, as replay writes them: keeping
  all 15 000 of a minute in a list would add ~0.4 us a sample of garbage collection.

Times are CPU time (``time.process_time``), the best of a few repeats (the host is shared).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable

from drivers.samples import FixQuality
from gateway.estimation.solution import Convergence, Mode, Solution
from gateway.isobus.j1939 import Pgn
from gateway.isobus.n2k_encode import LAYOUTS, LoopStatus, OutputEncoder
from gateway.isobus.output_scheduler import OutputScheduler

REPEATS = 2000  # solutions per per-PGN and per-instant measurement
BEST_OF = 5
IMU_RATE_HZ = 204.8
STREAM_S = 60.0  # seconds of IMU samples through the scheduler
T0 = 1_700_000_000.0


def solution(t: float, k: int = 0) -> Solution:
    """A fully populated solution, so every field takes the numeric path (``k`` varies it)."""
    a = 1e-3 * (k % 1000)
    return Solution(
        t=t,
        mode=Mode.NAVIGATING,
        roll_rad=0.01 + a,
        pitch_rad=-0.02 - a,
        yaw_rad=(1.0 + 10 * a) % (2 * math.pi),
        yaw_rate_rps=0.05 - a,
        lat_deg=52.1 + 1e-6 * k,
        lon_deg=10.5 - 1e-6 * k,
        alt_m=80.0 + a,
        vel_ned_mps=(2.0, 1.0 + a, 0.0),
        bias_g_rps=(1e-4, 2e-4, 3e-4),
        bias_a_mps2=(0.01, 0.02, 0.03),
        sigma_tilt_rad=math.radians(0.2),
        fix_quality=FixQuality.RTK_FIXED,
        num_sats=15,
        hdop=0.7,
        age_s=1.0,
        gnss_ok=True,
        imu_ok=True,
        convergence=Convergence(gyro_xy=True, gyro_z=True, accel_xy=True),
    )


def best_cpu(fn: Callable[[], object], setup: Callable[[], None] = lambda: None) -> float:
    """The least CPU seconds of ``BEST_OF`` calls of ``fn``, each after an untimed ``setup``."""
    times = []
    for _ in range(BEST_OF):
        setup()
        t0 = time.process_time()
        fn()
        times.append(time.process_time() - t0)
    return min(times)


def per_pgn(sols: list[Solution], loop: LoopStatus) -> None:
    encoder = OutputEncoder()
    print("per PGN (OutputEncoder.frames):      us/call  us/frame")
    for pgn in LAYOUTS:
        n_frames = len(encoder.frames(pgn, sols[0], loop, 0))

        def run(pgn: Pgn = pgn) -> None:
            for k, sol in enumerate(sols):
                encoder.frames(pgn, sol, loop, k % 253)

        t = best_cpu(run) / len(sols) * 1e6
        print(f"  {pgn.value:6d} {pgn.name:26s} {t:7.2f}  {t / n_frames:7.2f}")


def instant(sols: list[Solution], loop: LoopStatus) -> None:
    encoder = OutputEncoder()
    frames = sum(len(encoder.frames(pgn, sols[0], loop, 0)) for pgn in LAYOUTS)

    def run() -> None:
        for k, sol in enumerate(sols):
            for pgn in LAYOUTS:
                encoder.frames(pgn, sol, loop, k % 253)

    t = best_cpu(run) / len(sols) * 1e6
    print(f"output instant, all {len(LAYOUTS)} PGNs due ({frames} frames): {t:.1f} us")


def stream(loop: LoopStatus) -> None:
    n = round(STREAM_S * IMU_RATE_HZ)
    sols = [solution(T0 + k / IMU_RATE_HZ, k) for k in range(n)]
    schedulers: list[OutputScheduler] = []
    counts: list[int] = []

    def fresh() -> None:  # a new scheduler (and encoder) for each run, built untimed
        schedulers[:] = [OutputScheduler()]

    def gated() -> None:  # as FusionCore.on_imu; replay writes each frame and drops it
        scheduler, count = schedulers[0], 0
        for sol in sols:
            if scheduler.is_due(sol.t):
                for _ in scheduler.frames(sol, loop):
                    count += 1
        counts.append(count)

    def ungated() -> None:
        scheduler, count = schedulers[0], 0
        for sol in sols:
            for _ in scheduler.frames(sol, loop):
                count += 1

    t_gated = best_cpu(gated, fresh) / n * 1e6
    t_ungated = best_cpu(ungated, fresh) / n * 1e6
    per_s = counts[-1] / STREAM_S
    print(
        f"per IMU sample, {IMU_RATE_HZ} Hz, default rates ({per_s:.0f} frames/s): "
        f"{t_gated:.2f} us encode + scheduler (target <= 3)"
    )
    print(f"  frames() on every sample, no is_due gate: {t_ungated:.2f} us")


def main() -> None:
    loop = LoopStatus(address_claimed=True)
    sols = [solution(T0 + k * 0.1, k) for k in range(REPEATS)]
    per_pgn(sols, loop)
    instant(sols, loop)
    stream(loop)


if __name__ == "__main__":
    main()
