"""Figures like seed 000's Figures 4 and 5 (true vs estimated biases) and attitude error.

Run:  .venv/bin/python benchmarks/plots.py --scenario field --seed 1 --out docs/img/
      .venv/bin/python benchmarks/plots.py --paper --seed 1 --out docs/img/

``--paper`` uses the field run with seed 000's known biases added (section 4). Writes
``<name>_gyro_bias.png``, ``<name>_accel_bias.png`` and ``<name>_attitude_error.png``. The
observer and, with ``--engines``, other engines of :data:`gateway.demo.baselines.ENGINES` are
drawn; the curves come from :mod:`gateway.demo.accuracy`, as the benchmark's numbers do.
matplotlib is an optional extra (``pip install navgw[plots]``), imported here only.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from accuracy import paper_scenario, run_engines, simulate_inputs

from drivers.units import DEG_TO_RAD
from gateway.demo.accuracy import Trace, attitude_error_rad, truth_at
from sim_bus.scenarios import SCENARIOS
from sim_bus.truth import Truth


def plots(traces: dict[str, Trace], truth: Truth, name: str, out_dir: Path) -> list[Path]:
    """Write the three figures of one run; returns their paths."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out_dir.mkdir(parents=True, exist_ok=True)
    t0 = float(truth.t[0])
    tt = (truth.t - t0)[::20]
    written = []
    for what, col, scale, unit in (
        ("gyro_bias", "bias_g_rps", 1 / DEG_TO_RAD, "deg/s"),
        ("accel_bias", "bias_a_mps2", 1.0, "m/s$^2$"),
    ):
        fig, axes = plt.subplots(2, 1, figsize=(8, 5), sharex=True)
        true = getattr(truth, col)[::20] * scale
        for i, ax in enumerate(axes):
            ax.plot(tt, true[:, i], "k", lw=1.5, label="true")
            for eng, tr in traces.items():
                est = getattr(tr, col)[:, i] * scale
                if np.isfinite(est).any():
                    ax.plot(tr.t - t0, est, lw=0.9, label=eng)
            ax.set_ylabel(f"{'xy'[i]} bias, {unit}")
            ax.grid(alpha=0.4)
        axes[0].legend(loc="upper right", fontsize=8)
        axes[-1].set_xlabel("time, s")
        axes[0].set_title(f"{name}: true and estimated {what.replace('_', ' ')}")
        written.append(_save(fig, out_dir / f"{name}_{what}.png"))
    fig, axes = plt.subplots(2, 1, figsize=(8, 5), sharex=True)
    for eng, tr in traces.items():
        err = attitude_error_rad(tr.rpy_rad, truth_at(truth, tr.t).rpy_rad) / DEG_TO_RAD
        for i, ax in enumerate(axes):
            ax.plot(tr.t - t0, err[:, i], lw=0.7, label=eng)
    for i, ax in enumerate(axes):
        ax.set_ylabel(f"{('roll', 'pitch')[i]} error, deg")
        ax.set_ylim(-0.5, 0.5)
        ax.grid(alpha=0.4)
    axes[0].legend(loc="upper right", fontsize=8)
    axes[-1].set_xlabel("time, s")
    axes[0].set_title(f"{name}: attitude error (estimate - truth)")
    written.append(_save(fig, out_dir / f"{name}_attitude_error.png"))
    return written


def _save(fig: object, path: Path) -> Path:
    fig.tight_layout()  # type: ignore[attr-defined]
    fig.savefig(path, dpi=80)  # type: ignore[attr-defined]
    import matplotlib.pyplot as plt

    plt.close(fig)  # type: ignore[arg-type]
    return path


def main(argv: Sequence[str] | None = None) -> None:
    """Generate the run, record the engines, write the PNGs."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenario", choices=sorted(SCENARIOS), default="field")
    ap.add_argument("--paper", action="store_true", help="field with seed 000's known biases")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--engines", nargs="+", default=["observer"])
    ap.add_argument("--out", type=Path, default=Path("docs/img"))
    args = ap.parse_args(argv)
    scenario = paper_scenario() if args.paper else SCENARIOS[args.scenario]
    data = simulate_inputs(scenario, args.seed)
    traces = run_engines(data, args.engines)
    name = ("paper" if args.paper else args.scenario) + f"_seed{args.seed}"
    for path in plots(traces, data.truth, name, args.out):
        print(path)


if __name__ == "__main__":
    main()
