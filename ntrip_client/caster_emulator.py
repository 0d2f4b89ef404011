"""A real NTRIP caster on 127.0.0.1 for tests and bench work: the frames of an RTCM 3 capture
served in a loop, NTRIP 2 (HTTP/1.1 chunked) or NTRIP 1 (``ICY``), with the faults a client
must survive (stall, dropped connections, restarts, garbage between frames).

Every connection has a thread of its own, which paces the frames, cuts the stream into chunks
(or writes) of random sizes unaligned to frames and reads the client's GGA. A frame is recorded
in ``sent_frames`` once its last byte is written; a dropped client's socket is shut for writing
first and closed once the client has closed, so that everything recorded reaches it.
"""

from __future__ import annotations

import base64
import random
import select
import socket
import ssl
import threading
import time
import urllib.parse
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import TracebackType

from gnss_ins_common.rtcm import PREAMBLE, split_frames

#: Period of a connection's loop: pacing, writes and reads [s].
TICK_S = 0.1
#: A request head longer than this is refused [bytes].
MAX_REQUEST_BYTES = 8192
#: Longest wait for a dropped client to close its end [s].
DRAIN_S = 2.0
_NOT_PREAMBLE = bytes(b for b in range(256) if b != PREAMBLE)


@dataclass
class _Connection:
    sock: socket.socket
    dropped: threading.Event = field(default_factory=threading.Event)


