"""photic.solar: the sun's position and a clear sky's direct beam (the Clear-Sky Sun helper).

Checked against what is known in closed form: the declination at the solstices and equinoxes,
the zenith at solar noon (|latitude - declination|), the sun due south at noon north of the
tropics, the black body's integral, and the clear sky's transmittance falling with air mass and
towards the blue."""
import math
from datetime import datetime, timezone

import numpy as np
import pytest

from photic import solar
from analytic import trapezoid


def test_declination_and_noon_zenith():
    assert solar.declination_deg(datetime(2026, 6, 21, 12)) == pytest.approx(23.44, abs=0.1)
    assert solar.declination_deg(datetime(2026, 12, 21, 12)) == pytest.approx(-23.44, abs=0.1)
    assert abs(solar.declination_deg(datetime(2026, 3, 20, 12))) < 0.7
    # solar noon at Greenwich (12:07 UTC: the equation of time), equinox: zenith = latitude
    for lat in (0.0, 30.0, 51.48, -45.0):
        zen, az = solar.solar_position(lat, 0.0, datetime(2026, 3, 20, 12, 7, tzinfo=timezone.utc))
        decl = solar.declination_deg(datetime(2026, 3, 20, 12, 7))
        assert zen == pytest.approx(abs(lat - decl), abs=0.3), lat
        if lat > 5:  # due south: -y, 270 deg counterclockwise from east
            assert az == pytest.approx(270.0, abs=1.0)
        if lat < -5:  # due north
            assert az == pytest.approx(90.0, abs=1.0)


def test_morning_sun_is_in_the_east():
    zen, az = solar.solar_position(40.0, 0.0, datetime(2026, 3, 20, 7, 0))
    assert 60.0 < zen < 90.0 and (az < 30.0 or az > 330.0), (zen, az)


def test_spectrum_and_transmittance():
    lam = np.array([400.0, 450.0, 550.0, 650.0, 700.0])
    e0 = solar.extraterrestrial(lam)
    assert np.all(e0 > 1.0) and np.all(e0 < 2.2)  # W m^-2 nm^-1, near the measured 1.4-2.0
    grid = np.linspace(200.0, 4000.0, 20000)
    assert trapezoid(solar.extraterrestrial(grid, 80), grid) == pytest.approx(1361.0 * 0.97, rel=0.03)
    high, low = solar.clear_sky_direct(lam, 20.0), solar.clear_sky_direct(lam, 70.0)
    assert np.all(low < high) and np.all(high < e0)
    t = high / e0
    assert np.all(np.diff(t) > 0)  # the atmosphere takes more blue than red
    assert solar.air_mass(0.0) == pytest.approx(1.0, abs=1e-3)
    assert solar.air_mass(60.0) == pytest.approx(2.0, rel=0.01)
    assert np.all(solar.clear_sky_direct(lam, 95.0) == 0.0)
    assert np.all(solar.clear_sky_direct(lam, 30.0, aerosol_beta=0.3) < solar.clear_sky_direct(lam, 30.0))
    with pytest.raises(ValueError, match="latitude"):
        solar.solar_position(95.0, 0.0, datetime(2026, 1, 1))
    with pytest.raises(ValueError, match="wavelengths"):
        solar.clear_sky_direct([100.0], 30.0)
