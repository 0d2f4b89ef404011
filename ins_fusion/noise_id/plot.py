"""The Allan-deviation figure of a noise report (matplotlib, Agg; no pyplot state, no display).

One log-log panel per axis (gyros on top in deg/h, accelerometers below in mg): the measured
overlapping Allan deviation with its confidence interval (points left out of the fit in grey),
the fitted model, each visible term as its own line (quantisation -1, white -1/2, Gauss-Markov
hump or flicker floor, random walk +1/2) and the flat minimum B·0.664 read off the curve.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from ins_fusion.noise_id.analysis import AXES, SENSORS, AxisNoise, NoiseReport
from ins_fusion.noise_id.terms import FLICKER_ADEV_FACTOR

_LINE_POINTS = 200
_COLOURS = {
    "quantization": "tab:purple",
    "white": "tab:blue",
    "bias": "tab:green",
    "random_walk": "tab:red",
}


def _labels(axis: AxisNoise) -> dict[str, str]:
    """Legend text of each term line: slope, value in the user's unit."""
    terms, sensor = axis.terms, axis.sensor
    bias = terms.bias
    if bias is None:
        bias_text = "no bias"
    else:
        sigma = bias.sigma.value * sensor.bias.per_si
        bias_text = f"{bias.model} {sigma:.3g} {sensor.bias.label}, {bias.time_constant_s:.0f} s"
    return {
        "quantization": f"Q (-1) {terms.quantization.value * sensor.quantization.per_si:.3g} "
        f"{sensor.quantization.label}",
        "white": f"N (-1/2) {terms.white.value * sensor.white.per_si:.3g} {sensor.white.label}",
        "bias": bias_text,
        "random_walk": f"K (+1/2) {terms.random_walk.value * sensor.random_walk.per_si:.3g} "
        f"{sensor.random_walk.label}",
    }


def _panel(ax: Axes, axis: AxisNoise, confidence: float) -> None:
    curve, terms, unit = axis.curve, axis.terms, axis.sensor.adev
    k = unit.per_si
    low, high = curve.interval(confidence)
    fitted = (curve.tau_s >= terms.fit_tau_s[0]) & (curve.tau_s <= terms.fit_tau_s[1])
    for mask, colour, label in ((fitted, "black", "data"), (~fitted, "0.6", "not fitted")):
        if np.any(mask):
            ax.errorbar(
                curve.tau_s[mask],
                curve.adev[mask] * k,
                yerr=[(curve.adev - low)[mask] * k, (high - curve.adev)[mask] * k],
                fmt="o",
                ms=2.5,
                lw=0.8,
                color=colour,
                label=label,
            )
    tau = np.geomspace(curve.tau_s[0], curve.tau_s[-1], _LINE_POINTS)
    ax.plot(tau, np.sqrt(terms.avar(tau)) * k, color="tab:orange", lw=1.5, label="fit")
    shown = {
        "quantization": terms.quantization.visible,
        "white": terms.white.visible,
        "bias": terms.bias is not None,
        "random_walk": terms.random_walk.visible,
    }
    floor = np.sqrt(terms.avar(tau)).min() * k * 1e-2
    labels = _labels(axis)
    for name, part in terms.components(tau).items():
        if not shown[name]:
            continue
        ax.plot(
            tau,
            np.maximum(np.sqrt(part) * k, floor),
            "--",
            color=_COLOURS[name],
            lw=1.0,
            label=labels[name],
        )
    flat = terms.flat_minimum
    ax.plot(
        terms.flat_minimum_tau_s,
        flat.value * FLICKER_ADEV_FACTOR * k,
        "v",
        color="tab:green",
        ms=8,
        label=f"B = min/0.664 = {flat.value * axis.sensor.bias.per_si:.3g} "
        f"{axis.sensor.bias.label} at {terms.flat_minimum_tau_s:.0f} s"
        + ("" if flat.visible else " (last point)"),
    )
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_ylim(bottom=floor * 10.0)
    ax.set_title(axis.name)
    ax.set_xlabel("τ [s]")
    ax.set_ylabel(f"Allan deviation [{unit.label}]")
    ax.grid(True, which="both", lw=0.3)
    ax.legend(fontsize=7, loc="best")


def plot_allan(path: Path | str, report: NoiseReport) -> None:
    """Save the figure to ``path`` (format from its suffix: .png, .pdf, .svg)."""
    fig = Figure(figsize=(16, 9), layout="constrained")
    FigureCanvasAgg(fig)
    panels = fig.subplots(len(SENSORS), len(AXES))
    for row, sensor in zip(panels, SENSORS, strict=True):
        for ax, axis in zip(row, report.of(sensor), strict=True):
            _panel(ax, axis, report.confidence)
    fig.suptitle(
        f"{report.source}: {report.duration_s:.0f} s at {report.clock.rate_hz:.2f} Hz, "
        f"{report.confidence:.0%} intervals"
    )
    fig.savefig(path)
