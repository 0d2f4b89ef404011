"""The systemd unit of the vehicle daemon (no ROS): ``gnss_ins launch`` started at boot,
restarted by systemd whenever it ends, as a user of the machine, with the ROS domain and the log
location fixed. ``gnss_ins install-service`` writes it (ins_fusion/tools/install_service.py)."""

from __future__ import annotations

import shlex
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

#: The unit's name.
UNIT_NAME = "gnss_ins.service"
#: Where a system unit goes.
SYSTEM_UNIT_DIR = Path("/etc/systemd/system")


@dataclass(frozen=True)
class Service:
    """What the unit runs and as whom."""

    #: ``gnss_ins launch`` and its options, as a command line
    command: Sequence[str]
    user: str
    working_dir: Path
    domain_id: int
    #: seconds systemd waits after SIGINT before it kills (launch stops its nodes within 15 s each)
    stop_timeout_s: int = 90


def unit_text(service: Service) -> str:
    """The unit file: ``Restart=always`` (launch restarts the nodes; systemd restarts launch),
    SIGINT to stop (launch's clean stop, the recording closed), output to the journal."""
    environment = {
        "ROS_DOMAIN_ID": str(service.domain_id),
        "PYTHONUNBUFFERED": "1",  # launch's console lines reach the journal as they come
    }
    lines = [
        "[Unit]",
        "Description=gnss_ins vehicle INS: IMU400CC and GNSS drivers, fusion, recording",
        "After=local-fs.target",
        "StartLimitIntervalSec=0",
        "",
        "[Service]",
        "Type=simple",
        f"User={service.user}",
        f"WorkingDirectory={service.working_dir}",
        *(f"Environment={key}={value}" for key, value in environment.items()),
        f"ExecStart={shlex.join(service.command)}",
        "KillSignal=SIGINT",
        f"TimeoutStopSec={service.stop_timeout_s}",
        "Restart=always",
        "RestartSec=2",
        "",
        "[Install]",
        "WantedBy=multi-user.target",
    ]
    return "\n".join(line.replace("%", "%%") for line in lines) + "\n"  # % starts a specifier
