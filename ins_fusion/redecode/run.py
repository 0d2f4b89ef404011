"""A recording decoded again: its raw topics through today's driver cores into a new bag (no ROS).

Which node read which raw topics, and with which parameters, is the vehicle's node set
(``ins_fusion.runtime.vehicle_nodes``: imu400cc_node in the root namespace, the Leica and the
ADU5 gnss_node in /leica and /adu5). A recording does not hold the nodes' parameters: they come
from the parameter files of ``config_dir`` (those ``gnss_ins launch --config DIR`` gives the
nodes; default the installed config/), each overridden by the sections named after the node in
``param_files``. The new bag holds every topic of the recording unchanged except the ones the
decoders rebuild (all four GNSS outputs of a receiver, both IMU topics), which are replaced.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from gnss_driver.parameters import DRIVER_PARAMETERS as GNSS_PARAMETERS
from gnss_ins_common.params import (
    AUTOSTART,
    Param,
    ParameterValueError,
    read_parameter_file,
    validate_all,
)
from gnss_ins_common.paths import config_file
from imu400cc_driver.parameters import DRIVER_PARAMETERS as IMU_PARAMETERS
from ins_fusion.bags.bag_io import BagError, BagReader, BagWriter
from ins_fusion.bags.output import refuse_existing, whole_bag
from ins_fusion.bags.summary import BagSummary
from ins_fusion.redecode.decoders import (
    GNSS_TOPICS,
    IMU_TOPICS,
    GnssDecoder,
    ImuDecoder,
    header_ns,
)
from ins_fusion.runtime.vehicle_nodes import ADU5, IMU, LEICA, NodeSpec

#: What a recording must hold for a device to be decoded again.
IMU_RAW = "/imu/raw"
NMEA, PORT_EVENTS = "nmea", "port_events"
RECEIVERS = (LEICA, ADU5)


class RedecodeError(Exception):
    """The recording cannot be decoded again as asked (nothing written)."""


@dataclass
class Redecoded:
    """What ``redecode`` did: the devices decoded, the recorded and the rebuilt messages per
    replaced topic, the new bag's summary."""

    nodes: list[str]
    recorded: dict[str, int]
    rebuilt: dict[str, int] = field(default_factory=dict)
    summary: BagSummary = field(default_factory=BagSummary)

    def format(self) -> str:
        """Lines for the terminal: one per replaced topic."""
        lines = [f"decoded again: {', '.join(self.nodes)}"]
        for topic in sorted(self.recorded):
            lines.append(
                f"  {topic}: {self.rebuilt.get(topic, 0)} rebuilt, {self.recorded[topic]} recorded"
            )
        return "\n".join(lines)


def _topic(spec: NodeSpec, relative: str) -> str:
    return f"/{spec.namespace}/{relative}" if spec.namespace else f"/{relative}"


def node_parameters(
    spec: NodeSpec, config_dir: Path | None, param_files: Sequence[Path]
) -> dict[str, Any]:
    """The validated parameters of ``spec``'s node: its file of ``config_dir`` (default the
    installed config/), then each of ``param_files``' sections for it (``NAME``, ``/NAME`` or
    ``/**``) over them. RedecodeError when a file is missing or a value is bad."""
    specs: tuple[Param, ...] = (
        *(IMU_PARAMETERS if spec is IMU else GNSS_PARAMETERS),
        AUTOSTART,
    )
    try:
        base = config_dir / spec.config if config_dir is not None else config_file(spec.config)
        values: dict[str, Any] = {}
        for path in (base, *param_files):
            document = read_parameter_file(path)
            for key in ("/**", spec.name, f"/{spec.name}"):
                values.update((document.get(key) or {}).get("ros__parameters", {}))
        return validate_all(specs, values)
    except (ParameterValueError, FileNotFoundError) as exc:
        raise RedecodeError(f"parameters of {spec.name}: {exc}") from exc


def redecode(
    source: Path,
    output: Path,
    config_dir: Path | None = None,
    param_files: Sequence[Path] = (),
) -> Redecoded:
    """Write ``output``: the recording ``source`` with the topics rebuilt from its raw topics.
    RedecodeError (nothing written) when ``output`` exists, ``source`` holds no raw topic or a
    parameter is bad."""
    try:
        refuse_existing(output)
        with BagReader(source) as reader:
            imu, receivers = _devices(reader)
            params = {
                spec.name: node_parameters(spec, config_dir, param_files)
                for spec in ([IMU] if imu else []) + receivers
            }
            rebuilt_types = {
                _topic(spec, relative): msgtype
                for spec in ([IMU] if imu else []) + receivers
                for relative, msgtype in (IMU_TOPICS if spec is IMU else GNSS_TOPICS).items()
            }
            result = Redecoded(
                list(params),
                {t: reader.topics[t].count for t in rebuilt_types if t in reader.topics},
            )
            with whole_bag(output, "redecoding") as path, BagWriter(path) as writer:
                for topic, info in reader.topics.items():
                    if topic not in rebuilt_types:
                        writer.add_topic(topic, info.msgtype, info.qos)
                for topic, msgtype in rebuilt_types.items():
                    known = reader.topics.get(topic)
                    writer.add_topic(topic, msgtype, known.qos if known else ())
                for topic, log_time_ns, message in _decoded(reader, params, imu, receivers):
                    if topic in rebuilt_types:
                        result.rebuilt[topic] = result.rebuilt.get(topic, 0) + 1
                    writer.write(topic, log_time_ns, message)
            result.summary = writer.summary
    except BagError as exc:
        raise RedecodeError(str(exc)) from exc
    return result


