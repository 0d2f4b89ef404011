"""Epoch assembly, UTC dates and the driver core's host stamps (gnss_driver.epoch/utc/driver)."""

from __future__ import annotations

import dataclasses
import datetime
import itertools
import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gnss_driver.driver import DriverConfig, GnssDriver
from gnss_driver.fix_type import FixType
from gnss_driver.reader import frame_sentence as nmea
from gnss_driver.utc import DateSource, UtcResolver, gps_time_of_week_to_time_of_day_ms

T0 = 1_700_000_000.0  # an arbitrary host time [s]


def gga(hhmmss: str, quality: int = 4, lat: str = "5702.12345,N") -> bytes:
    return nmea(f"GPGGA,{hhmmss},{lat},00959.54321,E,{quality},12,0.8,34.567,M,42.123,M,1.0,0001")


def vtg(kmph: float) -> bytes:
    return nmea(f"GPVTG,090.0,T,,M,,N,{kmph:.1f},K,D")


def llq(hhmmss: str, mmddyy: str = "051005") -> bytes:
    return nmea(f"GPLLQ,{hhmmss},{mmddyy},,M,,M,3,12,0.025,76.69,M")


def speeds(outputs) -> list[float]:
    return [round(o.velocity.vel_enu_m_s[0] * 3.6, 3) for o in outputs]


def test_leica_order_vtg_first_associates_each_vtg_with_its_own_epoch():
    driver = GnssDriver(DriverConfig())
    outputs = []
    for k in range(4):
        t = f"1234{10 + k}.00"
        outputs += driver.feed(vtg(10.0 + k) + gga(t) + llq(t), T0 + k)
    # Epoch 0 closes when the second VTG comes; from then on each closes at its last sentence.
    assert speeds(outputs) == [10.0, 11.0, 12.0, 13.0]
    assert [o.utc.utc_s % 60 for o in outputs] == [10.0, 11.0, 12.0, 13.0]
    assert driver.assembler.stats.epochs == 4
    assert driver.assembler.stats.late_sentences == 0


def test_gga_first_order_and_an_epoch_closed_by_idle_time():
    driver = GnssDriver(DriverConfig(epoch_idle_s=0.1))
    t = "123410.00"
    assert driver.feed(gga(t) + vtg(20.0) + llq(t), T0) == []
    assert driver.flush_idle(T0 + 0.05) == []
    (first,) = driver.flush_idle(T0 + 0.11)
    assert speeds([first]) == [20.0]
    # Two epochs closed by the idle line with the same content confirm it: from then on each
    # epoch is out as soon as its LLQ is in.
    assert driver.feed(gga("123411.00") + vtg(21.0) + llq("123411.00"), T0 + 1) == []
    (second,) = driver.flush_idle(T0 + 1.2)
    (third,) = driver.feed(gga("123412.00") + vtg(22.0) + llq("123412.00"), T0 + 2)
    assert speeds([second, third]) == [21.0, 22.0]


def hdt(deg: float) -> bytes:
    return nmea(f"GPHDT,{deg:.1f},T")


def zda(hhmmss: str) -> bytes:
    return nmea(f"GPZDA,{hhmmss},14,11,2023,00,00")


def test_idle_time_counts_every_byte_not_only_epoch_sentences():
    driver = GnssDriver(DriverConfig(epoch_idle_s=0.5))
    gsv = nmea("GPGSV,3,1,12,01,40,083,46,02,17,308,41,12,07,344,39,14,22,228,45")
    gst = nmea("GPGST,123410.00,0.006,0.023,0.020,273.6,0.023,0.020,0.031")
    assert driver.feed(gga("123410.00"), T0) == []
    for k in range(1, 8):  # a GSV block trickling in for 0.7 s
        driver.feed(gsv, T0 + 0.1 * k)
        assert driver.flush_idle(T0 + 0.1 * k + 0.05) == []
    driver.feed(gst[:20], T0 + 1.1)  # half a sentence is traffic too
    assert driver.flush_idle(T0 + 1.5) == []
    driver.feed(gst[20:], T0 + 1.2)
    (out,) = driver.flush_idle(T0 + 1.71)
    assert out.fix.accuracy_source == "GST"
    assert driver.assembler.stats.late_sentences == 0


