"""Recorded inputs (SPEC 3 logs) decoded by the live drivers and merged on the host clock.

Replay, the accuracy benchmark and tests feed engines from here, so they see exactly the
samples and fixes the live service would: IMU samples at their reconstructed sample time,
GNSS fixes at their host receive time (after the IMU samples that preceded them).
"""

from __future__ import annotations

import heapq
from collections.abc import Iterator
from operator import attrgetter
from pathlib import Path

from drivers.errors import InputError
from drivers.imu_can import ImuCanConfig, ImuDecoder, read_log
from drivers.nmea import NmeaDecoder, read_fixes_from_log
from drivers.samples import GnssFix, ImuAux, ImuSample
from sim_bus.canlog import read_candump
from sim_bus.nmealog import NmeaLogReader, read_nmea_log

Input = ImuSample | ImuAux | GnssFix


class LogInputs:
    """Iterate the merged inputs of one recording; the decoders keep their counters."""

    def __init__(
        self, can_log: str | Path, nmea_log: str | Path, imu_config: ImuCanConfig | None = None
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
        imu = read_log(self.can_reader, self.imu_decoder)
        gnss = read_fixes_from_log(self.nmea_reader, self.nmea_decoder)
        return heapq.merge(imu, gnss, key=attrgetter("t"))
