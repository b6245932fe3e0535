"""camsim.render.raw_render's own arithmetic: the clean layer's interpolation and the source's electrons."""

from __future__ import annotations

import numpy as np
import pytest
from colour_demosaicing import demosaicing_CFA_Bayer_bilinear

from camsim.render.raw_render import clean_planes, source_electrons
from camsim.sensor.cfa import CFA_PATTERNS


@pytest.mark.parametrize("pattern", CFA_PATTERNS)
def test_clean_planes_are_colour_demosaicings_bilinear_inside_the_frame(pattern):
    rng = np.random.default_rng(3)
    mosaic = rng.uniform(0, 1000, (12, 18)).astype(np.float32)
    reference = np.moveaxis(demosaicing_CFA_Bayer_bilinear(mosaic.astype(np.float64), pattern), -1, 0)
    planes = clean_planes(mosaic, pattern)
    assert planes.shape == (3, 12, 18) and planes.dtype == np.float32
    np.testing.assert_allclose(planes[:, 1:-1, 1:-1], reference[:, 1:-1, 1:-1], rtol=2e-6, atol=1e-3)


@pytest.mark.parametrize("pattern", CFA_PATTERNS)
def test_clean_planes_keep_each_site_exactly_and_interpolate_at_the_edges_from_the_same_colour(pattern):
    rng = np.random.default_rng(4)
    mosaic = rng.uniform(0, 1000, (8, 10)).astype(np.float32)
    planes = clean_planes(mosaic, pattern)
    for i, colour in enumerate(pattern):
        dy, dx = divmod(i, 2)
        c = "RGB".index(colour)
        np.testing.assert_array_equal(planes[c, dy::2, dx::2], mosaic[dy::2, dx::2])
    # a constant colour stays constant everywhere, edges included (the mirror keeps each site's colour)
    flat = np.empty((8, 10), dtype=np.float32)
    for i, colour in enumerate(pattern):
        flat[i // 2::2, i % 2::2] = 100.0 * (1 + "RGB".index(colour))
    planes = clean_planes(flat, pattern)
    for c in range(3):
        np.testing.assert_allclose(planes[c], 100.0 * (1 + c), rtol=1e-6)


def test_source_electrons_subtract_each_sites_black_and_divide_by_k():
    class Capture:  # what source_electrons reads of a RawCapture
        mosaic = np.array([[600, 700, 650, 16383], [800, 900, 512, 400]], dtype=np.uint16)
        black_dn = np.array([[500.0, 510.0], [520.0, 530.0]])
        white_dn = 16383.0

    electrons, masked = source_electrons(Capture, 0.5)
    expected = (Capture.mosaic.astype(np.float64) - np.tile(Capture.black_dn, (1, 2))) / 0.5
    np.testing.assert_allclose(electrons, expected, rtol=1e-7)
    assert electrons.dtype == np.float32
    np.testing.assert_array_equal(masked, Capture.mosaic >= 16383)
