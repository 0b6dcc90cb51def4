"""Recorded inputs (SPEC 3 logs) decoded by the live drivers and merged on the host clock.

Replay, the accuracy benchmark and tests feed engines from here, so they see exactly the
samples and fixes the live service would: IMU samples at their reconstructed sample time,
GNSS fixes at their host receive time (after the IMU samples that preceded them). Other
nodes' address claims and requests in the CAN log come as :class:`BusFrame` (SPEC 5: they
replay into the gateway's answers); claims of ``own_name`` are the recorded gateway's own.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import can

from drivers.errors import InputError
from drivers.imu_can import ImuCanConfig, ImuDecoder
from drivers.logs.candump import read_candump
from drivers.logs.nmea_log import NmeaLogReader, read_nmea_log
from drivers.nmea import NmeaDecoder, read_fixes_from_log
from drivers.samples import GnssFix, ImuAux, ImuSample
from gateway.fusion.fusion_core import BusFrame
from gateway.isobus.j1939 import FrameId, Pgn

Input = ImuSample | ImuAux | GnssFix | BusFrame
_NAME_BYTES = 8
#: PDU formats (id bits 16-23) of the network-management PGNs replay hands to the claimer:
#: one shift and mask per frame tells the IMU bridge's frames from them.
_NETWORK_FORMATS = frozenset({Pgn.ISO_REQUEST >> 8 & 0xFF, Pgn.ADDRESS_CLAIM >> 8 & 0xFF})


class LogInputs:
    """Iterate the merged inputs of one recording; the decoders keep their counters."""

    def __init__(
        self,
        can_log: str | Path,
        nmea_log: str | Path,
        imu_config: ImuCanConfig | None = None,
        own_name: int | None = None,
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
        return _merged(self._can_inputs(), gnss)

    def _can_inputs(self) -> Iterator[ImuSample | ImuAux | BusFrame]:
        """IMU samples from the bridge's frames; other nodes' claims and requests as they are."""
        feed = self.imu_decoder.feed
        network = _NETWORK_FORMATS
        for msg in self.can_reader:
            if (
                msg.is_extended_id
                and msg.arbitration_id >> 16 & 0xFF in network
                and self._from_another_node(msg)
            ):
                yield BusFrame(float(msg.timestamp), msg)
            else:
                yield from feed(msg)
        self.imu_decoder.finish()

    def _from_another_node(self, msg: can.Message) -> bool:
        """An address claim or request, and not a claim of the recorded gateway's NAME."""
        pgn = FrameId.parse(msg.arbitration_id).pgn
        if pgn == Pgn.ISO_REQUEST:
            return True
        return pgn == Pgn.ADDRESS_CLAIM and (
            len(msg.data) < _NAME_BYTES
            or int.from_bytes(msg.data[:_NAME_BYTES], "little") != self.own_name
        )


def _merged(
    can_inputs: Iterator[ImuSample | ImuAux | BusFrame], fixes: Iterator[GnssFix]
) -> Iterator[Input]:
    """The two streams merged by ``t`` as ``heapq.merge(can_inputs, fixes, key=t)`` does
    (the smaller head first, the CAN input on a tie), without a key call and a heap step per
    item: fixes are fifty times rarer than IMU samples."""
    fix = next(fixes, None)
    for item in can_inputs:
        while fix is not None and fix.t < item.t:
            yield fix
            fix = next(fixes, None)
        yield item
    if fix is not None:
        yield fix
        yield from fixes
