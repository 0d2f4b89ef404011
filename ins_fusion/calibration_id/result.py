"""Estimates with their σ, and the calibration file the fusion node reads.

The file is the ``imu_calibration`` section of ins_fusion/core/nav/calibration.py (ImuCalibration):
per triad in imu_link FLU, user units named by the key suffix, every value with its 1σ next to
it, and the temperature range of the data. Only the terms a method estimates are written; with a
base file the other terms are kept from it.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from enum import Enum
from typing import Any

import numpy as np

from gnss_ins_common.types import FloatArray
from ins_fusion.calibration_id.segments import Segment
from ins_fusion.core.nav.calibration import ImuCalibration
from ins_fusion.core.nav.units import STANDARD_GRAVITY_M_S2, deg_s, mg


class Quantity(Enum):
    """A term of the calibration file: (triad, key, SI value of one user unit, unit text)."""

    GYRO_BIAS = ("gyro", "bias_deg_s", deg_s(1.0), "deg/s")
    GYRO_SCALE_POSITIVE = ("gyro", "scale_positive_percent", 1e-2, "%")
    GYRO_SCALE_NEGATIVE = ("gyro", "scale_negative_percent", 1e-2, "%")
    GYRO_MISALIGNMENT = ("gyro", "misalignment_mrad", 1e-3, "mrad")
    GYRO_G_SENSITIVITY = (
        "gyro",
        "g_sensitivity_deg_s_per_g",
        deg_s(1.0) / STANDARD_GRAVITY_M_S2,
        "(deg/s)/g",
    )
    ACCEL_BIAS = ("accel", "bias_mg", mg(1.0), "mg")
    ACCEL_SCALE_POSITIVE = ("accel", "scale_positive_percent", 1e-2, "%")
    ACCEL_SCALE_NEGATIVE = ("accel", "scale_negative_percent", 1e-2, "%")
    ACCEL_SCALE_LARGE_POSITIVE = ("accel", "scale_large_positive_percent", 1e-2, "%")
    ACCEL_SCALE_LARGE_NEGATIVE = ("accel", "scale_large_negative_percent", 1e-2, "%")
    ACCEL_MISALIGNMENT = ("accel", "misalignment_mrad", 1e-3, "mrad")

    def __init__(self, triad: str, key: str, unit: float, unit_text: str) -> None:
        self.triad = triad
        self.key = key
        self.unit = unit
        self.unit_text = unit_text

    @property
    def label(self) -> str:
        """``accel bias`` etc."""
        return f"{self.triad} {self.name.split('_', 1)[1].lower().replace('_', ' ')}"


def _sigma_key(key: str) -> str:
    """calibration.py's σ key: the unit suffix stays last (bias_mg -> bias_sigma_mg)."""
    for unit in ("_deg_s_per_g", "_deg_s", "_percent", "_mrad", "_mg"):
        if key.endswith(unit):
            return f"{key[: -len(unit)]}_sigma{unit}"
    raise ValueError(f"no unit suffix in {key}")


@dataclass(frozen=True)
class Estimate:
    """One term: value and 1σ in SI, shape (3,) or (3, 3); NaN = not estimated. ``source``
    names the method and equations; ``written`` whether it goes into the calibration file."""

    quantity: Quantity
    value: FloatArray
    sigma: FloatArray
    source: str
    written: bool = True

    def user(self) -> tuple[FloatArray, FloatArray]:
        """(value, σ) in the file's unit."""
        return self.value / self.quantity.unit, self.sigma / self.quantity.unit


@dataclass(frozen=True)
class Residual:
    """A residual of an observation: segment index (in the result's segments), what was
    observed (``f_x``, ``w_z``, ``S+ x``...), value in ``unit``, and value/σ."""

    segment: int
    observed: str
    value: float
    unit: str
    normalized: float


@dataclass(frozen=True)
class FitSummary:
    """χ² of one fit with its degrees of freedom."""

    name: str
    chi2: float
    dof: int


@dataclass
class CalibrationResult:
    """What a method found: estimates, residuals, the segments used with a label each, notes
    for the report (warnings, what was not estimated), and the input size [m/s²] from which
    the accelerometer scale is the large-range term (None: one range)."""

    method: str
    segments: list[Segment]
    labels: list[str]
    estimates: list[Estimate] = field(default_factory=list)
    residuals: list[Residual] = field(default_factory=list)
    fits: list[FitSummary] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    accel_large_input_m_s2: float | None = None

    def estimate(self, quantity: Quantity) -> Estimate | None:
        """The written estimate of a quantity, if any."""
        return next((e for e in self.estimates if e.quantity is quantity and e.written), None)


def _rounded(values: FloatArray) -> list[Any]:
    """Plain floats with 6 significant digits (nested lists for matrices)."""
    return [_rounded(v) if v.ndim else float(f"{float(v):.6g}") for v in values]


def calibration_mapping(
    result: CalibrationResult,
    base: Mapping[str, Any] | None,
    temperature_range_c: tuple[float, float] | None,
    sensor: str | None,
) -> dict[str, Any]:
    """The ``imu_calibration`` section: ``base`` (a parsed section, or None) with the written
    estimates replacing its terms. Components not estimated (NaN) keep the base's value, else
    0 ± 0 (a note says so). The temperature range covers the base's and the data's."""
    section: dict[str, Any] = {k: v for k, v in (base or {}).items() if k not in ("gyro", "accel")}
    triads = {t: dict((base or {}).get(t) or {}) for t in ("gyro", "accel")}
    for e in result.estimates:
        if not e.written:
            continue
        q = e.quantity
        value, sigma = e.user()
        missing = np.isnan(value)
        if np.any(missing):
            old = triads[q.triad]
            old_value = np.array(old.get(q.key, np.zeros_like(value)), dtype=np.float64)
            old_sigma = np.array(old.get(_sigma_key(q.key), np.zeros_like(value)), dtype=np.float64)
            value = np.where(missing, old_value, value)
            sigma = np.where(missing, old_sigma, sigma)
            kept = "kept from the base file" if q.key in old else "written as 0 ± 0"
            result.notes.append(f"{q.label}: components not estimated are {kept}")
        triads[q.triad][q.key] = _rounded(value)
        triads[q.triad][_sigma_key(q.key)] = _rounded(sigma)
    if result.accel_large_input_m_s2 is not None:
        triads["accel"]["large_input_g"] = float(
            f"{result.accel_large_input_m_s2 / STANDARD_GRAVITY_M_S2:.6g}"
        )
    ranges = [r for r in (section.get("temperature_range_c"), temperature_range_c) if r]
    if ranges:
        section["temperature_range_c"] = [
            round(min(float(r[0]) for r in ranges), 2),
            round(max(float(r[1]) for r in ranges), 2),
        ]
    if sensor is not None:
        section["sensor"] = sensor
    section.update({t: v for t, v in triads.items() if v})
    ImuCalibration.from_mapping(section)  # the fusion node must be able to read it
    return section
