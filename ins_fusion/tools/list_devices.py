"""``gnss_ins list-devices``: the serial adapters attached, with their stable names.

A USB serial adapter is /dev/ttyUSB0 or /dev/ttyUSB1 depending on the order it was plugged in;
udev also gives it a name of its own under /dev/serial/by-id (maker, model, serial number,
interface), which stays the same. This lists the ports pyserial finds (``serial.tools.list_ports``:
device, description, USB VID:PID and serial number) with the by-id names that point at them, and
any by-id name whose port pyserial does not list. The drivers' ``port`` parameters (and
``gnss_ins launch --imu-port`` ...) take the by-id path; a reconnect opens the path again and so
follows the link to wherever the adapter is now. ``--udev`` prints a udev rule per USB adapter
that gives it a name of your choice instead (``SYMLINK+="gnss_ins/NAME"``).
"""

from __future__ import annotations

import argparse
from collections import defaultdict
from pathlib import Path

from serial.tools import list_ports

#: Where udev puts the stable names.
BY_ID_DIR = Path("/dev/serial/by-id")


def by_id_names(by_id_dir: Path) -> dict[str, list[Path]]:
    """The by-id links of ``by_id_dir`` per port they point at (resolved path)."""
    names: dict[str, list[Path]] = defaultdict(list)
    if by_id_dir.is_dir():
        for link in sorted(by_id_dir.iterdir()):
            names[str(link.resolve())].append(link)
    return dict(names)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Command-line options of ``gnss_ins list-devices``."""
    parser.add_argument(
        "--by-id-dir", type=Path, default=BY_ID_DIR, help="directory of the stable names"
    )
    parser.add_argument("--udev", action="store_true", help="print a udev rule per USB adapter")


def run(args: argparse.Namespace) -> int:
    """Print the ports; 0 also when there is none (said so)."""
    names = by_id_names(args.by_id_dir)
    ports = sorted(list_ports.comports(), key=lambda p: p.device)
    listed = {str(Path(p.device).resolve()) for p in ports}
    if not ports and not names:
        print(f"no serial port found (and nothing in {args.by_id_dir})")
        return 0
    for port in ports:
        usb = f"USB {port.vid:04x}:{port.pid:04x}" if port.vid is not None else "not USB"
        print(f"{port.device}: {port.description} ({usb}, serial {port.serial_number or '-'})")
        for link in names.get(str(Path(port.device).resolve()), []):
            print(f"  stable name: {link}")
        if args.udev and port.vid is not None:
            serial = f', ATTRS{{serial}}=="{port.serial_number}"' if port.serial_number else ""
            print(
                f'  udev rule: SUBSYSTEM=="tty", ATTRS{{idVendor}}=="{port.vid:04x}", '
                f'ATTRS{{idProduct}}=="{port.pid:04x}"{serial}, SYMLINK+="gnss_ins/NAME"'
            )
    for target, links in names.items():
        if target not in listed:
            for link in links:
                print(f"{link} -> {target}")
    return 0
