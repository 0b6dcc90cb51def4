"""Decode cost of one NMEA epoch (GGA+RMC+VTG+GST+ZDA) in microseconds.

    .venv/bin/python benchmarks/nmea_decode.py

Feeds one sentence per `NmeaDecoder.feed` call, as a serial port delivering a line at a time
would (the worst case: chunking more per read only makes it cheaper).
"""

from __future__ import annotations

import time

from drivers.nmea import NmeaDecoder, nmea_checksum


def epoch(second: int) -> list[bytes]:
    tod = f"1200{second % 60:02d}.{second // 60 % 100:02d}"
    bodies = [
        f"GNRMC,{tod},A,4807.03801234,N,01131.00004567,E,3.1,87.5,010524,,,R,V",
        "GNVTG,87.5,T,,M,3.1,N,5.7,K,R",
        f"GNGGA,{tod},4807.03801234,N,01131.00004567,E,4,24,0.55,512.345,M,47.012,M,1.0,0001",
        f"GNGST,{tod},0.5,0.02,0.01,30.0,0.011,0.012,0.020",
        f"GNZDA,{tod},01,05,2024,00,00",
    ]
    return [f"${b}*{nmea_checksum(b):02X}\r\n".encode() for b in bodies]


def main(epochs: int = 6000) -> None:
    lines = [line for i in range(epochs) for line in epoch(i)]
    decoder = NmeaDecoder("bench")
    start = time.perf_counter()
    for i, line in enumerate(lines):
        decoder.feed(line, float(i))
    decoder.flush()
    elapsed = time.perf_counter() - start
    assert decoder.counters.fixes == epochs, decoder.counters
    print(
        f"NMEA decode: {elapsed / epochs * 1e6:.1f} us per epoch (GGA+RMC+VTG+GST+ZDA, "
        f"{epochs} epochs, one feed() per sentence)"
    )


if __name__ == "__main__":
    main()
