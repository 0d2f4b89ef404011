"""The covariance of a fix from GST, LLQ or the DOPs (no ROS); ``EpochSolver`` uses it.

ENU [m²], each of the horizontal and vertical parts from the first source present:
1. GST: σ_lat, σ_lon, σ_alt as the N, E, U standard deviations; with the error ellipse
   (semi-axes, orientation from north) also the E-N correlation of the ellipse -> KNOWN, else
   diagonal -> DIAGONAL_KNOWN. (Receivers do not always make the ellipse and the σ fields agree,
   so the σ fields set the variances.)
2. LLQ coordinate quality CQ = σ_h + σ_v with σ_h = sqrt(σ_E² + σ_N²) (notes §7.2, (7.1)),
   split as σ_h = f·CQ, σ_v = (1 - f)·CQ, σ_E² = σ_N² = σ_h² / 2 -> DIAGONAL_KNOWN. The report
   gives only the sum; the split f is this project's assumption (``LLQ_HORIZONTAL_FRACTION``).
3. HDOP x UERE (per fix type): σ_E² = σ_N² = (HDOP·UERE)² / 2; σ_U = VDOP·UERE with VDOP from
   GSA, else 2·HDOP [external: typical geometry] -> APPROXIMATED. No HDOP at all counts as 1.
The covariance type is the weaker of the two parts'.
"""

from __future__ import annotations

import math

import pynmea2

from gnss_driver.epoch import Epoch
from gnss_driver.plausibility import FieldReader
from gnss_driver.sentences import LLQ
from gnss_ins_common.navsat import CovarianceType

#: Default fraction of the LLQ coordinate quality that is horizontal: 2 cm of 2 + 3 cm (notes
#: §7.2); the project's assumption, the report gives only the sum (7.1).
LLQ_HORIZONTAL_FRACTION = 0.4
#: VDOP / HDOP when no GSA gives VDOP [external: typical satellite geometry].
VDOP_PER_HDOP = 2.0


class FixCovariance:
    """A fix's covariance (module docstring); keeps the latest GSA DOPs across epochs."""

    def __init__(self, fields: FieldReader, llq_horizontal_fraction: float) -> None:
        """``fields`` reads and counts the fields; ``llq_horizontal_fraction``: f above."""
        self.fields = fields
        self._llq_fraction = llq_horizontal_fraction
        self._hdop_gsa: float | None = None
        self._vdop_gsa: float | None = None

    def note_gsa(self, gsa: pynmea2.GSA) -> None:
        """Remember the DOPs of a GSA sentence (GSA is timeless and may repeat per epoch)."""
        hdop = self.fields.number(gsa, "hdop")
        vdop = self.fields.number(gsa, "vdop")
        if hdop is not None:
            self._hdop_gsa = hdop
        if vdop is not None:
            self._vdop_gsa = vdop

    def covariance(
        self, epoch: Epoch, gga: pynmea2.GGA | pynmea2.GNS | None, uere_m: float
    ) -> tuple[tuple[float, ...], CovarianceType, str]:
        """ENU covariance [m²] (row-major 3x3), its type and the horizontal accuracy's source
        of a fix; ``gga``: the GGA or GNS of the epoch (its HDOP), ``uere_m``: the UERE of its
        fix type [m]."""
        horizontal: tuple[tuple[float, float, float], CovarianceType, str] | None = None
        vertical: tuple[float, CovarianceType] | None = None
        gst = epoch.get(pynmea2.GST)
        if gst is not None:
            horizontal, vertical = self._gst(gst)
        llq = epoch.get(LLQ)
        cq = self.fields.number(llq, "coord_quality") if llq is not None else None
        if cq is not None:
            sigma_h = self._llq_fraction * cq
            if horizontal is None:
                h2 = sigma_h * sigma_h / 2.0
                horizontal = (h2, h2, 0.0), CovarianceType.DIAGONAL_KNOWN, "LLQ"
            if vertical is None:
                vertical = (cq - sigma_h) ** 2, CovarianceType.DIAGONAL_KNOWN
        if horizontal is None or vertical is None:
            hdop_field = "horizontal_dil" if isinstance(gga, pynmea2.GGA) else "hdop"
            hdop = self.fields.number(gga, hdop_field) if gga is not None else None
            hdop = hdop or self._hdop_gsa or 1.0
            vdop = self._vdop_gsa or VDOP_PER_HDOP * hdop
            h2 = (hdop * uere_m) ** 2 / 2.0
            if horizontal is None:
                horizontal = (h2, h2, 0.0), CovarianceType.APPROXIMATED, "HDOP"
            if vertical is None:
                vertical = (vdop * uere_m) ** 2, CovarianceType.APPROXIMATED
        (ee, nn, en), h_type, accuracy = horizontal
        up, v_type = vertical
        cov = (ee, en, 0.0, en, nn, 0.0, 0.0, 0.0, up)
        return cov, min(h_type, v_type), accuracy

    def _gst(
        self, gst: pynmea2.GST
    ) -> tuple[
        tuple[tuple[float, float, float], CovarianceType, str] | None,
        tuple[float, CovarianceType] | None,
    ]:
        sigma_n = self.fields.number(gst, "std_dev_latitude")
        sigma_e = self.fields.number(gst, "std_dev_longitude")
        sigma_u = self.fields.number(gst, "std_dev_altitude")
        vertical = None if sigma_u is None else (sigma_u * sigma_u, CovarianceType.KNOWN)
        if sigma_n is None or sigma_e is None:
            return None, vertical
        major = self.fields.number(gst, "std_dev_major")
        minor = self.fields.number(gst, "std_dev_minor")
        orientation = self.fields.number(gst, "orientation")
        if major is None or minor is None or orientation is None:
            diagonal = (sigma_e * sigma_e, sigma_n * sigma_n, 0.0)
            return (diagonal, CovarianceType.DIAGONAL_KNOWN, "GST"), vertical
        # Semi-major axis along azimuth θ (clockwise from north): u = (sin θ, cos θ) in (E, N);
        # only its E-N correlation is used, the variances stay those of the σ fields.
        theta = math.radians(orientation)
        ue, un = math.sin(theta), math.cos(theta)
        a2, b2 = major * major, minor * minor
        ee = a2 * ue * ue + b2 * un * un
        nn = a2 * un * un + b2 * ue * ue
        rho = (a2 - b2) * ue * un / math.sqrt(ee * nn)
        full = (sigma_e * sigma_e, sigma_n * sigma_n, rho * sigma_e * sigma_n)
        return (full, CovarianceType.KNOWN, "GST"), vertical
