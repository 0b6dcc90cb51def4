"""Per-IMU-sample cost of the EKF engine, and what the reduced covariance rate costs in accuracy.

Run:  .venv/bin/python benchmarks/ekf_cost.py [scenario] [seed]

Generates the scenario (default ``short``) through the log formats and the drivers, then runs
:class:`gateway.engine_ekf.EkfEngine` twice: covariance propagated every 50 ms from IMU sums
(default) and at every IMU sample (``covariance_period_s`` = 0). Prints microseconds per IMU
sample (GNSS epochs and NHC amortised) and roll/pitch and position RMS against the truth after
the first minute, for both.
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from drivers.imu_can import read_log
from drivers.nmea import read_fixes_from_log
from drivers.samples import ImuSample
from gateway.ekf_config import EkfConfig
from gateway.engine_ekf import EkfEngine
from gateway.geodesy import lla_to_ned
from sim_bus.scenarios import SCENARIOS, generate
from sim_bus.truth import Truth


def main() -> None:
    """Print cost and accuracy of the EKF engine at two covariance rates."""
    name = sys.argv[1] if len(sys.argv) > 1 else "short"
    seed = int(sys.argv[2]) if len(sys.argv) > 2 else 1
    with tempfile.TemporaryDirectory() as tmp:
        run = generate(SCENARIOS[name], tmp, seed)
        truth = Truth.load(run.truth_file)
        imu = [s for s in read_log(run.imu_log) if isinstance(s, ImuSample)]
        fixes = list(read_fixes_from_log(run.gnss_log))
    print(f"scenario {name} seed {seed}: {len(imu)} IMU samples, {len(fixes)} GNSS epochs")
    for period in (0.05, 0.0):
        cfg = EkfConfig(
            antenna_lever_arm_m=tuple(truth.antenna_lever_arm_m),
            imu_lever_arm_m=tuple(truth.imu_lever_arm_m),
            host_clock_synchronised=True,
            covariance_period_s=period,
        )
        engine = EkfEngine(cfg)
        rp_err, pos_err = [], []
        elapsed = 0.0
        j = 0
        for k, s in enumerate(imu):
            t0 = time.perf_counter()
            while j < len(fixes) and fixes[j].t <= s.t:
                engine.gnss(fixes[j])
                j += 1
            engine.imu(s)
            elapsed += time.perf_counter() - t0
            if k % 41 or s.t - truth.t[0] < 60.0:
                continue
            sol = engine.solution()
            i = int(np.argmin(np.abs(truth.t - s.t)))
            assert sol.roll_rad is not None and sol.pitch_rad is not None
            assert sol.lat_deg is not None and sol.lon_deg is not None and sol.alt_m is not None
            rp_err.append((sol.roll_rad - truth.rpy_rad[i, 0], sol.pitch_rad - truth.rpy_rad[i, 1]))
            pos_err.append(lla_to_ned([sol.lat_deg, sol.lon_deg, sol.alt_m], truth.lla[i]))
        rp = np.degrees(np.sqrt(np.mean(np.square(rp_err), axis=0)))
        ph = np.sqrt(np.mean(np.sum(np.square(pos_err)[:, :2], axis=1)))
        label = "every sample" if period == 0.0 else f"every {period * 1e3:.0f} ms"
        print(f"covariance {label:>13}: {1e6 * elapsed / len(imu):6.1f} us/sample; after 60 s "
              f"roll/pitch RMS {rp[0]:.3f}/{rp[1]:.3f} deg, horizontal position RMS "
              f"{100 * ph:.2f} cm")
    print(f"python {sys.version.split()[0]}; command: .venv/bin/python benchmarks/ekf_cost.py "
          f"{name} {seed}")


if __name__ == "__main__":
    main()
