"""Hypothesis strategies for IMU400CC packets, shared by the protocol, framer and axes tests."""

from __future__ import annotations

from hypothesis import strategies as st

from imu400cc_driver.protocol import RawPacket

int16s = st.integers(-(2**15), 2**15 - 1)
uint16s = st.integers(0, 2**16 - 1)
raw_packets = st.builds(
    RawPacket,
    rates=st.tuples(int16s, int16s, int16s),
    accels=st.tuples(int16s, int16s, int16s),
    temperature=uint16s,
    timer=uint16s,
)
