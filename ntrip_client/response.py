"""The caster's answer, parsed incrementally: its head (HTTP/1.x, NTRIP 1 ``ICY`` or
``SOURCETABLE``) and an HTTP/1.1 chunked body (RFC 9112 §7.1)."""

from __future__ import annotations

import re
from dataclasses import dataclass

#: A head longer than this without its end is no caster's answer [bytes].
MAX_HEAD_BYTES = 16 * 1024
#: A chunk-size line longer than this is malformed [bytes].
MAX_SIZE_LINE_BYTES = 1024
_PROTOCOL_STARTS = (b"HTTP/1.", b"ICY ", b"SOURCETABLE ")
_STATUS_LINE = re.compile(rb"(HTTP/1\.[01]|ICY|SOURCETABLE) (\d{3})(?: (.*))?")
_CHUNK_SIZE = re.compile(rb"[0-9A-Fa-f]{1,15}")
_ICY_OK = b"ICY 200 OK\r\n"


@dataclass(frozen=True, slots=True)
class ResponseHead:
    """Status line and headers of an answer; the body starts at ``body_start`` of the data."""

    protocol: str
    status: int
    reason: str
    #: Header names in lower case -> value (the last one of a repeated name).
    headers: dict[str, str]
    body_start: int

    @property
    def chunked(self) -> bool:
        """Whether the body comes in HTTP/1.1 chunks."""
        return "chunked" in self.headers.get("transfer-encoding", "").lower()

    @property
    def is_sourcetable(self) -> bool:
        """Whether the body is the caster's sourcetable (NTRIP 1 or 2)."""
        content_type = self.headers.get("content-type", "").lower()
        return self.protocol == "SOURCETABLE" or content_type.startswith("gnss/sourcetable")

    @property
    def is_data(self) -> bool:
        """Whether the body is the requested data stream."""
        return self.status == 200 and not self.is_sourcetable

    @property
    def status_text(self) -> str:
        """E.g. "401 Unauthorized"."""
        return f"{self.status} {self.reason}".rstrip()


def _not_an_answer(data: bytes) -> ValueError:
    return ValueError(f"the caster's answer is not HTTP, ICY or SOURCETABLE: {data[:60]!r}")


def parse_head(data: bytes) -> ResponseHead | None:
    """The head at the start of ``data``; None while it is not complete. ValueError for an
    answer that is none of HTTP/1.x, ``ICY`` or ``SOURCETABLE``, or a head over 16 kB."""
    if not any(data[: len(start)] == start[: len(data)] for start in _PROTOCOL_STARTS):
        raise _not_an_answer(data)
    if data.startswith(_ICY_OK) and _is_body_byte(data[len(_ICY_OK) : len(_ICY_OK) + 1]):
        # NTRIP 1 casters may send the data right after the status line's CRLF.
        end = body_start = len(_ICY_OK)
    else:
        end = data.find(b"\r\n\r\n")
        if end < 0:
            if len(data) > MAX_HEAD_BYTES:
                raise ValueError(f"the caster's answer has no end of head in {len(data)} bytes")
            return None
        body_start = end + 4
    lines = data[:end].split(b"\r\n")
    match = _STATUS_LINE.fullmatch(lines[0])
    if match is None:
        raise _not_an_answer(data)
    headers = {}
    for line in lines[1:]:
        name, colon, value = line.decode("latin-1").partition(":")
        if colon:
            headers[name.strip().lower()] = value.strip()
    return ResponseHead(
        protocol=match[1].decode("ascii"),
        status=int(match[2]),
        reason=(match[3] or b"").decode("latin-1").strip(),
        headers=headers,
        body_start=body_start,
    )


def _is_body_byte(following: bytes) -> bool:
    """Whether the byte after an ICY status line starts the body (neither a header nor CRLF)."""
    return bool(following) and following != b"\r" and not following.isalpha()


class ChunkedDecoder:
    """Incremental decoder of an HTTP/1.1 chunked body over arbitrary read boundaries; trailers
    after the last chunk are ignored."""

    def __init__(self) -> None:
        """Before the first chunk-size line."""
        self._buffer = bytearray()
        #: Data bytes of the current chunk still to come; -1 while a size line is expected.
        self._remaining = -1
        self._crlf_due = False
        self.finished = False

    def feed(self, data: bytes) -> bytes:
        """The body bytes ``data`` completes; ValueError for a malformed chunk framing."""
        buf = self._buffer
        buf += data
        out = bytearray()
        while buf and not self.finished:
            if self._crlf_due:
                if len(buf) < 2:
                    break
                if buf[:2] != b"\r\n":
                    raise ValueError(f"chunked body: no CRLF after a chunk's data: {buf[:20]!r}")
                del buf[:2]
                self._crlf_due = False
            elif self._remaining < 0:
                end = buf.find(b"\r\n")
                if end < 0:
                    if len(buf) > MAX_SIZE_LINE_BYTES:
                        raise ValueError("chunked body: chunk-size line too long")
                    break
                size = buf[:end].split(b";", 1)[0].strip(b" \t")
                if _CHUNK_SIZE.fullmatch(size) is None:
                    raise ValueError(f"chunked body: malformed chunk-size line {buf[:end]!r}")
                del buf[: end + 2]
                self._remaining = int(size, 16)
                self.finished = self._remaining == 0
            else:
                take = min(self._remaining, len(buf))
                out += buf[:take]
                del buf[:take]
                self._remaining -= take
                if self._remaining == 0:
                    self._remaining, self._crlf_due = -1, True
        return bytes(out)
