"""core.layout and the (name, width) tables of the core's flat arrays: every table's offsets are
contiguous, its constants (prefix + the field's name in capitals) are the table's offsets, and
they are the numbers the arrays had when they were numbered by hand (a checkpoint, a recorded
intake array or a calibration table keeps its meaning); FilterState's fields read their slots."""

from __future__ import annotations

from types import ModuleType

import numpy as np
import pytest

from ins_fusion.core import layout
from ins_fusion.core.engine import intake
from ins_fusion.core.filter import adaptation, state
from ins_fusion.core.filter.state import X_LAYOUT, FilterState, _ScalarField, _Vec3Field
from ins_fusion.core.nav import calibration, strapdown
from ins_fusion.core.nav.strapdown import NavState
from ins_fusion.core.output import solution

#: (module, constant prefix, table, name of its size) of every layout.
TABLES: list[tuple[ModuleType, str, layout.Layout, str]] = [
    (strapdown, "NAV_", strapdown.NAV_LAYOUT, "NAV_SIZE"),
    (strapdown, "INC_", strapdown.INCREMENT_LAYOUT, "INCREMENT_SIZE"),
    (state, "X_", state.X_LAYOUT, "X_SIZE"),
    (intake, "S_", intake.S_LAYOUT, "S_SIZE"),
    (adaptation, "B_", adaptation.B_LAYOUT, "B_SIZE"),
    (adaptation, "W_", adaptation.W_LAYOUT, "W_SIZE"),
    (calibration, "T_", calibration.T_LAYOUT, "T_SIZE"),
    (solution, "E_", solution.ERROR_LAYOUT, "E_SIZE"),
]

#: The offsets as they were numbered by hand before the tables (and the sizes).
HAND_NUMBERED = {
    "NAV_": {"LAT": 0, "LON": 1, "HEIGHT": 2, "VEL": 3, "QUAT": 6, "SIZE": 10},
    "INC_": {"DT": 0, "ANGLE": 1, "VEL": 4, "SIZE": 7},
    "X_": {
        **{"NAV": 0, "BG": 10, "BA": 13, "SG": 16, "SA": 19, "PREV": 22, "HAS_PREV": 29},
        **{"RATE_B": 30, "RATE_I": 33, "ACCEL_N": 36, "ACCEL_LP": 39, "RATE_LP": 42},
        **{"COV_DT": 45, "COV_DTH": 46, "COV_DV": 49, "COV_VEL0": 52, "T": 55},
        **{"GNSS_ERROR": 56, "GNSS_VARIANCE": 59, "GNSS_REPORTED": 62, "MOUNTING": 65},
        **{"TIME_OFFSET": 67, "NIS_MEAN": 68, "Q_SCALE": 69, "LAST_POSITION_T": 70},
        **{"HEADING_KNOWN": 71, "SPEED_SCALE": 72, "SR": 73, "SIZE": 76},
    },
    "S_": {
        **{"LAST_T": 0, "NOMINAL_DT": 1, "LAST_RATE": 2, "LAST_FORCE": 5, "ZARU_SUM": 8},
        **{"ZARU_N": 11, "SAMPLES": 12, "GAPS": 13, "DUPLICATES": 14, "OUT_OF_ORDER": 15},
        **{"IMPLAUSIBLE": 16, "BACK_RUN": 17, "MAX_RATE": 18, "MAX_FORCE": 19},
        **{"CALIBRATED": 20, "RATE": 21, "FORCE": 24, "READING_T": 27, "READING_RATE": 28},
        **{"READING_FORCE": 31, "STEP": 34, "SIZE": 35},
    },
    "B_": {
        **{"START": 0, "SUM": 1, "N": 7, "TAU": 8, "PREV": 9, "HELD": 21, "MEAN": 22},
        **{"GYRO_N": 28, "ACCEL_N": 29, "WINDOW": 30, "VERSION": 31, "SIZE": 32},
    },
    "W_": {
        **{"MEAN": 0, "COUNT": 3, "LAST_T": 4, "RESIDUAL": 5, "UPDATED": 8, "REPORTED": 11},
        **{"WINDOW": 14, "MAX_INTERVAL": 15, "SIZE": 16},
    },
    "T_": {"INVERSES": 0, "BIAS": 1152, "LARGE": 1158, "G": 1160, "SIZE": 1169},
    "E_": {"POS": 0, "VEL": 3, "ATT": 6, "ATT_IMU": 9, "SIZE": 12},
}


