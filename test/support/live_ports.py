"""The device ports a live simulated drive prints, read as it prints them."""

from __future__ import annotations

import subprocess
import threading


def port_lines(proc: subprocess.Popen[str], names: set[str]) -> dict[str, str]:
    """The ``name: path`` lines of the live drive's ports ``names`` (simulate --live prints
    them first, gnss_ins emulate after its own lines), read on a thread: no hang."""
    ports: dict[str, str] = {}

    def read() -> None:
        assert proc.stdout is not None
        while set(ports) != names and (line := proc.stdout.readline()):
            name, _, path = line.strip().partition(": ")
            if name in names:
                ports[name] = path

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    reader.join(timeout=30.0)
    assert set(ports) == names, f"port lines of simulate --live: {ports}"
    return ports
