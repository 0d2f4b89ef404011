"""The caster's address (``http[s]://[user@]host[:port]/[MOUNTPOINT]``) and its password.

The password never is part of the URL (a command line is visible to every user of the machine
in ``ps``): it comes from the environment variable ``NTRIP_PASSWORD`` or from a password file
that only its owner can read.
"""

from __future__ import annotations

import os
import stat
import urllib.parse
from collections.abc import Mapping
from dataclasses import dataclass

#: The NTRIP caster's registered port (IANA "ntrip").
DEFAULT_PORT = 2101
PASSWORD_VARIABLE = "NTRIP_PASSWORD"


@dataclass(frozen=True, slots=True)
class CasterUrl:
    """Where to ask for corrections; ``mountpoint`` "" asks for the caster's sourcetable."""

    scheme: str
    user: str
    host: str
    port: int = DEFAULT_PORT
    mountpoint: str = ""

    @property
    def display(self) -> str:
        """The URL as it can be logged (it never holds a password)."""
        user = f"{urllib.parse.quote(self.user, safe='')}@" if self.user else ""
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"{self.scheme}://{user}{host}:{self.port}/{self.mountpoint}"

    def __str__(self) -> str:
        """The same as ``display``."""
        return self.display


def parse_caster_url(text: str) -> CasterUrl:
    """``text`` as a CasterUrl; ValueError saying what is wrong (a password in it is refused)."""
    parts = urllib.parse.urlsplit(text.strip())
    if parts.scheme not in ("http", "https"):
        raise ValueError(
            f"caster URL {text!r}: expected http://[user@]host[:port]/MOUNTPOINT (or https://)"
        )
    if parts.password is not None:
        raise ValueError(
            "caster URL: a password in the URL is refused (a command line is readable by every"
            f" user): give it in the environment variable {PASSWORD_VARIABLE} or a password file"
        )
    if not parts.hostname:
        raise ValueError(f"caster URL {text!r}: no host")
    try:
        port = parts.port or DEFAULT_PORT
    except ValueError:
        raise ValueError(f"caster URL {text!r}: the port is not a number in 1..65535") from None
    if parts.query or parts.fragment:
        raise ValueError(f"caster URL {text!r}: no query or fragment expected")
    mountpoint = urllib.parse.unquote(parts.path.strip("/"))
    if "/" in mountpoint or any(c.isspace() for c in mountpoint):
        raise ValueError(f"caster URL {text!r}: a mountpoint is one name without spaces or '/'")
    return CasterUrl(
        scheme=parts.scheme,
        user=urllib.parse.unquote(parts.username or ""),
        host=parts.hostname,
        port=port,
        mountpoint=mountpoint,
    )


def read_password(env: Mapping[str, str], password_file: str | None) -> str:
    """The caster password: a given file's text less its trailing newline (a regular file
    only its owner may read), else ``NTRIP_PASSWORD`` from ``env``, else "" (none)."""
    if password_file is None:
        return env.get(PASSWORD_VARIABLE, "")
    try:
        info = os.stat(password_file)
    except OSError as exc:
        raise ValueError(f"password file {password_file}: {exc.strerror}") from None
    if not stat.S_ISREG(info.st_mode):
        raise ValueError(f"password file {password_file}: not a regular file")
    if info.st_mode & (stat.S_IRWXG | stat.S_IRWXO):
        raise ValueError(
            f"password file {password_file}: readable by others (mode"
            f" {stat.S_IMODE(info.st_mode):04o}); run: chmod 600 {password_file}"
        )
    with open(password_file, encoding="utf-8") as file:
        return file.read().rstrip("\r\n")