def test_offsets_of_a_table() -> None:
    assert layout.offsets((("a", 1), ("b", 3), ("c", 2))) == (0, 1, 4, 6)
    assert layout.fields((("a", 1), ("b", 3))) == {"a": (0, 1), "b": (1, 3)}
    with pytest.raises(ValueError, match="repeats"):
        layout.offsets((("a", 1), ("a", 2)))
    with pytest.raises(ValueError, match="width 0"):
        layout.offsets((("a", 1), ("b", 0)))


@pytest.mark.parametrize(("module", "prefix", "table", "size"), TABLES, ids=[t[1] for t in TABLES])
def test_table_is_contiguous_and_its_constants_are_its_offsets(
    module: ModuleType, prefix: str, table: layout.Layout, size: str
) -> None:
    end = 0
    for name, (start, width) in layout.fields(table).items():
        assert name == name.lower()
        assert start == end and width >= 1  # contiguous, no overlap, no hole
        assert getattr(module, prefix + name.upper()) == start
        assert type(getattr(module, prefix + name.upper())) is int  # a numba constant
        end = start + width
    assert getattr(module, size) == end == layout.offsets(table)[-1]
    # Every constant of the prefix is a field, the size or (X_) a field of the navigation.
    named = {prefix + name.upper() for name, _ in table} | ({size} & {prefix + "SIZE"})
    if prefix == "X_":
        named |= {f"X_{name.upper()}" for name, _ in strapdown.NAV_LAYOUT}
    constants = {
        key for key, value in vars(module).items() if key.startswith(prefix) and type(value) is int
    }
    assert constants == named


@pytest.mark.parametrize(("module", "prefix", "table", "size"), TABLES, ids=[t[1] for t in TABLES])
def test_offsets_are_the_hand_numbered_ones(
    module: ModuleType, prefix: str, table: layout.Layout, size: str
) -> None:
    numbers = {name.upper(): start for name, (start, _) in layout.fields(table).items()}
    numbers["SIZE"] = layout.offsets(table)[-1]
    assert numbers == HAND_NUMBERED[prefix]
    constants = {key: getattr(module, prefix + key) for key in numbers if key != "SIZE"}
    assert {**constants, "SIZE": getattr(module, size)} == HAND_NUMBERED[prefix]


def test_navigation_fields_of_the_state() -> None:
    nav = state.X_NAV
    for name, (start, _) in layout.fields(strapdown.NAV_LAYOUT).items():
        assert getattr(state, f"X_{name.upper()}") == nav + start
    assert dict(X_LAYOUT)["nav"] == strapdown.NAV_SIZE
    assert dict(X_LAYOUT)["prev"] == strapdown.INCREMENT_SIZE


#: FilterState's descriptors and the field of X_LAYOUT each keeps.
DESCRIPTOR_FIELDS = {
    "gyro_bias": "bg",
    "accel_bias": "ba",
    "gyro_scale": "sg",
    "accel_scale": "sa",
    "accel_lp": "accel_lp",
    "rate_lp": "rate_lp",
    "t_s": "t",
    "gnss_error": "gnss_error",
    "gnss_variance": "gnss_variance",
    "gnss_reported": "gnss_reported",
    "time_offset": "time_offset",
    "nis_mean": "nis_mean",
    "q_scale": "q_scale",
    "last_position_t_s": "last_position_t",
    "speed_scale": "speed_scale",
}


def _state() -> FilterState:
    nav = NavState(0.7, 0.2, 100.0, np.array([1.0, 2.0, 3.0]), np.array([0.0, 0.0, 0.0, 1.0]))
    return FilterState(5.0, nav, (0.0, 0.0, 0.0), True)