def test_a_sentence_for_a_published_epoch_extends_it_and_the_next_epochs_wait_for_it():
    driver = GnssDriver(DriverConfig())
    outs = []
    for k in range(3):
        outs += driver.feed(gga(f"12000{k}.00") + vtg(1.0 + k), T0 + k)
    # Epochs 0 and 1 closed by the next GGA confirmed {GGA, VTG}: epoch 2 is out at its VTG.
    assert len(outs) == 3
    early = outs[-1]
    # The receiver also sends HDT and ZDA: they extend epoch 2 instead of being dropped.
    assert driver.feed(hdt(90.0) + zda("120002.00"), T0 + 2.1) == []
    (ext,) = driver.feed(gga("120003.00") + vtg(4.0) + hdt(91.0) + zda("120003.00"), T0 + 3)
    assert ext.extends and ext.stamp_s == early.stamp_s and ext.utc == early.utc
    assert ext.fix is None and ext.velocity is None  # published with the early close
    assert ext.attitude.source == "HDT"
    # Epoch 3 waited for HDT and ZDA; closed by epoch 4's GGA it confirms the new content.
    third, fourth = driver.feed(gga("120004.00") + vtg(5.0) + hdt(92.0) + zda("120004.00"), T0 + 4)
    assert speeds([third, fourth]) == [4.0, 5.0]
    assert third.attitude is not None and fourth.attitude is not None
    stats = driver.assembler.stats
    assert (stats.late_sentences, stats.extended_epochs, driver.stats.extensions) == (0, 1, 1)


def test_a_partial_first_epoch_does_not_teach_its_content():
    def gll(t: str) -> bytes:
        return nmea(f"GPGLL,5702.12345,N,00959.54321,E,{t},A,A")

    def rmc(t: str) -> bytes:
        return nmea(f"GPRMC,{t},A,5702.12345,N,00959.54321,E,010.0,090.0,141123,,,A")

    driver = GnssDriver(DriverConfig())
    # The stream starts in the middle of an epoch: only its GLL arrives whole.
    outs = driver.feed(gll("120000.00"), T0)
    for k in range(1, 5):
        t = f"12000{k}.00"
        outs += driver.feed(gll(t) + gga(t) + rmc(t), T0 + k)
    # Epochs 1 and 2 are closed by the next GLL (no early close taught by epoch 0), 3 and 4 at
    # their RMC: every epoch has its GGA.
    assert [o.fix.position_source for o in outs] == ["GLL"] + ["GGA"] * 4
    assert all(o.velocity is not None for o in outs[1:])
    assert driver.assembler.stats.late_sentences == 0


def test_duplicates_are_dropped_and_counted():
    driver = GnssDriver(DriverConfig())
    driver.feed(gga("120000.00") + gga("120000.00", lat="0000.00000,N") + vtg(1.0), T0)
    (out,) = driver.flush_idle(T0 + 1)
    assert out.fix.lat_deg == pytest.approx(57.0353908, abs=1e-6)
    assert driver.assembler.stats.duplicate_sentences == 1


def test_no_fix_without_a_time_is_published_as_no_fix_stamped_on_arrival():
    driver = GnssDriver(DriverConfig(baud=9600))
    chunk = nmea("GPGGA,,,,,,0,00,99.99,,,,,,") + nmea("GPVTG,,T,,M,,N,,K,N")
    driver.feed(chunk, T0)
    (out,) = driver.flush_idle(T0 + 1)
    assert out.utc is None
    assert out.fix.fix_type is FixType.NO_FIX
    assert math.isnan(out.fix.lat_deg) and math.isnan(out.fix.alt_m)
    assert out.velocity is None
    assert out.stamp_s == pytest.approx(T0 - len(chunk) * 10 / 9600)
    assert driver.assembler.stats.untimed_epochs == 1


