"""The summary table of a noise report, and the ROS parameter file of ins_fusion_node with the
identified imu_noise.* values.

Parameter names and units are the node's own (ins_fusion.core.settings.params.PARAMETERS):
imu_noise.gyro_arw [deg/sqrt(h)] and imu_noise.accel_vrw [m/s/sqrt(h)] (white-noise densities),
imu_noise.gyro_bias_instability [deg/h] and imu_noise.accel_bias_instability [mg] (stationary σ
of the Gauss-Markov biases), per imu_link axis, and one imu_noise.bias_correlation_time [s] for
all biases: the geometric mean of the six axes' times. A provisional bias (noise_id.provisional,
a record too short to pin it) is written with its σ and time and marked PROVISIONAL. Every
value is checked with the node's Param specs before it is written. The node has no random-walk
or quantisation parameter; those, the classic read-offs and the confidence intervals are the
file's comments (the summary table).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from gnss_ins_common.params import ParameterValueError, validate
from ins_fusion.core.settings.params import PARAMETERS
from ins_fusion.noise_id.analysis import (
    ACCEL,
    GYRO,
    SENSORS,
    AxisNoise,
    NoiseReport,
    Sensor,
    Unit,
    hours,
)
from ins_fusion.noise_id.provisional import ProvisionalBiases
from ins_fusion.noise_id.terms import BiasInstability, Term

NODE_NAME = "ins_fusion_node"
_SIGNIFICANT = 4
_SPECS = {spec.name: spec for spec in PARAMETERS}


def yaml_number(value: float) -> str:
    """4 significant digits, always readable back as a YAML float (1.2e-05 -> 1.2e-05, 1e-05
    -> 1.0e-05, 3 -> 3.0)."""
    text = f"{value:.{_SIGNIFICANT}g}"
    if not math.isfinite(value):
        return text
    mantissa, _, exponent = text.partition("e")
    if "." not in mantissa:
        mantissa += ".0"
    return mantissa + (f"e{exponent}" if exponent else "")


def _rounded(value: float) -> float:
    return float(f"{value:.{_SIGNIFICANT}g}")


def _term_text(term: Term, unit: Unit) -> str:
    """``value [low, high]`` in the unit (interval to 3 digits), ``< high`` if not visible."""
    k = unit.per_si
    if not term.visible:
        return f"< {term.high * k:.3g}"
    return f"{yaml_number(term.value * k)} [{term.low * k:.3g}, {term.high * k:.3g}]"


def _rows(sensor: Sensor) -> list[tuple[str, Callable[[AxisNoise], str]]]:
    def bias_sigma(a: AxisNoise) -> str:
        bias = a.terms.bias
        return "-" if bias is None else _term_text(bias.sigma, sensor.bias)

    def bias_time(a: AxisNoise) -> str:
        bias = a.terms.bias
        if bias is None:
            return "-"
        low, high = bias.time_limits_s
        limits = f" [{low:.0f}, {high:.0f}]" if math.isfinite(low) else ""
        return f"{bias.time_constant_s:.0f}{limits}"

    def flat_minimum(a: AxisNoise) -> str:
        text = _term_text(a.terms.flat_minimum, sensor.bias)
        return text if a.terms.flat_minimum.visible else text + " (last point)"

    white = "ARW" if sensor is GYRO else "VRW"
    walk = "RRW" if sensor is GYRO else "acceleration random walk"
    return [
        (
            f"{white} N (-1/2 at 1 s) [{sensor.white.label}]",
            lambda a: _term_text(a.terms.white, sensor.white),
        ),
        ("bias instability model", lambda a: a.terms.bias.model if a.terms.bias else "none"),
        (f"bias instability sigma for the node [{sensor.bias.label}]", bias_sigma),
        ("its correlation time [s]", bias_time),
        (f"B (0, minimum / 0.664) [{sensor.bias.label}]", flat_minimum),
        ("tau of the minimum [s]", lambda a: f"{a.terms.flat_minimum_tau_s:.0f}"),
        (
            f"{walk} K (+1/2 at 3 s) [{sensor.random_walk.label}]",
            lambda a: _term_text(a.terms.random_walk, sensor.random_walk),
        ),
        (
            f"quantisation Q (-1 at sqrt(3) s) [{sensor.quantization.label}]",
            lambda a: _term_text(a.terms.quantization, sensor.quantization),
        ),
    ]


def summary_table(report: NoiseReport) -> list[str]:
    """The terms per axis, value [confidence interval], "< bound" where not visible."""
    lines = [
        f"source: {report.source}",
        f"record: {report.duration_s:.1f} s, {report.n_samples} samples at "
        f"{report.clock.rate_hz:.3f} Hz ({report.clock.missing} missing)",
        f"intervals: {report.confidence:.1%} (N, B, Q: chi-squared, Greenhall edf; Gauss-Markov "
        "sigma, T and K: Whittle likelihood); '< x': not visible, upper bound",
    ]
    for sensor in SENSORS:
        axes = report.of(sensor)
        rows = _rows(sensor)
        cells = [[cell(a) for a in axes] for _, cell in rows]
        label_width = max(len(label) for label, _ in rows) + 2
        width = max(len(c) for row in cells for c in row)
        lines.append(
            f"{sensor.name:<{label_width}}  " + "  ".join(f"{a.axis:<{width}}" for a in axes)
        )
        lines.extend(
            f"  {label:<{label_width - 2}}  " + "  ".join(f"{c:<{width}}" for c in row)
            for (label, _), row in zip(rows, cells, strict=True)
        )
    return [line.rstrip() for line in lines]


def _bias(axis: AxisNoise) -> BiasInstability:
    if axis.terms.bias is None:
        raise ParameterValueError(f"{axis.name}: no bias instability identified")
    return axis.terms.bias


def fusion_parameters(
    report: NoiseReport, terms: Sequence[str], provisional: ProvisionalBiases | None = None
) -> dict[str, Any]:
    """ins_fusion_node's imu_noise.* values for the requested terms (rounded to 4 significant
    digits), validated with the node's specs (ParameterValueError if out of range or missing).
    With ``provisional``, its axes get their provisional σ and every bias its time."""
    values: dict[str, Any] = {}

    def sigma(axis: AxisNoise) -> float:
        cover = None if provisional is None else provisional.of(axis)
        return _bias(axis).sigma.value if cover is None else cover.sigma

    def per_axis(sensor: Sensor, pick: Callable[[AxisNoise], float], unit: Unit) -> list[float]:
        return [_rounded(pick(a) * unit.per_si) for a in report.of(sensor)]

    if "white" in terms:
        values["imu_noise.gyro_arw"] = per_axis(GYRO, lambda a: a.terms.white.value, GYRO.white)
        values["imu_noise.accel_vrw"] = per_axis(ACCEL, lambda a: a.terms.white.value, ACCEL.white)
    if "bias" in terms:
        values["imu_noise.gyro_bias_instability"] = per_axis(GYRO, sigma, GYRO.bias)
        values["imu_noise.accel_bias_instability"] = per_axis(ACCEL, sigma, ACCEL.bias)
        if provisional is not None:
            time_constant = provisional.time_constant_s
        else:
            biases = [_bias(a) for a in report.axes]
            time_constant = math.exp(sum(math.log(b.time_constant_s) for b in biases) / len(biases))
        values["imu_noise.bias_correlation_time"] = _rounded(time_constant)
    return {name: validate(_SPECS[name], value) for name, value in values.items()}


def written_bias_lines(
    parameters: dict[str, Any], provisional: ProvisionalBiases | None, output: Path | str
) -> list[str]:
    """What ``output`` gets for the bias instability and why it is not the table's per-axis
    fit: the node takes one correlation time for all axes, and a provisional σ is the
    conservative value at that time (empty without bias terms)."""
    if "imu_noise.bias_correlation_time" not in parameters:
        return []
    why = (
        "the PROVISIONAL values of the warning (a conservative sigma at one common T), not the"
        " table's fits"
        if provisional is not None and provisional.axes
        else "the table's sigmas; T is one value for all axes, the geometric mean of theirs"
    )
    lines = [f"{output}: bias instability written for the node: {why}"]
    for name in ("gyro_bias_instability", "accel_bias_instability", "bias_correlation_time"):
        value = parameters[f"imu_noise.{name}"]
        shown = ", ".join(map(str, value)) if isinstance(value, list) else str(value)
        unit = _COMMENTS[f"imu_noise.{name}"].split("]")[0] + "]"
        lines.append(f"  {name} {unit} {shown}")
    return lines


_COMMENTS = {
    "imu_noise.gyro_arw": "[deg/sqrt(h)] white-noise density, -1/2 line at 1 s",
    "imu_noise.accel_vrw": "[m/s/sqrt(h)] white-noise density, -1/2 line at 1 s",
    "imu_noise.gyro_bias_instability": "[deg/h] stationary Gauss-Markov sigma (table above)",
    "imu_noise.accel_bias_instability": "[mg] stationary Gauss-Markov sigma (table above)",
    "imu_noise.bias_correlation_time": "[s] geometric mean of the six axes' times",
}


def provisional_lines(provisional: ProvisionalBiases) -> list[str]:
    """The provisional axes: floor B, fitted σ, the node's σ, and the record that would pin it."""
    lines = [
        f"PROVISIONAL bias instability: this record does not pin it on {len(provisional.axes)} "
        f"axes; the node gets a conservative Gauss-Markov bias, T = "
        f"{provisional.time_constant_s:.0f} s for all axes, and per axis sigma = the larger of "
        "the IEEE 952 floor B (minimum / 0.664) and the upper limit of the sigma fitted at T:",
    ]
    for cover in provisional.axes:
        axis, unit = cover.axis, cover.axis.sensor.bias
        k = unit.per_si
        needed = (
            f"≥ {hours(cover.needed_s)} of record would pin it"
            if math.isfinite(cover.needed_s)
            else "no record length pins it"
        )
        floor = (
            _term_text(cover.floor, unit)
            if cover.floor.visible
            else f"{yaml_number(cover.floor.value * k)} (last point, the curve still falls)"
        )
        lines.append(
            f"  {axis.name}: B {floor}, sigma at T {_term_text(cover.sigma_fit, unit)}"
            f" -> {yaml_number(cover.sigma * k)} {unit.label}; {needed}"
        )
    return lines


