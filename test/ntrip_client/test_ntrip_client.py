"""NtripClient against the caster emulator over real sockets on 127.0.0.1: NTRIP 2 and 1, TLS,
refusals, unknown mountpoints, stalls, restarts, noise, GGA upstream, the password kept secret.

Conditions are awaited by polling with a deadline; nothing asserts on timing."""

from __future__ import annotations

import base64
import math
import os
import shutil
import signal
import socket
import ssl
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
from support import waiting
from support.paths import FIXTURES

from gnss_ins_common.rtcm import MAX_FRAME_BYTES
from ntrip_client.caster_emulator import CasterEmulator
from ntrip_client.caster_url import parse_caster_url
from ntrip_client.client import CasterState, ClientSettings, NtripClient
from ntrip_client.gga import fixed_gga

CAPTURE = (FIXTURES / "rtcm" / "pygpsdata-NTRIP-USCL00CHL0.log").read_bytes()
AALBORG = (57.0148, 9.9865)
MOUNTPOINTS = {
    "AAU00DNK": AALBORG,
    "FAR": (40.0, -3.0),
    "MID": (52.0, 13.0),
    "NOPOS": (math.nan,) * 2,
}
USER, PASSWORD = "rover", "s3cr3t-Pw"
DEADLINE_S = 20.0


def wait_for(predicate: Callable[[], bool], timeout_s: float = DEADLINE_S) -> bool:
    """``support.waiting.wait_for`` with this module's deadline."""
    return waiting.wait_for(predicate, timeout_s)


class Rover:
    """A client with what it delivered and logged."""

    def __init__(
        self, caster: CasterEmulator, mountpoint: str, password: str, gga: bool, **settings
    ):
        scheme = "https" if caster.tls else "http"
        url = parse_caster_url(f"{scheme}://{USER}@127.0.0.1:{caster.port}/{mountpoint}")
        self.settings = ClientSettings(url, password, **settings)
        self.frames: list[bytes] = []
        self.logs: list[str] = []
        self.gga = fixed_gga(*AALBORG, 50.0, time.time()) if gga else None
        self._lock = threading.Lock()
        self.client = NtripClient(
            self.settings, self._on_frames, lambda: self.gga, log=self.logs.append
        )

    def _on_frames(self, frames: list[bytes], received_s: float) -> None:
        assert frames and received_s <= time.monotonic()
        with self._lock:
            self.frames += frames

    def delivered(self) -> list[bytes]:
        with self._lock:
            return list(self.frames)


@pytest.fixture
def rovers() -> Iterator[Callable[..., Rover]]:
    """Started clients, stopped at the end (each must stop)."""
    started: list[Rover] = []

    def start(
        caster: CasterEmulator,
        mountpoint: str = "AAU00DNK",
        password: str = PASSWORD,
        gga: bool = True,
        **settings,
    ) -> Rover:
        rover = Rover(caster, mountpoint, password, gga, **settings)
        rover.client.start()
        started.append(rover)
        return rover

    yield start
    for rover in started:
        rover.client.stop()
        assert rover.client.stats().state == CasterState.STOPPED


def caster(**options) -> CasterEmulator:
    options.setdefault("rate_bytes_s", 20000.0)
    return CasterEmulator(CAPTURE, MOUNTPOINTS, (USER, PASSWORD), **options)


def settle_and_compare(server: CasterEmulator, rover: Rover) -> None:
    """Stop the caster's sending; the client must have every frame sent, in order, once."""
    server.stall()
    assert wait_for(lambda: rover.delivered() == server.sent_frames), (
        len(rover.delivered()),
        len(server.sent_frames),
    )


