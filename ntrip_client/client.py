"""NTRIP client (NTRIP 2.0 over HTTP/1.1, chunked or not, and NTRIP 1 ``ICY``): one daemon
thread that keeps a caster connection up, hands the RTCM 3 frames it receives to a callback and
sends the rover's GGA upstream.

pygnssutils' GNSSNTRIPClient is not used: it gives up after a fixed number of retries and on any
answer but 200, has no cap on its back-off, drops the body bytes that arrive with the answer's
head, counts neither CRC failures nor non-RTCM bytes, and pulls in ~8 protocol packages. The
HTTP side here is the standard library's (socket, ssl, base64); the frames come from
``gnss_ins_common.rtcm.RtcmFramer``, one per connection.

Faults (refused, reset or closed connections, TLS errors, no data for ``stall_timeout_s``) are
retried after a back-off doubling from ``backoff_initial_s`` to ``backoff_max_s`` (back to the
start after a connection that delivered frames); an answer that will not change by retrying
(401/403, an unknown mountpoint, another status) only every ``backoff_max_s``. Nothing is raised
out of the thread; each change of state is logged once.
"""

from __future__ import annotations

import base64
import math
import socket
import ssl
import threading
import time
import urllib.parse
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from enum import StrEnum
from typing import NoReturn

from gnss_ins_common.rtcm import RtcmFramer, RtcmStats
from ntrip_client.caster_url import PASSWORD_VARIABLE, CasterUrl
from ntrip_client.gga import GgaSchedule, gga_position
from ntrip_client.response import ChunkedDecoder, ResponseHead, parse_head
from ntrip_client.sourcetable import by_distance, describe, parse_sourcetable

#: Longest wait in one receive, so that GGA and stop are served on time [s].
POLL_S = 0.2
#: A sourcetable longer than this is cut [bytes].
MAX_TABLE_BYTES = 1 << 20
_COUNTERS = ("bytes_in", "frames", "frame_bytes", "crc_failures", "skipped_bytes")


@dataclass(frozen=True, slots=True)
class ClientSettings:
    """What the client needs; times in seconds. ValueError for values it cannot work with."""

    url: CasterUrl
    password: str = field(repr=False)
    gga_interval_s: float = 10.0
    stall_timeout_s: float = 10.0
    connect_timeout_s: float = 5.0
    backoff_initial_s: float = 0.5
    backoff_max_s: float = 30.0
    #: CA certificates for an https caster (None: the system's).
    ca_file: str | None = None
    user_agent: str = "NTRIP gnss_ins/0.1"

    def __post_init__(self) -> None:
        """Checks the times."""
        GgaSchedule(self.gga_interval_s)  # its own check of the interval
        for name in ("stall_timeout_s", "connect_timeout_s", "backoff_initial_s"):
            if not getattr(self, name) > 0:
                raise ValueError(f"NTRIP {name} = {getattr(self, name)}: must be > 0")
        if not self.backoff_max_s >= self.backoff_initial_s:
            raise ValueError(
                f"NTRIP backoff_max_s = {self.backoff_max_s}: must be >= backoff_initial_s"
                f" ({self.backoff_initial_s})"
            )


class CasterState(StrEnum):
    """Where the client stands."""

    CONNECTING = "connecting"
    CONNECTED = "connected"
    RECONNECTING = "reconnecting"
    REFUSED = "refused"
    UNKNOWN_MOUNTPOINT = "unknown_mountpoint"
    STOPPED = "stopped"


