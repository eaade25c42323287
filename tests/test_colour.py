"""Band images to display colour through the CIE 1931 colour-matching functions."""
import numpy as np
import pytest

from photic.colour import band_matrix, bands_to_rgb, cmf
from analytic import trapezoid


def test_analytic_cmf_spot_values():
    """Against CIE 1931 2-degree table values (within the fit's ~1 %, a few % in the tails)."""
    x, y, z = cmf([555.0]).T
    assert y[0] == pytest.approx(1.0, abs=0.01)           # CIE: 1.0000 at 555 nm
    x, y, z = cmf([600.0])[0]
    assert (x, y) == pytest.approx((1.0622, 0.631), abs=0.02)   # CIE: 1.0622, 0.6310
    x, y, z = cmf([450.0])[0]
    assert (x, y, z) == pytest.approx((0.3362, 0.038, 1.7721), abs=0.04)
    areas = trapezoid(cmf(np.arange(360, 831.0)), np.arange(360, 831.0), axis=0)
    assert areas == pytest.approx((106.86, 106.86, 106.86), rel=0.02)  # equal areas (E white)


def test_flat_spectrum_is_grey_and_single_bands_have_their_hue():
    bands = [(c, 20.0) for c in range(410, 711, 20)]
    flat = bands_to_rgb(np.full(len(bands), 0.7), bands)
    np.testing.assert_allclose(flat, 0.7, rtol=1e-12)
    m = band_matrix(bands)
    red, green, blue = m[[i for i, (c, _) in enumerate(bands) if c == 630][0]], \
        m[[i for i, (c, _) in enumerate(bands) if c == 530][0]], m[[i for i, (c, _) in enumerate(bands) if c == 450][0]]
    assert red[0] > red[1] and red[0] > red[2]
    assert green[1] > green[0] and green[1] > green[2]
    assert blue[2] > blue[0] and blue[2] > blue[1]


def test_bands_outside_the_visible_are_refused():
    with pytest.raises(ValueError, match="visible"):
        band_matrix([(900.0, 10.0), (950.0, 10.0)])
