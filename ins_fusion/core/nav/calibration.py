"""Deterministic IMU error correction from a laboratory calibration file (no ROS).

Observation model of Aalborg notes §3.1, (2.1)/(2.2) (shared/reference/imu400cc-aalborg-notes.md),
per triad in imu_link FLU axes, y = true rate or specific force:

    ỹ = (I + diag(s±) + A) y + b  [+ G f for the gyros]

with the scale-factor error s± chosen by the sign of each input (asymmetric scale), A the
off-diagonal misalignment, b the bias and G the g-dependent gyro bias. The correction inverts it:
y = (I + diag(s±) + A)⁻¹ (ỹ - b - G f), which for A = 0 is Aalborg (9.1)/(9.2) per axis. The
sign is taken from ỹ - b. The accelerometers are corrected first; their result is the f of G f.

Two input ranges (Aalborg notes §3.2 after (9.2), report §9.1.1): the report measured the
accelerometer scale at ±0.2 g (S1 mod, per sign) and at ±1 g (S2) and, instead of a
non-linearity term, corrected each observation with the value for its input size. A triad may
carry a second pair s±_large with a threshold: an axis with |ỹ - b| at or above it takes s±_large,
below it s±. The report does not state its threshold; the file must (``large_input_g`` /
``large_input_deg_s``). Without large-range keys every input uses s±, as before.

File format (``imu_calibration:`` section; every term optional, zero when absent; the
``gnss_ins calibrate`` tool writes the same keys), in user units named by the key suffix, each
term with its 1σ (the day-to-day scatter of the laboratory estimate):

    imu_calibration:
      sensor: free text
      source: free text
      axes: imu_link                            # or device (below); default imu_link
      device_axes: [x, -y, -z]                  # axes: device only: imu_link axis i = this
      device_accel_sign: -1                     # device axis, accelerometers times this sign
      temperature_range_c: [low, high]          # calibration valid between these temperatures
      gyro:
        bias_deg_s: [x, y, z]                   # and bias_sigma_deg_s
        scale_positive_percent: [x, y, z]       # S+, and scale_positive_sigma_percent
        scale_negative_percent: [x, y, z]       # S-, and scale_negative_sigma_percent
        misalignment_mrad: [[..], [..], [..]]   # A[i][j]: axis i sensing input j (diagonal 0)
        g_sensitivity_deg_s_per_g: [[..], ..]   # G[i][j]: gyro i per g on accelerometer axis j
      accel:
        bias_mg: [x, y, z]                      # and bias_sigma_mg
        scale_positive_percent / scale_negative_percent / misalignment_mrad as for the gyros
        scale_large_positive_percent: [x, y, z] # optional second range, with its sigma,
        scale_large_negative_percent: [x, y, z] # used for |input| >= large_input_g
        large_input_g: 0.6                      # (the gyros: large_input_deg_s)

Each ``*_sigma_*`` key sits next to its value key (``misalignment_sigma_mrad``, ...).

``axes: imu_link`` (what ``gnss_ins calibrate`` writes, from imu_link records): the terms are per
imu_link FLU axis. ``axes: device``: the terms are per axis of the unit's own output, as a
laboratory report prints them (the Aalborg tables are per IMU400CC device axis); the loader
carries them into imu_link with the driver's axis map and accelerometer sign
(``device_axes``/``device_accel_sign``, the imu400cc_node parameters ``axis_map`` and
``accel_sign``): biases follow the signed axes, a FLU axis that reads minus its device axis swaps
the positive and negative scale factors, matrices become M A Mᵀ (``gnss_ins_common.axes``).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Mapping
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from gnss_ins_common.axes import AxisMap
from gnss_ins_common.types import FloatArray, Mat3, Vec3
from ins_fusion.core.compiled import compilable, jit
from ins_fusion.core.layout import offsets
from ins_fusion.core.nav.units import STANDARD_GRAVITY_M_S2, deg_s, mg, percent

_ZERO3: Vec3 = (0.0, 0.0, 0.0)
_ZERO33: Mat3 = (_ZERO3, _ZERO3, _ZERO3)

#: Layout of ImuCalibration.table, the numbers ``correct_sample`` reads (matrices row-major).
T_LAYOUT = (
    ("inverses", 2 * 64 * 9),  # the 64 3x3 TriadCalibration.inverses per triad (gyro, accel.)
    ("bias", 2 * 3),  # the two biases (gyro, then accelerometer)
    ("large", 2),  # the two large-input thresholds
    ("g", 9),  # G
)
T_INVERSES, T_BIAS, T_LARGE, T_G, T_SIZE = offsets(T_LAYOUT)


class CalibrationError(ValueError):
    """The calibration file is unreadable or malformed."""


@dataclass(frozen=True)
class TriadCalibration:
    """Deterministic errors of one triad (SI, imu_link FLU axes) and their 1σ.

    bias [rad/s or m/s²]; scale_positive / scale_negative: scale-factor error for positive /
    negative input [fraction]; scale_large_*: the same for inputs of magnitude ≥ large_input
    [rad/s or m/s²] (inf: one range); misalignment_rad: off-diagonal A[i][j] [rad].
    """

    bias: Vec3 = _ZERO3
    bias_sigma: Vec3 = _ZERO3
    scale_positive: Vec3 = _ZERO3
    scale_positive_sigma: Vec3 = _ZERO3
    scale_negative: Vec3 = _ZERO3
    scale_negative_sigma: Vec3 = _ZERO3
    misalignment_rad: Mat3 = _ZERO33
    misalignment_sigma_rad: Mat3 = _ZERO33
    scale_large_positive: Vec3 = _ZERO3
    scale_large_positive_sigma: Vec3 = _ZERO3
    scale_large_negative: Vec3 = _ZERO3
    scale_large_negative_sigma: Vec3 = _ZERO3
    large_input: float = math.inf

    def _scale(self, negative: bool, large: bool, axis: int) -> float:
        """Scale-factor error [fraction] of ``axis`` for an input of that sign and range."""
        if large:
            return (self.scale_large_negative if negative else self.scale_large_positive)[axis]
        return (self.scale_negative if negative else self.scale_positive)[axis]

    def in_flu(self, axes: AxisMap, sign: float) -> TriadCalibration:
        """These terms, given per device axis of a triad whose output is ``sign`` (±1) times
        ``axes.to_flu`` of the device output, per imu_link FLU axis (module docstring)."""
        scale = axes.scale_pair_to_flu(self.scale_positive, self.scale_negative, sign)
        scale_sigma = axes.scale_pair_to_flu(
            self.scale_positive_sigma, self.scale_negative_sigma, sign
        )
        large = axes.scale_pair_to_flu(self.scale_large_positive, self.scale_large_negative, sign)
        large_sigma = axes.scale_pair_to_flu(
            self.scale_large_positive_sigma, self.scale_large_negative_sigma, sign
        )
        return replace(
            self,
            bias=vec3(sign * axes.to_flu(self.bias)),
            bias_sigma=vec3(axes.permute_to_flu(self.bias_sigma)),
            scale_positive=vec3(scale[0]),
            scale_positive_sigma=vec3(scale_sigma[0]),
            scale_negative=vec3(scale[1]),
            scale_negative_sigma=vec3(scale_sigma[1]),
            scale_large_positive=vec3(large[0]),
            scale_large_positive_sigma=vec3(large_sigma[0]),
            scale_large_negative=vec3(large[1]),
            scale_large_negative_sigma=vec3(large_sigma[1]),
            misalignment_rad=mat3(axes.matrix_to_flu(self.misalignment_rad)),
            misalignment_sigma_rad=mat3(abs(axes.matrix_to_flu(self.misalignment_sigma_rad))),
        )

    @functools.cached_property
    def inverses(self) -> tuple[tuple[float, ...], ...]:
        """(I + diag(s) + A)⁻¹ row-major for the 64 patterns: bit i set = axis i < 0, bit i + 3
        set = axis i in the large range."""
        inverses = []
        for pattern in range(64):
            scale = [
                self._scale(bool(pattern >> i & 1), bool(pattern >> i + 3 & 1), i) for i in range(3)
            ]
            mat = np.eye(3) + np.diag(scale) + np.array(self.misalignment_rad) * (1 - np.eye(3))
            inverses.append(tuple(float(v) for v in np.linalg.inv(mat).ravel()))
        return tuple(inverses)


@dataclass(frozen=True)
class ImuCalibration:
    """Laboratory calibration of an IMU (see the module docstring for model and file format).

    g_sensitivity: G[i][j], rate error of gyro i per m/s² of specific force on axis j
    [(rad/s)/(m/s²)]; temperature_range_c: IMU temperatures the values are valid for [°C].
    """

    gyro: TriadCalibration = TriadCalibration()
    accel: TriadCalibration = TriadCalibration()
    g_sensitivity: Mat3 = _ZERO33
    g_sensitivity_sigma: Mat3 = _ZERO33
    temperature_range_c: tuple[float, float] | None = None
    sensor: str = ""
    source: str = ""

    @classmethod
    def from_yaml(cls, path: str | Path) -> ImuCalibration:
        """Read the ``imu_calibration`` section of a calibration file."""
        try:
            document = yaml.safe_load(Path(path).read_text())
        except (OSError, yaml.YAMLError) as exc:
            raise CalibrationError(f"cannot read calibration file {path}: {exc}") from exc
        if not isinstance(document, Mapping) or "imu_calibration" not in document:
            raise CalibrationError(f"{path}: no 'imu_calibration' section")
        return cls.from_mapping(document["imu_calibration"])

    @classmethod
    def from_mapping(cls, section: Mapping[str, Any]) -> ImuCalibration:
        """Calibration from the parsed ``imu_calibration`` mapping (user units)."""
        fields = _Fields(section, "imu_calibration")
        gyro = _Fields(fields.mapping("gyro"), "gyro")
        accel = _Fields(fields.mapping("accel"), "accel")
        per_g = deg_s(1.0) / STANDARD_GRAVITY_M_S2
        calibration = cls(
            gyro=_triad(gyro, "bias_deg_s", deg_s(1.0), "large_input_deg_s", deg_s(1.0)),
            accel=_triad(accel, "bias_mg", mg(1.0), "large_input_g", STANDARD_GRAVITY_M_S2),
            g_sensitivity=gyro.matrix("g_sensitivity_deg_s_per_g", per_g),
            g_sensitivity_sigma=gyro.matrix("g_sensitivity_sigma_deg_s_per_g", per_g),
            temperature_range_c=fields.temperature_range(),
            sensor=str(section.get("sensor", "")),
            source=str(section.get("source", "")),
        )
        device = fields.device_axes()
        for part in (fields, gyro, accel):
            part.reject_unknown()
        return calibration if device is None else calibration.in_flu(*device)

    def in_flu(self, axes: AxisMap, accel_sign: float) -> ImuCalibration:
        """This calibration, given per device axis of a unit read through ``axes`` with
        accelerometer sign ``accel_sign``, per imu_link FLU axis (module docstring). The
        g-sensitivity relates device gyro output to device accelerometer output, so it takes
        the accelerometer sign once."""
        return replace(
            self,
            gyro=self.gyro.in_flu(axes, 1.0),
            accel=self.accel.in_flu(axes, accel_sign),
            g_sensitivity=mat3(accel_sign * axes.matrix_to_flu(self.g_sensitivity)),
            g_sensitivity_sigma=mat3(abs(axes.matrix_to_flu(self.g_sensitivity_sigma))),
        )

    def correct(self, rate_flu_rad_s: Vec3, force_flu_m_s2: Vec3) -> tuple[Vec3, Vec3]:
        """(rate, specific force) corrected for the deterministic errors, imu_link FLU, SI."""
        wx, wy, wz, fx, fy, fz = correct_sample(self.table, *rate_flu_rad_s, *force_flu_m_s2)
        return (wx, wy, wz), (fx, fy, fz)

    @functools.cached_property
    def table(self) -> FloatArray:
        """The correction as numbers (T_* layout) for ``correct_sample``."""
        table = np.empty(T_SIZE)
        table[T_INVERSES:T_BIAS] = np.ravel((self.gyro.inverses, self.accel.inverses))
        table[T_BIAS : T_BIAS + 6] = (*self.gyro.bias, *self.accel.bias)
        table[T_LARGE : T_LARGE + 2] = (self.gyro.large_input, self.accel.large_input)
        table[T_G:] = np.ravel(self.g_sensitivity)
        return table

    def in_temperature_range(self, temperature_c: float) -> bool:
        """Whether the IMU temperature is inside the calibration's range (True when unknown)."""
        if self.temperature_range_c is None:
            return True
        low, high = self.temperature_range_c
        return low <= temperature_c <= high