@pytest.mark.parametrize("ntrip1_only", [False, True], ids=["ntrip2-chunked", "ntrip1-icy"])
def test_the_casters_frames_arrive_exactly_in_order(rovers, ntrip1_only):
    with caster(ntrip1_only=ntrip1_only) as server:
        rover = rovers(server)
        assert wait_for(lambda: len(rover.delivered()) >= 3 * len(server.frames))
        settle_and_compare(server, rover)
        stats = rover.client.stats()
        assert stats.state == CasterState.CONNECTED and stats.connects == 1
        assert (stats.http_status, stats.reason) == (200, "200 OK")
        assert stats.frames == len(rover.frames) and stats.crc_failures == 0
        assert stats.frame_bytes == sum(map(len, rover.frames)) and stats.skipped_bytes == 0
        assert stats.last_frame_monotonic_s is not None
        assert "Ntrip-Version: Ntrip/2.0" in server.requests[0]
    protocol = "ICY 200 OK" if ntrip1_only else "HTTP/1.1 200 OK, chunked"
    assert any(protocol in line for line in rover.logs), rover.logs


def test_a_caster_requiring_the_version_header_serves_the_client(rovers):
    with caster(require_version_header=True) as server:
        rover = rovers(server)
        assert wait_for(lambda: len(rover.delivered()) >= 10)


def test_a_wrong_password_is_refused_until_the_caster_accepts_it(rovers):
    with caster() as server:
        rover = rovers(server, password="wrong", backoff_max_s=0.5)
        assert wait_for(lambda: rover.client.stats().state == CasterState.REFUSED)
        stats = rover.client.stats()
        assert (stats.http_status, stats.reason) == (401, "401 Unauthorized")
        assert "401 Unauthorized" in stats.last_error and "NTRIP_PASSWORD" in stats.last_error
        assert wait_for(lambda: server.connections >= 3)  # retried, at backoff_max_s
        assert rover.delivered() == [] and rover.client.stats().frames == 0
        assert sum("refused" in line for line in rover.logs) == 1  # logged once, not per retry
        server.credentials = (USER, "wrong")
        assert wait_for(lambda: len(rover.delivered()) >= 10)
        assert rover.client.stats().state == CasterState.CONNECTED


@pytest.mark.parametrize("ntrip1_only", [False, True], ids=["ntrip2-404", "ntrip1-sourcetable"])
def test_an_unknown_mountpoint_lists_the_casters_nearest_first(rovers, ntrip1_only):
    with caster(ntrip1_only=ntrip1_only) as server:
        rover = rovers(server, "AAU00DNX")
        assert wait_for(lambda: rover.client.stats().state == CasterState.UNKNOWN_MOUNTPOINT)
        stats = rover.client.stats()
        assert stats.mountpoints == ("AAU00DNK", "MID", "FAR", "NOPOS")
        assert "'AAU00DNX'" in stats.last_error
        assert "AAU00DNK (AAU00DNK, RTCM 3.2, 0 km), MID (" in stats.last_error
        assert stats.http_status == 200 and stats.frames == 0


def test_no_mountpoint_lists_them_without_a_position_in_the_tables_order(rovers):
    with caster() as server:
        rover = rovers(server, "", gga=False)
        assert wait_for(lambda: rover.client.stats().state == CasterState.UNKNOWN_MOUNTPOINT)
        stats = rover.client.stats()
        assert stats.mountpoints == tuple(MOUNTPOINTS)
        assert stats.last_error.startswith("no mountpoint for")


def test_a_stalled_stream_is_reconnected_and_flows_again(rovers):
    with caster() as server:
        rover = rovers(server, stall_timeout_s=1.0, backoff_initial_s=0.05)
        assert wait_for(lambda: len(rover.delivered()) >= 10)
        server.stall()
        assert wait_for(lambda: rover.client.stats().reconnects >= 1)
        assert rover.client.stats().last_error == "no data for 1 s"
        assert rover.client.stats().state == CasterState.RECONNECTING
        count = len(rover.delivered())
        server.resume()
        assert wait_for(lambda: len(rover.delivered()) >= count + 10)
        assert rover.client.stats().state == CasterState.CONNECTED
        settle_and_compare(server, rover)


