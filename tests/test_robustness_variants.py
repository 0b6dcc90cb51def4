"""The robustness benchmark's variants, alone and combined (``a+b``), as scenarios."""

import sys
from pathlib import Path

import pytest

from sim_bus.scenarios import scenario_from_toml

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

from robustness import VARIANTS, variant_label, variant_overrides


def test_a_combined_variant_applies_both_setups_to_the_scenario() -> None:
    """A 1 Hz receiver on a free-running host: both changes reach the simulated run."""
    scenario = scenario_from_toml(
        {"base": "field", "name": "x", **variant_overrides("gnss-1hz+host-clock-free")}
    )
    assert scenario.gnss.rate_hz == 1.0
    assert scenario.gnss.host_clock_offset_s == 30.0


def test_sections_merge_key_by_key_the_later_variant_winning() -> None:
    """rough-prompt sets [gnss] latency and [vehicle]; gnss-1hz adds its rate to the same
    [gnss]; latency-150ms after it replaces the latency."""
    merged = variant_overrides("rough-prompt+gnss-1hz+latency-150ms")
    assert merged["gnss"] == {"latency_s": 0.15, "rate_hz": 1.0}
    assert merged["vehicle"] == VARIANTS["rough-prompt"][1]["vehicle"]
    assert VARIANTS["rough-prompt"][1]["gnss"] == {"latency_s": 0.0}  # not changed by merging
    assert variant_label("gnss-1hz+hdt") == "1 Hz receiver; dual-antenna heading (HDT)"


def test_an_unknown_part_is_named_with_the_known_ones() -> None:
    known = r".*known: default, gnss-1hz"
    with pytest.raises(ValueError, match=r"unknown variant 'gnss-2hz' in 'hdt\+gnss-2hz'" + known):
        variant_overrides("hdt+gnss-2hz")
