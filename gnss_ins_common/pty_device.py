"""The device side of an emulated serial port on a pseudo-terminal.

A driver opens ``PtyDevice.path`` with pyserial exactly as it would open ``/dev/ttyUSB0``: the
path is a symlink to the pty's slave end, so it stays the same when the emulated cable is pulled
and plugged back (``close_port`` / ``reopen_port``), which creates a new pty like a USB adapter
that re-enumerates.

Writes never block the emulator: a pty has a small kernel buffer and a real UART does not wait
for a reader, so bytes that do not fit are dropped and counted (``overflow_bytes``).
"""

from __future__ import annotations

import contextlib
import errno
import os
import select
import tempfile
import threading
import tty
from pathlib import Path
from typing import Self


class PtyDevice:
    """A pseudo-terminal whose slave end is reachable through a stable symlink path."""

    def __init__(self, link_path: str | Path | None = None) -> None:
        """Create the pty now; ``link_path`` defaults to a fresh temporary directory's ``tty``."""
        if link_path is None:
            self._tmpdir: tempfile.TemporaryDirectory[str] | None = tempfile.TemporaryDirectory(
                prefix="gnss_ins_pty_"
            )
            link_path = Path(self._tmpdir.name) / "tty"
        else:
            self._tmpdir = None
        self.path = str(link_path)
        self._lock = threading.Lock()
        self._master = -1
        self._slave = -1
        self.overflow_bytes = 0
        self.bytes_written = 0
        self.reopen_port()

    @property
    def is_open(self) -> bool:
        """True while the emulated cable is plugged in."""
        return self._master >= 0

    def reopen_port(self) -> None:
        """Plug the cable in (again): a new pty, the symlink pointed at its slave end."""
        with self._lock:
            self._close_fds()
            master, slave = os.openpty()
            # Raw mode on the slave: no echo of what the driver writes, no newline translation.
            tty.setraw(slave)
            os.set_blocking(master, False)
            tmp_link = f"{self.path}.{os.getpid()}.tmp"
            with contextlib.suppress(FileNotFoundError):
                os.unlink(tmp_link)
            os.symlink(os.ttyname(slave), tmp_link)
            os.replace(tmp_link, self.path)
            # Keeping our own slave fd open means the master never sees EIO while the driver
            # closes and reopens the port between reconnects.
            self._master, self._slave = master, slave

    def close_port(self) -> None:
        """Pull the cable: the driver's open port fails and the path disappears."""
        with self._lock:
            self._close_fds()
            with contextlib.suppress(FileNotFoundError):
                os.unlink(self.path)

    def write(self, data: bytes) -> int:
        """Send bytes to the driver; returns how many were accepted (the rest are dropped)."""
        with self._lock:
            if self._master < 0:
                self.overflow_bytes += len(data)
                return 0
            try:
                written = os.write(self._master, data)
            except OSError as exc:
                if exc.errno not in (errno.EAGAIN, errno.EIO):
                    raise
                written = 0
        self.bytes_written += written
        self.overflow_bytes += len(data) - written
        return written

    def read(self, timeout_s: float) -> bytes:
        """Bytes the driver sent, waiting at most ``timeout_s``; b'' when none (or unplugged)."""
        master = self._master
        if master < 0:
            return b""
        try:
            ready, _, _ = select.select([master], [], [], max(0.0, timeout_s))
            if not ready:
                return b""
            return os.read(master, 4096)
        except (OSError, ValueError):
            # The port was closed by close_port() from another thread while we waited.
            return b""

    def close(self) -> None:
        """Remove the pty and its symlink for good."""
        self.close_port()
        if self._tmpdir is not None:
            self._tmpdir.cleanup()
            self._tmpdir = None

    def _close_fds(self) -> None:
        for fd in (self._master, self._slave):
            if fd >= 0:
                with contextlib.suppress(OSError):
                    os.close(fd)
        self._master = self._slave = -1

    def __enter__(self) -> PtyDevice:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class PtyEmulator:
    """Base of the device emulators: a ``PtyDevice``, ``_run`` on a background thread until
    ``stop``, and a lock guarding the fault requests that other threads make."""

    thread_name = "pty-emulator"

    def __init__(self, link_path: str | Path | None = None) -> None:
        """Create the pty (the device is not running until ``start``)."""
        self.pty = PtyDevice(link_path)
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    @property
    def path(self) -> str:
        """Serial port path for the driver (a stable symlink to the pty)."""
        return self.pty.path

    def _run(self) -> None:
        """The device: runs on the background thread until ``self._stop`` is set."""
        raise NotImplementedError

    def start(self) -> Self:
        """Run the device on a background thread."""
        self._stop.clear()
        self._thread = threading.Thread(target=self._run, name=self.thread_name, daemon=True)
        self._thread.start()
        return self

    def stop(self) -> None:
        """Stop the device and remove its pty."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
        self.pty.close()

    def __enter__(self) -> Self:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()