def _triad(
    fields: _Fields, bias_key: str, bias_unit: float, large_key: str, large_unit: float
) -> TriadCalibration:
    sigma_key = bias_key.replace("bias_", "bias_sigma_")
    pct = percent(1.0)
    mrad = 1e-3
    large = fields.scalar(large_key, large_unit)
    large_keys = ("scale_large_positive_percent", "scale_large_negative_percent")
    if large is None and any(fields.has(k) for k in large_keys):
        raise CalibrationError(
            f"{fields.where}: scale_large_* needs {large_key}, the input size where it applies"
        )
    return TriadCalibration(
        bias=fields.vector(bias_key, bias_unit),
        bias_sigma=fields.vector(sigma_key, bias_unit),
        scale_positive=fields.vector("scale_positive_percent", pct),
        scale_positive_sigma=fields.vector("scale_positive_sigma_percent", pct),
        scale_negative=fields.vector("scale_negative_percent", pct),
        scale_negative_sigma=fields.vector("scale_negative_sigma_percent", pct),
        misalignment_rad=fields.matrix("misalignment_mrad", mrad),
        misalignment_sigma_rad=fields.matrix("misalignment_sigma_mrad", mrad),
        scale_large_positive=fields.vector(large_keys[0], pct),
        scale_large_positive_sigma=fields.vector("scale_large_positive_sigma_percent", pct),
        scale_large_negative=fields.vector(large_keys[1], pct),
        scale_large_negative_sigma=fields.vector("scale_large_negative_sigma_percent", pct),
        large_input=math.inf if large is None else large,
    )