def _devices(reader: BagReader) -> tuple[bool, list[NodeSpec]]:
    """Whether the IMU's raw topic is recorded, and the receivers whose ``nmea`` is."""
    imu = IMU_RAW in reader.topics
    receivers = [spec for spec in RECEIVERS if _topic(spec, NMEA) in reader.topics]
    if not imu and not receivers:
        wanted = ", ".join([IMU_RAW, *(_topic(spec, NMEA) for spec in RECEIVERS)])
        raise RedecodeError(
            f"{reader.path} holds no raw topic ({wanted}): it was recorded without the devices'"
            " own bytes (before they were recorded, or without raw_output / nmea_output), so"
            " it cannot be decoded again"
        )
    return imu, receivers


def _raw_message(reader: BagReader, topic: str, log_time_ns: int, data: bytes, msgtype: str) -> Any:
    """A raw topic's message deserialized; BagError naming it when its bytes are not one."""
    try:
        return reader.deserialize(data, msgtype)
    except Exception as exc:  # rosbags raises what its parser meets: struct, index, value errors
        raise BagError(
            f"{topic} message logged at {log_time_ns} ns is not a {msgtype} of this release"
            f" ({type(exc).__name__}: {exc}); nothing written"
        ) from exc


def _decoded(
    reader: BagReader,
    params: dict[str, dict[str, Any]],
    imu: bool,
    receivers: list[NodeSpec],
) -> Iterator[tuple[str, int, Any]]:
    """(topic, log time, raw bytes or rosbags message) of the new bag in log-time order: the
    recording's messages, the rebuilt topics' replaced by what the decoders make of the raw
    topics, each at the log time of the raw message that completed it. A receiver's port events
    are taken before its first line stamped after them: latched, they may reach the recorder
    after the lines that follow them. A raw message stamped before one taken already from its
    topic is the latched history sent again to a restarted recorder: not decoded twice."""
    imu_decoder = ImuDecoder(params[IMU.name]) if imu else None
    gnss: dict[str, tuple[NodeSpec, GnssDecoder, list[Any]]] = {}
    for spec in receivers:
        events_topic = _topic(spec, PORT_EVENTS)
        events = []
        if events_topic in reader.topics:
            events = [m.message for m in reader.messages([events_topic], deserialize=True)]
        events.sort(key=header_ns, reverse=True)  # popped from the end, oldest first
        gnss[_topic(spec, NMEA)] = (spec, GnssDecoder(params[spec.name]), events)
    replaced = {_topic(IMU, t) for t in IMU_TOPICS} if imu else set()
    replaced |= {_topic(spec, t) for spec in receivers for t in GNSS_TOPICS}
    last_ns = 0
    newest: dict[str, int] = {}
    for msg in reader.messages():
        last_ns = msg.log_time_ns
        if msg.topic not in replaced:
            yield msg.topic, msg.log_time_ns, msg.message
        if msg.topic != IMU_RAW and msg.topic not in gnss:
            continue
        raw = _raw_message(reader, msg.topic, msg.log_time_ns, msg.message, msg.msgtype)
        if header_ns(raw) < newest.get(msg.topic, 0):
            continue
        newest[msg.topic] = header_ns(raw)
        if imu_decoder is not None and msg.topic == IMU_RAW:
            try:
                decoded = list(imu_decoder.take(raw))
            except ValueError as exc:  # its reads do not cut its bytes (serial_reads)
                raise BagError(f"{IMU_RAW} message logged at {msg.log_time_ns} ns: {exc}") from exc
            for relative, rebuilt in decoded:
                yield _topic(IMU, relative), msg.log_time_ns, rebuilt
        elif msg.topic in gnss:
            spec, decoder, events = gnss[msg.topic]
            line = raw
            while events and header_ns(events[-1]) < header_ns(line):
                for relative, rebuilt in decoder.event(events.pop()):
                    yield _topic(spec, relative), msg.log_time_ns, rebuilt
            for relative, rebuilt in decoder.line(line):
                yield _topic(spec, relative), msg.log_time_ns, rebuilt
    for spec, decoder, _ in gnss.values():  # the epoch still open, if the line was idle by then
        for relative, rebuilt in decoder.idle(last_ns):
            yield _topic(spec, relative), last_ns, rebuilt
