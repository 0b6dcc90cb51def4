"""The generic config validator: types, 3-vectors, ranges, unknown keys, nested tables."""

from dataclasses import dataclass, field
from enum import Enum

import pytest

from gateway.config.config_schema import ConfigError, from_table, in_range, source_comments


class Engine(Enum):
    OBSERVER = "observer"
    EKF = "ekf"


@dataclass(frozen=True)
class Inner:
    rate_hz: float = field(default=10.0, metadata=in_range(0.0, 100.0))


@dataclass(frozen=True)
class Outer:
    lever_arm_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    count: int = 1
    enabled: bool = True
    name: str | None = None
    engine: Engine = Engine.OBSERVER
    inner: Inner = Inner()


def test_values_convert_and_defaults_fill() -> None:
    cfg = from_table(Outer, {"lever_arm_m": [0, 0.5, -3], "engine": "ekf", "inner": {"rate_hz": 5}})
    assert cfg.lever_arm_m == (0.0, 0.5, -3.0)
    assert cfg.engine is Engine.EKF
    assert cfg.inner == Inner(rate_hz=5.0)
    assert cfg.count == 1 and cfg.name is None


@pytest.mark.parametrize(
    ("table", "message"),
    [
        ({"lever_arm": [0, 0, 1]}, "unknown key vehicle.lever_arm: expected one of count, enabled"),
        ({"lever_arm_m": [0, 1]}, "vehicle.lever_arm_m = [0, 1]: expected a list of 3 numbers"),
        ({"lever_arm_m": [0, "x", 1]}, "vehicle.lever_arm_m[1] = 'x': expected a number"),
        ({"count": 1.5}, "vehicle.count = 1.5: expected an integer"),
        ({"enabled": 1}, "vehicle.enabled = 1: expected true or false"),
        ({"engine": "kalman"}, "vehicle.engine = 'kalman': expected one of 'observer', 'ekf'"),
        ({"inner": {"rate_hz": 500}}, "vehicle.inner.rate_hz = 500: expected a value in [0.0, 100"),
        ({"inner": 3}, "vehicle.inner = 3: expected a table"),
    ],
)
def test_errors_name_key_value_and_expectation(table: dict[str, object], message: str) -> None:
    with pytest.raises(ConfigError) as err:
        from_table(Outer, table, "vehicle")
    assert str(err.value).startswith(message)


@dataclass(frozen=True)
class Commented:
    """Fields documented as the engine tunings are: code comments, not metadata."""

    # --- timing ---
    rate_hz: float = 10.0  # how often
    # heads the group below
    # over two lines
    x_m: float = 0.0
    y_m: float = 0.0  # its own
    z_m: float = 0.0

    # --- a rule is not a field's comment ---
    w_m: float = 0.0
    label: str = field(
        default="#",  # a trailing comment inside the call
    )


def test_source_comments_trailing_else_group_heading() -> None:
    heading = "heads the group below over two lines"
    assert source_comments(Commented) == {
        "rate_hz": "how often",
        "x_m": heading,
        "y_m": "its own",
        "z_m": heading,
        "w_m": "",
        "label": "a trailing comment inside the call",
    }
