"""camsim.sensor.dn_law: the digital number's pmf against independent closed forms, and against rendered frames."""

import numpy as np
import pytest
from scipy import stats

from camsim.render.frame import render_frame
from camsim.sensor.dn_law import charge_pmf, dn_pmf
from camsim.sensor.expected import expected_signal
from camsim.sensor.params import PRESETS, preset
from tests.support.theory import digital_pmf, digital_pmf_without_read_noise

TABLE1 = PRESETS["paper-table1"]


@pytest.mark.parametrize("lam", [0.0, 0.4, 7.0, 230.0, 4000.0, 8990.0, 9000.0, 9400.0, 2e5])
@pytest.mark.parametrize("k, full_well, bits", [(TABLE1.dn_per_electron, 9000.0, 8), (0.25, 700.5, 8),
                                                (3.0, 1000.0, 12), (1.0, 9000.0, 16)])
def test_pmf_without_read_noise_is_the_poisson_cdf_at_the_level_edges(lam, k, full_well, bits):
    law = dn_pmf(lam, k, 0.0, full_well, bits)
    expected = digital_pmf_without_read_noise(lam, k, full_well, bits)
    np.testing.assert_allclose(law.dense(2**bits), expected, rtol=0, atol=1e-12)


@pytest.mark.parametrize("lam", [0.4, 30.0, 230.0, 8990.0, 9050.0])
@pytest.mark.parametrize("read", [0.6, 4.0, 40.0])
def test_pmf_with_read_noise_is_the_sum_over_charges(lam, read):
    law = dn_pmf(lam, TABLE1.dn_per_electron, read, 9000.0, 8)
    np.testing.assert_allclose(law.dense(256), digital_pmf(lam, TABLE1.dn_per_electron, read, 9000.0, 8),
                               rtol=0, atol=1e-11)
    assert abs(law.pmf.sum() - 1) < 1e-12


def test_unclipped_pmf_moments():
    """bits None, no full well: I = floor(k (N + R)). With k = 1 and R = 0 it is N itself; with read noise the
    mean of floor(Y) for a Y of mean λ spread over many levels is λ − 1/2 (within its Fourier remainder)."""
    law = dn_pmf(57.0, 1.0)
    np.testing.assert_allclose(law.pmf, stats.poisson.pmf(law.levels, 57.0), atol=1e-15)
    wide = dn_pmf(400.0, 1.0, read_noise_e=5.0)
    assert wide.first < 400 - 5 * 21 and abs(wide.mean - 399.5) < 1e-9
    assert abs(wide.pmf @ (wide.levels - wide.mean) ** 2 - (400 + 25 + 1 / 12)) < 1e-6


def test_charge_law_is_poisson_clipped_at_the_full_well():
    charges, p = charge_pmf(9000.0, 9000.0)
    assert charges[-1] == 9000.0 and charges[-2] == 8999.0
    assert abs(p[-1] - stats.poisson.sf(8999, 9000.0)) < 1e-12 and abs(p.sum() - 1) < 1e-14
    np.testing.assert_array_equal(charge_pmf(0.0, 9000.0)[0], [0.0])
    assert charge_pmf(1e30, 9000.0)[1][-1] == 1.0  # far above the full well: all of it there


def test_dense_refuses_a_window_outside_the_levels():
    with pytest.raises(ValueError):
        dn_pmf(400.0, 1.0, read_noise_e=5.0).dense(256)


def chi2_p(counts, p) -> float:
    """χ² p-value of the level counts against the pmf ``p`` (same levels), bins under 5 expected pooled."""
    keep = p * counts.sum() >= 5
    observed = np.append(counts[keep], counts[~keep].sum())
    wanted = counts.sum() * np.append(p[keep], p[~keep].sum())
    if wanted[-1] < 5:  # merge the thin remainder into the largest bin
        observed, wanted = observed[:-1], wanted[:-1]
        observed[np.argmax(wanted)] += counts[~keep].sum()
        wanted[np.argmax(wanted)] += counts.sum() * p[~keep].sum()
    chi2 = np.sum((observed - wanted) ** 2 / wanted)
    return float(stats.chi2.sf(chi2, observed.size - 1))


