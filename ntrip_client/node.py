"""ntrip_node: network-RTK corrections from an NTRIP caster onto ``rtcm``, the rover's GGA upstream.

The ROS-free ``NtripClient`` (ntrip_client.client) holds the caster connection on its own
thread; every whole RTCM 3 frame with a valid CRC is published as one ``rtcm_msgs/Message`` on
``rtcm`` straight from that thread, stamped with its arrival on the node's clock. The rover's
sentences come in on ``nmea`` (``nmea_msgs/Sentence``, as gnss_node publishes them): its newest GGA
with a position is what the client sends upstream (at most once a second, by default every
10 s), or before the rover's first fix the GGA of ``fixed_position`` when set. The password is
read from the file ``password_file`` or the environment variable ``NTRIP_PASSWORD``, never a
parameter, so that it appears in no command line, parameter listing, log, bag or status.
docs/ntrip.md describes use, parameters and troubleshooting.
"""

from __future__ import annotations

import os
import threading
import time
from typing import Any

from nmea_msgs.msg import Sentence
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rtcm_msgs.msg import Message

from gnss_ins_common import ros_diagnostics as diag
from gnss_ins_common.params import Param, ParameterValueError
from gnss_ins_common.rates import RateMeter
from gnss_ins_common.ros_endpoints import Endpoints
from gnss_ins_common.ros_node_main import run_node
from gnss_ins_common.ros_params import declare_parameters
from gnss_ins_common.ros_serial import node_time_s
from ntrip_client.caster_url import parse_caster_url, read_password
from ntrip_client.client import ClientSettings, NtripClient
from ntrip_client.gga import fixed_gga
from ntrip_client.health import ERROR, OK, RoverGga, assess, corrections_age_s


def _url_error(text: str) -> str | None:
    try:
        parse_caster_url(text)
    except ValueError as exc:
        return str(exc)
    return None


def _position_error(values: list[float]) -> str | None:
    if len(values) not in (0, 3):
        return "needs 3 values (latitude [deg], longitude [deg], height [m]) or none"
    if values and not (-90.0 <= values[0] <= 90.0 and -180.0 <= values[1] <= 180.0):
        return "latitude within ±90°, longitude within ±180°"
    return None


PARAMETERS = (
    Param(
        "url",
        "http://localhost:2101/",
        "the caster and mountpoint, http[s]://USER@HOST:PORT/MOUNTPOINT (no password in it);"
        " no mountpoint: the caster's mountpoints are listed",
        check=_url_error,
    ),
    Param(
        "password_file",
        "",
        "file holding the password (mode 0600); empty: the environment variable NTRIP_PASSWORD",
    ),
    Param("gga_interval", 10.0, "seconds between GGA sentences sent to the caster", 1.0, 600.0),
    Param(
        "fixed_position",
        [],
        "latitude [deg], longitude [deg], height [m] sent as GGA until the rover reports a"
        " position (casters that need one before the first fix); empty: none",
        -1.0e4,
        1.0e4,
        check=_position_error,
        empty_list_of="float",
    ),
    Param(
        "stall_timeout",
        10.0,
        "reconnect when the caster sends no data for this long [s]",
        2.0,
        120.0,
    ),
    Param(
        "age_warn",
        5.0,
        "WARN when the newest correction is older than this [s]",
        1.0,
        600.0,
    ),
    Param("tls_ca_file", "", "CA certificates for an https caster; empty: the system's"),
    Param("frame_id", "", "frame_id of the published rtcm messages"),
    Param("diagnostics_period", 1.0, "period of the /diagnostics status [s]", 0.1, 60.0),
)


