"""gnss_driver.sentences and gnss_driver.reader: proprietary classes, framing, counters, fuzzing.

Golden sentences carry their checksums literally; the Trimble GST and Leica LLQ lines are the
manufacturers' published examples, so their checksums are independent of our code.
"""

from __future__ import annotations

import datetime
import itertools

import pynmea2
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gnss_driver.reader import MAX_LINE_BYTES, NmeaReader, nmea_checksum
from gnss_driver.sentences import (
    ASHRACK,
    ASHRATT,
    ASHRNAK,
    ASHRPAT,
    LLQ,
    FieldError,
    lat_lon_deg,
    number,
    parse,
    sentence_id,
    time_of_day_ms,
)

GGA_SOUTH_EAST = b"$GPGGA,184353.07,1929.045,S,02410.506,E,1,04,2.6,100.00,M,-33.9,M,,0000*6D"
GGA_NORTH_WEST = b"$GPGGA,123519.00,4807.038,N,01131.000,W,5,10,0.9,545.4,M,46.9,M,1.2,0001*5A"
RMC_SOUTH_WEST = b"$GPRMC,235959.50,A,3351.000,S,07040.500,W,010.0,090.0,311224,,,D*5D"
GST_TRIMBLE = b"$GPGST,172814.0,0.006,0.023,0.020,273.6,0.023,0.020,0.031*6A"
LLQ_LEICA = b"$GPLLQ,154324.00,111414,546629.232,M,5250781.577,M,1,09,3.876,366.549,M*05"
PAT = (
    b"$PASHR,PAT,123519.20,5702.12345,N,00959.54321,E,+00076.69,045.000,+01.00,-02.00,"
    b"0.0021,0.0123,0*0C"
)
VTG_EMPTY = b"$GPVTG,,T,,M,,N,,K,N*2C"
GOLDEN = [GGA_SOUTH_EAST, GGA_NORTH_WEST, RMC_SOUTH_WEST, GST_TRIMBLE, LLQ_LEICA, PAT, VTG_EMPTY]


def _one(line: bytes) -> pynmea2.NMEASentence:
    reads = NmeaReader().feed(line + b"\r\n")
    assert len(reads) == 1
    assert reads[0].wire_bytes == len(line) + 2
    return reads[0].sentence


def test_southern_eastern_gga():
    gga = _one(GGA_SOUTH_EAST)
    # 19°29.045' S = -(19 + 29.045/60); 24°10.506' E = 24 + 10.506/60
    assert lat_lon_deg(gga) == pytest.approx((-19.4840833333, 24.1751), abs=1e-9)
    assert time_of_day_ms(gga) == (18 * 3600 + 43 * 60 + 53) * 1000 + 70
    assert number(gga, "altitude") == 100.0
    assert number(gga, "geo_sep") == -33.9


def test_northern_western_and_southern_western_positions():
    assert lat_lon_deg(_one(GGA_NORTH_WEST)) == pytest.approx((48.1173, -11.5166667), abs=1e-7)
    # 33°51.000' S, 70°40.500' W
    assert lat_lon_deg(_one(RMC_SOUTH_WEST)) == pytest.approx((-33.85, -70.675), abs=1e-12)


def test_leica_llq_is_talker_independent_with_an_mmddyy_date():
    llq = _one(LLQ_LEICA)
    assert isinstance(llq, LLQ)
    assert llq.datestamp == datetime.date(2014, 11, 14)
    assert (llq.gps_qual, llq.num_sats, llq.coord_quality) == (1, 9, 3.876)
    assert (llq.easting, llq.northing, llq.height) == (546629.232, 5250781.577, 366.549)
    gn = parse("$GNLLQ,154149.00,111414,546629.191,M,5250782.727,M,1,20,3.880,367.387,M")
    assert isinstance(gn, LLQ) and gn.talker == "GN" and gn.num_sats == 20


