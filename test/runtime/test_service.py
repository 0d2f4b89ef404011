"""``gnss_ins install-service`` (the systemd unit) and ``gnss_ins list-devices``."""

from __future__ import annotations

import configparser
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from imu400cc_driver.emulator import Imu400ccEmulator
from ins_fusion.runtime.service import Service, unit_text
from ins_fusion.tools.cli import main


def unit_sections(text: str) -> configparser.ConfigParser:
    parser = configparser.ConfigParser(strict=False, interpolation=None)
    parser.optionxform = str  # type: ignore[assignment,method-assign]
    parser.read_string(text)
    return parser


def test_the_unit_restarts_launch_as_the_user_with_the_domain_and_the_options(capsys):
    argv = ["install-service", "--dry-run", "--user", "survey", "--working-dir", "/srv/gnss"]
    argv += ["--domain-id", "42", "--record", "/data/bags", "--log-dir", "/var/log/gnss_ins"]
    argv += ["--imu-port", "/dev/serial/by-id/usb-FTDI_FT232R_A1B2-if00-port0", "--no-adu5"]
    assert main(argv) == 0
    text = capsys.readouterr().out
    unit = unit_sections(text)
    service = unit["Service"]
    assert (service["User"], service["WorkingDirectory"]) == ("survey", "/srv/gnss")
    assert (service["Restart"], service["KillSignal"]) == ("always", "SIGINT")
    assert "Environment=ROS_DOMAIN_ID=42" in text.splitlines()
    exec_start = service["ExecStart"].split()
    assert exec_start[0] == str(Path(sys.executable).parent / "gnss_ins")
    assert exec_start[1:] == [
        "launch",
        "--imu-port=/dev/serial/by-id/usb-FTDI_FT232R_A1B2-if00-port0",
        "--leica-port=/dev/ttyUSB1",
        "--adu5-port=/dev/ttyUSB2",
        "--no-adu5",
        "--log-dir=/var/log/gnss_ins",
        "--record=/data/bags",
    ]
    assert unit["Install"]["WantedBy"] == "multi-user.target"


def test_the_unit_carries_the_ntrip_client_with_its_password_file_only(
    tmp_path: Path, capsys, monkeypatch
):
    """The caster's URL and the password file's path go into the world-readable unit, never the
    password; without a file a caster user is refused (NTRIP_PASSWORD would not reach the
    daemon), and so is a file others may read."""
    password = "unit-S3cret"
    monkeypatch.setenv("NTRIP_PASSWORD", password)
    secret = tmp_path / "ntrip"
    secret.write_text(password + "\n")
    secret.chmod(0o600)
    url = "http://rover@caster.example.net:2101/AAU00DNK"
    argv = ["install-service", "--dry-run", "--user", "survey", "--ntrip", url]
    assert main([*argv, "--ntrip-password-file", str(secret)]) == 0
    text = capsys.readouterr().out
    exec_start = unit_sections(text)["Service"]["ExecStart"].split()
    assert exec_start[-2:] == [f"--ntrip={url}", f"--ntrip-password-file={secret}"]
    assert password not in text
    assert main(argv) == 2
    assert "--ntrip-password-file" in capsys.readouterr().err
    secret.chmod(0o640)
    assert main([*argv, "--ntrip-password-file", str(secret)]) == 2
    assert f"chmod 600 {secret}" in capsys.readouterr().err
    anonymous = ["install-service", "--dry-run", "--ntrip", "http://caster.example.net/MP"]
    assert main(anonymous) == 0
    assert "--ntrip=http://caster.example.net/MP" in capsys.readouterr().out


def test_percent_signs_are_escaped_for_systemd():
    text = unit_text(
        Service(["/opt/gnss ins/bin/gnss_ins", "launch", "--record=/d/50%"], "u", Path("/w"), 0)
    )
    assert "--record=/d/50%%" in text and "'/opt/gnss ins/bin/gnss_ins'" in text


@pytest.mark.skipif(shutil.which("systemd-analyze") is None, reason="no systemd-analyze here")
def test_systemd_accepts_the_unit_and_refuses_a_broken_one(tmp_path: Path):
    user = subprocess.run(["id", "-un"], capture_output=True, text=True, check=True).stdout.strip()
    assert main(["install-service", "--unit-dir", str(tmp_path), "--user", user]) == 0
    unit = tmp_path / "gnss_ins.service"
    verify = subprocess.run(
        ["systemd-analyze", "verify", str(unit)], capture_output=True, text=True
    )
    assert verify.returncode == 0, verify.stderr
    broken = tmp_path / "broken" / "gnss_ins.service"
    broken.parent.mkdir()
    broken.write_text(unit.read_text().replace("ExecStart=/", "ExecStart=relative/"))
    verify = subprocess.run(
        ["systemd-analyze", "verify", str(broken)], capture_output=True, text=True
    )
    assert verify.returncode != 0  # the check is live


def test_an_existing_unit_is_kept_unless_forced(tmp_path: Path, capsys):
    (tmp_path / "gnss_ins.service").write_text("mine\n")
    assert main(["install-service", "--unit-dir", str(tmp_path)]) == 2
    assert "exists" in capsys.readouterr().err
    assert (tmp_path / "gnss_ins.service").read_text() == "mine\n"
    assert main(["install-service", "--unit-dir", str(tmp_path), "--force"]) == 0
    assert "Restart=always" in (tmp_path / "gnss_ins.service").read_text()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["gnss_ins.service"]


def test_list_devices_names_the_stable_link_of_a_port(tmp_path: Path, capsys):
    """A by-id directory with a link to an emulated IMU's pty (pyserial lists no pty: the link
    is shown with its target)."""
    with Imu400ccEmulator() as imu:
        target = Path(imu.path).resolve()
        (tmp_path / "usb-FTDI_FT232R_USB_UART_A1B2C3-if00-port0").symlink_to(target)
        assert main(["list-devices", "--by-id-dir", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert f"usb-FTDI_FT232R_USB_UART_A1B2C3-if00-port0 -> {target}" in out
