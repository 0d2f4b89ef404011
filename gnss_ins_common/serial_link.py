"""A serial port read on a background thread that reopens itself.

``SerialLink`` owns one pyserial port. After every (re)open it calls ``on_open(port)`` so the
driver can put the device in its mode (and verify it answers); then it reads continuously and hands
each chunk to ``on_data(chunk, receive_time_s)``, where the receive time is taken right after the
read returned, on the clock the caller supplies (the node's ROS clock). A vanished port, a read
error, an exception from ``on_open``, a stream that stays silent longer than ``stall_timeout_s``
or (with ``valid_timeout_s``) one whose bytes hold nothing valid for that long — noise on the line
of a unit that power-cycled and waits for its start command; the driver calls ``note_valid`` for
each valid message — closes the port and reopens it with exponential back-off. Nothing here
raises into the caller. The reader sleeps in one ``select`` until data, the stall time-out or
``stop`` (a pipe of its own wakes it): an idle line costs no wake-ups.

``write`` (any thread) sends only to a port that is open *and* set up: while ``on_open`` writes
the set-up commands directly on the port, and while the port is closed or being reopened, it
refuses (returns False, writes nothing), so another thread's bytes never interleave with the
set-up or go to a device in an unknown mode. Each accepted write is one ``port.write`` of the
whole buffer under the write lock (pyserial loops until all of it is written or its write
time-out expires), so two writers' messages never interleave either.
"""

from __future__ import annotations

import contextlib
import os
import select
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass

import serial

#: Largest read per wake-up [bytes]; a 38400-baud line delivers 3840 bytes/s.
_READ_SIZE = 4096


class LinkStallError(Exception):
    """The device stopped sending (anything, or anything valid) for longer than its time-out."""

    def __init__(self, message: str, invalid: bool = False) -> None:
        """``invalid``: bytes kept arriving but none made a valid message."""
        super().__init__(message)
        self.invalid = invalid


@dataclass
class LinkStats:
    """Counters of one link since start-up."""

    opens: int = 0
    reconnects: int = 0
    open_failures: int = 0
    stalls: int = 0
    #: Stalls with bytes arriving but nothing valid in them (``valid_timeout_s``).
    invalid_stalls: int = 0
    bytes_read: int = 0
    callback_errors: int = 0
    #: Writes that raised (write time-out, I/O error); refused writes are not counted.
    write_failures: int = 0
    #: The last problem, cleared when the port is open and the device set up again.
    last_error: str = ""


@dataclass(frozen=True)
class LinkSettings:
    """How to open and supervise the port (38400 8N1 without flow control by default)."""

    port: str
    baud: int = 38400
    stall_timeout_s: float = 1.0
    #: Reconnect when no valid message was noted for this long although bytes arrive [s];
    #: None: bytes alone keep the link up.
    valid_timeout_s: float | None = None
    backoff_initial_s: float = 0.1
    backoff_max_s: float = 5.0
    read_timeout_s: float = 0.05


