"""The steps of ``gnss_ins replay`` (ins_fusion/tools/replay.py parses the arguments): check the
parameters, read the bag, replay (and smooth) or sweep, print, write the report, plot, fused bag
and exports.

Bad input raises UsageError, printed by ``execute`` with exit status 2; ``run_replay`` raises it
(``gnss_ins batch`` runs one bag with it, ins_fusion.fleet.task).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from gnss_ins_common.params import ParameterValueError, file_values, load_yaml, validate_all
from ins_fusion.bags.bag_io import BagError
from ins_fusion.core.engine.engine import InsEngine
from ins_fusion.core.nav.calibration import CalibrationError
from ins_fusion.core.settings.config import NODE_NAME, FusionConfig
from ins_fusion.core.settings.params import PARAMETERS
from ins_fusion.replay import free_inertial
from ins_fusion.replay.export import FORMATS, export
from ins_fusion.replay.frames import IMU_FRAME, comparison_frame, is_imu_frame
from ins_fusion.replay.inputs import InputError, ReplayInputs, load_bag
from ins_fusion.replay.outages import Outage
from ins_fusion.replay.pipeline import Replay, replay
from ins_fusion.replay.ranking import DEFAULT_RANK_BY
from ins_fusion.replay.report import Report, format_table, to_json
from ins_fusion.replay.settings import grid
from ins_fusion.replay.sweep import format_sweep, run_sweep
from ins_fusion.replay.topics import DEFAULT_REFERENCE
from ins_fusion.replay.withheld import WithheldEvaluation
from ins_fusion.runtime.cluster import ClusterError
from ins_fusion.runtime.progress import Progress


class UsageError(Exception):
    """Bad input: printed and exit status 2."""


def execute(args: argparse.Namespace) -> int:
    """Replay (or sweep) as the arguments say; 0 done, 1 no fused solution, 2 bad input (the
    requested outputs that were not written are named)."""
    absent = [(label, path) for label, path in _requested(args) if not Path(path).exists()]
    try:
        return run_replay(args)
    except UsageError as exc:
        print(f"gnss_ins replay: error: {exc}", file=sys.stderr)
        for label, path in absent:
            if not Path(path).exists():
                print(
                    f"gnss_ins replay: {label} {path} not written because of the error",
                    file=sys.stderr,
                )
        return 2


def _requested(args: argparse.Namespace) -> list[tuple[str, Path]]:
    """The outputs the command line asks for, as (what, path)."""
    requested = [("report", args.report), ("plot", args.plot), ("fused bag", args.output)]
    requested += [("export", path) for path in args.export]
    return [(label, Path(path)) for label, path in requested if path is not None]


def _parameters(args: argparse.Namespace) -> dict[str, Any]:
    """Every parameter: defaults, the YAML file, then --set."""
    try:
        base = (
            load_yaml(args.params, NODE_NAME, PARAMETERS)
            if args.params is not None
            else validate_all(PARAMETERS, {})
        )
    except ParameterValueError as exc:
        raise UsageError(str(exc)) from None
    unaided = free_inertial.UNAIDED if args.free_inertial is not None else {}
    return {**base, **dict(args.settings), **unaided}


def _speed_declined(args: argparse.Namespace) -> str | None:
    """Where the user set ``speed.use`` false (``--set`` or the --params file), else None: a
    bag's vehicle speed is used unless declined there."""
    settings = dict(args.settings)
    if "speed.use" in settings:
        return None if settings["speed.use"] else "--set"
    if args.params is not None and file_values(args.params, NODE_NAME).get("speed.use") is False:
        return str(args.params)
    return None


def _check_engine(parameters: dict[str, Any]) -> None:
    """The engine accepts the parameters (and reads the calibration file they name)."""
    try:
        InsEngine(FusionConfig.from_parameters(parameters))
    except (ParameterValueError, CalibrationError) as exc:
        raise UsageError(str(exc)) from None


def _check_usage(args: argparse.Namespace) -> None:
    if args.sweep and (args.plot is not None or args.output is not None):
        raise UsageError("--plot and --output are for a single replay, not with --sweep")
    if args.rank_by is not None and not args.sweep:
        raise UsageError("--rank-by ranks the runs of a --sweep")
    if args.workers is not None and args.workers < 1:
        raise UsageError("--workers must be at least 1")
    if args.scheduler is not None and not args.sweep:
        raise UsageError("--scheduler runs the settings of a --sweep")
    if args.free_inertial is not None and (args.outage or args.sweep):
        raise UsageError("--free-inertial withholds GNSS itself: not with --outage or --sweep")
    if args.output is not None and args.output.exists():
        raise UsageError(f"{args.output} exists already, not overwriting")
    if any(name == "speed.use" for name, _ in args.sweep):
        raise UsageError(
            "speed.use is not swept: a bag's vehicle speed is used unless --set speed.use=false"
        )
    if args.sweep and (args.smooth or args.export):
        raise UsageError("--smooth and --export are for a single replay, not with --sweep")
    if args.export_solution == "smoothed" and not args.smooth:
        raise UsageError("--export-solution smoothed needs --smooth")
    for path in args.export:
        if path.suffix.lower() not in FORMATS:
            raise UsageError(f"--export {path}: the suffix must be one of {', '.join(FORMATS)}")


