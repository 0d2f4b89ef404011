"""Throughput of the GNSS driver core (sentences/s); prints numbers, asserts nothing.

Streams: one hour of the Leica rover (VTG, GGA, LLQ, GST, RMC, ZDA at 1 Hz: 21 600 sentences)
and one hour of the ADU5 (PAT + ATT at 5 Hz: 36 000 sentences), as the emulator formats them,
fed in random 1..64-byte chunks, once clean and once with 1 % of the bytes replaced. Measured:
the reader alone (framing, checksum, pynmea2) and the whole core (reader, epochs, solutions,
clock mapping). The real receivers send 6 and 10 sentences/s.

``--repeat N``: also the whole core's best CPU time of N passes over each clean stream, the
figure to compare two trees by (wall-clock rates swing with the machine's other load).
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from byte_streams import chunks, corrupt

from gnss_driver.driver import DriverConfig, GnssDriver
from gnss_driver.emulator import EmulatorConfig, adu5_sentences, constant_velocity, leica_sentences
from gnss_driver.profiles import Receiver
from gnss_driver.reader import NmeaReader, frame_sentence

SECONDS = 3600
START_UTC_S = 1_700_000_000.0
SEED = 1


def leica_stream() -> bytes:
    config = EmulatorConfig(receiver=Receiver.LEICA, leica_extra=("GST", "RMC", "ZDA"))
    truth = constant_velocity((10.0, 5.0, 0.0), start_utc_s=START_UTC_S)
    times = START_UTC_S + np.arange(SECONDS)
    return _stream([leica_sentences(t, truth(t), config, True) for t in times])


def adu5_stream() -> bytes:
    config = EmulatorConfig(receiver=Receiver.ADU5, adu5_att=True)
    truth = constant_velocity((10.0, 5.0, 0.0), start_utc_s=START_UTC_S)
    times = START_UTC_S + np.arange(SECONDS * 5) * 0.2
    return _stream([adu5_sentences(t, truth(t), config, (0.0, 0.0, 0.0), 0, 0.002) for t in times])


def _stream(epochs: list[list[str]]) -> bytes:
    return b"".join(frame_sentence(body) for bodies in epochs for body in bodies)


def run(name: str, stream: bytes, rng: np.random.Generator, baud: int, rate_hz: float) -> None:
    pieces = chunks(stream, rng)
    reader = NmeaReader()
    start = time.perf_counter()
    for piece in pieces:
        reader.feed(piece)
    reader_s = time.perf_counter() - start
    sentences = reader.stats.sentences

    driver = GnssDriver(DriverConfig(baud=baud))
    # Arrival times: the receive time advances with the bytes on the wire at ``baud``.
    seconds_per_byte = 10.0 / baud
    clock = START_UTC_S
    outputs = 0
    start = time.perf_counter()
    for piece in pieces:
        clock += len(piece) * seconds_per_byte
        outputs += len(driver.feed(piece, clock))
    core_s = time.perf_counter() - start
    rejected = {k: v for k, v in reader.stats.rejected().items() if v}
    print(
        f"{name:>14}: reader {sentences / reader_s:9,.0f} sentences/s"
        f" ({len(stream) / reader_s / 1e6:5.2f} MB/s); whole core {sentences / core_s:9,.0f}"
        f" sentences/s, {driver.stats.epochs / core_s:8,.0f} epochs/s"
        f" ({driver.stats.epochs / core_s / rate_hz:,.0f}x real time); sentences={sentences:,}"
        f" epochs={driver.stats.epochs:,} outputs={outputs:,} rejected={rejected}"
    )


def best_cpu(name: str, stream: bytes, baud: int, repeat: int) -> None:
    """The whole core's epochs per CPU second, best of ``repeat`` passes over ``stream``."""
    pieces = chunks(stream, np.random.default_rng(SEED))
    best_s, epochs = float("inf"), 0
    for _ in range(repeat):
        driver = GnssDriver(DriverConfig(baud=baud))
        clock = START_UTC_S
        start = time.process_time()
        for piece in pieces:
            clock += len(piece) * 10.0 / baud
            driver.feed(piece, clock)
        best_s, epochs = min(best_s, time.process_time() - start), driver.stats.epochs
    print(f"{name:>14}: whole core, best CPU of {repeat}: {epochs / best_s:8,.0f} epochs/s")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=0, help="best-of-N CPU passes (0: none)")
    args = parser.parse_args()
    rng = np.random.default_rng(SEED)
    for name, stream, baud, rate in (
        ("leica", leica_stream(), 9600, 1.0),
        ("adu5", adu5_stream(), 115200, 5.0),
    ):
        print(f"{name}: {len(stream):,} bytes, chunks of 1..64 bytes")
        run(f"{name} clean", stream, rng, baud, rate)
        run(f"{name} 1% bytes", corrupt(stream, rng), rng, baud, rate)
        if args.repeat > 0:
            best_cpu(f"{name} clean", stream, baud, args.repeat)


if __name__ == "__main__":
    main()