def test_a_caster_killed_and_restarted_delivers_no_frame_twice_or_cut(rovers):
    with caster() as server:
        rover = rovers(server, backoff_initial_s=0.05, backoff_max_s=0.2)
        assert wait_for(lambda: len(rover.delivered()) >= 10)
        server.stop()
        assert wait_for(lambda: rover.client.stats().reconnects >= 3)  # refused meanwhile
        assert rover.client.stats().backoff_s == 0.2  # doubled up to its cap
        count = len(rover.delivered())
        server.start()
        assert wait_for(lambda: len(rover.delivered()) >= count + 10)
        settle_and_compare(server, rover)
        stats = rover.client.stats()
        assert stats.connects == 2 and stats.crc_failures == 0
        assert sum("reconnecting" in line for line in rover.logs) == 1


def test_noise_between_frames_is_counted_never_delivered(rovers):
    with caster(garbage_every=3, seed=7) as server:
        rover = rovers(server)
        assert wait_for(lambda: len(rover.delivered()) >= 50)
        settle_and_compare(server, rover)
        stats = rover.client.stats()
        assert stats.skipped_bytes > 0 and stats.crc_failures == 0
        # the rest is the start of a frame the stall cut, held by the framer
        held = stats.bytes_in - stats.frame_bytes - stats.skipped_bytes
        assert 0 <= held < MAX_FRAME_BYTES


def test_gga_goes_upstream_at_its_interval(rovers):
    with caster(rate_bytes_s=2000.0) as server:
        rover = rovers(server, gga_interval_s=1.0)
        assert wait_for(lambda: len(server.gga_received) >= 4)
        times = [t for t, _ in server.gga_received]
        # never more than one a second (+1 for where the window starts)
        assert len(times) <= (times[-1] - times[0]) / 1.0 + 2
        assert all(sentence.startswith("$GPGGA,") for _, sentence in server.gga_received)
        stats = rover.client.stats()
        assert stats.gga_sent >= 4 and stats.last_gga_monotonic_s is not None


def test_the_password_is_never_shown(rovers):
    token = base64.b64encode(f"{USER}:{PASSWORD}".encode()).decode()
    with caster() as server:
        rover = rovers(server)
        refused = rovers(server, password=PASSWORD + "x")
        assert wait_for(lambda: len(rover.delivered()) >= 5)
        assert wait_for(lambda: refused.client.stats().state == CasterState.REFUSED)
        shown = [*server.requests, *rover.logs, *refused.logs]
        shown += [repr(r.client.stats()) for r in (rover, refused)]
        shown += [repr(r.settings) + str(r.settings.url) for r in (rover, refused)]
        assert all("Authorization: <redacted>" in request for request in server.requests)
        assert not [text for text in shown if PASSWORD in text or token in text]


@pytest.fixture(scope="module")
def certificate(tmp_path_factory) -> tuple[Path, Path]:
    """A self-signed certificate for 127.0.0.1 (openssl CLI)."""
    if shutil.which("openssl") is None:
        pytest.skip("no openssl command to make a certificate")
    folder = tmp_path_factory.mktemp("tls")
    cert, key = folder / "cert.pem", folder / "key.pem"
    subject = ["-subj", "/CN=127.0.0.1", "-addext", "subjectAltName=IP:127.0.0.1"]
    subprocess.run(
        ["openssl", "req", "-x509", "-newkey", "rsa:2048", "-nodes", "-days", "1", *subject,
         "-keyout", str(key), "-out", str(cert)],
        check=True, capture_output=True, timeout=60,
    )  # fmt: skip
    return cert, key


def test_https_with_the_casters_certificate(rovers, certificate):
    cert, key = certificate
    context = ssl.SSLContext(ssl.PROTOCOL_TLS_SERVER)
    context.load_cert_chain(cert, key)
    with caster(tls=context) as server:
        rover = rovers(server, ca_file=str(cert))
        untrusted = rovers(server)  # the system's CAs do not know the self-signed certificate
        assert wait_for(lambda: len(rover.delivered()) >= 3 * len(server.frames))
        assert wait_for(lambda: untrusted.client.stats().reconnects >= 1)
        assert "CERTIFICATE_VERIFY_FAILED" in untrusted.client.stats().last_error
        assert untrusted.delivered() == []
        # only the trusted client's frames were sent: compare them
        settle_and_compare(server, rover)


