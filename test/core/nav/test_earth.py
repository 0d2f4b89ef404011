"""Earth model: WGS-84 constants, radii, normal gravity, rates, frame conversions."""

from __future__ import annotations

import math

import numpy as np
import pymap3d
import pytest
from hypothesis import given
from hypothesis import strategies as st

from ins_fusion.core.nav import earth

LAT_57 = math.radians(57.0)


def test_wgs84_semi_minor_axis_matches_aalborg_notes():
    # Aalborg notes §10: b = 6356752.3 m.
    b = earth.SEMI_MAJOR_AXIS_M * (1.0 - earth.FLATTENING)
    assert b == pytest.approx(6356752.3, abs=0.05)


def test_radii_at_equator_and_pole():
    a, e2 = earth.SEMI_MAJOR_AXIS_M, earth.ECCENTRICITY_SQ
    r_m, r_n = earth.radii_m(0.0)
    assert r_n == pytest.approx(a)
    assert r_m == pytest.approx(a * (1.0 - e2))
    r_m, r_n = earth.radii_m(math.pi / 2)
    assert r_m == pytest.approx(r_n)  # both a/sqrt(1-e²) at the pole
    assert r_n == pytest.approx(a / math.sqrt(1.0 - e2))


def test_radii_accept_arrays_and_floats_alike():
    lats = np.radians([0.0, 30.0, 57.0, 80.0])
    r_m, r_n = earth.radii_m(lats)
    for i, lat in enumerate(lats):
        assert earth.radii_m(float(lat)) == pytest.approx((r_m[i], r_n[i]), rel=1e-15)


def test_radii_derivative_matches_finite_difference():
    h = 1e-6
    lat = LAT_57
    plus, minus = earth.radii_m(lat + h), earth.radii_m(lat - h)
    numeric = [(p - m) / (2 * h) for p, m in zip(plus, minus, strict=True)]
    assert earth.radii_derivative_m_per_rad(lat) == pytest.approx(numeric, rel=1e-6)


@pytest.mark.parametrize(
    ("lat_deg", "height_m", "expected"),
    [(57.0, 100.0, 9.8164), (57.0, 0.0, 9.8168), (57.03, 0.0, 9.8168), (56.0, 100.0, 9.8156)],
)
def test_normal_gravity_reproduces_aalborg_fig_c2(lat_deg, height_m, expected):
    # Aalborg notes §5.2 Fig. C-2 (the 56° entry corrected as in §12 item 9).
    g = earth.normal_gravity_m_s2(math.radians(lat_deg), height_m)
    assert g == pytest.approx(expected, abs=6e-5)


def test_normal_gravity_equator_pole_and_free_air_gradient():
    assert earth.normal_gravity_m_s2(0.0, 0.0) == pytest.approx(9.780327)
    assert earth.normal_gravity_m_s2(math.pi / 2, 0.0) == pytest.approx(9.832186, abs=1e-5)
    gradient = earth.normal_gravity_m_s2(LAT_57, 1000.0) - earth.normal_gravity_m_s2(LAT_57, 0.0)
    assert gradient == pytest.approx(-3.086e-3, rel=2e-3)


def test_earth_rate_ned():
    north, east, down = earth.earth_rate_ned_rad_s(LAT_57)
    assert math.hypot(north, down) == pytest.approx(7.292115e-5)
    assert east == 0.0
    assert down < 0.0 < north  # the rotation axis points up and north in the northern hemisphere


def test_transport_rate_third_component_uses_east_velocity():
    # Aalborg notes §12 item 8: -v_E tan(lat)/(R+h), not -v_N tan(lat)/(R+h).
    r_m, r_n = earth.radii_m(LAT_57)
    east_only = earth.transport_rate_ned_rad_s(LAT_57, 40.0, 0.0, 10.0)
    assert east_only == pytest.approx(
        (10.0 / (r_n + 40.0), 0.0, -10.0 * math.tan(LAT_57) / (r_n + 40.0)), rel=1e-12
    )
    north_only = earth.transport_rate_ned_rad_s(LAT_57, 40.0, 10.0, 0.0)
    assert north_only == pytest.approx((0.0, -10.0 / (r_m + 40.0), 0.0), rel=1e-12, abs=1e-20)


def test_mat_en_columns_are_ned_axes_in_ecef():
    lat, lon = LAT_57, math.radians(9.987)
    mat = earth.mat_en(lat, lon)
    assert mat @ mat.T == pytest.approx(np.eye(3), abs=1e-15)
    assert np.linalg.det(mat) == pytest.approx(1.0)
    up = np.array(pymap3d.enu2uvw(0.0, 0.0, 1.0, lat, lon, deg=False))
    assert -mat[:, 2] == pytest.approx(up, abs=1e-15)
    batch = earth.mat_en(np.array([lat, 0.1]), np.array([lon, 0.2]))
    assert batch.shape == (2, 3, 3)
    assert batch[0] == pytest.approx(mat)


@given(
    lat=st.floats(-1.5, 1.5),
    lon=st.floats(-3.1, 3.1),
    height=st.floats(-500.0, 9000.0),
)
def test_geodetic_ecef_round_trip(lat, lon, height):
    back = earth.ecef_to_geodetic(earth.geodetic_to_ecef(lat, lon, height))
    assert float(back[0]) == pytest.approx(lat, abs=1e-14)
    assert float(back[1]) == pytest.approx(lon, abs=1e-14)
    assert float(back[2]) == pytest.approx(height, abs=1e-6)


@given(east=st.floats(-5e3, 5e3), north=st.floats(-5e3, 5e3), up=st.floats(-100.0, 100.0))
def test_enu_round_trip(east, north, up):
    lat0, lon0, h0 = LAT_57, math.radians(9.987), 40.0
    lat, lon, h = earth.enu_to_geodetic(np.array([east, north, up]), lat0, lon0, h0)
    enu = earth.geodetic_to_enu(float(lat), float(lon), float(h), lat0, lon0, h0)
    assert enu == pytest.approx([east, north, up], abs=1e-6)


@given(
    st.floats(-1.4, 1.4),
    st.floats(-3.1, 3.1),
    st.floats(-100.0, 3000.0),
    st.tuples(st.floats(-5e-3, 5e-3), st.floats(-5e-3, 5e-3), st.floats(-500.0, 500.0)),
)
def test_tangent_plane_agrees_with_pymap3d(lat0, lon0, h0, offset):
    plane = earth.TangentPlane(lat0, lon0, h0)
    point = (lat0 + offset[0], lon0 + offset[1], h0 + offset[2])
    expected = earth.geodetic_to_enu(*point, lat0, lon0, h0)
    assert np.abs(plane.enu(*point) - expected).max() < 1e-6