class NtripNode(Node):
    """The NTRIP client node; see the module docstring."""

    def __init__(self, **kwargs: Any) -> None:
        """Declare and validate the parameters, read the password, start the client."""
        super().__init__("ntrip_client", **kwargs)
        p = declare_parameters(self, PARAMETERS)
        self.params = p
        url = parse_caster_url(p["url"])
        try:
            password = read_password(os.environ, p["password_file"] or None)
        except ValueError as exc:
            raise ParameterValueError(f"password_file: {exc}") from exc
        self._url = url
        self._rover = RoverGga()
        self._lock = threading.Lock()
        self._fixed = p["fixed_position"]
        self._published = 0
        self._publish_errors = 0
        self._frame_rate = RateMeter(time.monotonic())
        self._byte_rate = RateMeter(time.monotonic())
        endpoints = Endpoints(self)
        qos = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
        self._rtcm_pub = endpoints.publisher(Message, "rtcm", qos)
        endpoints.subscription(Sentence, "nmea", self._on_sentence, qos)
        self._diagnostics = diag.DiagnosticsPublisher(self, endpoints)
        self.create_timer(p["diagnostics_period"], diag.guarded(self, self._publish_diagnostics))
        self._client = NtripClient(
            ClientSettings(
                url=url,
                password=password,
                gga_interval_s=p["gga_interval"],
                stall_timeout_s=p["stall_timeout"],
                ca_file=p["tls_ca_file"] or None,
            ),
            self._on_frames,
            self._gga,
            log=self._log,
        )
        self._client.start()
        self.get_logger().info(
            f"NTRIP client for {url}: GGA every {p['gga_interval']:g} s"
            + (", password given" if password else ", no password")
        )

    def close(self) -> None:
        """Stop the client (run_node calls this before the node is destroyed)."""
        self._client.stop()

    # ---- client thread ------------------------------------------------------------------------
    def _log(self, line: str) -> None:
        """The client's errors (refused, unknown mountpoint) at ERROR, its reconnects at WARN,
        the rest of its news at INFO."""
        logger = self.get_logger()
        if line.startswith("NTRIP: error:"):
            logger.error(line)
        elif line.endswith("reconnecting"):
            logger.warning(line)
        else:
            logger.info(line)

    def _on_frames(self, frames: list[bytes], _received_monotonic_s: float) -> None:
        stamp = self.get_clock().now().to_msg()
        for frame in frames:
            msg = Message(message=frame)
            msg.header.stamp = stamp
            msg.header.frame_id = self.params["frame_id"]
            try:
                self._rtcm_pub.publish(msg)
            except Exception:  # the context shut down under the client thread (Ctrl-C)
                self._publish_errors += 1
                return
            self._published += 1

    def _gga(self) -> bytes | None:
        with self._lock:
            sentence = self._rover.sentence
        if sentence is not None or not self._fixed:
            return sentence
        lat, lon, height = self._fixed
        return fixed_gga(lat, lon, height, node_time_s(self))

    # ---- executor -----------------------------------------------------------------------------
    def _on_sentence(self, msg: Sentence) -> None:
        with self._lock:
            self._rover.note(msg.sentence)

    def _publish_diagnostics(self) -> None:
        stats = self._client.stats()
        now = time.monotonic()
        level, message = assess(stats, now, self.params["age_warn"])
        with self._lock:
            rover = (self._rover.solution, self._rover.seen, self._rover.with_position)
        solution, ggas, positions = rover
        values: dict[str, object] = {
            "caster": str(self._url),
            "caster_state": stats.state.value,
            "http_status": "-" if stats.http_status is None else stats.http_status,
            "reason": stats.reason or "-",
            "corrections_age_s": corrections_age_s(stats, now),
            "bytes_per_s": self._byte_rate.rate_hz(stats.bytes_in, now),
            "frames_per_s": self._frame_rate.rate_hz(stats.frames, now),
            "frames": stats.frames,
            "frames_published": self._published,
            "crc_failures": stats.crc_failures,
            "non_rtcm_bytes": stats.skipped_bytes,
            "gga_sent": stats.gga_sent,
            "rover_solution": solution,
            "rover_ggas": ggas,
            "rover_positions": positions,
            "connects": stats.connects,
            "reconnects": stats.reconnects,
            "publish_errors": self._publish_errors,
            "last_error": stats.last_error or "-",
        }
        if stats.mountpoints:
            values["mountpoints"] = ", ".join(stats.mountpoints[:20])
        if level == OK and solution != "-":
            message += f", rover {solution}"
        diag_level = {OK: diag.OK, ERROR: diag.ERROR}.get(level, diag.WARN)
        name = f"{self.get_name()}: NTRIP {self._url.mountpoint or '(sourcetable)'}"
        self._diagnostics.publish(
            diag.make_status(name, f"ntrip {self._url.host}", diag_level, message, values)
        )


def main(args: list[str] | None = None) -> int:
    """Console-script entry point (``ros2 run gnss_ins ntrip_node``)."""
    return run_node(NtripNode, args)