@pytest.mark.parametrize(
    ("setting", "value", "message"),
    [
        ("gga_interval_s", 0.5, "at least 1 s"),
        ("stall_timeout_s", 0.0, "must be > 0"),
        ("backoff_max_s", 0.1, "backoff_initial_s"),
    ],
)
def test_settings_refuse_what_cannot_work(setting, value, message):
    with pytest.raises(ValueError, match=message):
        ClientSettings(parse_caster_url("http://h/M"), "", **{setting: value})


def test_dropped_clients_reconnect_and_lose_nothing(rovers):
    with caster() as server:
        rover = rovers(server, backoff_initial_s=0.05)
        for drops in (1, 2):
            assert wait_for(lambda n=drops: len(rover.delivered()) >= 20 * n)
            server.drop_clients()
            assert wait_for(lambda n=drops: rover.client.stats().connects > n)
        settle_and_compare(server, rover)
        assert rover.client.stats().reconnects == 2
        assert sum("connection closed by the caster" in line for line in rover.logs) == 2


def _ask(server: CasterEmulator, request: bytes) -> bytes:
    """The emulator's raw answer to ``request`` (until it closes, at most ~4 kB)."""
    with socket.create_connection(("127.0.0.1", server.port), timeout=5.0) as sock:
        sock.sendall(request)
        data = b""
        while len(data) < 4096 and (chunk := sock.recv(4096)):
            data += chunk
    return data


def test_the_emulator_answers_as_ntrip_1_and_2_casters_do():
    auth = base64.b64encode(f"{USER}:{PASSWORD}".encode())
    ntrip1 = b"GET /AAU00DNK HTTP/1.0\r\nUser-Agent: NTRIP x\r\nAuthorization: Basic %s\r\n\r\n"
    ntrip2 = b"GET /%s HTTP/1.1\r\nNtrip-Version: Ntrip/2.0\r\n\r\n"
    with caster() as server:
        assert _ask(server, ntrip1 % auth).startswith(b"ICY 200 OK\r\n\xd3")
        assert _ask(server, ntrip2 % b"NONE").startswith(b"HTTP/1.1 404 Not Found\r\n")
        assert _ask(server, ntrip1.replace(b"AAU00DNK", b"NONE") % auth).startswith(
            b"SOURCETABLE 200 OK\r\n"
        )
        assert b"ENDSOURCETABLE" in _ask(server, ntrip2 % b"")
        unauthorised = _ask(server, ntrip2 % b"AAU00DNK")
        assert unauthorised.startswith(b"HTTP/1.1 401 Unauthorized\r\nWWW-Authenticate: Basic")
        assert server.requests[0].endswith("Authorization: <redacted>")
    with caster(require_version_header=True) as server:
        assert _ask(server, ntrip1 % auth).startswith(b"HTTP/1.0 404 Not Found\r\n")


def test_emulate_caster_command_serves_until_sigterm(rovers):
    command = [str(Path(sys.executable).parent / "gnss_ins"), "emulate-caster", "--port", "0"]
    env = {**os.environ, "NTRIP_PASSWORD": PASSWORD}
    with subprocess.Popen(
        [*command, "--user", USER, "--rate", "20000", "--mountpoint", "AAU00DNK", "B@40,10"],
        stdout=subprocess.PIPE,
        text=True,
        env=env,
    ) as process:
        assert process.stdout is not None
        first = process.stdout.readline()
        assert first.startswith("caster on 127.0.0.1:") and "mountpoints AAU00DNK B" in first
        server = CasterEmulator(CAPTURE, {})  # only for its address in the client's URL
        server.port = int(first.split(":")[1].split()[0])
        rover = rovers(server)
        assert wait_for(lambda: len(rover.delivered()) >= 10)
        assert rover.delivered()[:3] == server.frames[:3]
        process.send_signal(signal.SIGTERM)
        assert process.wait(timeout=30) == 0
