"""Output scheduler: rates on a time grid, shared SID, no burst after a gap; bus load."""

import math
from collections import Counter
from collections.abc import Collection

import can
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

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


class ReferenceScheduler:
    """The grid rule of output_scheduler.py, computed PGN by PGN on every call, as the
    scheduler did before issue 14: the slot of ``t`` is ``floor(t * rate + 1e-6)``; a PGN
    is due when its slot is past the last one sent; ``is_due`` compares with the earliest
    next slot's time ``(last + 1 - 1e-6) / rate``."""

    def __init__(self, rates_hz: dict[Pgn, float]) -> None:
        rates = {**DEFAULT_RATES_HZ, **rates_hz}
        self.rates = {pgn: rate for pgn, rate in rates.items() if rate > 0}
        self.last: dict[Pgn, int] = {}
        self.next_due = -math.inf

    def due(self, t: float, only: Collection[Pgn] | None = None) -> list[Pgn]:
        pgns = []
        for pgn, rate in self.rates.items():
            if only is not None and pgn not in only:
                continue
            slot = math.floor(t * rate + 1e-6)
            if pgn not in self.last or slot > self.last[pgn]:
                self.last[pgn] = slot
                pgns.append(pgn)
        self.next_due = min(
            (
                (self.last[p] + 1 - 1e-6) / r if p in self.last else -math.inf
                for p, r in self.rates.items()
            ),
            default=math.inf,
        )
        return pgns

    def is_due(self, t: float) -> bool:
        return t >= self.next_due


rates_hz = st.dictionaries(
    st.sampled_from(list(DEFAULT_RATES_HZ)),
    st.one_of(st.sampled_from([0, 0.0, 1, 1.0, 3.3, 10.0, 20, 50.0, 100.0]), st.floats(0, 100)),
    max_size=9,
)


@st.composite
def times(draw: st.DrawFn) -> list[float]:
    """Solution times: IMU steps, pauses, steps back, repeats, and grid points of the usual
    rates exactly, a float step either side, and a tolerance before."""
    t = draw(st.one_of(st.floats(0, 4e9), st.sampled_from([0.0, 10.0, T0])))
    steps = [1 / IMU_RATE_HZ, 0.02, 0.1, 1.0, 2.5, 0.0, 1e-9, -1 / IMU_RATE_HZ]
    out = []
    for step in draw(st.lists(st.one_of(st.sampled_from(steps), st.floats(-1, 3)), max_size=200)):
        t += step
        out.append(t)
    for k in draw(st.lists(st.integers(0, 10**4), max_size=10)):
        for rate in (50.0, 10.0, 1.0):
            g = (math.floor(t * rate) + k) / rate
            out += [g, math.nextafter(g, -math.inf), math.nextafter(g, math.inf), g - 1e-6 / rate]
    return sorted(out) if draw(st.booleans()) else out


only_pgns = st.one_of(
    st.none(),
    st.just((Pgn.NAVGW_STATUS,)),
    st.sets(st.sampled_from(list(DEFAULT_RATES_HZ))).map(tuple),
)


@settings(max_examples=250, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(rates_hz, times(), st.data())
def test_due_and_is_due_equal_the_reference(
    rates: dict[Pgn, float], ts: list[float], data: st.DataObject
) -> None:
    scheduler, reference = OutputScheduler(rates), ReferenceScheduler(rates)
    for t in ts:
        only = data.draw(only_pgns) if data.draw(st.integers(0, 4)) == 0 else None
        assert scheduler.is_due(t) == reference.is_due(t)
        assert scheduler.due(t, only) == reference.due(t, only), (t, only)


@pytest.mark.parametrize("t", [math.nan, math.inf, -math.inf, -1e308, 1e308, 5e306])
@pytest.mark.parametrize("sent_before", [False, True])
@pytest.mark.parametrize("rates", [{}, {Pgn.ATTITUDE: 1.0, Pgn.NAVGW_STATUS: 100.0}])
def test_due_at_odd_times_raises_or_answers_as_the_reference(
    t: float, sent_before: bool, rates: dict[Pgn, float]
) -> None:
    """Where t * rate overflows for some rates and not others (1 Hz first, 50 Hz next),
    the reference marks the PGNs before the one that raises: so must the scheduler."""
    scheduler, reference = OutputScheduler(rates), ReferenceScheduler(rates)
    if sent_before:
        assert scheduler.due(T0) == reference.due(T0)
    for at, only in [(t, (Pgn.NAVGW_STATUS,)), (t, None), (T0 + 1, None), (T0 + 2, None)]:
        try:
            expected: object = reference.due(at, only)
        except (ValueError, OverflowError) as error:
            with pytest.raises(type(error)):
                scheduler.due(at, only)
        else:
            assert scheduler.due(at, only) == expected
        assert scheduler.is_due(T0 + 3) == reference.is_due(T0 + 3)


def test_frames_not_due_is_empty_and_keeps_the_sid() -> None:
    scheduler = OutputScheduler()
    first = list(scheduler.frames(Solution(t=T0, mode=Mode.NAVIGATING), LOOP))
    for k in range(1, 4):  # 4.9 ms apart: nothing due before T0 + 20 ms
        assert (
            list(scheduler.frames(Solution(t=T0 + k / IMU_RATE_HZ, mode=Mode.NAVIGATING), LOOP))
            == []
        )
    later = list(scheduler.frames(Solution(t=T0 + 0.02, mode=Mode.NAVIGATING), LOOP))
    assert first[0].data[0] == 0 and later[0].data[0] == 1  # the SID advanced once