def _load(args: argparse.Namespace) -> ReplayInputs:
    prefix = args.reference if args.reference is not None else DEFAULT_REFERENCE
    with Progress("read", unit="msgs") as bar:
        try:
            inputs = load_bag(
                args.bag,
                args.topics,
                prefix,
                reference_required=args.reference is not None,
                progress=bar.update_with_total,
            )
        except InputError as exc:
            raise UsageError(str(exc)) from None
    for note in inputs.notes:
        print(f"note: {note}", file=sys.stderr)
    declined = _speed_declined(args)
    if declined is not None and inputs.has_speed:
        readings = sum(role == "speed" for _, role, _ in inputs.measurements)
        inputs = inputs.without_speed()
        print(
            f"note: speed.use false ({declined}): the bag's {readings} vehicle speed readings"
            f" ({inputs.topics.speed}) not used",
            file=sys.stderr,
        )
    for outage in args.outage:
        if outage.start_s >= inputs.duration_s:
            raise UsageError(
                f"outage {outage.start_s:g}:{outage.duration_s:g} starts after the IMU data"
                f" ends ({inputs.duration_s:.1f} s after the first IMU stamp)"
            )
    if inputs.reference is None and args.reference is None:
        scored = "; outages scored against the withheld GNSS fixes" if args.outage else ""
        print(
            f"note: no reference ({prefix}/fix) in the bag; accuracy not evaluated{scored}",
            file=sys.stderr,
        )
    return inputs


def _frame_note(inputs: ReplayInputs, parameters: dict[str, Any]) -> None:
    """Say on stderr how the reference's frame is handled when it is not base_link."""
    if inputs.reference is None:
        return
    frame_id = inputs.reference.frame_id
    frame = comparison_frame(frame_id, str(parameters.get("base_frame", "")), inputs.imu_frame)
    if frame is None:
        print(
            f"note: the reference's frame_id {frame_id!r} is neither base_link nor the IMU's"
            f" ({inputs.imu_frame or IMU_FRAME}); the fused base_link solution is compared as is",
            file=sys.stderr,
        )
    elif is_imu_frame(frame, inputs.imu_frame):
        print(
            f"note: the reference is of {frame}; the fused solution is moved there by"
            " imu_lever_arm and imu_mounting_rpy_deg before the comparison",
            file=sys.stderr,
        )


def check_options(args: argparse.Namespace) -> tuple[dict[str, Any], list[dict[str, Any]]]:
    """Everything but the bag: the options' combination, the parameters and the sweep's
    settings the engine accepts; (parameters, settings), UsageError otherwise."""
    _check_usage(args)
    parameters = _parameters(args)
    try:
        settings = grid(args.sweep) if args.sweep else []
    except ParameterValueError as exc:
        raise UsageError(str(exc)) from None
    for setting in settings or [{}]:
        _check_engine({**parameters, **setting})
    return parameters, settings


def run_replay(args: argparse.Namespace) -> int:
    """Replay (or sweep) as the arguments say; 0 done, 1 no fused solution (the report is
    written, the other outputs not), UsageError on bad input."""
    parameters, settings = check_options(args)
    inputs = _load(args)
    reference = None if inputs.reference is None else inputs.reference_prefix
    _frame_note(inputs, parameters)
    outages: list[Outage] = args.outage
    if args.free_inertial is not None:
        if args.free_inertial >= inputs.duration_s:
            raise UsageError(
                f"--free-inertial {args.free_inertial:g} is after the IMU data end"
                f" ({inputs.duration_s:.1f} s after the first IMU stamp)"
            )
        outages = [free_inertial.outage(args.free_inertial, inputs.duration_s)]
    if settings:
        return _sweep(args, inputs, parameters, settings, outages, reference)
    with Progress("fuse", total=len(inputs.imu), unit="samples") as bar:
        result = replay(
            inputs, parameters, outages, reference, lambda done, _: bar.update(done), args.smooth
        )
    print(format_table(result.report))
    if args.free_inertial is not None:
        _free_inertial(args.free_inertial, result)
    if args.report is not None:
        _write_report(args.report, result.report)
    if not len(result.run.track.t_s):
        print(
            "gnss_ins replay: the engine produced no solution (no alignment: is there a"
            " standstill or GNSS course/attitude and a fix?)",
            file=sys.stderr,
        )
        _not_written(args, "there is no fused solution")
        return 1
    _write_outputs(args, inputs, parameters, result, outages)
    return 0


