"""SerialLink over a real pseudo-terminal: what counts as a stall (no rclpy)."""

from __future__ import annotations

import threading
import time

from support.waiting import wait_for

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

            def stalled() -> bool:  # bytes keep coming, none of them valid
                if link.stats.stalls:
                    return True
                device.write(b"\x01\x02\x03")
                return False

            wait_for(stalled, 10.0)
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


def _read_exactly(device: PtyDevice, size: int) -> bytes:
    data = b""
    deadline = time.monotonic() + 10.0
    while len(data) < size and time.monotonic() < deadline:
        data += device.read(0.1)
    return data


def test_write_is_refused_while_the_device_is_set_up_and_goes_whole_after():
    in_setup, tried = threading.Event(), threading.Event()
    refused: list[bool] = []

    def on_open(port) -> None:
        port.write(b"SETUP\r\n")
        in_setup.set()
        tried.wait(10.0)  # another thread writes meanwhile

    def other_writer() -> None:
        in_setup.wait(10.0)
        refused.append(link.write(b"during set-up"))
        tried.set()

    with PtyDevice() as device:
        link = SerialLink(
            LinkSettings(port=device.path, stall_timeout_s=30.0),
            on_open=on_open,
            on_data=lambda _chunk, _received: None,
            now=time.monotonic,
            log=lambda _message: None,
            info=lambda _message: None,
        )
        assert link.write(b"before start") is False
        writer = threading.Thread(target=other_writer)
        writer.start()
        link.start()
        try:
            writer.join(timeout=20.0)
            assert wait_for(lambda: link.is_open, 10.0)
            assert link.write(b"after") is True
            data = _read_exactly(device, len(b"SETUP\r\nafter"))
        finally:
            link.stop()
    assert refused == [False]
    assert data == b"SETUP\r\nafter"
    assert link.stats.write_failures == 0


def test_write_is_refused_while_the_port_is_lost_and_resumes_after():
    with PtyDevice() as device:
        link = _link(device, [], stall_timeout_s=30.0, backoff_max_s=0.2)
        try:
            assert wait_for(lambda: link.is_open, 10.0)
            device.close_port()
            assert wait_for(lambda: not link.is_open, 10.0)
            assert link.write(b"lost") is False
            device.reopen_port()
            assert wait_for(lambda: link.is_open, 10.0)
            assert link.write(b"back") is True
            data = _read_exactly(device, len(b"back"))
        finally:
            link.stop()
    assert data == b"back"
    assert link.stats.write_failures == 0 and link.stats.reconnects >= 1


def test_a_write_that_times_out_is_counted():
    with PtyDevice() as device:  # the device never reads: the pty's buffer fills up
        link = _link(device, [], stall_timeout_s=30.0)
        try:
            assert wait_for(lambda: link.is_open, 10.0)
            assert link.write(bytes(1_000_000)) is False  # pyserial's 1 s write time-out
        finally:
            link.stop()
    assert link.stats.write_failures == 1
    assert link.stats.last_error.startswith("write failed")