def test_filter_state_fields_read_their_slots() -> None:
    descriptors = {
        name
        for name, value in vars(FilterState).items()
        if isinstance(value, _Vec3Field | _ScalarField)
    }
    assert descriptors == set(DESCRIPTOR_FIELDS)
    fields = layout.fields(X_LAYOUT)
    s = _state()
    s.x[:] = np.arange(state.X_SIZE) + 0.5  # every slot its own number
    s.changed()
    for attribute, field in DESCRIPTOR_FIELDS.items():
        start, width = fields[field]
        expected = s.x[start : start + width].tolist()
        value = getattr(s, attribute)
        assert (list(value) if width > 1 else [value]) == expected, attribute
    start, _ = fields["mounting"]
    assert s.mounting == (start + 0.5, start + 1.5)
    nav = s.nav
    n = state.X_NAV
    assert (nav.lat_rad, nav.lon_rad, nav.height_m) == (n + 0.5, n + 1.5, n + 2.5)
    assert nav.vel_ned_m_s.tolist() == [n + 3.5, n + 4.5, n + 5.5]
    assert nav.quat_nb.tolist() == [n + 6.5, n + 7.5, n + 8.5, n + 9.5]
    s.x[state.X_HEADING_KNOWN] = 0.0
    assert not s.heading_known


def test_filter_state_fields_write_their_slots() -> None:
    s = _state()
    s.x[:] = 0.0
    fields = layout.fields(X_LAYOUT)
    for k, (attribute, field) in enumerate(DESCRIPTOR_FIELDS.items()):
        start, width = fields[field]
        value = 10.0 * k + np.arange(width) + 1.0
        setattr(s, attribute, tuple(value.tolist()) if width > 1 else float(value[0]))
        assert s.x[start : start + width].tolist() == value.tolist(), attribute
    s.mounting = (0.25, -0.5)
    assert s.x[state.X_MOUNTING : state.X_MOUNTING + 2].tolist() == [0.25, -0.5]
    s.heading_known = True
    assert s.x[state.X_HEADING_KNOWN] == 1.0
    nav = NavState(0.1, 0.3, 9.0, np.array([4.0, 5.0, 6.0]), np.array([0.5, 0.5, 0.5, 0.5]))
    s.set_nav(nav)
    assert s.x[state.X_NAV : state.X_NAV + strapdown.NAV_SIZE].tolist() == [
        0.1,
        0.3,
        9.0,
        4.0,
        5.0,
        6.0,
        0.5,
        0.5,
        0.5,
        0.5,
    ]
    # Every slot was written once: no two fields share one.
    written = np.flatnonzero(s.x)
    slots = set(DESCRIPTOR_FIELDS.values()) | {"mounting", "heading_known", "nav"}
    expected = sorted(i for f in slots for i in range(*_span(fields[f])))
    assert written.tolist() == expected


def _span(field: tuple[int, int]) -> tuple[int, int]:
    return field[0], field[0] + field[1]


def test_the_solution_row_and_the_output_numbers_keep_their_positions() -> None:
    """The row's and the outputs' layouts give the positions the rows and messages had when
    they were numbered by hand (saved rows and replays' exports read them)."""
    from ins_fusion.core.output import output_numbers as o
    from ins_fusion.core.output import solution as s

    assert (s.T, s.LAT, s.LON, s.HEIGHT, s.STATE, s.WIDTH) == (0, 1, 2, 3, 53, 63)
    spans = (s.POS, s.VEL, s.QUAT, s.RATE, s.COV_POS, s.COV_VEL, s.COV_ATT)
    assert [(x.start, x.stop) for x in spans] == [
        (4, 7),
        (7, 10),
        (10, 14),
        (14, 17),
        (17, 26),
        (26, 35),
        (35, 44),
    ]
    spans = (s.GYRO, s.ACCEL, s.MOUNTING, s.COV_ATT_IMU)
    assert [(x.start, x.stop) for x in spans] == [(44, 47), (47, 50), (50, 53), (54, 63)]
    assert s.NAVIGATION_FIELDS == ((1, 1), (2, 1), (3, 1), (4, 3), (7, 3), (10, 4), (14, 3))
    assert (
        slice(0, 85),
        slice(0, 7),
        slice(85, 97),
        slice(97, 134),
        134,
    ) == (o.ODOMETRY, o.TRANSFORM, o.FIX, o.IMU, o.NUMBERS)
    offsets = (o._O_QUAT, o._O_POSE_COV, o._O_VEL, o._O_RATE, o._O_TWIST_COV)
    assert offsets == (3, 7, 43, 46, 49)
    assert (o._I_COV, o._I_RATE, o._I_RATE_COV, o._I_ACCEL_COV) == (101, 110, 113, 125)