# ---- UTC ------------------------------------------------------------------------------------
def test_midnight_rollover_carries_the_receiver_date_forward():
    driver = GnssDriver(DriverConfig())
    rmc = nmea("GPRMC,235959.50,A,3351.000,S,07040.500,W,010.0,090.0,311224,,,D")
    gga_after = nmea("GPGGA,000000.50,3351.000,S,07040.500,W,2,09,1.0,12.0,M,30.0,M,2.0,0100")
    outs = driver.feed(rmc + gga_after, T0)
    outs += driver.flush_idle(T0 + 1)
    # 2025-01-01T00:00:00Z = 1735689600 s
    assert [o.utc.utc_s for o in outs] == [1735689599.5, 1735689600.5]
    assert [o.utc.date_source for o in outs] == [DateSource.RECEIVER] * 2
    assert driver.utc.rollovers == 1


def test_date_sources_zda_rmc_llq_and_the_host():
    resolver = UtcResolver()
    assert resolver.resolve(0, datetime.date(2005, 10, 5), T0).utc_s == 1128470400.0
    # No date ever: the host day nearest the time of day (T0 = 2023-11-14T22:13:20Z).
    fresh = UtcResolver()
    late_evening = fresh.resolve((23 * 3600 + 59 * 60) * 1000, None, T0)
    assert late_evening.utc_s == 1700006340.0  # 2023-11-14T23:59:00Z
    assert late_evening.date_source is DateSource.HOST
    just_after = UtcResolver().resolve(1000, None, 1700006390.0)  # host 23:59:50
    assert just_after.utc_s == 1700006401.0  # 2023-11-15T00:00:01Z, the next day
    # A late epoch from before midnight after the rollover goes back a day.
    back = resolver.resolve((23 * 3600 + 59 * 60 + 59) * 1000, None, T0)
    assert back.utc_s == 1128470399.0


def test_zda_and_llq_dates_in_the_stream():
    driver = GnssDriver(DriverConfig())
    zda = nmea("GPZDA,235959.00,31,12,2024,00,00")
    driver.feed(gga("235959.00") + zda, T0)
    (out,) = driver.flush_idle(T0 + 1)
    assert out.utc.utc_s == 1735689599.0
    driver = GnssDriver(DriverConfig())
    driver.feed(gga("120000.00") + llq("120000.00", "111414"), T0)  # Leica mmddyy
    (out,) = driver.flush_idle(T0 + 1)
    assert out.utc.utc_s == 1415966400.0  # 2014-11-14T12:00:00Z


def test_gps_time_of_week_to_utc_time_of_day():
    # Tuesday 12:00:18 GPS = 12:00:00 UTC with 18 leap seconds.
    tow = 2 * 86400 + 12 * 3600 + 18
    assert gps_time_of_week_to_time_of_day_ms(tow, 18) == 12 * 3600 * 1000
    assert gps_time_of_week_to_time_of_day_ms(10.0, 18) == (86400 - 8) * 1000  # before midnight


def test_pat_and_att_of_the_same_instant_form_one_epoch():
    driver = GnssDriver(DriverConfig())
    pat = nmea(
        "PASHR,PAT,120000.00,5702.12345,N,00959.54321,E,+00076.69,045.000,+01.00,-02.00,"
        "0.0021,0.0123,0"
    )
    att = nmea(f"PASHR,ATT,{2 * 86400 + 12 * 3600 + 18:.1f},045.0,1.0,-2.0,0.0021,0.0123,0")
    driver.feed(pat + att, T0)
    (out,) = driver.flush_idle(T0 + 1)
    assert out.attitude.source == "PASHR,PAT"
    assert driver.assembler.stats.duplicate_sentences == 0


