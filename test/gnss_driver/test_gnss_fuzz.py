"""No NMEA input breaks the GNSS core: hypothesis field values in valid-checksum sentences.

The fuzzed sentences are the templates of gnss_driver.fuzz with fields replaced; the checksum is
always right, so only the field checks (gnss_driver.plausibility) protect the arithmetic.
"""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gnss_driver.driver import DriverConfig, GnssDriver
from gnss_driver.fix_type import FixType
from gnss_driver.fuzz import (
    FIELD_CHARACTERS,
    SPECIAL_VALUES,
    TEMPLATES,
    FuzzSource,
    build,
    fields_of,
    output_problems,
)
from gnss_driver.reader import frame_sentence as nmea
from gnss_driver.solution import SolutionConfig

T0 = 1_700_000_000.0
LLQ_GRID = SolutionConfig(llq_projection="EPSG:25832")
#: The templates one second later: a complete epoch that closes the fuzzed one.
NEXT_EPOCH = b"".join(
    nmea(t.replace("123519.00", "123520.00").replace("218137.0", "218138.0")) for t in TEMPLATES
)

values = st.one_of(
    st.sampled_from(SPECIAL_VALUES),
    st.floats().map(repr),
    st.floats().map(lambda v: f"{v:.3f}"),
    st.integers().map(str),
    st.text(alphabet=FIELD_CHARACTERS, max_size=12),
)


@st.composite
def fuzzed_sentences(draw: st.DrawFn) -> bytes:
    fields = fields_of(draw(st.sampled_from(TEMPLATES)))
    first = 2 if fields[0] == "PASHR" else 1
    indices = st.integers(min_value=first, max_value=len(fields) - 1)
    for index in draw(st.lists(indices, min_size=1, max_size=4)):
        fields[index] = draw(values)
    return build(fields)


def run(stream: bytes) -> tuple[list, GnssDriver]:
    # LLQ positions on: its grid fields are fuzzed too.
    driver = GnssDriver(DriverConfig(baud=115200, solution=LLQ_GRID))
    outputs = driver.feed(stream, T0)
    outputs += driver.flush_idle(T0 + 10.0)
    return outputs, driver


def test_the_templates_are_valid_and_make_one_full_epoch():
    outputs, driver = run(b"".join(nmea(t) for t in TEMPLATES))
    assert driver.solver.fields.bad_fields == 0, driver.solver.fields.rejected
    assert driver.reader.stats.sentences == len(TEMPLATES)
    (out,) = outputs
    assert out.fix.fix_type is FixType.SPS and out.fix.accuracy_source == "GST"
    assert out.velocity is not None and out.attitude.source == "PASHR,PAT"
    assert output_problems(out) == []


@settings(max_examples=1000, deadline=None)
@given(st.lists(fuzzed_sentences(), min_size=1, max_size=6))
def test_fuzzed_fields_never_raise_and_outputs_stay_sound(sentences):
    outputs, driver = run(b"".join(sentences) + NEXT_EPOCH)
    assert driver.stats.internal_errors == 0, driver.stats.last_internal_error
    for out in outputs:
        assert output_problems(out) == []
    # The complete epoch after the fuzzed ones always comes out (maybe extended, if the fuzz
    # taught a smaller content): its fix from its GGA.
    last = [o for o in outputs if o.utc is not None and o.utc.utc_s % 86400 == 45320.0]
    assert [o.fix.fix_type for o in last if o.fix is not None] == [FixType.SPS]


GGA = TEMPLATES[0]


@pytest.mark.parametrize(
    ("bodies", "field"),
    [
        (
            (GGA, "GPGST,123519.00,0.006,0.023,0.020,273.6,1e-200,1e-200,0.031"),
            "GST.std_dev_latitude",
        ),
        (
            ("GPGGA,123519.00,4807.038,N,01131.000,W,1,08,1e200,545.4,M,46.9,M,,",),
            "GGA.horizontal_dil",
        ),
        (
            ("GPGGA,123519.00,4807.038,N,01131.000,W,1,08,0.0,545.4,M,46.9,M,,",),
            "GGA.horizontal_dil",
        ),
        ((GGA, "GPZDA,123519.00,100000000000000000000,03,1994,00,00"), "ZDA.day"),
        (
            ("GPRMC,123519.00,A,4807.038,N,01131.000,W,2000.0,084.4,230394,,,A",),
            "RMC.spd_over_grnd",
        ),
        ((GGA, "GPLLQ,123519.00,032394,1.0,M,2.0,M,3,12,0.0,76.69,M"), "LLQ.coord_quality"),
    ],
)
def test_the_reported_crashers_are_rejected_and_counted(bodies, field):
    outputs, driver = run(b"".join(nmea(b) for b in bodies) + NEXT_EPOCH)
    assert driver.stats.internal_errors == 0
    assert driver.solver.fields.rejected[field] == 1
    assert len(outputs) == 2 and all(output_problems(out) == [] for out in outputs)


def test_an_att_with_an_absurd_time_of_week_costs_only_itself():
    att = nmea("PASHR,ATT,1e306,274.07,+01.00,-02.00,0.0021,0.0123,0")
    outputs, driver = run(att + b"".join(nmea(t) for t in TEMPLATES))
    assert driver.solver.fields.rejected["PASHR,ATT.time_of_week"] == 1
    (out,) = outputs  # the rest of the chunk is read: one full epoch
    assert out.fix.fix_type is FixType.SPS and driver.reader.stats.sentences == 1 + len(TEMPLATES)


def test_a_gga_with_too_few_satellites_is_no_fix():
    gga = "GPGGA,123519.00,4807.038,N,01131.000,W,1,{},0.9,545.4,M,46.9,M,,"
    (out,), driver = run(nmea(gga.format("02")))
    assert out.fix.fix_type is FixType.NO_FIX and math.isnan(out.fix.lat_deg)
    assert driver.solver.stats.too_few_satellites == 1
    (out,), _ = run(nmea(gga.format("04")))
    assert out.fix.fix_type is FixType.SPS


def test_the_seeded_fuzz_source_is_reproducible_and_harmless():
    first, second = FuzzSource(7), FuzzSource(7)
    stream = b"".join(first.sentence() for _ in range(3000))
    assert stream == b"".join(second.sentence() for _ in range(3000))
    outputs, driver = run(stream)
    assert driver.stats.internal_errors == 0
    assert driver.reader.stats.bad_checksum == 0 and driver.reader.stats.sentences > 2000
    assert driver.solver.fields.bad_fields > 1000
    assert all(output_problems(out) == [] for out in outputs)