def test_ashtech_pat_fields_in_the_order_of_the_notes():
    pat = _one(PAT)
    assert isinstance(pat, ASHRPAT)
    assert lat_lon_deg(pat) == pytest.approx((57 + 2.12345 / 60, 9 + 59.54321 / 60), abs=1e-12)
    values = [pat.altitude, pat.heading, pat.pitch, pat.roll, pat.mrms, pat.brms, pat.reset_flag]
    assert values == [76.69, 45.0, 1.0, -2.0, 0.0021, 0.0123, 0]
    assert sentence_id(pat) == "PASHR,PAT"


def test_adu5_att_is_not_read_as_the_rt300_sentence():
    att = parse("$PASHR,ATT,345123.5,123.4,1.2,-0.5,0.0021,0.012,0")
    assert isinstance(att, ASHRATT)
    assert (att.time_of_week, att.heading, att.pitch, att.roll) == (345123.5, 123.4, 1.2, -0.5)
    assert (att.mrms, att.brms, att.reset_flag) == (0.0021, 0.012, 0)
    # pynmea2's own class still takes the RT300 sentence, which has a time where ATT stands.
    rt300 = parse("$PASHR,145719.272,252.41,T,1.22,0.48,0.01,0.090,0.090,0.116,2,1")
    assert type(rt300).__module__.startswith("pynmea2")
    assert rt300.true_heading == 252.41
    assert sentence_id(rt300) == "PASHR"


def test_ack_and_nak_answers():
    assert isinstance(_one(b"$PASHR,ACK*3D"), ASHRACK)
    assert isinstance(_one(b"$PASHR,NAK*30"), ASHRNAK)


def test_empty_and_malformed_fields():
    gga = parse("$GPGGA,,,,,,0,00,99.99,,,,,,")
    assert lat_lon_deg(gga) is None
    assert time_of_day_ms(gga) is None
    assert number(gga, "altitude") is None
    with pytest.raises(FieldError):
        lat_lon_deg(parse("$GPGGA,123519,4807.038,,01131.000,E,1,08,0.9,545.4,M,46.9,M,,"))
    with pytest.raises(FieldError):  # 61 minutes
        lat_lon_deg(parse("$GPGGA,123519,4861.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,"))
    with pytest.raises(FieldError):
        number(parse("$GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,5x5,M,46.9,M,,"), "altitude")
    with pytest.raises(FieldError):  # 25 o'clock
        time_of_day_ms(parse("$GPGGA,253519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,"))


def test_every_kind_of_bad_input_is_counted_and_the_good_lines_survive():
    good = GGA_SOUTH_EAST + b"\r\n"
    stream = (
        b"\x00\xff\xfe junk"  # garbage before the first sentence
        + good
        + GGA_SOUTH_EAST[:-1]
        + b"E\r\n"  # bad checksum (6E)
        + GGA_SOUTH_EAST[:-3]
        + b"\r\n"  # missing checksum
        + GGA_SOUTH_EAST[:30]  # cut by the next '$'
        + good
        + b"$GP"
        + b"A" * (MAX_LINE_BYTES + 10)
        + b"\r\n"  # overlong
        + b"$GPXYZ,1,2*"
        + b"%02X" % nmea_checksum(b"GPXYZ,1,2")
        + b"\r\n"  # unknown type
        + b"$PXXXX,1*"
        + b"%02X" % nmea_checksum(b"PXXXX,1")
        + b"\r\n"  # unknown maker
        + b"$GP\x01GGA,1*00\r\n"  # binary inside a line
        + b"$PASHR*"
        + b"%02X" % nmea_checksum(b"PASHR")
        + b"\r\n"  # pynmea2 fails on it
        + good
    )
    reader, lines = NmeaReader(), []
    reads = reader.feed(stream, lines)
    assert [r.sentence.render().encode() for r in reads] == [GGA_SOUTH_EAST] * 3
    # Every line as received, rejected or not; only the overlong one is left out.
    assert lines == [
        GGA_SOUTH_EAST,
        GGA_SOUTH_EAST[:-1] + b"E",
        GGA_SOUTH_EAST[:-3],
        GGA_SOUTH_EAST[:30],
        GGA_SOUTH_EAST,
        b"$GPXYZ,1,2*%02X" % nmea_checksum(b"GPXYZ,1,2"),
        b"$PXXXX,1*%02X" % nmea_checksum(b"PXXXX,1"),
        b"$GP\x01GGA,1*00",
        b"$PASHR*%02X" % nmea_checksum(b"PASHR"),
        GGA_SOUTH_EAST,
    ]
    assert reader.stats.rejected() == {
        "garbage": 2,
        "truncated": 1,
        "overlong": 1,
        "bad_checksum": 1,
        "missing_checksum": 1,
        "unknown_sentence": 2,
        "malformed": 1,
    }
    assert reader.stats.by_type == {"GGA": 3}
    assert reader.buffered == 0


