"""The output of `navgw replay` does not change by accident (restructuring, the fast path).

A fixed simulated run (scenario "short", seed 7, with its own navgw.toml) is replayed with
both engines; the output logs must be byte-identical to the reference, stored as SHA-256
digests in tests/data/regression/replay.json with the inputs' digests (if those differ, the
simulator changed, not the gateway). An intended change of output regenerates the reference:

    .venv/bin/python -m tests.test_output_regression --update

and the commit that does so says why the output changed.
"""

from __future__ import annotations

import hashlib
import json
import subprocess
import sys
from pathlib import Path

import pytest

from gateway.config.gateway_config import Engine, load_config
from gateway.offline.log_replay import replay
from sim_bus.scenarios import SCENARIOS, generate

REFERENCE = Path(__file__).parent / "data" / "regression" / "replay.json"
SCENARIO, SEED = "short", 7


def digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def digests(out: Path) -> dict[str, dict[str, str]]:
    """Digests of the simulated inputs and of each engine's replay output."""
    run = generate(SCENARIOS[SCENARIO], out, seed=SEED)
    config = load_config(run.config_file)
    outputs = {}
    for engine in Engine:
        log = out / f"{engine.value}.log"
        replay(run.imu_log, run.gnss_log, log, config.with_engine(engine))
        outputs[engine.value] = digest(log)
    inputs = {p.name: digest(p) for p in (run.imu_log, run.gnss_log, run.config_file)}
    return {"inputs": inputs, "outputs": outputs}


def test_replay_output_is_byte_identical_to_the_reference(tmp_path: Path) -> None:
    reference = json.loads(REFERENCE.read_text())
    now = digests(tmp_path)
    assert now["inputs"] == reference["inputs"], "the simulator's output changed: see docstring"
    assert now["outputs"] == reference["outputs"]


def _update() -> None:
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        result = digests(Path(tmp))
    head = subprocess.run(
        ["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True, check=False
    ).stdout.strip()
    result["made_at"] = {"commit": head, "scenario": SCENARIO, "seed": SEED}  # type: ignore[dict-item]
    REFERENCE.write_text(json.dumps(result, indent=2) + "\n")
    print(f"wrote {REFERENCE}")


if __name__ == "__main__":
    if sys.argv[1:] != ["--update"]:
        pytest.fail("usage: python -m tests.test_output_regression --update")
    _update()
