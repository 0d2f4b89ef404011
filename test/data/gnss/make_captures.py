"""Writes the NMEA capture fixtures of this folder (run from the repository root).

Each ``*.nmea`` file is one receiver's output as it queues it for its UART: one line per
sentence, ``<queue time [s]> <sentence>``, the queue time being the epoch's UTC instant plus the
receiver's output delay, relative to the first epoch. The tests put the bytes on a simulated
wire at any baud rate (test/nmea_captures.py). Emulator-generated, not recorded: the sentence
sets, orders and rates follow the receivers named below, the values are a slow drive.

- ``mixed_rate_oxts.nmea``: an OxTS-style INS, GGA and VTG at 10 Hz, RMC, HDT and ZDA at 1 Hz
  after the full second's GGA/VTG; 6 s; output delay 5 ms.
- ``ublox_gsv_block.nmea``: a u-blox M9-style 1 Hz set RMC, VTG, GGA, 2 GSA, a 7-sentence GSV
  block, GLL and GST last, ~930 bytes per epoch (0.97 s at 9600 baud); 6 s; output delay 40 ms.
- ``cut_first_line.nmea``: a SiRF-style 1 Hz set GGA, RMC, VTG, GSA, 3 GSV, GLL; the capture
  starts in the middle of epoch 0's GSV block (a cut line), so epoch 0 holds only its GLL; 6 s.
"""

from __future__ import annotations

import math
from pathlib import Path

from gnss_driver.reader import frame_sentence

HERE = Path(__file__).resolve().parent
START_S = 12 * 3600 + 35 * 60 + 19  # 12:35:19 UTC


def hhmmss(t_s: float) -> str:
    t = round(t_s * 100)
    s, cs = divmod(t, 100)
    h, rest = divmod(s, 3600)
    m, sec = divmod(rest, 60)
    return f"{h:02d}{m:02d}{sec:02d}.{cs:02d}"


def position(t_s: float) -> tuple[str, str]:
    """ddmm.mmmmm of a drive north-east at ~10 m/s from 57°02.12345'N 009°59.54321'E."""
    lat_min = 2.12345 + 10.0 * (t_s - START_S) / 1852.0
    lon_min = 54.54321 + 10.0 * (t_s - START_S) / (1852.0 * math.cos(math.radians(57.035)))
    return f"57{lat_min:08.5f}", f"009{lon_min:08.5f}"


def gga(t: float) -> str:
    lat, lon = position(t)
    return f"GPGGA,{hhmmss(t)},{lat},N,{lon},E,1,12,0.8,34.567,M,42.123,M,,"


def gsv_block(n: int) -> list[str]:
    bodies = []
    for k in range(n):
        sats = ",".join(
            f"{(4 * k + j) % 32 + 1:02d},{40 + j},{(83 * (k + j)) % 360:03d},4{j}" for j in range(4)
        )
        bodies.append(f"GPGSV,{n},{k + 1},{4 * n},{sats}")
    return bodies


def write(name: str, lines: list[tuple[float, str]], cut: int = 0) -> None:
    """``cut``: characters of the first sentence left out (the capture started mid-line)."""
    out = []
    for k, (t, body) in enumerate(lines):
        text = frame_sentence(body).decode().rstrip("\r\n")
        out.append(f"{t:.4f} {text[cut:] if k == 0 else text}")
    (HERE / name).write_text("\n".join(out) + "\n")


def mixed_rate() -> None:
    lines = []
    for k in range(60):
        t = START_S + 0.1 * k
        queue = 0.1 * k + 0.005
        lines += [(queue, gga(t)), (queue, "GPVTG,045.0,T,,M,19.4,N,36.0,K,A")]
        if k % 10 == 0:
            lat, lon = position(t)
            date = "141123"
            lines += [
                (queue, f"GPRMC,{hhmmss(t)},A,{lat},N,{lon},E,19.4,045.0,{date},,,A"),
                (queue, "GPHDT,045.3,T"),
                (queue, f"GPZDA,{hhmmss(t)},14,11,2023,00,00"),
            ]
    write("mixed_rate_oxts.nmea", lines)


def ublox() -> None:
    lines = []
    for k in range(6):
        t, queue = START_S + k, k + 0.040
        lat, lon = position(t)
        bodies = [
            f"GNRMC,{hhmmss(t)},A,{lat},N,{lon},E,19.4,045.0,141123,,,A,V",
            "GNVTG,045.0,T,,M,19.4,N,36.0,K,A",
            gga(t).replace("GPGGA", "GNGGA"),
            "GNGSA,A,3,01,02,03,04,05,06,07,08,09,10,11,12,1.5,0.8,1.2,1",
            "GNGSA,A,3,65,66,67,68,,,,,,,,,1.5,0.8,1.2,2",
            *gsv_block(7),
            f"GNGLL,{lat},N,{lon},E,{hhmmss(t)},A,A",
            f"GNGST,{hhmmss(t)},1.2,0.9,0.7,35.0,0.8,0.75,1.6",
        ]
        lines += [(queue, b) for b in bodies]
    write("ublox_gsv_block.nmea", lines)


def cut_first_line() -> None:
    lines = []
    for k in range(-1, 6):
        t, queue = START_S + k, max(0.0, k + 0.060)
        lat, lon = position(t)
        bodies = [
            gga(t),
            f"GPRMC,{hhmmss(t)},A,{lat},N,{lon},E,19.4,045.0,141123,,,A",
            "GPVTG,045.0,T,,M,19.4,N,36.0,K,A",
            "GPGSA,A,3,01,02,03,04,05,06,07,08,09,10,11,12,1.5,0.8,1.2",
            *gsv_block(3),
            f"GPGLL,{lat},N,{lon},E,{hhmmss(t)},A,A",
        ]
        # Epoch -1 is cut: the capture starts in its second GSV sentence.
        lines += [(queue, b) for b in (bodies[5:] if k < 0 else bodies)]
    write("cut_first_line.nmea", lines, cut=30)


if __name__ == "__main__":
    mixed_rate()
    ublox()
    cut_first_line()
