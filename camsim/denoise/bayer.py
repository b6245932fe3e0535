"""Bayer (CFA) frames in ``camsim denoise-eval``: what a denoiser receives, and the scores in the raw domain and
after the ISP.

A Bayer frame's EXR holds the mosaic (layer ``noisy.CFA``: the noisy DN before quantisation, one value per pixel)
and a clean layer ``clean.R/G/B`` with the expected DN of *every* channel at every pixel; the clean mosaic is the
clean layer's value of each site's own colour (:func:`clean_mosaic`).

What a denoiser gets (:data:`BAYER_INPUTS`):

* ``packed`` (default; the SID/ELD convention): the mosaic, black subtracted and divided by white − black
  (:func:`camsim.isp.normalise` with :func:`camsim.isp.facts_of`: 0 = black, 1 = the white level; not clipped),
  packed into four half-resolution planes in the order R, G1, G2, B whatever the native pattern (G1 the green on
  R's row; :func:`camsim.isp.pack_rggb`), given channels-last: a (H/2, W/2, 4) float32 array;
* ``mosaic``: the same normalised values unpacked, a (H, W) float32 array in the frame's own pattern.

The result has the same shape, unit and (for the mosaic) pattern. Scores:

* raw: PSNR and SSIM (scikit-image, ``data_range`` = 1, the white level) of each packed plane R, G1, G2, B of the
  denoised (and of the noisy) frame against the clean mosaic, normalised the same way, and over all four planes
  (PSNR from the mean squared error over every value; SSIM the mean of the four planes') — :func:`raw_scores`;
* after the ISP: the noisy, the denoised and the clean mosaics each developed by :func:`camsim.isp.develop` with
  the frame's facts and :func:`isp_settings` (white balance as shot, the camera matrix, the default demosaicing,
  ``gain="white"`` by default — the perfect white under the frame's light at its F maps to 1, so that low-light
  frames are seen exposed for their light; ``"auto"`` = 1 / F clips much of a frame where F = 1 would pass the
  white level, :data:`GAIN_WHY` — and the sRGB tone curve), then PSNR and SSIM (``data_range`` = 1) and the mean
  CIEDE2000 over the pixels of the developed denoised (or noisy) image against the developed clean one, both taken
  as sRGB (IEC 61966-2-1, D65) to CIELAB — :func:`srgb_scores`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from camsim.core.errors import CamsimError
from camsim.core.optional_numbers import finite_or_none
from camsim.denoise.image_scores import SSIM_MIN_SIDE
from camsim.sensor.cfa import cfa_sites, mosaic_of

__all__ = ["BAYER_INPUTS", "BAYER_PLANES", "PACKED", "MOSAIC", "DEFAULT_ISP_GAIN", "GAIN_WHY", "gain_text",
           "isp_text", "isp_settings", "BayerFrame", "bayer_frame", "clean_mosaic", "denormalise", "to_packed",
           "from_packed", "developed_image", "raw_scores", "srgb_lab", "srgb_scores"]

PACKED = "packed"
MOSAIC = "mosaic"
#: What a denoiser receives for a Bayer frame (``--bayer-input``).
BAYER_INPUTS = (PACKED, MOSAIC)
#: The packed planes, in order (G1: the green on R's row).
BAYER_PLANES = ("R", "G1", "G2", "B")


#: The gain of the development for the scores after the ISP: ``"white"`` (default) maps the perfect white under the
#: frame's light at its F to 1; ``"auto"`` is 1 / F (the SID/ELD exposure ratio); a number is a fixed gain.
DEFAULT_ISP_GAIN = "white"
#: Why "white" and not "auto" by default (for the report and the help).
GAIN_WHY = ("with gain 1 / F a frame is developed as at F = 1, which clips wherever the light at F = 1 would pass "
            "the white level: 70 % of the pixels (a channel at 1) of each developed clean frame of the astronaut "
            "photograph through the sony-a7s2 preset at ISO 12800, against 0.7 % with the white gain (12 frames, "
            "measured 2026-11-25)")


def isp_settings(gain=DEFAULT_ISP_GAIN):
    """The :class:`camsim.isp.IspSettings` of the scores after the ISP: white balance as shot, the camera matrix,
    the default demosaicing (Malvar 2004), ``gain`` (:data:`DEFAULT_ISP_GAIN`), the sRGB tone curve."""
    from camsim.isp import IspSettings

    return IspSettings(white_balance="as-shot", matrix="camera", gain=gain, tone="srgb")


def gain_text(gain) -> str:
    """The gain in words."""
    if gain == "white":
        return "gain = white (the perfect white under the frame's light at its F → 1)"
    if gain == "auto":
        return "gain = auto (1 / F: every frame as at F = 1)"
    return f"gain = {float(gain):g}"


def isp_text(gain=DEFAULT_ISP_GAIN) -> str:
    """How the frames are developed for the scores after the ISP (for the report)."""
    return ("camsim.isp.develop with white balance as shot (the frame's AsShotNeutral), the camera → sRGB matrix "
            "(from the camera's spectral sensitivities), the default demosaicing (Malvar 2004), " + gain_text(gain)
            + " and the sRGB tone curve, clipped to [0, 1]")


def clean_mosaic(clean: np.ndarray, pattern: str) -> np.ndarray:
    """The clean mosaic of a Bayer frame: at each site, the clean layer's value of that site's colour.

    Parameters
    ----------
    clean : numpy.ndarray, shape (3, H, W)
        The EXR's clean layer (expected DN of R, G and B at every pixel). Unit: DN.
    pattern : str
        The Bayer pattern (``"RGGB"``, ``"BGGR"``, ``"GRBG"``, ``"GBRG"``).

    Returns
    -------
    numpy.ndarray, shape (H, W), float32
        Unit: DN.
    """
    return mosaic_of(clean, pattern).astype(np.float32, copy=False)


def denormalise(mosaic: np.ndarray, facts) -> np.ndarray:
    """The inverse of :func:`camsim.isp.normalise` on a mosaic: x · (white − black) + black per site, float32 DN."""
    black = np.asarray(facts.black_dn, dtype=np.float64)
    white = float(facts.white_dn)
    out = np.empty(mosaic.shape, dtype=np.float32)
    for dy, dx, c in cfa_sites(facts.cfa_pattern):
        out[dy::2, dx::2] = mosaic[dy::2, dx::2].astype(np.float64) * (white - black[c]) + black[c]
    return out


def to_packed(mosaic: np.ndarray, pattern: str) -> np.ndarray:
    """A (H, W) mosaic as the (H/2, W/2, 4) channels-last planes R, G1, G2, B (:func:`camsim.isp.pack_rggb`)."""
    from camsim.isp import pack_rggb

    return np.ascontiguousarray(np.moveaxis(pack_rggb(mosaic, pattern), 0, -1))


def from_packed(planes: np.ndarray, pattern: str) -> np.ndarray:
    """The (H, W) mosaic of (H/2, W/2, 4) channels-last planes R, G1, G2, B (:func:`camsim.isp.unpack_rggb`)."""
    from camsim.isp import unpack_rggb

    return np.ascontiguousarray(unpack_rggb(np.ascontiguousarray(np.moveaxis(planes, -1, 0)), pattern))


@dataclass
class BayerFrame:
    """A Bayer frame ready for the denoisers: its ISP facts and the normalised noisy and clean mosaics and planes.

    Attributes
    ----------
    facts : camsim.isp.IspFacts
    pattern : str
    noisy_mosaic, clean_mosaic : numpy.ndarray, shape (H, W), float32
        Normalised (0 = black, 1 = the white level).
    noisy_packed, clean_packed : numpy.ndarray, shape (H/2, W/2, 4), float32
        The same, packed R, G1, G2, B, channels last.
    settings : camsim.isp.IspSettings
        How it is developed (:func:`isp_settings`).
    gain : str or float
        The gain of ``settings``: the one asked for, but ``"auto"`` where ``"white"`` was asked for and the sidecar
        has no perfect white's signal (``white_signal_e``, older sidecars).
    """

    facts: object
    pattern: str
    settings: object  # the camsim.isp.IspSettings it is developed with
    gain: object  # the gain used: "white", "auto" or a number
    noisy_mosaic: np.ndarray
    clean_mosaic: np.ndarray
    noisy_packed: np.ndarray
    clean_packed: np.ndarray


def bayer_frame(loaded, clean: np.ndarray, gain=DEFAULT_ISP_GAIN) -> BayerFrame:
    """The :class:`BayerFrame` of a loaded Bayer EXR (:func:`camsim.render.frame_files.load_frame`) and its clean
    layer (3, H, W), developed with ``gain`` (:func:`isp_settings`) for the scores after the ISP.

    Raises
    ------
    CamsimError
        An odd width or height (the mosaic cannot be packed).
    """
    from camsim.isp import facts_of, normalise

    pattern = loaded.cfa_pattern
    height, width = loaded.pixels_dn.shape[1:]
    if height % 2 or width % 2:
        raise CamsimError(f"{loaded.path}: a {width}x{height} Bayer frame cannot be packed into 2 × 2 cells (width "
                          "and height must be even)")
    facts = facts_of(loaded)
    noisy = np.asarray(normalise(loaded.pixels_dn[0].astype(np.float32, copy=False), facts), dtype=np.float32)
    clean_n = np.asarray(normalise(clean_mosaic(clean, pattern), facts), dtype=np.float32)
    if gain == "white" and facts.white_signal_dn is None:
        gain = "auto"
    return BayerFrame(facts, pattern, isp_settings(gain), gain, noisy, clean_n, to_packed(noisy, pattern),
                      to_packed(clean_n, pattern))


def raw_scores(clean_packed: np.ndarray, test_packed: np.ndarray) -> dict:
    """PSNR (dB) and SSIM of normalised packed planes against the clean ones, per plane and over all four.

    Parameters
    ----------
    clean_packed, test_packed : numpy.ndarray, shape (h, w, 4)
        Planes R, G1, G2, B, normalised (1 = the white level): ``data_range`` = 1.

    Returns
    -------
    dict
        ``psnr_db``, ``ssim`` (over all planes: PSNR from the mean squared error over every value, SSIM the mean of
        the planes') and ``psnr_{P}_db``, ``ssim_{P}`` for P in R, G1, G2, B; None where undefined (a perfect
        result's infinite PSNR, SSIM of planes smaller than its 7 × 7 window).
    """
    from skimage.metrics import peak_signal_noise_ratio, structural_similarity

    clean = np.asarray(clean_packed, dtype=np.float64)
    test = np.asarray(test_packed, dtype=np.float64)

    def psnr(a, b):
        mse = float(np.mean((a - b) ** 2))
        return None if not mse > 0 else finite_or_none(peak_signal_noise_ratio(a, b, data_range=1.0))

    out = {"psnr_db": psnr(clean, test)}
    ssims = []
    for i, plane in enumerate(BAYER_PLANES):
        out[f"psnr_{plane}_db"] = psnr(clean[..., i], test[..., i])
        ssim = None
        if min(clean.shape[:2]) >= SSIM_MIN_SIDE:
            ssim = finite_or_none(structural_similarity(clean[..., i], test[..., i], data_range=1.0))
        out[f"ssim_{plane}"] = ssim
        ssims.append(ssim)
    out["ssim"] = None if any(s is None for s in ssims) else float(np.mean(ssims))
    return out


def developed_image(mosaic_normalised: np.ndarray, frame: BayerFrame) -> np.ndarray:
    """A normalised mosaic developed by :func:`camsim.isp.develop` with the frame's facts and settings: (3, H, W)
    float32 sRGB in [0, 1]."""
    from camsim.isp import develop

    raw = denormalise(mosaic_normalised, frame.facts)
    return np.asarray(develop(raw, frame.facts, frame.settings).image, dtype=np.float32)


def srgb_lab(srgb_chw: np.ndarray) -> np.ndarray:
    import colour

    rgb = np.moveaxis(np.asarray(srgb_chw, dtype=np.float64), 0, -1)
    xyz = colour.RGB_to_XYZ(rgb, colour.RGB_COLOURSPACES["sRGB"], apply_cctf_decoding=True)
    white = colour.CCS_ILLUMINANTS["CIE 1931 2 Degree Standard Observer"]["D65"]
    return colour.XYZ_to_Lab(xyz, white)


def srgb_scores(clean_dev: np.ndarray, test_dev: np.ndarray, clean_lab: np.ndarray | None = None) -> dict:
    """PSNR (dB), SSIM (``data_range`` = 1) and mean CIEDE2000 of a developed image against the developed clean one.

    Parameters
    ----------
    clean_dev, test_dev : numpy.ndarray, shape (3, H, W)
        sRGB-encoded images in [0, 1] (:func:`developed_image`).
    clean_lab : numpy.ndarray, shape (H, W, 3), optional
        The clean image's CIELAB, if already computed.

    Returns
    -------
    dict
        ``psnr_db`` (None for a perfect result), ``ssim`` (None below 7 × 7), ``delta_e00`` (mean over the pixels;
        sRGB decoded, to XYZ and CIELAB against D65 by colour-science).
    """
    import colour
    from skimage.metrics import peak_signal_noise_ratio, structural_similarity

    clean = np.asarray(clean_dev, dtype=np.float64)
    test = np.asarray(test_dev, dtype=np.float64)
    mse = float(np.mean((clean - test) ** 2))
    psnr = None if not mse > 0 else finite_or_none(peak_signal_noise_ratio(clean, test, data_range=1.0))
    ssim = None
    if min(clean.shape[1:]) >= SSIM_MIN_SIDE:
        ssim = finite_or_none(structural_similarity(clean, test, data_range=1.0, channel_axis=0))
    if clean_lab is None:
        clean_lab = srgb_lab(clean)
    de = colour.delta_E(clean_lab, srgb_lab(test), method="CIE 2000")
    return {"psnr_db": psnr, "ssim": ssim, "delta_e00": finite_or_none(float(np.mean(de)))}
