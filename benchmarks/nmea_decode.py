"""Decode cost of one NMEA epoch (GGA+RMC+VTG+GST+ZDA) in microseconds of CPU time.

    .venv/bin/python benchmarks/nmea_decode.py

Two ways in, as the gateway uses them:

- serial bytes: one `NmeaDecoder.feed` call per sentence, as a serial port delivering a line
  at a time would (the worst case: chunking more per read only makes it cheaper);
- log lines: `NmeaDecoder.feed_lines` over (host time, sentence) records, as replay reads an
  NMEA log (the log reader's own cost is not included: see benchmarks/replay_speed.py).

Each also with ``fast_path = False`` (issue 14): every sentence framed byte by byte and parsed
by pynmea2.parse, the careful way the fast path is tested against (same fixes).
"""

from __future__ import annotations

import time
from collections.abc import Callable

from drivers.nmea import NmeaDecoder, nmea_checksum
from drivers.samples import GnssFix


def epoch(second: int) -> list[str]:
    tod = f"1200{second % 60:02d}.{second // 60 % 100:02d}"
    bodies = [
        f"GNRMC,{tod},A,4807.03801234,N,01131.00004567,E,3.1,87.5,010524,,,R,V",
        "GNVTG,87.5,T,,M,3.1,N,5.7,K,R",
        f"GNGGA,{tod},4807.03801234,N,01131.00004567,E,4,24,0.55,512.345,M,47.012,M,1.0,0001",
        f"GNGST,{tod},0.5,0.02,0.01,30.0,0.011,0.012,0.020",
        f"GNZDA,{tod},01,05,2024,00,00",
    ]
    return [f"${b}*{nmea_checksum(b):02X}" for b in bodies]


def by_bytes(decoder: NmeaDecoder, lines: list[str]) -> list[GnssFix]:
    fixes = [f for i, line in enumerate(lines) for f in decoder.feed(f"{line}\r\n".encode(), i)]
    return fixes + decoder.flush()


def by_lines(decoder: NmeaDecoder, lines: list[str]) -> list[GnssFix]:
    return [*decoder.feed_lines((float(i), line) for i, line in enumerate(lines)), *decoder.flush()]


def main(epochs: int = 6000) -> None:
    lines = [line for i in range(epochs) for line in epoch(i)]
    feeds: list[tuple[str, Callable[[NmeaDecoder, list[str]], list[GnssFix]]]] = [
        ("serial bytes, one feed() per sentence", by_bytes),
        ("log lines, feed_lines()", by_lines),
    ]
    for label, feed in feeds:
        results = []
        for fast in (True, False):
            decoder = NmeaDecoder("bench")
            decoder.fast_path = fast
            start = time.process_time()
            fixes = feed(decoder, lines)
            elapsed = time.process_time() - start
            assert decoder.counters.fixes == len(fixes) == epochs, decoder.counters
            results.append((elapsed / epochs * 1e6, fixes))
        assert results[0][1] == results[1][1]
        print(
            f"NMEA decode, {label}: {results[0][0]:.1f} us per epoch "
            f"(GGA+RMC+VTG+GST+ZDA, {epochs} epochs; careful path {results[1][0]:.1f} us)"
        )


if __name__ == "__main__":
    main()