# ---- host stamps ----------------------------------------------------------------------------
def test_stamps_follow_the_lower_envelope_of_arrival_minus_wire_time():
    baud, latency, offset = 9600, 0.05, 1000.123  # host = UTC + offset at the first byte
    driver = GnssDriver(DriverConfig(baud=baud, latency_s=latency))
    delays = [0.030, 0.0, 0.012, 0.0, 0.050, 0.004, 0.0, 0.021, 0.0, 0.007, 0.0, 0.015]
    stamps, utcs = [], []
    for k, delay in enumerate(delays):
        t = f"1200{k:02d}.00"
        first_byte = 1_415_966_400.0 + k + offset  # 2014-11-14 12:00:kk UTC
        wire = 0
        for sentence in (vtg(10.0), gga(t), llq(t, "111414")):
            wire += len(sentence)
            # Each sentence is read when its last byte is in, plus a positive OS delay.
            for out in driver.feed(sentence, first_byte + wire * 10 / baud + delay):
                stamps.append(out.stamp_s)
                utcs.append(out.utc.utc_s)
    # Once two zero-delay epochs span the window's mean time, the mapping is exact:
    # stamp = UTC + offset - latency, whatever the other epochs' delays.
    errors = [s - (u + offset - latency) for s, u in zip(stamps, utcs, strict=True)]
    assert len(errors) == len(delays)
    assert errors[0] == pytest.approx(0.030)  # the first epoch only knew its own delay
    assert all(abs(e) < 1e-6 for e in errors[3:]), errors
    assert driver.clock_offset_s() == pytest.approx(offset, abs=1e-6)
    assert driver.clock.skew == pytest.approx(0.0, abs=1e-9)


@settings(max_examples=100, deadline=None)
@given(
    st.lists(st.integers(min_value=1, max_value=120), min_size=1, max_size=400),
    st.sampled_from([("VTG", "GGA", "LLQ"), ("GGA", "VTG", "LLQ"), ("GGA", "LLQ", "VTG")]),
)
def test_any_chunking_and_sentence_order_gives_one_output_per_epoch(sizes, order):
    """Every epoch comes out once, with its own VTG, however the bytes are split."""
    epochs = 8
    stream, ends = b"", []
    for k in range(epochs):
        t = f"1200{k:02d}.00"
        parts = {"VTG": vtg(10.0 + k), "GGA": gga(t), "LLQ": llq(t)}
        stream += b"".join(parts[name] for name in order)
        ends.append(len(stream))
    driver = GnssDriver(DriverConfig(baud=9600, epoch_idle_s=0.5))
    outputs, pos = [], 0
    for size in itertools.cycle(sizes):
        if pos >= len(stream):
            break
        # Reads never span the quiet second between two epochs.
        epoch = next(k for k, end in enumerate(ends) if pos < end)
        chunk = stream[pos : min(pos + size, ends[epoch])]
        pos += len(chunk)
        outputs += driver.flush_idle(T0 + epoch)
        outputs += driver.feed(chunk, T0 + epoch + 0.3 * pos / len(stream))
    outputs += driver.flush_idle(T0 + epochs + 1)
    assert [round(o.utc.utc_s % 60) for o in outputs] == list(range(epochs))
    assert speeds(outputs) == [10.0 + k for k in range(epochs)]
    assert driver.assembler.stats.late_sentences == 0


def test_use_gnss_time_stamps_with_the_utc_and_still_measures_the_host_offset():
    baud, latency, offset = 9600, 0.05, 0.0423  # host = UTC + 42.3 ms at the first byte
    config = DriverConfig(baud=baud, latency_s=latency)
    envelope, gnss = GnssDriver(config), GnssDriver(dataclasses.replace(config, use_gnss_time=True))
    compared = 0
    for k in range(12):
        t = f"1200{k:02d}.00"
        first_byte = 1_415_966_400.0 + k + offset
        wire = 0
        for sentence in (vtg(10.0), gga(t), llq(t, "111414")):
            wire += len(sentence)
            arrival = first_byte + wire * 10 / baud + 0.003 * (k % 3)
            for a, b in zip(
                envelope.feed(sentence, arrival), gnss.feed(sentence, arrival), strict=True
            ):
                assert b.stamp_s == b.utc.utc_s  # the UTC instant itself
                assert b.host_s == a.host_s == a.stamp_s  # the envelope as before
                compared += 1
    assert compared == 12
    assert gnss.clock_offset_s() == pytest.approx(offset, abs=1e-6)
