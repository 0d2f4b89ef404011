"""SerialLink over a real pseudo-terminal: what counts as a stall (no rclpy)."""

from __future__ import annotations

import time

from ros_harness import wait_for

from gnss_ins_common.pty_device import PtyDevice
from gnss_ins_common.serial_link import LinkSettings, SerialLink


def _link(device: PtyDevice, chunks: list[bytes], **settings: float) -> SerialLink:
    link = SerialLink(
        LinkSettings(port=device.path, **settings),
        on_open=lambda _port: None,
        on_data=lambda chunk, _received: chunks.append(chunk),
        now=time.monotonic,
        log=lambda _message: None,
        info=lambda _message: None,
    )
    link.start()
    return link


def test_noise_without_a_valid_message_is_an_invalid_stall():
    chunks: list[bytes] = []
    with PtyDevice() as device:
        link = _link(device, chunks, stall_timeout_s=5.0, valid_timeout_s=0.3)
        try:
            assert wait_for(lambda: link.is_open, 5.0)
            deadline = time.monotonic() + 10.0
            while link.stats.stalls == 0 and time.monotonic() < deadline:
                device.write(b"\x01\x02\x03")  # bytes, none of them valid
                time.sleep(0.02)
        finally:
            link.stop()
    assert chunks
    assert link.stats.stalls >= 1 and link.stats.invalid_stalls == link.stats.stalls
    assert "no valid message" in link.stats.last_error


def test_a_silence_is_a_stall_after_stall_timeout_whatever_valid_timeout_says():
    chunks: list[bytes] = []
    with PtyDevice() as device:
        # The valid-message time-out is shorter, but no byte arrives: that is a plain stall.
        link = _link(device, chunks, stall_timeout_s=0.6, valid_timeout_s=0.2)
        try:
            assert wait_for(lambda: link.stats.stalls >= 1, 10.0)
        finally:
            link.stop()
    assert not chunks
    assert link.stats.invalid_stalls == 0
    assert "no data" in link.stats.last_error