class CasterEmulator:
    """The caster; ``with CasterEmulator(capture) as caster:`` serves on ``caster.port``."""

    def __init__(
        self,
        data: bytes,
        mountpoints: Mapping[str, tuple[float, float]],
        credentials: tuple[str, str] | None = None,
        *,
        port: int = 0,
        host: str = "127.0.0.1",
        rate_bytes_s: float = 1000.0,
        frames_per_s: float | None = None,
        ntrip1_only: bool = False,
        require_version_header: bool = False,
        tls: ssl.SSLContext | None = None,
        garbage_every: int = 0,
        seed: int = 0,
    ) -> None:
        """Serve the frames of ``data`` on the ``mountpoints`` (name -> (lat, lon) [deg]) at
        ``rate_bytes_s``, or ``frames_per_s`` when given; ``credentials`` (user, password) or
        None for no authentication; ``port`` 0 picks a free one. ``garbage_every`` N > 0 puts
        1..32 random non-RTCM bytes after every N-th frame (``seed`` for them and the cuts)."""
        self.frames, _ = split_frames(data)
        if not self.frames:
            raise ValueError("caster emulator: the data holds no RTCM 3 frame")
        self.mountpoints = dict(mountpoints)
        self.credentials = credentials
        self.host, self.port = host, port
        self.rate_bytes_s, self.frames_per_s = rate_bytes_s, frames_per_s
        self.ntrip1_only, self.require_version_header = ntrip1_only, require_version_header
        self.tls, self.garbage_every = tls, garbage_every
        self._random = random.Random(seed)
        self._lock = threading.Lock()
        self._resumed = threading.Event()
        self._resumed.set()
        self._listener: socket.socket | None = None
        self._threads: list[threading.Thread] = []
        self._live: list[_Connection] = []
        #: Every whole frame written, in order (all connections); GGA lines (monotonic time [s],
        #: sentence); requests (their heads, an Authorization value redacted).
        self.sent_frames: list[bytes] = []
        self.gga_received: list[tuple[float, str]] = []
        self.requests: list[str] = []
        self.connections = 0

    # ---- control ------------------------------------------------------------------------------
    def start(self) -> None:
        """Listen (again, on the same port after ``stop``)."""
        listener = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        listener.bind((self.host, self.port))
        listener.listen(16)
        listener.settimeout(TICK_S)
        self.port = listener.getsockname()[1]
        self._listener = listener
        self._spawn(self._accept, listener)

    def stop(self) -> None:
        """Stop listening and drop every client; returns when their threads ended."""
        listener, self._listener = self._listener, None
        if listener is not None:
            listener.close()
        self.drop_clients()
        with self._lock:
            threads, self._threads = self._threads, []
        for thread in threads:
            thread.join(timeout=DRAIN_S + 1.0)

    def drop_clients(self) -> None:
        """End every client connection now (the frames written still reach the client)."""
        with self._lock:
            for connection in self._live:
                connection.dropped.set()

    def stall(self) -> None:
        """Keep the connections open and send nothing (no answer either) until ``resume``."""
        self._resumed.clear()

    def resume(self) -> None:
        """Send again after ``stall``."""
        self._resumed.set()

    def __enter__(self) -> CasterEmulator:
        """Start."""
        self.start()
        return self

    def __exit__(
        self,
        kind: type[BaseException] | None,
        error: BaseException | None,
        trace: TracebackType | None,
    ) -> None:
        """Stop."""
        self.stop()

    def sourcetable(self) -> bytes:
        """The sourcetable body: a CAS line, one STR line per mountpoint, ENDSOURCETABLE."""
        lines = [f"CAS;{self.host};{self.port};gnss_ins;emulator;0;DNK;57.01;9.99;0.0.0.0;0;none"]
        auth = "N" if self.credentials is None else "B"
        for name, (lat, lon) in self.mountpoints.items():
            lines.append(
                f"STR;{name};{name};RTCM 3.2;1004(1),1005(10);2;GPS+GLO;EMU;DNK;{lat:.4f};"
                f"{lon:.4f};1;0;gnss_ins emulator;none;{auth};N;{self.rate_bytes_s * 8:.0f};"
            )
        return ("\r\n".join([*lines, "ENDSOURCETABLE"]) + "\r\n").encode()

    # ---- threads ------------------------------------------------------------------------------
    def _spawn(self, target: object, *args: object) -> None:
        thread = threading.Thread(target=target, args=args, daemon=True)  # type: ignore[arg-type]
        with self._lock:
            self._threads.append(thread)
        thread.start()

    def _accept(self, listener: socket.socket) -> None:
        while self._listener is listener:
            try:
                sock, _ = listener.accept()
            except TimeoutError:
                continue
            except OSError:  # closed by stop
                return
            connection = _Connection(sock)
            with self._lock:
                self.connections += 1
                self._live.append(connection)
            self._spawn(self._serve, connection)

    def _serve(self, connection: _Connection) -> None:
        sock = connection.sock
        try:
            sock.settimeout(DRAIN_S)
            if self.tls is not None:
                sock = connection.sock = self.tls.wrap_socket(sock, server_side=True)
            request = self._read_request(sock)
            if request is not None:
                self._answer(connection, *request)
        except OSError:  # the client went away (or a TLS handshake failed)
            pass
        finally:
            with self._lock:
                self._live.remove(connection)
            connection.sock.close()

    def _read_request(self, sock: socket.socket) -> tuple[str, dict[str, str], bytes] | None:
        """(mountpoint, headers in lower case, bytes after the head) of a GET request."""
        data = b""
        while b"\r\n\r\n" not in data:
            chunk = sock.recv(4096)
            if not chunk or len(data) > MAX_REQUEST_BYTES:
                return None
            data += chunk
        head, _, rest = data.partition(b"\r\n\r\n")
        lines = head.decode("latin-1").split("\r\n")
        headers = {}
        shown = [lines[0]]
        for line in lines[1:]:
            name, _, value = line.partition(":")
            headers[name.strip().lower()] = value.strip()
            redacted = name.strip().lower() == "authorization"
            shown.append(f"{name}: <redacted>" if redacted else line)
        with self._lock:
            self.requests.append("\r\n".join(shown))
        words = lines[0].split(" ")
        target = words[1] if len(words) == 3 else ""
        return urllib.parse.unquote(target.lstrip("/")), headers, rest

    def _answer(
        self, connection: _Connection, mountpoint: str, headers: dict[str, str], rest: bytes
    ) -> None:
        sock = connection.sock
        has_version = headers.get("ntrip-version", "").lower().startswith("ntrip/2")
        ntrip2 = has_version and not self.ntrip1_only
        status = "HTTP/1.1" if ntrip2 else "HTTP/1.0"
        known = mountpoint in self.mountpoints
        if (self.require_version_header and not has_version) or (
            ntrip2 and not known and mountpoint
        ):
            sock.sendall(f"{status} 404 Not Found\r\nConnection: close\r\n\r\n".encode())
        elif not known:
            table = self.sourcetable()
            kind = "HTTP/1.1 200 OK\r\nNtrip-Version: Ntrip/2.0" if ntrip2 else "SOURCETABLE 200 OK"
            ctype = "gnss/sourcetable" if ntrip2 else "text/plain"
            sock.sendall(
                f"{kind}\r\nServer: gnss_ins emulator\r\nContent-Type: {ctype}\r\n"
                f"Content-Length: {len(table)}\r\nConnection: close\r\n\r\n".encode()
                + table
            )
        elif not self._authorised(headers.get("authorization", "")):
            sock.sendall(
                f'{status} 401 Unauthorized\r\nWWW-Authenticate: Basic realm="/{mountpoint}"\r\n'
                "Connection: close\r\n\r\n".encode()
            )
        else:
            head = (
                b"HTTP/1.1 200 OK\r\nNtrip-Version: Ntrip/2.0\r\nContent-Type: gnss/data\r\n"
                b"Transfer-Encoding: chunked\r\nCache-Control: no-store\r\n"
                b"Connection: close\r\n\r\n"
                if ntrip2
                else b"ICY 200 OK\r\n"  # the data right after one CRLF, as many casters do
            )
            self._stream(connection, head, ntrip2, bytearray(rest))
            return
        sock.shutdown(socket.SHUT_WR)

    def _authorised(self, authorization: str) -> bool:
        if self.credentials is None:
            return True
        user, password = self.credentials
        expected = base64.b64encode(f"{user}:{password}".encode()).decode("ascii")
        return authorization == f"Basic {expected}"

    def _stream(
        self, connection: _Connection, head: bytes, chunked: bool, received: bytearray
    ) -> None:
        """The answer's head and the frames, paced, until the client closes or is dropped."""
        sock = connection.sock
        pending = bytearray()
        ends: list[tuple[int, bytes]] = []  # (end offset in pending, frame)
        index, due_s = 0, time.monotonic()
        while not connection.dropped.is_set():
            now_s = time.monotonic()
            if not self._resumed.is_set():
                due_s = now_s  # no catching up after a stall
            else:
                if head:
                    sock.sendall(head)
                    head = b""
                while due_s <= now_s:
                    frame = self.frames[index % len(self.frames)]
                    pending += frame
                    ends.append((len(pending), frame))
                    index += 1
                    if self.garbage_every and index % self.garbage_every == 0:
                        size = self._random.randint(1, 32)
                        pending += bytes(self._random.choices(_NOT_PREAMBLE, k=size))
                    rate = self.frames_per_s
                    due_s += 1.0 / rate if rate else len(frame) / self.rate_bytes_s
                if pending:  # a random cut, unaligned to the frames
                    n = self._random.randint((len(pending) + 1) // 2, len(pending))
                    piece = bytes(pending[:n])
                    sock.sendall(b"%x\r\n%s\r\n" % (n, piece) if chunked else piece)
                    del pending[:n]
                    with self._lock:
                        self.sent_frames += [frame for end, frame in ends if end <= n]
                    ends = [(end - n, frame) for end, frame in ends if end > n]
            if not self._read_gga(sock, received):
                return
        sock.shutdown(socket.SHUT_WR)
        deadline = time.monotonic() + DRAIN_S
        while time.monotonic() < deadline and self._read_gga(sock, received):
            pass

    def _read_gga(self, sock: socket.socket, received: bytearray) -> bool:
        """Wait up to TICK_S for the client's lines and record its GGA; False once it closed."""
        pending = isinstance(sock, ssl.SSLSocket) and sock.pending() > 0
        if not pending and not select.select([sock], [], [], TICK_S)[0]:
            return True
        chunk = sock.recv(4096)
        if not chunk:
            return False
        received += chunk
        *lines, rest = received.split(b"\n")
        received[:] = rest[-MAX_REQUEST_BYTES:]
        for line in lines:
            text = line.decode("ascii", "replace").strip()
            if text.startswith("$") and text[3:6] == "GGA":
                with self._lock:
                    self.gga_received.append((time.monotonic(), text))
        return True
