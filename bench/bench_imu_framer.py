"""Throughput of the IMU400CC PacketFramer (packets/s, MB/s); prints numbers, asserts nothing.

Stream: 100 000 packets of plausible values fed in random 1..64-byte chunks, once clean and once
with 1 % of the bytes replaced by random values. The device itself sends 134 packets/s.
Both framer modes are measured: checksum only (polled mode) and confirmed by the next packet
(continuous mode). "false" counts accepted packets that were never sent (random bytes passing
the 8-bit checksum).
"""

from __future__ import annotations

import time

import numpy as np
from byte_streams import chunks, corrupt

from imu400cc_driver.framer import PacketFramer
from imu400cc_driver.protocol import PACKET_LENGTH, RawPacket, encode_packet

PACKETS = 100_000
DEVICE_RATE_HZ = 134.0
SEED = 1


def make_stream(rng: np.random.Generator) -> bytes:
    rates = rng.normal(0.0, 200.0, (PACKETS, 3)).astype(int)  # ~1 deg/s
    accels = rng.normal([0.0, 0.0, 10923.0], 500.0, (PACKETS, 3)).astype(int)  # ~1 g on z
    packets = (
        RawPacket(
            (int(r[0]), int(r[1]), int(r[2])),
            (int(a[0]), int(a[1]), int(a[2])),
            1514,
            (41606 - 9412 * i) % 65536,
        )
        for i, (r, a) in enumerate(zip(rates, accels, strict=True))
    )
    return b"".join(encode_packet(p) for p in packets)


def run(
    name: str, stream: bytes, rng: np.random.Generator, sent: set[bytes], confirm: bool
) -> None:
    pieces = chunks(stream, rng)
    framer = PacketFramer(confirm_with_next_packet=confirm)
    start = time.perf_counter()
    for piece in pieces:
        framer.feed(piece)  # packets dropped at once, as a driver publishes and forgets them
    elapsed = time.perf_counter() - start
    s = framer.stats
    checker = PacketFramer(
        confirm_with_next_packet=confirm
    )  # untimed second pass: which accepted packets were never sent
    false_packets = sum(
        encode_packet(p) not in sent for piece in pieces for p in checker.feed(piece)
    )
    rate = s.packets / elapsed
    print(
        f"{name:>9} {'confirmed' if confirm else 'checksum':>9}: {rate:9,.0f} packets/s"
        f" {len(stream) / elapsed / 1e6:6.2f} MB/s"
        f" ({rate / DEVICE_RATE_HZ:,.0f}x the device rate), {len(pieces):,} chunks;"
        f" packets={s.packets:,} false={false_packets:,} bad_checksums={s.bad_checksums:,}"
        f" unconfirmed={s.unconfirmed:,} skipped={s.skipped_bytes:,} resyncs={s.resyncs:,}"
    )


def main() -> None:
    rng = np.random.default_rng(SEED)
    clean = make_stream(rng)
    print(f"PacketFramer, {PACKETS:,} packets ({len(clean):,} bytes), chunks of 1..64 bytes")
    sent = {clean[i : i + PACKET_LENGTH] for i in range(0, len(clean), PACKET_LENGTH)}
    corrupted = corrupt(clean, rng)
    for confirm in (False, True):
        run("clean", clean, rng, sent, confirm)
        run("1% bytes", corrupted, rng, sent, confirm)


if __name__ == "__main__":
    main()
