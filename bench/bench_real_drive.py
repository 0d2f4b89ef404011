"""The real car drive (comma2k19 fixture, test/fixtures/comma2k19/README.md) through
`gnss_ins replay`'s pipeline: accuracy, consistency and outage drift with the parameters a
user would give, against the reference (compared in its own frame, imu_link) and against the
GNSS fixes each outage withheld.

    .venv/bin/python bench/bench_real_drive.py        (about 30 s)

Parameter sets: 'defaults' (config/ins_fusion.yaml: the IMU400CC's noise, the survey car's
lever arms, no mounting), 'datasheet' (test/fixtures/comma2k19/ins_fusion_phone.yaml: a
consumer MEMS datasheet, zero lever arms, the mounting measured against the reference), the
same without NHC, and with the receiver's σ scaled to its measured scatter (0.5).
"""

from __future__ import annotations

import math
import sys
from pathlib import Path
from typing import Any

from gnss_ins_common.params import load_yaml, validate_all
from ins_fusion.core.settings.config import NODE_NAME
from ins_fusion.core.settings.params import PARAMETERS
from ins_fusion.replay.inputs import load_bag
from ins_fusion.replay.outages import Outage
from ins_fusion.replay.pipeline import replay
from ins_fusion.replay.topics import DEFAULT_REFERENCE, TopicMap

FIXTURE = Path(__file__).resolve().parents[1] / "test" / "fixtures" / "comma2k19"
BAG = FIXTURE / "comma2k19_ex1_seg40"
OUTAGE_SETS = {
    "none": (),
    "10-15 s": (Outage(8.0, 10.0), Outage(22.0, 15.0), Outage(42.0, 12.0)),
    "15 s": (Outage(5.0, 15.0), Outage(25.0, 15.0), Outage(43.0, 15.0)),
}


def _sets() -> dict[str, dict[str, Any]]:
    defaults = validate_all(PARAMETERS, {})
    phone = load_yaml(FIXTURE / "ins_fusion_phone.yaml", NODE_NAME, PARAMETERS)
    return {
        "defaults": defaults,
        "datasheet": phone,
        "datasheet, no NHC": {**phone, "use_nhc": False},
        "datasheet, fix σ x0.5": {**phone, "gnss_position_noise_scale": 0.5},
    }


def _f(value: Any, digits: int = 2) -> str:
    return "-" if value is None or not math.isfinite(value) else f"{value:.{digits}f}"


def main() -> int:
    inputs = load_bag(BAG, TopicMap(), DEFAULT_REFERENCE, reference_required=True)
    print(f"bag {BAG.name}: {len(inputs.imu)} IMU samples, {inputs.duration_s:.1f} s")
    print(
        "| parameters | outages | horiz RMS m | vert RMS m | roll/pitch/yaw RMS ° | NEES (in 3σ)"
        " | fixes/NHC gated | outage end m (3σ m), reference | withheld fixes: end m, NEES |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    for name, params in _sets().items():
        for label, outages in OUTAGE_SETS.items():
            rep = replay(inputs, params, outages, DEFAULT_REFERENCE).report
            pos, att, nees = rep["position_error_m"], rep["attitude_error_deg"], rep["nees"]
            m = rep["measurements"]
            ends = ", ".join(
                f"{_f(o['horizontal_error_end_m'])} ({_f(3.0 * o['horizontal_sigma_end_m'])})"
                for o in rep["outages"]
            )
            withheld = ", ".join(
                f"{_f(o['horizontal_error_end_m'])}, {_f(o['nees']['mean'], 1)}"
                for o in rep["withheld_fixes"]
            )
            inside = 100.0 * nees["position_within_3sigma_fraction"]
            print(
                f"| {name} | {label} | {_f(pos['horizontal_rms'])} | {_f(pos['vertical_rms'])}"
                f" | {_f(att['roll_rms'])}/{_f(att['pitch_rms'])}/{_f(att['yaw_rms'])}"
                f" | {_f(nees['position_mean'])} ({inside:.0f}%)"
                f" | {m['gnss_position']['gated']}/{m['nhc']['gated']}"
                f" | {ends or '-'} | {withheld or '-'} |"
            )
            sys.stdout.flush()
        adapted = rep["adapted_noise"]
        print(
            f"|   adapted ({name}) | gyro ARW "
            + "/".join(_f(adapted[f"gyro_arw_{a}_deg_sqrt_h"]) for a in "xyz")
            + " °/√h, accel VRW "
            + "/".join(_f(adapted[f"accel_vrw_{a}_m_s_sqrt_h"]) for a in "xyz")
            + " m/s/√h | | | | | | | |"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
