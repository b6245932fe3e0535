"""The ISP written out in float64, independently of :mod:`camsim.isp`'s code: the oracle of the fast paths'
and the fused kernel's tests. Only the record's numbers (black levels, white-balance gains, matrix, gain) are
taken from the development under test; every operation is written here or is colour-demosaicing's."""

import numpy as np

import camsim.isp as isp


def made_up_facts(pattern="RGGB", illuminant="D65", neutral=(0.5, 1.0, 0.8)):
    """A made-up camera: Gaussian QE bumps at 600, 540, 460 nm on a 400–700 nm grid, a 10-bit white level."""
    wl = np.arange(400.0, 701.0, 10.0)
    qe = np.stack([np.exp(-0.5 * ((wl - c) / 40.0) ** 2) for c in (600.0, 540.0, 460.0)])
    return isp.IspFacts(cfa_pattern=pattern, black_dn=np.array([60.0, 64.0, 70.0]), white_dn=1023.0,
                        as_shot_neutral=np.array(neutral), intensity_factor=0.05, illuminant=illuminant,
                        wavelengths_nm=wl, qe=qe)


def colour_demosaicing_bilinear(mosaic, pattern):
    """colour-demosaicing's bilinear (float64) on the mosaic mirrored by 4 pixels without its edge row (the ISP's
    border rule), cut back: (3, H, W)."""
    import colour_demosaicing

    padded = np.pad(np.asarray(mosaic, dtype=np.float64), 4, mode="reflect")
    rgb = colour_demosaicing.demosaicing_CFA_Bayer_bilinear(padded, pattern)[4:-4, 4:-4]
    return np.moveaxis(rgb, -1, 0)


def reference_development(raw, facts, record, tone="srgb"):
    """The ISP in float64 from the record's numbers: normalise, white balance, bilinear (colour-demosaicing's),
    matrix, gain, (filmic,) clip, the tone curve's formula. (3, H, W)."""
    stages = record["stages"]
    black, gains = np.asarray(stages["black"]["black_dn"]), np.asarray(stages["white_balance"]["gains"])
    matrix, gain = stages["matrix"]["matrix"], stages["gain"]["value"]
    raw = np.asarray(raw, dtype=np.float64)
    if facts.cfa_pattern is None:
        x = gains[:, None, None] * (raw - black[:, None, None]) / (facts.white_dn - black[:, None, None])
    else:
        site_black, site_gain = np.empty(raw.shape), np.empty(raw.shape)
        for i, letter in enumerate(facts.cfa_pattern):
            c = "RGB".index(letter)
            site_black[i // 2::2, i % 2::2], site_gain[i // 2::2, i % 2::2] = black[c], gains[c]
        x = colour_demosaicing_bilinear(site_gain * (raw - site_black) / (facts.white_dn - site_black),
                                        facts.cfa_pattern)
    if matrix is not None:
        x = np.einsum("cj,jhw->chw", np.asarray(matrix), x)
    v = gain * x
    if tone == "filmic":
        v = np.maximum(v, 0.0)
        v = v * (2.51 * v + 0.03) / (v * (2.43 * v + 0.59) + 0.14)
    v = np.clip(v, 0.0, 1.0)
    if tone == "linear":
        return v
    return np.where(v <= 0.0031308, 12.92 * v, 1.055 * v ** (1 / 2.4) - 0.055)
