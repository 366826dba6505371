"""WGS-84 Earth model against published values and closed-form relations."""
import numpy as np
import pytest

from sins_align_ros.nav import earth
from sins_align_ros.units import DEG


def test_normal_gravity_matches_wgs84_table():
    # TR8350.2: equator 9.7803253359, pole 9.8321849378 m/s^2
    assert earth.gravity(0.0, 0.0) == pytest.approx(9.7803253359, abs=1e-9)
    assert earth.gravity(90 * DEG, 0.0) == pytest.approx(9.8321849378, abs=1e-8)
    # free-air gradient about -3.086e-6 (m/s^2)/m at mid latitudes
    dg = earth.gravity(45 * DEG, 1000.0) - earth.gravity(45 * DEG, 0.0)
    assert dg == pytest.approx(-3.0867e-3, rel=2e-3)


def test_radii_at_equator_and_pole():
    R_M, R_N = earth.radii(0.0)
    assert R_N == pytest.approx(earth.A)
    assert R_M == pytest.approx(earth.A * (1 - earth.E2))
    R_M, R_N = earth.radii(90 * DEG)
    assert R_M == pytest.approx(R_N)          # both equal a^2/b at the pole
    b = earth.A * (1 - earth.F)
    assert R_N == pytest.approx(earth.A ** 2 / b)


def test_earth_rate_components_and_norm():
    lat = 34 * DEG
    w = earth.w_ie_n(lat)
    assert np.linalg.norm(w) == pytest.approx(earth.OMEGA_IE)
    assert w[0] == 0.0
    assert w[2] / w[1] == pytest.approx(np.tan(lat))


def test_transport_rate_is_rotation_of_local_level_frame():
    # moving north at v, the ENU frame turns about east by -v/(R_M+h): dlat/dt = -w_en_E
    lat, h, v = 30 * DEG, 100.0, np.array([3.0, 7.0, 0.0])
    w_en = earth.w_en_n(lat, h, v)
    rate = earth.position_rate(lat, h, v)
    assert w_en[0] == pytest.approx(-rate[0])
    assert w_en[1] == pytest.approx(rate[1] * np.cos(lat))
    assert w_en[2] == pytest.approx(rate[1] * np.sin(lat))


def test_vectorised_shapes():
    lat = np.linspace(-1, 1, 5)
    assert earth.w_ie_n(lat).shape == (5, 3)
    assert earth.gravity_n(lat, np.zeros(5)).shape == (5, 3)
    assert earth.w_en_n(lat, np.zeros(5), np.ones((5, 3))).shape == (5, 3)
