"""Output scheduler: rates on a time grid, shared SID, no burst after a gap; bus load."""

from collections import Counter

import can
import pytest

from gateway.estimation.solution import Mode, Solution
from gateway.isobus.bus_load import bus_load, frame_bits, frames_per_second
from gateway.isobus.j1939 import FrameId, Pgn
from gateway.isobus.n2k_encode import LAYOUTS, LoopStatus, OutputEncoder
from gateway.isobus.output_scheduler import DEFAULT_RATES_HZ, SID_PGNS, OutputScheduler

IMU_RATE_HZ = 204.8
T0 = 1_700_000_000.0
LOOP = LoopStatus(address_claimed=True)


def solutions(seconds: float, start: float = T0) -> list[Solution]:
    n = round(seconds * IMU_RATE_HZ)
    return [
        Solution(t=start + k / IMU_RATE_HZ, mode=Mode.NAVIGATING, yaw_rad=0.1) for k in range(n)
    ]


def run(
    scheduler: OutputScheduler, sols: list[Solution], loop: LoopStatus = LOOP
) -> list[can.Message]:
    return [frame for s in sols for frame in scheduler.frames(s, loop)]


def per_pgn(frames: list[can.Message]) -> Counter[int]:
    return Counter(FrameId.parse(f.arbitration_id).pgn for f in frames)


def test_default_rates_over_10_s_give_exact_counts() -> None:
    counts = per_pgn(run(OutputScheduler(), solutions(10.0)))
    assert counts == {
        Pgn.ATTITUDE: 500,
        Pgn.RATE_OF_TURN: 500,
        Pgn.VESSEL_HEADING: 100,
        Pgn.POSITION_RAPID_UPDATE: 500,
        Pgn.COG_SOG_RAPID_UPDATE: 100,
        Pgn.GNSS_POSITION_DATA: 700,  # 100 packets of 7 fast-packet frames
        Pgn.NAVGW_GYRO_BIAS: 10,
        Pgn.NAVGW_ACCEL_BIAS: 10,
        Pgn.NAVGW_STATUS: 100,
    }


def test_is_due_is_true_exactly_at_the_instants_due_sends() -> None:
    gated, reference = OutputScheduler(), OutputScheduler()
    asked = []
    for s in solutions(5.0):
        if gated.is_due(s.t):
            asked.append(s.t)
            assert gated.due(s.t)  # never true in vain
    sent_reference = [s.t for s in solutions(5.0) if reference.due(s.t)]
    assert asked == sent_reference and len(asked) == 250  # the 50 Hz instants, none missed


def test_rate_zero_turns_a_pgn_off_and_rates_are_configurable() -> None:
    rates = {Pgn.ATTITUDE: 0.0, Pgn.GNSS_POSITION_DATA: 0, Pgn.NAVGW_STATUS: 1.0}
    counts = per_pgn(run(OutputScheduler(rates), solutions(10.0)))
    assert Pgn.ATTITUDE not in counts
    assert Pgn.GNSS_POSITION_DATA not in counts
    assert counts[Pgn.NAVGW_STATUS] == 10
    assert counts[Pgn.RATE_OF_TURN] == 500


def test_bad_rates_are_refused() -> None:
    with pytest.raises(ValueError, match="-1"):
        OutputScheduler({Pgn.ATTITUDE: -1.0})
    with pytest.raises(ValueError, match="not an output"):
        OutputScheduler({Pgn.ADDRESS_CLAIM: 1.0})


def test_frames_of_one_instant_share_the_sid_which_advances_per_instant() -> None:
    scheduler = OutputScheduler()
    sids: list[int] = []
    for s in solutions(1.0):
        frames = list(scheduler.frames(s, LOOP))
        sid_frames = [
            f
            for f in frames
            if FrameId.parse(f.arbitration_id).pgn in SID_PGNS
            and FrameId.parse(f.arbitration_id).pgn != Pgn.GNSS_POSITION_DATA
        ]
        instant = {f.data[0] for f in sid_frames}
        fast = [f for f in frames if FrameId.parse(f.arbitration_id).pgn == Pgn.GNSS_POSITION_DATA]
        if fast:
            instant.add(fast[0].data[2])  # payload byte 0 sits after seq/frame and length
        assert len(instant) <= 1
        sids.extend(instant)
        assert {f.timestamp for f in frames} <= {s.t}
    assert sids == list(range(50))  # 50 instants in 1 s, SID 0..49


def test_sid_wraps_at_253() -> None:
    scheduler = OutputScheduler({Pgn.ATTITUDE: 50.0})
    frames = run(scheduler, solutions(6.0))
    sids = [f.data[0] for f in frames if FrameId.parse(f.arbitration_id).pgn == Pgn.ATTITUDE]
    assert sids[251:255] == [251, 252, 0, 1]


def test_stable_phase_and_no_burst_after_a_gap() -> None:
    scheduler = OutputScheduler({pgn: 0.0 for pgn in DEFAULT_RATES_HZ} | {Pgn.ATTITUDE: 50.0})
    before = run(scheduler, solutions(1.0))
    after_gap = run(scheduler, solutions(1.0, start=T0 + 3.5))  # 2.5 s without solutions
    assert len(before) == 50 and len(after_gap) == 50
    # every frame sits on the 20 ms grid: within one IMU period after a grid point
    for frame in before + after_gap:
        phase = (frame.timestamp * 50.0) % 1.0
        assert phase < 50.0 / IMU_RATE_HZ + 1e-6


def test_replay_is_deterministic_and_nothing_is_sent_unclaimed() -> None:
    sols = solutions(2.0)
    a = [(f.timestamp, f.arbitration_id, bytes(f.data)) for f in run(OutputScheduler(), sols)]
    b = [(f.timestamp, f.arbitration_id, bytes(f.data)) for f in run(OutputScheduler(), sols)]
    assert a == b
    assert run(OutputScheduler(), sols, LoopStatus(address_claimed=False)) == []


def test_bus_load_of_the_default_output_set() -> None:
    encoder = OutputEncoder()
    sol = Solution(t=T0, mode=Mode.NAVIGATING)
    payload_bytes = {pgn: len(encoder.payload(pgn, sol, LOOP, 0)) for pgn in LAYOUTS}
    assert payload_bytes[Pgn.GNSS_POSITION_DATA] == 47
    assert frame_bits(8) == 160  # 131 bits + 29 worst-case stuff bits
    assert frame_bits(8, worst_case_stuffing=False) == 131
    assert frames_per_second(DEFAULT_RATES_HZ, payload_bytes) == pytest.approx(252.0)
    assert bus_load(DEFAULT_RATES_HZ, payload_bytes) == pytest.approx(0.16128)
    assert bus_load(DEFAULT_RATES_HZ, payload_bytes, worst_case_stuffing=False) == pytest.approx(
        0.132048
    )


def test_a_pgn_alone_first_leaves_the_others_due() -> None:
    """NAVGW_STATUS alone (a silent IMU) before any other PGN was ever sent."""
    scheduler = OutputScheduler()
    status = list(
        scheduler.frames(Solution(t=10.0, mode=Mode.FAULT), LOOP, only=(Pgn.NAVGW_STATUS,))
    )
    assert [FrameId.parse(f.arbitration_id).pgn for f in status] == [Pgn.NAVGW_STATUS]
    assert scheduler.is_due(10.001)
    later = list(scheduler.frames(Solution(t=10.001, mode=Mode.NAVIGATING), LOOP))
    assert Pgn.ATTITUDE in {FrameId.parse(f.arbitration_id).pgn for f in later}
