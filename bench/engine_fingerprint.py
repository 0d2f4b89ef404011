"""Fingerprint of the fusion engine's numbers, to show a refactoring of ins_fusion/core changed
none of them: every solution row and every counter of the engine on the repository's fixture
drives, written to an .npz; ``--compare`` checks a new run against a saved one (bit-identical or
within 1e-9 relative, every counter equal) and prints what differs.

Drives: the simulated figure eight (90 s) and test pattern (75 s) of test/support/sim_bags.py, the
same with damaged IMU data (test/support/sample_runs.py), the real comma2k19 segment with the phone
parameters (test/fixtures/comma2k19). Parameter sets: the defaults, every optional state on
(mounting, time offset, scale factors), no pseudo-measurements. Paths: the replay's compiled runs
(``run_fusion``, with and without the RTS smoother) and, on the figure eight, the engine fed
sample by sample (``add_imu``, ``solution_row``) with the smoother's history attached (every
update the general way).

Usage: python bench/engine_fingerprint.py OUT.npz [--compare BASELINE.npz]   (~2-4 min)
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "test"))

from support.sample_runs import SETS, damaged, sample_by_sample  # noqa: E402
from support.sim_bags import FIGURE_EIGHT_90_S, TEST_PATTERN_75_S  # noqa: E402

from gnss_ins_common.params import load_yaml, validate_all  # noqa: E402
from ins_fusion.core.settings.config import NODE_NAME  # noqa: E402
from ins_fusion.core.settings.params import PARAMETERS  # noqa: E402
from ins_fusion.replay.inputs import ReplayInputs, load_bag  # noqa: E402
from ins_fusion.replay.run import run_fusion  # noqa: E402
from ins_fusion.replay.topics import TopicMap  # noqa: E402
from ins_fusion.sim.simulated_bag import write_bag  # noqa: E402

COMMA = REPO / "test" / "fixtures" / "comma2k19"
RELATIVE = 1e-9


def fingerprint() -> dict[str, Any]:
    """name -> rows (array) or status (repr string) of every run."""
    out: dict[str, Any] = {}
    with tempfile.TemporaryDirectory() as tmp:
        drives: dict[str, tuple[ReplayInputs, dict[str, object]]] = {}
        for name, sim in (("eight", FIGURE_EIGHT_90_S), ("pattern", TEST_PATTERN_75_S)):
            write_bag(sim, Path(tmp) / name)
            inputs = load_bag(Path(tmp) / name, TopicMap())
            drives[name] = (inputs, {})
            drives[f"{name}damaged"] = (damaged(inputs), {})
        phone = load_yaml(COMMA / "ins_fusion_phone.yaml", NODE_NAME, PARAMETERS)
        drives["comma2k19"] = (load_bag(COMMA / "comma2k19_ex1_seg40", TopicMap()), phone)
        for drive, (inputs, base) in drives.items():
            for set_name, overrides in SETS.items():
                parameters = validate_all(PARAMETERS, {**base, **overrides})
                key = f"{drive}/{set_name}"
                print(key, flush=True)
                smooth = set_name != "no_pseudo"
                run = run_fusion(inputs, parameters, smooth=smooth)
                out[f"{key}/rows"] = run.track.rows
                out[f"{key}/status"] = repr(run.status)
                out[f"{key}/datum"] = repr(run.datum)
                if run.smoothed is not None:
                    out[f"{key}/smoothed"] = run.smoothed.rows
                if drive == "eight" and set_name != "no_pseudo":
                    rows, status = sample_by_sample(inputs, parameters, smooth=True)
                    out[f"{key}/general_rows"] = rows
                    out[f"{key}/general_status"] = repr(status)
    return out


def compare(new: dict[str, Any], old: dict[str, Any]) -> list[str]:
    """What differs between two fingerprints (empty: the same numbers)."""
    problems = [f"{k}: missing" for k in sorted(set(old) - set(new))]
    problems += [f"{k}: new" for k in sorted(set(new) - set(old))]
    for key in sorted(set(old) & set(new)):
        a, b = np.asarray(new[key]), np.asarray(old[key])
        if a.dtype.kind in "US" or b.dtype.kind in "US":
            if str(a) != str(b):
                problems.append(f"{key}: {a} != {b}")
        elif a.shape != b.shape:
            problems.append(f"{key}: shape {a.shape} != {b.shape}")
        elif not np.array_equal(a, b, equal_nan=True):
            scale = np.maximum(np.abs(b), 1e-300)
            with np.errstate(invalid="ignore"):
                rel = np.nanmax(np.where(np.isnan(a) & np.isnan(b), 0.0, np.abs(a - b) / scale))
            if not rel <= RELATIVE:
                problems.append(f"{key}: largest relative difference {rel:.3g}")
            else:
                print(f"{key}: not bit-identical, largest relative difference {rel:.3g}")
    return problems


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path)
    parser.add_argument("--compare", type=Path)
    args = parser.parse_args()
    found = fingerprint()
    np.savez_compressed(args.out, **{k: np.asarray(v) for k, v in found.items()})
    print(f"{len(found)} entries written to {args.out}")
    if args.compare is None:
        return 0
    with np.load(args.compare) as saved:
        problems = compare(found, {k: saved[k] for k in saved.files})
    print("\n".join(problems) if problems else "the same numbers: every row and counter")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