class _Fields:
    """Typed access to one mapping of the file; remembers which keys were read."""

    _TEXT = frozenset({"sensor", "source"})

    def __init__(self, section: Any, where: str) -> None:
        if not isinstance(section, Mapping):
            raise CalibrationError(f"'{where}' must be a mapping")
        self._section = section
        self._where = where
        self._used: set[str] = set(self._TEXT)

    @property
    def where(self) -> str:
        """The mapping's name in messages."""
        return self._where

    def _get(self, key: str) -> Any:
        self._used.add(key)
        return self._section.get(key)

    def has(self, key: str) -> bool:
        """Whether the mapping holds ``key``."""
        return key in self._section

    def scalar(self, key: str, unit: float) -> float | None:
        """A positive number times ``unit``, None when absent."""
        value = self._get(key)
        if value is None:
            return None
        number = _numbers([value], f"{self._where}.{key}")[0]
        if number <= 0.0:
            raise CalibrationError(f"{self._where}.{key}: must be positive, got {value!r}")
        return number * unit

    def mapping(self, key: str) -> Mapping[str, Any]:
        value = self._get(key)
        return {} if value is None else value  # type checked by _Fields of the sub-section

    def vector(self, key: str, unit: float) -> Vec3:
        value = self._get(key)
        if value is None:
            return _ZERO3
        numbers = _numbers(value, f"{self._where}.{key}")
        if len(numbers) != 3:
            raise CalibrationError(f"{self._where}.{key}: needs three values (x, y, z)")
        return (numbers[0] * unit, numbers[1] * unit, numbers[2] * unit)

    def matrix(self, key: str, unit: float) -> Mat3:
        value = self._get(key)
        if value is None:
            return _ZERO33
        if not isinstance(value, list) or len(value) != 3:
            raise CalibrationError(f"{self._where}.{key}: needs three rows of three values")
        rows = [_numbers(row, f"{self._where}.{key}") for row in value]
        if any(len(row) != 3 for row in rows):
            raise CalibrationError(f"{self._where}.{key}: needs three rows of three values")
        (a, b, c) = ((r[0] * unit, r[1] * unit, r[2] * unit) for r in rows)
        return (a, b, c)

    def temperature_range(self) -> tuple[float, float] | None:
        value = self._get("temperature_range_c")
        if value is None:
            return None
        numbers = _numbers(value, f"{self._where}.temperature_range_c")
        if len(numbers) != 2 or numbers[0] > numbers[1]:
            raise CalibrationError(f"{self._where}.temperature_range_c: needs [low, high]")
        return numbers[0], numbers[1]

    def device_axes(self) -> tuple[AxisMap, float] | None:
        """(axis map, accelerometer sign) when the terms are per device axis (``axes:
        device``), None when they are per imu_link axis."""
        frame = self._get("axes")
        if frame in (None, "imu_link"):
            for key in ("device_axes", "device_accel_sign"):
                if self._get(key) is not None:
                    raise CalibrationError(f"{self._where}.{key} needs 'axes: device'")
            return None
        if frame != "device":
            raise CalibrationError(f"{self._where}.axes: 'imu_link' or 'device', got {frame!r}")
        spec, sign = self._get("device_axes"), self._get("device_accel_sign")
        if spec is None or isinstance(sign, bool) or sign not in (1, -1):
            raise CalibrationError(
                f"{self._where}: 'axes: device' needs device_axes (the driver's axis_map, e.g."
                " [x, -y, -z]) and device_accel_sign (+1 or -1, the driver's accel_sign)"
            )
        try:
            return AxisMap.from_spec(spec), float(sign)
        except ValueError as exc:
            raise CalibrationError(f"{self._where}.device_axes: {exc}") from exc

    def reject_unknown(self) -> None:
        unknown = sorted(set(self._section) - self._used)
        if unknown:
            raise CalibrationError(f"{self._where}: unknown key(s) {', '.join(unknown)}")