def parameter_file(
    report: NoiseReport, parameters: dict[str, Any], provisional: ProvisionalBiases | None = None
) -> str:
    """The YAML text: provenance and the summary table as comments (and the provisional axes),
    then the parameters."""
    header = [
        "Noise of the IMU identified by `gnss_ins allan` (overlapping Allan deviation, IEEE 952",
        "slopes fitted together; Gauss-Markov bias and random walk by the Whittle likelihood of",
        "the samples; docs/allan.md). Values are noise densities and Gauss-Markov sigmas, never",
        "per-sample sigmas, so they do not depend on the sample rate.",
        "Use: ros2 run gnss_ins ins_fusion_node --ros-args --params-file config/ins_fusion.yaml",
        "     --params-file THIS_FILE ;  gnss_ins replay BAG --params THIS_FILE",
        "",
        *summary_table(report),
        *([] if provisional is None or not provisional.axes else provisional_lines(provisional)),
    ]
    lines = [f"# {line}".rstrip() for line in header]
    lines += [f"{NODE_NAME}:", "  ros__parameters:"]
    if not parameters:
        lines[-1] += " {}"
    else:
        lines.append("    imu_noise:")
    for name, value in parameters.items():
        key = name.split(".", 1)[1]
        text = (
            "[" + ", ".join(yaml_number(v) for v in value) + "]"
            if isinstance(value, list)
            else yaml_number(value)
        )
        comment = _COMMENTS[name]
        if provisional is not None and provisional.axes and "bias" in name:
            comment += "; PROVISIONAL (above)"
        lines.append(f"      {key}: {text}  # {comment}")
    return "\n".join(lines) + "\n"


def write_parameter_file(
    path: Path,
    report: NoiseReport,
    parameters: dict[str, Any],
    provisional: ProvisionalBiases | None = None,
) -> None:
    """Write parameter_file(report, parameters, provisional) to path."""
    path.write_text(parameter_file(report, parameters, provisional), encoding="utf-8")
