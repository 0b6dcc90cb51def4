"""Recorded inputs (SPEC 3 logs) decoded by the live drivers and merged on the host clock.

Replay, the accuracy benchmark and tests feed engines from here, so they see exactly the
samples and fixes the live service would: IMU samples at their reconstructed sample time,
GNSS fixes at their host receive time (after the IMU samples that preceded them). All on
core time (:mod:`drivers.host_clock`): the host clock less the steps the IMU decoder found,
which it finds within 0.375 s of arrivals (:attr:`ImuDecoder.step_pending`, at the default
``wrap_check_s``); the CAN inputs are decoded :data:`DECODE_AHEAD` or more ahead of the one
handed out, so that a fix or another node's frame is put on core time, and the merge and the
output stamps are right, across a step.

Every other frame of the CAN log comes as a :class:`BusFrame`, received from the ISOBUS (SPEC
5: by default the IMU bridge and the ISOBUS are one bus, so a recording of it holds other
nodes' claims, requests and commands, which replay into the gateway's answers), except the
recorded gateway's own: its claims (those of ``own_name``) and every frame from the address
it held. That address is ``own_address`` (the configured preferred one) until a claim of
``own_name`` in the log says another; a cannot-claim, or another NAME's claim of it, leaves
it none. Live, the echo filter
drops our own frames the same way before the claimer sees them.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import can

from drivers.errors import InputError
from drivers.host_clock import HostClock, HostStream, retimed
from drivers.imu_can import ImuCanConfig, ImuDecoder
from drivers.logs.candump import message_of, read_candump
from drivers.logs.nmea_log import NmeaLogReader, read_nmea_log
from drivers.nmea import NmeaDecoder, read_fixes_from_log
from drivers.samples import GnssFix, ImuAux, ImuSample
from gateway.fusion.fusion_core import BusFrame
from gateway.isobus.j1939 import NULL_ADDRESS, FrameId, Pgn

Input = ImuSample | ImuAux | GnssFix | BusFrame
_NAME_BYTES = 8
_SOURCE_MASK = 0xFF

#: CAN inputs decoded in one run, and at least ahead of the one handed out: decoding a run of
#: frames, then fusing a run of samples, keeps each one's code and data hot (replay of the
#: EKF on `short` 33.0 -> 30.1-30.3 us a sample, docs/PERFORMANCE.md), and memory stays flat.
#: Ahead by this many, a step of the host clock is found before any input on the new clock is
#: handed out: a step forward takes the IMU decoder 0.375 s of arrivals (a step back none),
#: 308 samples at 819.2 Hz, the fastest DEC.
DECODE_AHEAD = 512


@dataclass
class SeenLoss:
    """The IMU samples lost on the bus as of the input last handed out: what a live
    decoder's counters say when that input reaches the fusion core (this decoder reads
    ahead). The core reports it on the bus (NAVGW_STATUS byte 6), so a replay tells a loss
    when live would: with the first input after the gap, not at a GNSS fix within it."""

    lost: int = 0
    #: (the first input decoded after a loss, the count then), oldest first
    pending: deque[tuple[object, int]] = field(default_factory=deque)


class LogInputs:
    """Iterate the merged inputs of one recording; the decoders keep their counters."""

    def __init__(
        self,
        can_log: str | Path,
        nmea_log: str | Path,
        imu_config: ImuCanConfig | None = None,
        own_name: int | None = None,
        own_address: int | None = None,
    ) -> None:
        self.can_log, self.nmea_log = Path(can_log), Path(nmea_log)
        for path, what in ((self.can_log, "CAN log"), (self.nmea_log, "NMEA log")):
            if not path.is_file():
                raise InputError(
                    f"{what} not found or not a file", str(path), "a readable SPEC 3 log file"
                )
        self.imu_decoder = ImuDecoder(imu_config or ImuCanConfig())
        self.nmea_decoder = NmeaDecoder(str(self.nmea_log))
        self.can_reader = read_candump(self.can_log)
        self.nmea_reader: NmeaLogReader | None = None
        self.own_name = own_name
        self.own_address = own_address
        self.imu_lost = SeenLoss()  # for the fusion core, not the decoder's counters

    @property
    def bad_can_lines(self) -> int:
        """Malformed candump lines skipped so far."""
        return self.can_reader.bad_lines

    @property
    def bad_nmea_lines(self) -> int:
        """NMEA log lines with a malformed host-time prefix skipped so far."""
        return self.nmea_reader.bad_lines if self.nmea_reader else 0

    def __iter__(self) -> Iterator[Input]:
        self.nmea_reader = read_nmea_log(self.nmea_log)
        gnss = read_fixes_from_log(self.nmea_reader, self.nmea_decoder)
        return _merged(self._can_inputs(), gnss, self.imu_lost, self.imu_decoder.host_clock)

    def _can_inputs(self) -> Iterator[ImuSample | ImuAux | BusFrame]:
        """IMU samples from the bridge's frames; the other nodes' frames as they are.

        Decoded in runs of :data:`DECODE_AHEAD` inputs, each handed out once as many more are
        decoded after it, in order; a loss the decoder finds goes with the first input decoded
        after it (:attr:`imu_lost`). Another node's frame is put on core time as it is
        handed out.
        """
        decoder = self.imu_decoder
        bus_clock = decoder.host_clock.stream()
        others = 0  # other nodes' frames decoded, not yet handed out
        feed_record = decoder.feed_record
        bridge = decoder.frame_keys
        key_mask = decoder.key_mask
        counters, pending = decoder.counters, self.imu_lost.pending
        lost = self.imu_lost.lost = counters.lost
        loss = False  # a loss found, not yet given to an input
        ahead: list[ImuSample | ImuAux | BusFrame] = []
        keep = ahead.append
        item: ImuSample | ImuAux | BusFrame | None
        for record in self.can_reader.records():
            # a common line of the bridge's is decoded as read: no can.Message is made
            if isinstance(record, tuple) and record[1] & key_mask in bridge:
                item = feed_record(record)
            else:
                msg = message_of(record)
                if (
                    msg.is_extended_id
                    and msg.arbitration_id & key_mask not in bridge
                    and self._from_another_node(msg)
                ):
                    item = BusFrame(float(msg.timestamp), msg)  # host time until handed out
                    others += 1
                else:
                    item = feed_record(msg)  # the bridge's; and the others' the decoder counts
            if counters.lost != lost:
                lost, loss = counters.lost, True
            if item is not None:
                if loss:
                    pending.append((item, lost))
                    loss = False
                keep(item)
                if len(ahead) >= 2 * DECODE_AHEAD:
                    if others:
                        others -= _on_core_time(ahead, DECODE_AHEAD, bus_clock, pending)
                    yield from ahead[:DECODE_AHEAD]
                    del ahead[:DECODE_AHEAD]
        _on_core_time(ahead, len(ahead), bus_clock, pending)
        yield from ahead
        decoder.finish()

    def _from_another_node(self, msg: can.Message) -> bool:
        """Not a frame of the recorded gateway: not a claim of its NAME (which tells its
        address), not from the address it held."""
        source = msg.arbitration_id & _SOURCE_MASK
        if FrameId.parse(msg.arbitration_id).pgn == Pgn.ADDRESS_CLAIM:
            data = msg.data
            if len(data) >= _NAME_BYTES and int.from_bytes(data[:_NAME_BYTES], "little") == (
                self.own_name
            ):
                self.own_address = None if source == NULL_ADDRESS else source
                return False
            if source == self.own_address:  # another NAME claims it: its frames from now on
                self.own_address = None
            return True
        return source != self.own_address


def _on_core_time(
    items: list[ImuSample | ImuAux | BusFrame],
    count: int,
    clock: HostStream,
    pending: deque[tuple[object, int]],
) -> int:
    """Put the other nodes' frames among the first ``count`` items on core time (a loss
    pending for one stays with it); returns how many."""
    done = 0
    for i in range(count):
        item = items[i]
        if type(item) is BusFrame:
            items[i] = BusFrame(clock.core(item.t), item.msg)
            for j, (first, lost) in enumerate(pending):
                if first is item:
                    pending[j] = (items[i], lost)
            done += 1
    return done


def _merged(
    can_inputs: Iterator[ImuSample | ImuAux | BusFrame],
    fixes: Iterator[GnssFix],
    seen: SeenLoss,
    clock: HostClock,
) -> Iterator[Input]:
    """The two streams merged by ``t`` as ``heapq.merge(can_inputs, fixes, key=t)`` does
    (the smaller head first, the CAN input on a tie), without a key call and a heap step per
    item: fixes are fifty times rarer than IMU samples. A fix's host receive time is put on
    core time with the host clock steps ``clock`` has (again when it finds one more). A
    loss pending for a CAN input (:class:`SeenLoss`) is told as that input goes out."""
    gnss_clock = clock.stream()
    steps = clock.steps
    fix = next(fixes, None)
    t_fix = 0.0 if fix is None else gnss_clock.core(fix.t, fix.t_utc)
    known = len(steps)  # the steps t_fix was put on core time with
    pending = seen.pending
    for item in can_inputs:
        if fix is not None:
            if len(steps) != known:
                t_fix, known = gnss_clock.core(fix.t, fix.t_utc), len(steps)
            while t_fix < item.t:
                yield retimed(fix, t_fix)
                fix = next(fixes, None)
                if fix is None:
                    break
                t_fix, known = gnss_clock.core(fix.t, fix.t_utc), len(steps)
        if pending and pending[0][0] is item:
            seen.lost = pending.popleft()[1]
        yield item
    while fix is not None:
        t_fix = gnss_clock.core(fix.t, fix.t_utc)
        yield retimed(fix, t_fix)
        fix = next(fixes, None)
