"""Fields where the signs of latitude or longitude change under the tractor.

Fiji's cane fields straddle the 180th meridian; farms in Ecuador, Kenya and Brazil the
equator; farms in England, France, Spain and Ghana the prime meridian. The receiver writes
each fix's hemisphere letter (W/E, S/N) and the gateway computes in a local frame, so a field
crossing one of those lines must read, fuse and send positions as anywhere else. Each run is
the 2-minute scenario moved there, replayed through the real drivers, its frames decoded by
the independent ``nmea2000`` package.
"""

from pathlib import Path

import numpy as np
import pytest

from gateway.config.gateway_config import Engine, load_config
from gateway.estimation.geodesy import lla_to_ned
from gateway.offline.log_replay import replay
from sim_bus.scenarios import generate, scenario_from_toml
from sim_bus.truth import Truth
from tests.n2k_check import Decoded, decode_log, implausible_frames, status_modes

#: (name, origin lat, lon deg): the field starts 4-6 m from each line and drives across it
FIELDS = {
    "antimeridian": (-16.8, 179.99995),  # Vanua Levu, Fiji
    "equator-and-prime-meridian": (0.00005, -0.00005),  # both at once: each sign flips
}


def _hemispheres(nmea: Path) -> set[tuple[str, str]]:
    """The (N/S, E/W) letter pairs of a log's GGA sentences."""
    out = set()
    for line in nmea.read_text().splitlines():
        f = line.split(",")
        if f[0].endswith("GGA") and f[3] and f[5]:
            out.add((f[3], f[5]))
    return out


def _horizontal_errors_m(messages: list[Decoded], pgn_id: str, truth: Truth) -> np.ndarray:
    """Horizontal errors (m) of the positions of one PGN after 60 s, against the truth at
    each frame's time (reference point)."""
    rows = [
        m for m in messages
        if m.id == pgn_id and m.fields["latitude"] is not None and m.t - truth.t[0] > 60.0
    ]  # fmt: skip
    lla = np.array([[m.fields["latitude"], m.fields["longitude"], 0.0] for m in rows], dtype=float)
    ned = lla_to_ned(lla, truth.origin_lla)
    t = np.array([m.t for m in rows])
    true_n = np.interp(t, truth.t, truth.pos_ned_m[:, 0])
    true_e = np.interp(t, truth.t, truth.pos_ned_m[:, 1])
    return np.hypot(ned[:, 0] - true_n, ned[:, 1] - true_e)


@pytest.mark.parametrize("engine", [Engine.OBSERVER, Engine.EKF])
@pytest.mark.parametrize("field", sorted(FIELDS))
def test_a_field_across_a_sign_change_of_lat_or_lon_reads_and_sends_as_anywhere(
    tmp_path: Path, field: str, engine: Engine
) -> None:
    lat, lon = FIELDS[field]
    sc = scenario_from_toml(
        {"base": "short", "name": field, "vehicle": {"origin_lla": [lat, lon, 20.0]}}
    )
    run = generate(sc, tmp_path, seed=3)
    seen = _hemispheres(run.gnss_log)
    if field == "antimeridian":
        assert seen == {("S", "E"), ("S", "W")}  # the receiver's letters flip under it
    else:
        assert len({ns for ns, _ in seen}) == 2 and len({ew for _, ew in seen}) == 2
    out = tmp_path / "out.log"
    replay(run.imu_log, run.gnss_log, out, load_config(run.config_file).with_engine(engine))
    truth = Truth.load(run.truth_file)
    messages = decode_log(out)
    assert implausible_frames(messages, truth, status=status_modes(out)) == []
    for pgn_id in ("positionRapidUpdate", "gnssPositionData"):
        err = _horizontal_errors_m(messages, pgn_id, truth)
        assert len(err) > 500 if pgn_id == "positionRapidUpdate" else len(err) > 100
        # RTK fixed: 1 cm of GNSS noise and the tilt's share of a 3 m mast (the field's
        # figures elsewhere: 1.5-2 cm RMS, at most 5 cm)
        assert float(np.sqrt(np.mean(err**2))) < 0.03, pgn_id
        assert float(err.max()) < 0.08, pgn_id
    sent = [
        (lat_out, lon_out) for m in messages
        if m.id == "gnssPositionData"
        and isinstance(lat_out := m.fields["latitude"], float)
        and isinstance(lon_out := m.fields["longitude"], float)
    ]  # fmt: skip
    assert {lon > 0 for _, lon in sent} == {False, True}  # the sent positions cross it too
    if field != "antimeridian":
        assert {lat > 0 for lat, _ in sent} == {False, True}