def test_missing_checksum_is_accepted_only_when_allowed():
    line = GGA_SOUTH_EAST[:-3] + b"\r\n"
    assert NmeaReader(allow_missing_checksum=False).feed(line) == []
    reader = NmeaReader(allow_missing_checksum=True)
    reads = reader.feed(line)
    assert len(reads) == 1 and reads[0].sentence.gps_qual == 1
    assert reader.stats.missing_checksum == 1


def test_lowercase_checksum_digits_and_cr_or_lf_alone_end_a_line():
    lower = GGA_SOUTH_EAST[:-2] + b"6d"
    reads = NmeaReader().feed(lower + b"\n" + GGA_SOUTH_EAST + b"\r" + GGA_SOUTH_EAST + b"\n")
    assert len(reads) == 3


def test_an_overlong_line_is_dropped_until_the_next_dollar_without_counting_garbage():
    reader = NmeaReader()
    assert reader.feed(b"$GPGGA," + b"9" * 300) == []
    assert reader.buffered == 0
    assert reader.feed(b"99,junk-that-belongs-to-the-long-line\r\n" + GGA_SOUTH_EAST + b"\r\n")
    assert reader.stats.overlong == 1
    assert reader.stats.garbage == 0


# ---- fuzzing ----------------------------------------------------------------------------------
_GOOD_LINES = st.sampled_from([line + b"\r\n" for line in GOLDEN])
_NOISE = st.binary(max_size=40)


def _feed_in_chunks(
    data: bytes, cuts: list[int], lines: list[bytes] | None = None
) -> tuple[list[bytes], NmeaReader]:
    reader = NmeaReader()
    out: list[bytes] = []
    bounds = sorted({0, len(data), *(c % (len(data) + 1) for c in cuts)})
    for start, end in itertools.pairwise(bounds):
        out += [r.sentence.render().encode() for r in reader.feed(data[start:end], lines)]
        assert reader.buffered <= MAX_LINE_BYTES
    return out, reader


@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=2000), st.lists(st.integers(min_value=0), max_size=30))
def test_fuzz_arbitrary_bytes_never_raise_and_chunking_does_not_matter(data, cuts):
    lines_whole: list[bytes] = []
    lines_split: list[bytes] = []
    whole, reader_whole = _feed_in_chunks(data, [], lines_whole)
    split, reader_split = _feed_in_chunks(data, cuts, lines_split)
    assert whole == split
    assert lines_whole == lines_split
    assert all(line.startswith(b"$") and len(line) <= MAX_LINE_BYTES for line in lines_whole)
    assert len(lines_whole) >= reader_whole.stats.sentences
    assert reader_whole.stats == reader_split.stats
    assert reader_whole.stats.sentences == len(whole)


@settings(max_examples=300, deadline=None)
@given(
    st.lists(st.tuples(_NOISE, _GOOD_LINES), max_size=12),
    st.lists(st.integers(min_value=0), max_size=20),
)
def test_fuzz_valid_sentences_survive_any_garbage_between_them(pieces, cuts):
    data = b"".join(noise + line for noise, line in pieces)
    expected = [line[:-2] for _, line in pieces]
    got, _ = _feed_in_chunks(data, cuts)
    # Every inserted sentence comes out, in order; random noise cannot forge a checksummed one.
    assert got == expected