class SerialLink:
    """Reconnecting pyserial reader thread; see the module docstring."""

    def __init__(
        self,
        settings: LinkSettings,
        *,
        on_open: Callable[[serial.Serial], None],
        on_data: Callable[[bytes, float], None],
        now: Callable[[], float],
        log: Callable[[str], None] = print,
        info: Callable[[str], None] = print,
    ) -> None:
        """``now``: host time [s] stamping each chunk; ``log``: problems; ``info``: news."""
        self.settings = settings
        self.stats = LinkStats()
        self._on_open = on_open
        self._on_data = on_data
        self._now = now
        self._log = log
        self._info = info
        self._stop = threading.Event()
        # Guards _ready and every write on the port outside on_open.
        self._write_lock = threading.Lock()
        self._ready = False  # the port is open and on_open has returned
        self._port: serial.Serial | None = None
        self._thread: threading.Thread | None = None
        self._last_valid = time.monotonic()
        # stop() writes to it to end the reader's select at once (None while stopped).
        self._wake: tuple[int, int] | None = None

    def note_valid(self) -> None:
        """The driver found a valid message in the data: the ``valid_timeout_s`` clock restarts."""
        self._last_valid = time.monotonic()

    @property
    def is_open(self) -> bool:
        """True while the port is open and configured (``on_open`` returned)."""
        return self._ready

    def start(self) -> None:
        """Start the reader thread (opens the port in the background)."""
        self._stop.clear()
        self._wake = os.pipe()
        self._thread = threading.Thread(
            target=self._run, name=f"serial:{self.settings.port}", daemon=True
        )
        self._thread.start()

    def stop(self, before_close: Callable[[serial.Serial], None] | None = None) -> None:
        """Stop the thread and close the port; ``before_close`` may still write to it."""
        self._stop.set()
        wake = self._wake
        if wake is not None:
            os.write(wake[1], b"\0")
        if self._thread is not None:
            self._thread.join(timeout=2.0)
            self._thread = None
        if wake is not None:
            self._wake = None
            os.close(wake[0])
            os.close(wake[1])
        with self._write_lock:
            self._ready = False  # the shutdown command goes alone
            port = self._port
        if port is not None and before_close is not None:
            try:
                before_close(port)
            except (serial.SerialException, OSError) as exc:
                self._log(f"could not send the shutdown command: {exc}")
        self._close()

    def write(self, data: bytes) -> bool:
        """Send all of ``data`` in one write when the port is open and set up; False when it is
        not (nothing written) or the write failed (counted in ``write_failures``)."""
        with self._write_lock:
            port = self._port
            if not self._ready or port is None:
                return False
            try:
                port.write(data)
            except (serial.SerialException, OSError) as exc:  # SerialTimeoutException included
                self.stats.write_failures += 1
                self.stats.last_error = f"write failed: {exc}"
                return False
        return True

    def _run(self) -> None:
        backoff = self.settings.backoff_initial_s
        while not self._stop.is_set():
            try:
                self._open()
                backoff = self.settings.backoff_initial_s
                self._read_until_error()
            except LinkStallError as exc:
                self.stats.stalls += 1
                self.stats.invalid_stalls += exc.invalid
                self._note(str(exc))
            except (serial.SerialException, OSError, ValueError) as exc:
                if self._port is None:
                    self.stats.open_failures += 1
                self._note(f"serial error on {self.settings.port}: {exc}")
            except Exception as exc:  # an on_open callback failing must not end the thread
                self._note(f"device set-up failed on {self.settings.port}: {exc!r}")
            if self._stop.is_set():
                break  # stop() still writes its shutdown command before it closes the port
            self._close()
            if self._stop.wait(backoff):
                break
            backoff = min(2.0 * backoff, self.settings.backoff_max_s)

    def _open(self) -> None:
        port = serial.Serial(
            self.settings.port,
            self.settings.baud,
            bytesize=serial.EIGHTBITS,
            parity=serial.PARITY_NONE,
            stopbits=serial.STOPBITS_ONE,
            timeout=self.settings.read_timeout_s,
            write_timeout=1.0,
            xonxoff=False,
            rtscts=False,
            dsrdtr=False,
        )
        # pyserial asserts DTR and RTS on open (its defaults), as the Aalborg MATLAB set-up did
        # (imu400cc-aalborg-notes.md §2.1); it ignores ports without modem lines, like a pty.
        port.reset_input_buffer()
        if self.stats.opens > 0:
            self.stats.reconnects += 1
        self.stats.opens += 1
        with self._write_lock:
            self._ready = False
            self._port = port
        self._on_open(port)
        with self._write_lock:
            self._ready = True
        self.stats.last_error = ""  # recovered: the device answered its set-up
        self._info(f"opened {self.settings.port} at {self.settings.baud} baud")

    def _read_until_error(self) -> None:
        port = self._port
        assert port is not None
        # One select and one read per wake-up on the descriptor pyserial opened and configured:
        # pyserial's read(1) + in_waiting + read(n) takes three rounds of system calls, and
        # measured 3.8-4.2 % of a core for imu400cc_node at 134 Hz against 3.2-3.5 % for this.
        fd = port.fileno()
        assert self._wake is not None
        descriptors = [fd, self._wake[0]]
        last_data = self._last_valid = time.monotonic()
        valid_timeout_s = self.settings.valid_timeout_s
        stall_timeout_s = self.settings.stall_timeout_s
        while not self._stop.is_set():
            silent_s = time.monotonic() - last_data
            ready, _, _ = select.select(descriptors, [], [], max(stall_timeout_s - silent_s, 0.0))
            if self._stop.is_set():
                return
            if not ready:
                if time.monotonic() - last_data <= stall_timeout_s:
                    continue
                if select.select([fd], [], [], 0.0)[0]:
                    continue  # the thread woke late (a loaded machine): read what came first
                raise LinkStallError(
                    f"no data from {self.settings.port} for {self.settings.stall_timeout_s:.1f} s"
                )
            chunk = os.read(fd, _READ_SIZE)
            if not chunk:
                raise serial.SerialException(f"{self.settings.port} disconnected")
            received = self._now()
            last_data = time.monotonic()
            self.stats.bytes_read += len(chunk)
            try:
                self._on_data(chunk, received)
            except Exception as exc:  # a decoding bug must not take the link down
                self.stats.callback_errors += 1
                self.stats.last_error = f"data callback failed: {exc!r}"
            # Judged on arriving bytes only: a silence is a stall (stall_timeout_s).
            if valid_timeout_s is not None and last_data - self._last_valid > valid_timeout_s:
                raise LinkStallError(
                    f"bytes but no valid message from {self.settings.port} for "
                    f"{valid_timeout_s:.1f} s",
                    invalid=True,
                )

    def _close(self) -> None:
        with self._write_lock:
            self._ready = False
            port, self._port = self._port, None
        if port is not None:
            with contextlib.suppress(serial.SerialException, OSError):
                port.close()

    def _note(self, message: str) -> None:
        if message != self.stats.last_error:
            self._log(message)
        self.stats.last_error = message
