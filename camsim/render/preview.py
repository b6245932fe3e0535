"""An sRGB preview of a rendered frame, so that a person can look at it without a raw converter.

The preview develops the frame's digital numbers the way a simple camera pipeline does:

1. **Numbers**: the quantised digital numbers I (``frame.digital_dn``), or the float ``frame.noisy_dn`` when
   quantisation is off. A Bayer mosaic is demosaiced first (bilinear, colour-demosaicing).
2. **Black level**: the mean of an unlit pixel's numbers is subtracted — the true black level
   (:attr:`camsim.sensor.params.SensorParams.black_level_dn`, after Eq. 11's floor) from quantised numbers, the level
   before the ADC (``dark_level_dn``) from unquantised ones, as ``camsim analyze --subtract-black`` does.
3. **Camera RGB → XYZ**: by default (``matrix="least-squares"``) the 3 × 3 matrix that best maps the chart
   patches' expected camera DN (k · S, noise-free, under the frame's own illuminant) to their CIE 1931 XYZ in
   cd/m²; ``matrix="paper"`` uses Eq. 15's projection on the colour-matching functions, M = (T Tᵗ)(C Tᵗ)⁻¹,
   times 683 lm/W · δ / exposure, which makes its XYZ cd/m² too. A frame without patches (a cube) always uses
   ``"paper"``.
4. **White balance**: von Kries adaptation (Bradford cone space) from the scene's white — the XYZ of the
   camera's response to the perfect white under the frame's illuminant (``as_shot_neutral`` through the matrix)
   — to D65, the sRGB white, as a camera's auto white balance would.
5. **Exposure** (see :func:`preview_srgb`): by default (``"scene"``) the scene's reference luminance — the
   perfect white at F = 1, ``luminance_cd_m2`` — maps to sRGB white, so a frame at intensity factor F is F times
   darker and the low light is seen as low light. ``exposure="auto"`` adds the gain 1 / F, as a camera's
   auto-exposure would (the noise is then amplified with the signal); a number is a gain on ``"scene"``.
6. **sRGB**: XYZ → linear sRGB (colour-science's sRGB colourspace), clipped to [0, 1], the sRGB transfer
   function, rounded to 8 bits.

:func:`write_preview_png` writes the result as a PNG without timestamps (same frame, same bytes), atomically.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from camsim.colour.colorimetry import camera_to_xyz_matrix
from camsim.core.errors import CamsimError
from camsim.io.atomic import atomic_path
from camsim.light.photons import KM_LM_PER_W
from camsim.render.frame import BLOCK_PIXELS  # the preview works in the renderer's row blocks: memory does not grow

__all__ = ["EXPOSURES", "MATRICES", "linear_srgb", "preview_srgb", "preview_transform", "write_preview_png"]

EXPOSURES = ("scene", "auto")
"""Named exposures of :func:`preview_srgb`; a positive number is a linear gain on ``"scene"``."""
MATRICES = ("least-squares", "paper")
"""Camera → XYZ matrices of :func:`preview_srgb`."""
CHROMATIC_ADAPTATION = "Bradford"
"""Cone space of the von Kries white balance."""


@dataclass(frozen=True)
class _ColourFacts:
    """What the preview needs to know about a frame besides the frame itself: from a FrameInfo or a sidecar."""

    intensity_factor: float
    luminance_cd_m2: float
    wavelengths_nm: np.ndarray  # (N,)
    as_shot_neutral: np.ndarray  # (3,)
    patch_xyz: np.ndarray  # (P, 3), cd/m² at the frame's F; P = 0 without a chart


def _facts(info) -> _ColourFacts:
    if isinstance(info, dict):  # a sidecar
        patches = info.get("patches") or []
        xyz = [p.get("xyz_cd_m2") for p in patches]
        xyz = np.asarray(xyz, dtype=np.float64) if xyz and all(v is not None for v in xyz) else None
        values = (info["intensity_factor"], info["luminance_cd_m2"], info["wavelengths_nm"], info["as_shot_neutral"])
    else:  # camsim.render.frame_files.FrameInfo
        xyz = info.patch_xyz
        values = (info.intensity_factor, info.luminance_cd_m2, info.wavelengths_nm, info.as_shot_neutral)
    factor, luminance, wl, neutral = values
    xyz = np.zeros((0, 3)) if xyz is None else np.asarray(xyz, dtype=np.float64).reshape(-1, 3)
    return _ColourFacts(float(factor), float(luminance), np.asarray(wl, dtype=np.float64),
                        np.asarray(neutral, dtype=np.float64), xyz)


def _camera_to_xyz(frame, facts: _ColourFacts, matrix: str) -> np.ndarray:
    """3 × 3 matrix from black-subtracted camera DN to XYZ in cd/m² (``xyz = dn @ M.T``)."""
    ex, k = frame.expected, frame.sensor.dn_per_electron
    wl = facts.wavelengths_nm
    n = facts.patch_xyz.shape[0]
    if matrix == "least-squares" and n >= 3:
        return camera_to_xyz_matrix(ex.qe, wl, k, method="least-squares",
                                    training=(ex.signal_e[:n] * k, facts.patch_xyz))
    m = camera_to_xyz_matrix(ex.qe, wl, k, method="paper")
    # Eq. 15 gives Σ x̄ L per DN of exposure T; 683 lm/W · δ / T turns that into cd/m² per DN
    return m * (KM_LM_PER_W * float(np.mean(np.gradient(wl))) / frame.sensor.exposure_s)


def preview_transform(frame, info, *, exposure: str | float = "scene", matrix: str = "least-squares") -> np.ndarray:
    """The 3 × 3 matrix from black-subtracted camera DN to linear sRGB (D65 white = 1) that the preview applies.

    Parameters are those of :func:`preview_srgb`. ``rgb_linear = dn @ A.T``.
    """
    if matrix not in MATRICES:
        raise CamsimError(f"unknown preview matrix {matrix!r}; matrices: {', '.join(MATRICES)}")
    gain = _exposure_gain(exposure, info)
    import colour  # colour-science: imported late, it is slow to import

    facts = _facts(info)
    to_xyz = _camera_to_xyz(frame, facts, matrix)
    # white balance: the camera's perfect white under the scene light, through the same matrix, to D65
    white = to_xyz @ facts.as_shot_neutral
    if not (np.all(np.isfinite(white)) and white[1] > 0):
        raise CamsimError(f"cannot white-balance the preview: the scene white maps to XYZ {white.tolist()}")
    srgb = colour.RGB_COLOURSPACES["sRGB"]
    d65 = colour.xy_to_XYZ(srgb.whitepoint)
    adapt = colour.adaptation.matrix_chromatic_adaptation_VonKries(white / white[1], d65 / d65[1],
                                                                   transform=CHROMATIC_ADAPTATION)
    scale = gain / facts.luminance_cd_m2  # the reference luminance (perfect white at F = 1) → Y = 1
    return scale * (np.asarray(srgb.matrix_XYZ_to_RGB) @ adapt @ to_xyz)


def _exposure_gain(exposure, info) -> float:
    if isinstance(exposure, str):
        if exposure == "scene":
            return 1.0
        if exposure == "auto":
            return 1.0 / _facts(info).intensity_factor
        raise CamsimError(f"unknown preview exposure {exposure!r}; use {', '.join(EXPOSURES)} or a positive gain")
    if not (isinstance(exposure, (int, float)) and np.isfinite(exposure) and exposure > 0):
        raise CamsimError(f"preview exposure gain must be a positive number, got {exposure!r}")
    return float(exposure)


def _camera_dn(frame, r0: int, r1: int, unquantised: bool = False) -> np.ndarray:
    """Black-subtracted camera DN of rows ``r0:r1``, shape (r1 − r0, W, 3), float64: of the quantised numbers where
    the frame has them, else (or with ``unquantised``) of ``noisy_dn`` less ``dark_level_dn``."""
    sensor = frame.sensor
    quantised = frame.digital_dn is not None and not unquantised
    numbers = frame.digital_dn if quantised else frame.noisy_dn
    black = sensor.black_level_dn if quantised else sensor.dark_level_dn  # the mean of an unlit pixel's numbers
    if sensor.cfa is None:
        return np.moveaxis(numbers[:, r0:r1], 0, -1).astype(np.float64) - black
    from colour_demosaicing import demosaicing_CFA_Bayer_bilinear

    from camsim.sensor.cfa import cfa_sites

    # two rows of context each side (r0 is even, so the block starts on the pattern's first row): the 3 × 3
    # bilinear kernels then see what they would see in the whole frame, and the block's result is the same
    h0, h1 = max(0, r0 - 2), min(numbers.shape[1], r1 + 2)
    mosaic = numbers[0, h0:h1].astype(np.float64)
    for dy, dx, c in cfa_sites(sensor.cfa):  # each site its own channel's black level
        mosaic[dy::2, dx::2] -= black[c]
    rgb = np.asarray(demosaicing_CFA_Bayer_bilinear(mosaic, sensor.cfa), dtype=np.float64)
    return rgb[r0 - h0:r1 - h0]


def preview_srgb(frame, info, *, exposure: str | float = "scene", matrix: str = "least-squares") -> np.ndarray:
    """An 8-bit sRGB picture of a rendered frame: black level off, camera RGB → XYZ, white balance, sRGB.

    Parameters
    ----------
    frame : camsim.render.frame.Frame
        A rendered frame: three-chip (3, H, W) or Bayer (1, H, W) numbers; ``digital_dn`` is used when the frame
        is quantised, ``noisy_dn`` otherwise.
    info : camsim.render.frame_files.FrameInfo or dict
        The frame's FrameInfo, or its sidecar (the dict :func:`camsim.render.frame_files.sidecar` returns): the
        intensity factor F, the scene's reference luminance, the wavelength grid, ``as_shot_neutral`` and the patches'
        XYZ.
    exposure : {"scene", "auto"} or float
        ``"scene"`` (default): the perfect white at F = 1 (the scene's ``luminance_cd_m2``) maps to sRGB white
        (a ColorChecker white, reflectance 0.9, to about 241 of 255) and a frame at F is F times darker — a
        user sees the low light, and the noise at its true level. ``"auto"``: times 1 / F, so every F is exposed
        like F = 1 and the noise is amplified with the signal. A positive number: that linear gain on
        ``"scene"``.
    matrix : {"least-squares", "paper"}
        Camera → XYZ: the least-squares fit on the chart's patches under the frame's illuminant (default; the
        better picture: mean CIEDE2000 about 1 against the patches' true colours under D65, A, FL2, HP1, where
        the paper's projection gives 1.2–6), or Eq. 15's projection on the colour-matching functions. Frames
        without patches use ``"paper"``.

    Returns
    -------
    numpy.ndarray, shape (H, W, 3), uint8
        sRGB (IEC 61966-2-1 transfer function, D65 white), values clipped to [0, 1] before encoding.
    """
    import colour

    t = preview_transform(frame, info, exposure=exposure, matrix=matrix)
    height, width = frame.labels.shape
    out = np.empty((height, width, 3), dtype=np.uint8)
    rows = max(2, BLOCK_PIXELS // width)
    rows -= rows % 2  # blocks start on even rows (a Bayer pattern's first row)
    for r0 in range(0, height, rows):
        r1 = min(height, r0 + rows)
        dn = _camera_dn(frame, r0, r1)
        rgb = np.empty_like(dn)
        for c in range(3):  # element by element (not BLAS): the same numbers whatever the block size
            rgb[..., c] = t[c, 0] * dn[..., 0] + t[c, 1] * dn[..., 1] + t[c, 2] * dn[..., 2]
        np.clip(rgb, 0.0, 1.0, out=rgb)
        out[r0:r1] = np.round(np.asarray(colour.models.eotf_inverse_sRGB(rgb)) * 255.0)
    return out


#: The largest factor from DN to the linear sRGB view that keeps the view's float32 values finite (1 = the white).
VIEW_FACTOR_MAX = 1e30


def _check_view_transform(t: np.ndarray) -> None:
    """Refuse a DN → linear sRGB matrix that float32 cannot hold: the perfect white at F = 1 is then a vanishing
    number of DN (a conversion gain, analog gain, luminance or reference charge tens of orders of magnitude below
    any camera's), and every pixel of the view would be infinite or NaN."""
    size = float(np.max(np.abs(t), initial=0.0)) if np.all(np.isfinite(t)) else np.inf
    if size > VIEW_FACTOR_MAX:
        from camsim.core.errors import CamsimError

        white = 1.0 / size if size > 0 else 0.0
        raise CamsimError(f"the perfect white at F = 1 is about {white:.3g} DN, too small for the EXR's linear "
                          f"sRGB view (float32): a gain, luminance or reference charge far below any camera's; "
                          "raise it")


def linear_srgb(frame, info, *, matrix: str = "least-squares", transform: np.ndarray | None = None) -> np.ndarray:
    """The frame's values before quantisation as linear sRGB: the picture of :func:`preview_srgb` before its clip
    and transfer function, from ``noisy_dn`` (never the quantised numbers) less ``dark_level_dn``.

    Steps 2 to 5 of the module docstring with the ``"scene"`` exposure: black-subtracted camera DN → XYZ → white
    balance to D65 → linear sRGB (IEC 61966-2-1 primaries, D65 white), scaled so that the perfect white at F = 1
    (the scene's ``luminance_cd_m2``) is 1 in every channel. A Bayer mosaic is demosaiced (bilinear). What the EXR
    of a frame holds in ``R, G, B`` (:func:`camsim.render.frame_files.write_frame`).

    Parameters
    ----------
    frame : camsim.render.frame.Frame
        A rendered frame, three-chip (3, H, W) or Bayer (1, H, W) ``noisy_dn``. Unit: DN.
    info : camsim.render.frame_files.FrameInfo or dict
        As for :func:`preview_srgb`.
    matrix : {"least-squares", "paper"}
        As for :func:`preview_srgb`.
    transform : numpy.ndarray, shape (3, 3), optional
        The matrix :func:`preview_transform` gives for ``frame``, ``info`` and ``matrix``, where the caller has it.

    Returns
    -------
    numpy.ndarray, shape (3, H, W), float32
        Linear sRGB R, G, B, unclipped (noise goes below 0, saturated or very bright light above 1). Unit: 1 =
        the perfect white at F = 1.
    """
    t = preview_transform(frame, info, exposure="scene", matrix=matrix) if transform is None else transform
    _check_view_transform(t)
    height, width = frame.labels.shape
    out = np.empty((3, height, width), dtype=np.float32)
    if frame.sensor.cfa is None:
        # float32, element by element, the black level folded into one offset per channel: 3 × 3 products and
        # sums over whole planes, a third of the float64 blocks' time (absolute error about 2e-7 on 1 = white)
        t32, offset = t.astype(np.float32), (t @ frame.sensor.dark_level_dn).astype(np.float32)
        noisy, term = frame.noisy_dn, np.empty((height, width), dtype=np.float32)
        for c in range(3):
            np.multiply(noisy[0], t32[c, 0], out=out[c])
            for j in (1, 2):
                np.multiply(noisy[j], t32[c, j], out=term)
                out[c] += term
            out[c] -= offset[c]
        return out
    rows = max(2, BLOCK_PIXELS // width)
    rows -= rows % 2  # blocks start on even rows (a Bayer pattern's first row)
    for r0 in range(0, height, rows):
        r1 = min(height, r0 + rows)
        dn = _camera_dn(frame, r0, r1, unquantised=True)
        for c in range(3):  # element by element (not BLAS): the same numbers whatever the block size
            out[c, r0:r1] = t[c, 0] * dn[..., 0] + t[c, 1] * dn[..., 1] + t[c, 2] * dn[..., 2]
    return out


def write_preview_png(path: str | Path, image: np.ndarray, compress_level: int = 3) -> None:
    """Write an (H, W, 3) uint8 picture as a PNG, atomically; no timestamp, so the same picture gives the same
    bytes.

    ``compress_level`` is zlib's (0–9); 3 writes a 4000 × 3000 frame in 1.5 s, 4× faster than 6, for 12 % more
    bytes (noise does not compress)."""
    import imageio.v3 as iio

    image = np.asarray(image)
    if image.dtype != np.uint8 or image.ndim != 3 or image.shape[2] != 3:
        raise ValueError(f"need an (H, W, 3) uint8 picture, got {image.shape} {image.dtype}")
    with atomic_path(path) as tmp:
        iio.imwrite(tmp, image, extension=".png", compress_level=compress_level)