@dataclass(frozen=True, slots=True)
class ClientStats:
    """A snapshot of the client; counters since ``start``, times on the ``now`` clock [s]."""

    state: CasterState = CasterState.CONNECTING
    #: Status of the caster's last answer ("" / None before any).
    http_status: int | None = None
    reason: str = ""
    #: Connections that delivered a data stream; attempts after a fault.
    connects: int = 0
    reconnects: int = 0
    #: Stream bytes after HTTP chunk decoding, and what the framers made of them.
    bytes_in: int = 0
    frames: int = 0
    frame_bytes: int = 0
    crc_failures: int = 0
    skipped_bytes: int = 0
    gga_sent: int = 0
    last_gga_monotonic_s: float | None = None
    last_frame_monotonic_s: float | None = None
    last_error: str = ""
    #: The caster's mountpoints, nearest first, when the requested one is not there.
    mountpoints: tuple[str, ...] = ()
    #: The wait before the next connection attempt [s] (0 while connected).
    backoff_s: float = 0.0


class _LostError(Exception):
    """The caster closed the connection or sent nothing for too long."""


class _StoppedError(Exception):
    """``stop`` was called."""


class NtripClient:
    """See the module docstring. ``on_frames(frames, received_s)`` gets each read's whole frames
    with the ``now`` time of the read; ``gga()`` gives the sentence to send (with CRLF) or None."""

    def __init__(
        self,
        settings: ClientSettings,
        on_frames: Callable[[list[bytes], float], None],
        gga: Callable[[], bytes | None],
        *,
        log: Callable[[str], None] = print,
        now: Callable[[], float] = time.monotonic,
    ) -> None:
        """A client that does nothing before ``start``."""
        self.settings = settings
        self._on_frames, self._gga, self._log, self._now = on_frames, gga, log, now
        self._lock = threading.Lock()
        self._stopping = threading.Event()
        self._thread: threading.Thread | None = None
        self._stats = ClientStats()
        self._totals = RtcmStats()  # of the connections that ended
        self._framer: RtcmFramer | None = None
        self._schedule = GgaSchedule(settings.gga_interval_s)
        self._backoff_s = settings.backoff_initial_s
        self._delivered = False  # the current connection delivered frames
        self._last_gga: bytes | None = None

    def start(self) -> None:
        """Start the thread (once)."""
        if self._thread is not None:
            raise RuntimeError("NtripClient.start: already started")
        self._log(f"NTRIP: connecting to {self.settings.url}")
        self._thread = threading.Thread(target=self._run, name="ntrip-client", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        """Stop within ~POLL_S (the thread closes its socket; one still connecting ends when its
        connect times out, without any further effect)."""
        self._stopping.set()
        if self._thread is not None:
            self._thread.join(timeout=1.0)
        self._set_state(CasterState.STOPPED, "NTRIP: stopped")

    def stats(self) -> ClientStats:
        """A consistent snapshot."""
        with self._lock:
            current = self._framer.stats if self._framer else RtcmStats()
            counts = {k: getattr(self._totals, k) + getattr(current, k) for k in _COUNTERS}
            return replace(self._stats, **counts)

    def _book(self, **changes: object) -> None:
        with self._lock:
            self._stats = replace(self._stats, **changes)  # type: ignore[arg-type]

    def _set_state(self, state: CasterState, message: str) -> None:
        with self._lock:
            if state == self._stats.state or (
                self._stopping.is_set() and state != CasterState.STOPPED
            ):
                return
            self._stats = replace(self._stats, state=state)
        self._log(message)

    def _run(self) -> None:
        while not self._stopping.is_set():
            sock: list[socket.socket] = []
            try:
                wait_s = self._attempt(sock)
            except _StoppedError:
                break
            except Exception as exc:  # every fault is retried: nothing leaves the thread
                if self._stopping.is_set():
                    break
                wait_s = self._fault(str(exc) or type(exc).__name__)
            finally:
                self._end_connection(sock)
            self._stopping.wait(wait_s)

    def _fault(self, error: str) -> float:
        if self._delivered:
            self._backoff_s, self._delivered = self.settings.backoff_initial_s, False
        wait_s = self._backoff_s
        self._backoff_s = min(2 * wait_s, self.settings.backoff_max_s)
        with self._lock:
            reconnects = self._stats.reconnects + 1
        self._book(reconnects=reconnects, last_error=error, backoff_s=wait_s)
        self._set_state(
            CasterState.RECONNECTING, f"NTRIP: {self.settings.url}: {error}; reconnecting"
        )
        return wait_s

    def _attempt(self, sock: list[socket.socket]) -> float:
        """One connection; the wait before the next [s]. ``sock`` receives the sockets opened."""
        url = self.settings.url
        head, body = self._ask(url.mountpoint, sock)
        if head.is_data:
            self._stream(sock[-1], head, body)
        if head.status in (401, 403):
            hint = f"; check the user and the password ({PASSWORD_VARIABLE} or the password file)"
            return self._refused(head, f"{url} refused the request: {head.status_text}{hint}")
        if head.status == 404 or head.is_sourcetable:
            text = self._read_table(sock[-1], head, body) if head.is_sourcetable else ""
            return self._unknown_mountpoint(text, sock)
        return self._refused(head, f"{url} answered {head.status_text}")

    def _refused(self, head: ResponseHead, error: str) -> float:
        max_s = self.settings.backoff_max_s
        self._book(last_error=error, backoff_s=max_s)
        self._set_state(CasterState.REFUSED, f"NTRIP: error: {error}; retrying every {max_s:g} s")
        return max_s

    def _unknown_mountpoint(self, table: str, sock: list[socket.socket]) -> float:
        url, max_s = self.settings.url, self.settings.backoff_max_s
        note = ""
        if not table:
            try:
                head, body = self._ask("", sock)
                table = self._read_table(sock[-1], head, body) if head.is_sourcetable else ""
                note = "" if table else f" (GET / answered {head.status_text})"
            except (OSError, ValueError, _LostError) as exc:
                note = f" (its sourcetable could not be read: {exc})"
        mountpoints = parse_sourcetable(table)
        position = self._position()
        if position is not None:
            mountpoints = by_distance(mountpoints, *position)
        wanted = (
            f"mountpoint {url.mountpoint!r} is not on" if url.mountpoint else "no mountpoint for"
        )
        error = f"{wanted} {url}; the caster's: {describe(mountpoints, position)}{note}"
        self._book(
            last_error=error, mountpoints=tuple(mp.name for mp in mountpoints), backoff_s=max_s
        )
        self._set_state(
            CasterState.UNKNOWN_MOUNTPOINT, f"NTRIP: error: {error}; retrying every {max_s:g} s"
        )
        return max_s

    def _position(self) -> tuple[float, float] | None:
        """The rover's position from its latest GGA, else from the last one sent."""
        for sentence in (self._gga(), self._last_gga):
            position = gga_position(sentence.decode("ascii", "replace")) if sentence else None
            if position is not None:
                return position
        return None

    def _ask(self, mountpoint: str, sock: list[socket.socket]) -> tuple[ResponseHead, bytes]:
        """Connect, request ``mountpoint`` ("" the sourcetable); the answer's head and the body
        bytes that came with it."""
        opened = self._connect()
        sock.append(opened)
        opened.sendall(self._request(mountpoint))
        data, since = b"", self._now()
        while (head := parse_head(data)) is None:
            chunk = self._recv(opened, since)
            if chunk:
                data, since = data + chunk, self._now()
        self._book(http_status=head.status, reason=head.status_text)
        return head, data[head.body_start :]

    def _connect(self) -> socket.socket:
        s = self.settings
        sock = socket.create_connection((s.url.host, s.url.port), timeout=s.connect_timeout_s)
        if s.url.scheme == "https":
            context = ssl.create_default_context(cafile=s.ca_file)
            try:
                sock = context.wrap_socket(sock, server_hostname=s.url.host)
            except BaseException:
                sock.close()
                raise
        sock.settimeout(POLL_S)
        if self._stopping.is_set():
            sock.close()
            raise _StoppedError
        return sock

    def _request(self, mountpoint: str) -> bytes:
        s, url = self.settings, self.settings.url
        host = f"[{url.host}]" if ":" in url.host else url.host
        lines = [
            f"GET /{urllib.parse.quote(mountpoint)} HTTP/1.1",
            f"Host: {host}:{url.port}",
            "Ntrip-Version: Ntrip/2.0",
            f"User-Agent: {s.user_agent}",
        ]
        if url.user:
            token = base64.b64encode(f"{url.user}:{s.password}".encode()).decode("ascii")
            lines.append(f"Authorization: Basic {token}")
        lines.append("Connection: close")
        return ("\r\n".join(lines) + "\r\n\r\n").encode()

    def _recv(self, sock: socket.socket, since_s: float) -> bytes:
        """What arrived within POLL_S (b"" for nothing); _LostError when the caster closed or sent
        nothing for ``stall_timeout_s`` since ``since_s``."""
        if self._stopping.is_set():
            raise _StoppedError
        try:
            chunk = sock.recv(65536)
        except TimeoutError:
            stall_s = self.settings.stall_timeout_s
            if self._now() - since_s >= stall_s:
                raise _LostError(f"no data for {stall_s:g} s") from None
            return b""
        if not chunk:
            raise _LostError("connection closed by the caster")
        return chunk

    def _stream(self, sock: socket.socket, head: ResponseHead, body: bytes) -> NoReturn:
        """Frames out, GGA in, until the connection fails."""
        decoder = ChunkedDecoder() if head.chunked else None
        with self._lock:
            self._framer = RtcmFramer()
            connects = self._stats.connects + 1
        self._book(connects=connects, last_error="", mountpoints=(), backoff_s=0.0)
        chunked = ", chunked" if head.chunked else ""
        self._set_state(
            CasterState.CONNECTED,
            f"NTRIP: connected to {self.settings.url}: {head.protocol} {head.status_text}{chunked}",
        )
        self._schedule.connected()
        data, since = body, self._now()
        while True:
            if data:
                self._take(decoder.feed(data) if decoder else data, since)
                if decoder is not None and decoder.finished:
                    raise _LostError("the caster ended the stream")
            self._send_gga(sock)
            data = self._recv(sock, since)
            if data:
                since = self._now()

    def _take(self, stream: bytes, received_s: float) -> None:
        with self._lock:
            assert self._framer is not None
            frames = self._framer.feed(stream)
            if frames:
                self._stats = replace(self._stats, last_frame_monotonic_s=received_s)
        if frames:
            self._delivered = True
            self._on_frames(frames, received_s)

    def _send_gga(self, sock: socket.socket) -> None:
        now_s = self._now()
        if not self._schedule.due(now_s):
            return
        sentence = self._gga()
        if not sentence:
            return
        sock.sendall(sentence)
        self._schedule.sent(now_s)
        self._last_gga = sentence
        with self._lock:
            sent = self._stats.gga_sent + 1
        self._book(gga_sent=sent, last_gga_monotonic_s=now_s)

    def _read_table(self, sock: socket.socket, head: ResponseHead, body: bytes) -> str:
        """The sourcetable body: up to ENDSOURCETABLE, its length, its last chunk or the close."""
        decoder = ChunkedDecoder() if head.chunked else None
        length_text = head.headers.get("content-length", "")
        length = int(length_text) if length_text.isdigit() else math.inf
        text, since = bytearray(), self._now()
        data = body
        while True:
            text += decoder.feed(data) if decoder else data
            done = decoder is not None and decoder.finished
            if done or b"ENDSOURCETABLE" in text or len(text) >= min(length, MAX_TABLE_BYTES):
                break
            try:
                data = self._recv(sock, since)
            except _LostError:
                break
            if data:
                since = self._now()
        return text.decode("utf-8", "replace")

    def _end_connection(self, sock: list[socket.socket]) -> None:
        """Close the sockets; a partial frame at the cut counts as skipped bytes."""
        for opened in sock:
            opened.close()
        with self._lock:
            if self._framer is not None:
                self._framer.reset()
                for name in _COUNTERS:
                    total = getattr(self._totals, name) + getattr(self._framer.stats, name)
                    setattr(self._totals, name, total)
                self._framer = None