def vec3(values: np.ndarray[Any, Any]) -> Vec3:
    """A 3-vector array as a tuple of floats."""
    return (float(values[0]), float(values[1]), float(values[2]))


def mat3(values: np.ndarray[Any, Any]) -> Mat3:
    """A 3x3 array as a tuple of rows."""
    return (vec3(values[0]), vec3(values[1]), vec3(values[2]))


def _numbers(value: Any, where: str) -> list[float]:
    if not isinstance(value, list) or not all(
        isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v) for v in value
    ):
        raise CalibrationError(f"{where}: expected a list of finite numbers, got {value!r}")
    return [float(v) for v in value]


@compilable
def _invert(table: FloatArray, triad: int, x: float, y: float, z: float) -> Vec3:
    """(I + diag(s±) + A)⁻¹ (x, y, z) of a triad (0 gyro, 1 accelerometer) of ``table``, with
    the matrix chosen by the signs and sizes of x, y, z (TriadCalibration.inverses)."""
    pattern = (1 if x < 0.0 else 0) + (2 if y < 0.0 else 0) + (4 if z < 0.0 else 0)
    big = table[T_LARGE + triad]
    if big != math.inf:
        pattern += (8 if abs(x) >= big else 0) + (16 if abs(y) >= big else 0)
        pattern += 32 if abs(z) >= big else 0
    k = T_INVERSES + (triad * 64 + pattern) * 9
    m = table[k : k + 9]
    return (
        m[0] * x + m[1] * y + m[2] * z,
        m[3] * x + m[4] * y + m[5] * z,
        m[6] * x + m[7] * y + m[8] * z,
    )


@jit
def correct_sample(
    table: FloatArray, wx: float, wy: float, wz: float, fx: float, fy: float, fz: float
) -> tuple[float, float, float, float, float, float]:
    """ImuCalibration.correct of one sample with its ``table``: the accelerometers first, their
    result is the f of the g-dependent gyro bias G f; the sign of each input is that of the
    reading minus its bias."""
    b = T_BIAS
    ax, ay, az = _invert(table, 1, fx - table[b + 3], fy - table[b + 4], fz - table[b + 5])
    g = table[T_G : T_G + 9]
    gx = g[0] * ax + g[1] * ay + g[2] * az
    gy = g[3] * ax + g[4] * ay + g[5] * az
    gz = g[6] * ax + g[7] * ay + g[8] * az
    rx, ry, rz = _invert(
        table, 0, wx - table[b] - gx, wy - table[b + 1] - gy, wz - table[b + 2] - gz
    )
    return rx, ry, rz, ax, ay, az