def test_pmf_is_the_law_of_rendered_digital_numbers():
    """A χ² test of a poisson-rendered frame's DN against dn_pmf (one spectrum per channel, 240 000 pixels)."""
    sensor = preset("paper-table1")
    means = np.array([[30.0, 2000.0, 8950.0]])
    expected = expected_signal(means, np.eye(3), sensor.with_stages(dark_current=False), 1.0, "pixel")
    frame = render_frame(np.zeros((400, 600), np.uint8), expected, sensor.with_stages(dark_current=False),
                         method="poisson", rng=7)
    for c, lam in enumerate(means[0]):
        p = dn_pmf(lam, sensor.dn_per_electron, sensor.read_noise_e, sensor.full_well_e, sensor.bits).dense(256)
        counts = np.bincount(frame.digital_dn[c].ravel(), minlength=256)
        assert chi2_p(counts, p) > 1e-4, lam


@pytest.mark.parametrize("lam", [0.0, 3.0, 500.0, 8990.0])
@pytest.mark.parametrize("read", [0.0, 2.5])
@pytest.mark.parametrize("pedestal, bits", [(64, 12), (200, 8), (4090, 12)])
def test_pmf_with_a_pedestal_is_the_sum_over_charges(lam, read, pedestal, bits):
    """I = clip(floor(k (charge + R)) + P, 0, 2^nb − 1): the pedestal lifts the levels before the clip (dark
    values below the black level are kept; a pedestal near the top clips there)."""
    k = 0.9
    law = dn_pmf(lam, k, read, 9000.0, bits, pedestal_dn=pedestal)
    np.testing.assert_allclose(law.dense(2**bits), digital_pmf(lam, k, read, 9000.0, bits, pedestal_dn=pedestal),
                               rtol=0, atol=1e-11)
    with pytest.raises(ValueError):
        dn_pmf(lam, k, read, 9000.0, bits, pedestal_dn=0.5)


def test_pmf_with_a_pedestal_is_the_law_of_rendered_digital_numbers():
    """χ² of a 12-bit frame with pedestal 64 and 50 e⁻ of read noise (1.4 DN; dark and dim spectra: levels below
    the pedestal occur) against dn_pmf with the pedestal; the dark channel's mean is the pedestal."""
    sensor = preset("paper-table1", bits=12, pedestal_dn=64, read_noise_e=50.0, dark_current=False)
    means = np.array([[0.0, 4.0, 150.0]])
    expected = expected_signal(means, np.eye(3), sensor, 1.0, "pixel")
    frame = render_frame(np.zeros((400, 600), np.uint8), expected, sensor, method="poisson", rng=11)
    for c, lam in enumerate(means[0]):
        p = dn_pmf(lam, sensor.dn_per_electron, sensor.read_noise_e, sensor.full_well_e, sensor.bits,
                   pedestal_dn=64).dense(4096)
        counts = np.bincount(frame.digital_dn[c].ravel(), minlength=4096)
        assert counts[:64].sum() > 0  # every channel reaches below the black level
        assert chi2_p(counts, p) > 1e-4, lam
    dark = frame.digital_dn[0].astype(float)
    assert abs(dark.mean() - 64) < 5 * dark.std() / np.sqrt(dark.size)  # the ADC's offset P + ½: P on average


def test_expected_tv_of_an_exact_sample_by_enumeration():
    """E[TV] for n = 4 draws of a 3-level law, summed over every outcome of the multinomial."""
    from itertools import product

    from camsim.sensor.dn_law import DnPmf, expected_tv, sample_distances

    law = DnPmf(5, np.array([0.2, 0.5, 0.3]))
    total = 0.0
    for draws in product(range(3), repeat=4):
        prob = np.prod(law.pmf[list(draws)])
        total += prob * sample_distances(law, 5 + np.array(draws))[0]
    assert abs(expected_tv(law, 4) - total) < 1e-12
    assert expected_tv(DnPmf(0, np.array([1.0])), 10) == 0.0


def test_sample_distances_by_hand():
    from camsim.sensor.dn_law import DnPmf, sample_distances

    law = DnPmf(2, np.array([0.25, 0.75]))
    tv, ks = sample_distances(law, [2, 3, 3, 7])  # one value outside the window: 1/4 of TV, and the CDF ends early
    assert abs(tv - 0.5 * (0 + 0.25 + 0.25)) < 1e-15 and abs(ks - 0.25) < 1e-15
    tv, ks = sample_distances(law, [1, 2, 3, 3])  # one below: the CDF starts at 1/4
    assert abs(tv - 0.25) < 1e-15 and abs(ks - 0.25) < 1e-15
