"""Receiver profiles: what each supported receiver sends and how it is set up (no ROS).

- ``leica``: Leica GPS System 500 RTK rover, NMEA at 9600 baud, one epoch per second: GGA, VTG
  and the proprietary LLQ (optionally GST, RMC, ZDA); configured on the receiver itself, so no
  set-up commands (imu400cc-aalborg-notes.md §7.2, §11.2 item 1).
- ``adu5``: Thales/Ashtech ADU5 attitude receiver, ``$PASHR,PAT`` at up to 5 Hz (also ``ATT``);
  set up with ``$PASHS`` commands (notes §7.3, §11.2 item 2). 115200 baud is the rate of the
  report's calibration set-up; use what the receiver's port is set to.
- ``generic``: any NMEA 0183 receiver; nothing is sent unless configured.

The ADU5 defaults configure, in the notes' command forms: elevation mask 15°, the three antenna
vectors V12, V13, V14 (x right, y forward, z up [m]; the car's calibrated values), the offset
angles (yaw, pitch, roll [deg]), NMEA period 0.2 s and PAT on the connected port. ``$PASHS,RST``
is not sent by default: it returns every setting, possibly the port's own, to factory values.
``$PASHS,3DF,Vxx`` is printed in the notes with two numeric fields but described as x, y, z
(notes §12 item 16): three fields are sent; check against the receiver's manual.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum


class Receiver(StrEnum):
    """Supported receiver profiles (the node's ``receiver`` parameter)."""

    LEICA = "leica"
    ADU5 = "adu5"
    GENERIC = "generic"


@dataclass(frozen=True)
class ReceiverProfile:
    """Defaults of one receiver type: baud and nominal epoch rate [Hz]."""

    receiver: Receiver
    baud: int
    rate_hz: float


PROFILES: dict[Receiver, ReceiverProfile] = {
    Receiver.LEICA: ReceiverProfile(Receiver.LEICA, 9600, 1.0),
    Receiver.ADU5: ReceiverProfile(Receiver.ADU5, 115200, 5.0),
    Receiver.GENERIC: ReceiverProfile(Receiver.GENERIC, 9600, 1.0),
}

#: Antenna vectors 1-2, 1-3, 1-4 as calibrated on the report's car, X(R) Y(F) Z(U) [m]
#: (notes §7.3, "Calibrated vectors on the car").
CAR_VECTORS_M: tuple[tuple[float, float, float], ...] = (
    (0.000, 3.939, 0.000),
    (-1.172, 4.010, -0.025),
    (1.179, 4.010, -0.025),
)
#: Offset angles (heading, pitch, roll) of the same calibration [deg] (notes §7.3).
CAR_OFFSETS_DEG = (0.00, 1.14, -1.48)


@dataclass(frozen=True)
class Adu5Setup:
    """Values of the ADU5 set-up commands."""

    vectors_m: tuple[tuple[float, float, float], ...] = CAR_VECTORS_M
    offsets_deg: tuple[float, float, float] = CAR_OFFSETS_DEG
    elevation_mask_deg: int = 15
    period_s: float = 0.2
    port: str = "A"


def _signed(value: float, digits: int, decimals: int) -> str:
    """``Sddd.ddd``-style field: sign, zero-padded integer part, fixed decimals."""
    return f"{value:+0{digits + decimals + 2}.{decimals}f}"


def adu5_commands(setup: Adu5Setup) -> list[str]:
    """The ADU5 ``$PASHS`` set-up sequence for ``setup`` (see the module docstring)."""
    commands = [f"$PASHS,ELM,{setup.elevation_mask_deg:02d}"]
    for index, (x, y, z) in enumerate(setup.vectors_m, start=2):
        fields = ",".join(_signed(v, 3, 3) for v in (x, y, z))
        commands.append(f"$PASHS,3DF,V1{index},{fields}")
    heading, pitch, roll = setup.offsets_deg
    commands.append(
        f"$PASHS,3DF,OFS,{_signed(heading, 3, 2)},{_signed(pitch, 2, 2)},{_signed(roll, 2, 2)}"
    )
    commands.append(f"$PASHS,NME,PER,{setup.period_s:g}")
    commands.append(f"$PASHS,NME,PAT,{setup.port},ON")
    return commands


def default_setup_commands(receiver: Receiver, adu5: Adu5Setup) -> list[str]:
    """Commands sent after each (re)open when the ``setup_commands`` parameter is empty."""
    return adu5_commands(adu5) if receiver is Receiver.ADU5 else []
