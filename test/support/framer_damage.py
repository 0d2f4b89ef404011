"""Serial-line damage for the IMU400CC framer: realistic streams, one byte dropped, inserted or
flipped in every DAMAGE_EVERY-th packet, and the false and lost packets that result.

Shared by bench/bench_framer.py (large samples) and test/imu400cc_driver/test_imu_framer.py (a
smaller one).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from imu400cc_driver.framer import PacketFramer
from imu400cc_driver.protocol import PACKET_LENGTH, RawPacket, encode_packet

KINDS = ("drop", "insert", "flip")
#: One packet in DAMAGE_EVERY is damaged; the others are intact.
DAMAGE_EVERY = 5
#: Device-timer step per packet at 134 Hz and its packet-to-packet spread [counts] (notes §2.6).
TIMER_STEP, TIMER_JITTER = 9412, 9
#: Counts per deg/s (±100 deg/s full scale) and per g (1 g = 10923 counts, bench_imu_framer.py).
RATE_COUNTS_PER_DPS, ACCEL_COUNTS_PER_G = 327.67, 10923.0


def realistic_packets(count: int, rng: np.random.Generator) -> list[RawPacket]:
    """Half of the time at rest (0.1 deg/s, 5 mg noise: many 0xFF MSBs), half driving (20 deg/s,
    0.3 g), timer counting down by TIMER_STEP ± TIMER_JITTER."""
    moving = (np.arange(count) // 500) % 2 == 1
    rate_sd = np.where(moving, 20.0, 0.1)[:, None] * RATE_COUNTS_PER_DPS
    accel_sd = np.where(moving, 0.3, 0.005)[:, None] * ACCEL_COUNTS_PER_G
    rates = np.clip(rng.normal(0.0, rate_sd, (count, 3)), -32768, 32767).astype(int)
    accels = rng.normal([0.0, 0.0, ACCEL_COUNTS_PER_G], accel_sd, (count, 3))
    accels = np.clip(accels, -32768, 32767).astype(int)
    jitter = rng.integers(-TIMER_JITTER, TIMER_JITTER + 1, count)
    timers = (41606 - TIMER_STEP * np.arange(count) + jitter) % 65536
    return [
        RawPacket(
            (int(r[0]), int(r[1]), int(r[2])), (int(a[0]), int(a[1]), int(a[2])), 1514, int(t)
        )
        for r, a, t in zip(rates, accels, timers, strict=True)
    ]


def damage(packet: bytes, kind: str, rng: np.random.Generator) -> bytes:
    """``packet`` with one byte (anywhere, header and checksum included) dropped, a random byte
    inserted before it, or its value changed."""
    at = int(rng.integers(0, PACKET_LENGTH))
    if kind == "drop":
        return packet[:at] + packet[at + 1 :]
    if kind == "insert":
        return packet[:at] + bytes([int(rng.integers(0, 256))]) + packet[at:]
    flipped = packet[at] ^ int(rng.integers(1, 256))
    return packet[:at] + bytes([flipped]) + packet[at + 1 :]


@dataclass(frozen=True)
class DamageResult:
    """Counts of one run: damaged packets, false packets accepted (content never sent; of those,
    with measurements never sent, the rest has a wrong timer only), intact packets lost, and of
    those the ones right after a damaged packet."""

    damaged: int
    false: int
    false_values: int
    lost: int
    lost_after_damage: int


def run_damaged(
    packets: list[RawPacket], kind: str, rng: np.random.Generator, confirm: bool = True
) -> DamageResult:
    """Damage every DAMAGE_EVERY-th packet of ``packets`` by ``kind`` and frame the stream."""
    wire = [encode_packet(p) for p in packets]
    damaged = set(range(DAMAGE_EVERY // 2, len(wire), DAMAGE_EVERY))
    stream = b"".join(damage(w, kind, rng) if i in damaged else w for i, w in enumerate(wire))
    received = set(PacketFramer(confirm_with_next_packet=confirm).feed(stream))
    sent = set(packets)
    sent_values = {(p.rates, p.accels) for p in packets}
    lost = [i for i, p in enumerate(packets[:-1]) if i not in damaged and p not in received]
    return DamageResult(
        damaged=len(damaged),
        false=len(received - sent),
        false_values=sum((p.rates, p.accels) not in sent_values for p in received - sent),
        lost=len(lost),
        lost_after_damage=sum(i - 1 in damaged for i in lost),
    )
