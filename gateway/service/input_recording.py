"""Optional recording of the live inputs in the SPEC 3 log formats, rotated by size.

A recording is a pair of files with one stem, ``navgw-000042-20250301T101500Z``: ``.imu.log``
holds the IMU bridge frames as received (candump ``-L``, no R/T flag) and ``.gnss.nmea`` the
NMEA sentences with their host receive times. The pair replays with ``navgw replay --can
X.imu.log --nmea X.gnss.nmea``. Both files rotate together when either reaches
``max_file_mb`` (checked on disk every few hundred writes, so a file may exceed it by one
write buffer), and the oldest pairs beyond ``keep_files`` are deleted. The running number
orders the pairs: it does not depend on the host clock, which may jump at boot.

Sentences are taken where the live NMEA decoder frames them (its ``on_sentence`` hook),
so nothing is parsed twice and the log holds exactly what the decoder was given, bad
checksums included. A write error (disk full) stops the recording, logged, and nothing else.
"""

from __future__ import annotations

import logging
import re
import time
from collections.abc import Callable
from pathlib import Path

import can

from drivers.logs.candump import CandumpWriter
from drivers.logs.nmea_log import NmeaLogWriter
from gateway.config.gateway_config import RecordingSection

log = logging.getLogger(__name__)

CAN_SUFFIX = ".imu.log"
NMEA_SUFFIX = ".gnss.nmea"
CHECK_EVERY = 256  # writes between two size checks
_STEM = re.compile(r"navgw-(\d{6})-\d{8}T\d{6}Z")


class InputRecorder:
    """Writes IMU frames and NMEA sentences to rotating pairs of SPEC 3 logs."""

    def __init__(
        self,
        section: RecordingSection,
        channel: str = "can0",
        clock: Callable[[], float] = time.time,
    ) -> None:
        self.directory = Path(section.directory)
        self.max_bytes = int(section.max_file_mb * 1e6)
        self.keep_files = section.keep_files
        self.channel = channel
        self.clock = clock  # service time, for the file names
        self.stem: str | None = None
        self._can: CandumpWriter | None = None
        self._nmea: NmeaLogWriter | None = None
        self._writes = 0

    def open(self) -> None:
        """Start the first pair; raises OSError if the directory cannot be used."""
        self.directory.mkdir(parents=True, exist_ok=True)
        self._start_pair()

    def can(self, msg: can.Message) -> None:
        """Record one received IMU frame (its timestamp is the service's arrival time)."""
        if self._can is not None:
            self._guard(self._can.write, msg)

    def sentence(self, t_host: float | None, text: str) -> None:
        """Record one framed NMEA sentence with its host receive time."""
        if self._nmea is not None:
            self._guard(self._nmea.write, t_host, text)

    def close(self) -> None:
        """Flush and close the current pair; safe to call twice."""
        for writer in (self._can, self._nmea):
            if writer is not None:
                writer.close()
        self._can = self._nmea = None

    def pairs(self) -> list[str]:
        """Stems of the recordings in the directory, oldest first."""
        return recorded_stems(self.directory)

    def _guard(self, write: Callable[..., None], *args: object) -> None:
        try:
            write(*args)
            self._writes += 1
            if self._writes % CHECK_EVERY == 0 and self._size() >= self.max_bytes:
                self.close()
                self._start_pair()
        except OSError as exc:
            log.error("recording stopped: %s: %s", self.directory, exc)
            self.close()

    def _size(self) -> int:
        assert self.stem is not None
        return max(
            (self.directory / (self.stem + s)).stat().st_size for s in (CAN_SUFFIX, NMEA_SUFFIX)
        )

    def _start_pair(self) -> None:
        existing = self.pairs()
        number = int(existing[-1].split("-")[1]) + 1 if existing else 1
        stamp = time.strftime("%Y%m%dT%H%M%SZ", time.gmtime(self.clock()))
        self.stem = f"navgw-{number:06d}-{stamp}"
        self._can = CandumpWriter(self.directory / (self.stem + CAN_SUFFIX), self.channel)
        self._nmea = NmeaLogWriter(self.directory / (self.stem + NMEA_SUFFIX))
        log.info("recording inputs to %s/%s.*", self.directory, self.stem)
        for old in existing[: max(0, len(existing) + 1 - self.keep_files)]:
            for suffix in (CAN_SUFFIX, NMEA_SUFFIX):
                (self.directory / (old + suffix)).unlink(missing_ok=True)
            log.info("deleted old recording %s/%s.*", self.directory, old)


def recorded_stems(directory: Path) -> list[str]:
    """Stems of the pairs (either file of a pair) in ``directory``, oldest first: the running
    number orders them."""
    stems = {m[0] for p in directory.glob("navgw-*") if (m := _STEM.match(p.name)) is not None}
    return sorted(stems)
