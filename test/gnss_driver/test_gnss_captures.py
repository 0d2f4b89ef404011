"""Captures fed byte by byte at 4800, 9600 and 115200 baud: nothing late, any chunking alike.

The fixtures (test/data/gnss, written by make_captures.py) are a mixed-rate INS (GGA/VTG 10 Hz,
RMC/HDT/ZDA 1 Hz), a u-blox-style set with a long GSV block and GST last, and a SiRF-style set
whose capture starts with a cut line. At 4800 baud the first two do not fit the line: the
receiver's queue grows, sentences arrive later and later, and still none may be lost.
"""

from __future__ import annotations

import json
import math
import os
import random

import pytest
from support.nmea_captures import CAPTURES, DATA, chunk_ends, feed, on_the_wire

from gnss_driver.driver import DriverConfig, GnssDriver
from gnss_driver.epoch import EPOCH_TYPES
from gnss_driver.fix_type import FixType

START_S = 1_699_965_319.0  # 2023-11-14T12:35:19Z, the captures' first epoch
BAUDS = (4800, 9600, 115200)


def run(name: str, baud: int, max_bytes: int, seed: int | None = None):
    stream, times = on_the_wire(name, baud, START_S + 100.0)  # host clock 100 s ahead of UTC
    driver = GnssDriver(DriverConfig(baud=baud))
    rng = random.Random(seed) if seed is not None else None
    return feed(driver, stream, times, chunk_ends(times, max_bytes, rng)), driver


def content(outputs) -> list[str]:
    return [repr((o.utc, o.fix, o.velocity, o.attitude, o.extends)) for o in outputs]


def summary(out) -> dict:
    """What a golden file holds of an output (rounded to the sentences' resolution)."""
    fix, vel, att = out.fix, out.velocity, out.attitude
    return {
        "utc": round(out.utc.utc_s - START_S, 3),
        "extends": out.extends,
        "fix": None
        if fix is None
        else [fix.fix_type.name, fix.position_source, fix.accuracy_source, fix.satellites]
        + [None if math.isnan(v) else round(v, 9) for v in (fix.lat_deg, fix.lon_deg)]
        + [None if math.isnan(fix.alt_m) else round(fix.alt_m, 3)],
        "velocity": None if vel is None else [vel.source, *(round(v, 3) for v in vel.vel_enu_m_s)],
        "attitude": None if att is None else att.source,
    }


@pytest.mark.parametrize("name", CAPTURES)
def test_golden_output_at_every_baud_rate(name):
    """The outputs (all but their stamps) match the golden file at 4800, 9600 and 115200 baud;
    ``GNSS_UPDATE_GOLDEN=1`` rewrites it from 115200 baud."""
    path = DATA / f"{name}.golden.json"
    outputs = {baud: [summary(o) for o in run(name, baud, 1)[0]] for baud in BAUDS}
    if os.environ.get("GNSS_UPDATE_GOLDEN"):
        path.write_text(json.dumps(outputs[115200], indent=1) + "\n")
    golden = json.loads(path.read_text())
    for baud in BAUDS:
        assert outputs[baud] == golden, baud


@pytest.mark.parametrize("baud", BAUDS)
@pytest.mark.parametrize("name", CAPTURES)
def test_no_sentence_is_lost_and_any_chunking_gives_the_same_output(name, baud):
    outputs, driver = run(name, baud, 1)
    stats = driver.assembler.stats
    epoch_names = {cls.__name__ for cls in EPOCH_TYPES} | {"LLQ", "PASHR,PAT", "PASHR,ATT"}
    read = sum(n for kind, n in driver.reader.stats.by_type.items() if kind in epoch_names)
    assert (stats.late_sentences, stats.duplicate_sentences) == (0, 0)
    assert stats.sentences == read  # every epoch sentence went into an epoch
    assert driver.stats.internal_errors == 0
    for seed, max_bytes in ((1, 7), (2, 64), (3, 4096)):
        other, _ = run(name, baud, max_bytes, seed)
        assert content(other) == content(outputs)
        # Stamps come from the arrival of whole reads, so they may differ by one read's time.
        stamps = [a.stamp_s - b.stamp_s for a, b in zip(other, outputs, strict=True)]
        assert max(map(abs, stamps)) <= max_bytes * 10.0 / baud + 1e-6


@pytest.mark.parametrize("baud", BAUDS)
def test_mixed_rates_keep_every_hdt_zda_and_rmc(baud):
    outputs, _ = run("mixed_rate_oxts", baud, 1)
    fixes = [o for o in outputs if o.fix is not None]
    assert len(fixes) == 60 and len({o.utc for o in fixes}) == 60  # each GGA once
    assert all(o.fix.fix_type is FixType.SPS for o in fixes)
    attitudes = [o for o in outputs if o.attitude is not None]
    assert [round(o.utc.utc_s - START_S, 3) for o in attitudes] == [0, 1, 2, 3, 4, 5]
    assert all(o.utc.date_source == "receiver" for o in outputs)
    assert len([o for o in outputs if o.velocity is not None]) == 60


@pytest.mark.parametrize("baud", BAUDS)
def test_a_gsv_block_does_not_cost_the_gst_after_it(baud):
    outputs, _ = run("ublox_gsv_block", baud, 1)
    assert [o.fix.accuracy_source for o in outputs] == ["GST"] * 6
    assert all(o.velocity is not None for o in outputs)


@pytest.mark.parametrize("baud", BAUDS)
def test_a_cut_first_line_costs_only_the_cut_epoch(baud):
    outputs, driver = run("cut_first_line", baud, 1)
    sources = [o.fix.position_source for o in outputs]
    assert sources == ["GLL"] + ["GGA"] * 6
    assert all(o.velocity is not None for o in outputs[1:])
    assert driver.reader.stats.garbage == 1  # the cut line's tail