def _free_inertial(start_s: float, result: Replay) -> None:
    """Print the drift of the unaided run and add it to the report."""
    withheld = result.withheld if result.withheld is not None else WithheldEvaluation.empty()
    run = free_inertial.drift(withheld, start_s, free_inertial.ELAPSED_S)
    print(free_inertial.format_drift(run, start_s))
    result.report["free_inertial"] = free_inertial.report_section(run, start_s)


def _not_written(args: argparse.Namespace, reason: str) -> None:
    """Name the requested plot, fused bag and exports that are not written, and why (stderr)."""
    for label, path in _requested(args):
        if label != "report":
            print(f"gnss_ins replay: {label} {path} not written: {reason}", file=sys.stderr)


def _write_report(path: Path, report: Report) -> None:
    try:
        path.write_text(to_json(report), encoding="utf-8")
    except OSError as exc:
        raise UsageError(f"cannot write {path}: {exc}") from None
    print(f"report: {path}")


def _write_outputs(
    args: argparse.Namespace,
    inputs: ReplayInputs,
    parameters: dict[str, Any],
    result: Replay,
    outages: list[Outage],
) -> None:
    # Imported when asked for: matplotlib and the message classes cost ~1 s of every start-up.
    if args.plot is not None:
        from ins_fusion.replay.plot import measured, plot_replay

        title = f"gnss_ins replay {inputs.bag}"
        if outages:
            title += "; outages " + ", ".join(f"{o.start_s:g}:{o.duration_s:g}" for o in outages)
        data = None
        if result.evaluation is None and result.run.datum is not None:
            arm = FusionConfig.from_parameters(parameters).gnss_lever_arm_flu_m
            data = measured(
                result.run.track, inputs.measurements, result.run.datum, arm, inputs.t0_s
            )
        try:
            plot_replay(
                args.plot,
                result.compared_track,
                inputs.t0_s,
                result.evaluation,
                outages,
                title,
                result.smoothed,
                data,
            )
        except (OSError, ValueError) as exc:
            raise UsageError(f"cannot write the plot {args.plot}: {exc}") from None
        print(f"plot: {args.plot}")
    if args.output is not None:
        from ins_fusion.replay.output import write_fused_bag

        config = FusionConfig.from_parameters(parameters)
        # Rate variance per axis as the node publishes it: mean gyro density² x the IMU rate.
        imu_rate_hz = (len(inputs.imu) - 1) / inputs.duration_s
        rate_variance = float(config.imu_noise.gyro_psd.mean()) * imu_rate_hz
        smoothed = result.run.smoothed
        try:
            summary = write_fused_bag(
                args.output,
                result.run.track.solutions,
                config.map_frame,
                config.base_frame,
                rate_variance,
                None if smoothed is None else smoothed.solutions,
            )
        except BagError as exc:
            raise UsageError(str(exc)) from None
        print(summary.format(f"fused bag {args.output}"))
    _export(args, result)


def _export(args: argparse.Namespace, result: Replay) -> None:
    """Write the --export files of the chosen solution."""
    which = args.export_solution or ("smoothed" if args.smooth else "forward")
    track = result.run.smoothed if which == "smoothed" else result.run.track
    assert track is not None
    for path in args.export:
        try:
            count = export(path, track, f"{Path(result.report['bag']).name} {which}")
        except OSError as exc:
            raise UsageError(f"cannot write {path}: {exc}") from None
        print(f"export: {path} ({which}, {count} epochs)")


def _sweep(
    args: argparse.Namespace,
    inputs: ReplayInputs,
    parameters: dict[str, Any],
    settings: list[dict[str, Any]],
    outages: list[Outage],
    reference: str | None,
) -> int:
    rank_by = args.rank_by or DEFAULT_RANK_BY
    with Progress("sweep", total=len(settings), unit="runs") as bar:
        try:
            results = run_sweep(
                inputs,
                parameters,
                settings,
                outages,
                reference,
                rank_by,
                args.workers,
                lambda done, _: bar.update(done),
                args.scheduler,
            )
        except ClusterError as exc:
            raise UsageError(str(exc)) from None
    print(format_sweep(results, rank_by))
    if args.report is not None:
        runs = [{"setting": r.setting, "score": r.score, "report": r.report} for r in results]
        _write_report(args.report, {"rank_by": rank_by, "runs": runs})
    return 0
