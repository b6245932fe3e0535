"""The ISP's stages: one pure array function each (no I/O), and the registries of demosaicing methods and tone
curves.

Arrays follow camsim's convention: planes first, float32. A three-chip image is (3, H, W); a Bayer mosaic is
(H, W) with its pattern name (:data:`camsim.sensor.cfa.CFA_PATTERNS`).
"""

from __future__ import annotations

import functools
import threading

import numpy as np

from camsim.core.errors import CamsimError
from camsim.sensor.cfa import CFA_PATTERNS, cfa_sites

__all__ = ["DEMOSAIC_METHODS", "PER_CHANNEL_LINEAR", "TONE_CURVES", "WHITE_BALANCE_MODES", "MATRICES",
           "CHROMATIC_ADAPTATION", "normalise", "white_balance_gains", "apply_white_balance", "demosaic",
           "srgb_matrix", "apply_matrix", "apply_gain", "tone_curve", "camera_to_xyz", "illuminant_neutral"]

#: White balance modes besides an illuminant's name.
WHITE_BALANCE_MODES = ("as-shot", "none")
#: Colour matrices (camera → XYZ, :func:`camera_to_xyz`, then to linear sRGB): from the camera's spectral
#: sensitivities under the white-balance illuminant (``"camera"``), the paper's Eq. 15 projection (``"paper"``),
#: the DNG's ColorMatrix1 as raw converters use it (``"dng"``), or none.
MATRICES = ("camera", "paper", "dng", "none")
#: The cone space of the von Kries adaptation from the white-balance illuminant's white to D65.
CHROMATIC_ADAPTATION = "Bradford"


def _check_image(x, what="image") -> np.ndarray:
    x = np.asarray(x)
    if x.ndim == 3 and x.shape[0] == 3:
        return x
    raise CamsimError(f"{what} must be a (3, H, W) three-chip image, got shape {x.shape}")


def _check_mosaic(x, cfa_pattern) -> np.ndarray:
    x = np.asarray(x)
    if cfa_pattern not in CFA_PATTERNS:
        raise CamsimError(f"unknown CFA pattern {cfa_pattern!r}; patterns: {', '.join(CFA_PATTERNS)}")
    if x.ndim == 3 and x.shape[0] == 1:
        x = x[0]
    if x.ndim != 2:
        raise CamsimError(f"a Bayer mosaic must be (H, W) (or (1, H, W)), got shape {x.shape}")
    return x


def _per_site(x, cfa_pattern, values, op) -> np.ndarray:
    """``op(site array, values[channel])`` on each 2 × 2 site of a mosaic, or per plane of an image; float32."""
    if cfa_pattern is None:
        x = _check_image(x)
        out = np.empty(x.shape, dtype=np.float32)
        for c in range(3):
            out[c] = op(x[c].astype(np.float32, copy=False), np.float32(values[c]))
        return out
    x = _check_mosaic(x, cfa_pattern)
    out = np.empty(x.shape, dtype=np.float32)
    for dy, dx, c in cfa_sites(cfa_pattern):
        out[dy::2, dx::2] = op(x[dy::2, dx::2].astype(np.float32, copy=False), np.float32(values[c]))
    return out


# ---------------------------------------------------------------------------------------------------------- black
def normalise(raw, facts) -> np.ndarray:
    """Black level off and divided by white − black: 0 = black, 1 = the white level.

    Parameters
    ----------
    raw : array_like, shape (3, H, W), or (H, W) / (1, H, W) for a Bayer mosaic
        The frame's numbers. Unit: DN (those of ``facts.black_dn`` and ``facts.white_dn``).
    facts : IspFacts
        ``black_dn`` (3,) per channel (a mosaic: each CFA site its channel's), ``white_dn``, ``cfa_pattern``.

    Returns
    -------
    numpy.ndarray, float32, same shape as ``raw`` ((H, W) for a mosaic)
        (raw − black_c) / (white − black_c). Unitless; noise goes below 0.
    """
    black = np.asarray(facts.black_dn, dtype=np.float64)
    scale = 1.0 / (facts.white_dn - black)
    return _normalise(raw, facts.cfa_pattern, black, scale)


def _normalise(raw, cfa_pattern, black, scale):
    def op(v, c):  # x · s − b · s in float32
        out = v * np.float32(scale[c])
        out -= np.float32(black[c] * scale[c])
        return out

    if cfa_pattern is None:
        raw = _check_image(raw, "raw")
        return np.stack([op(raw[c].astype(np.float32, copy=False), c) for c in range(3)])
    raw = _check_mosaic(raw, cfa_pattern)
    out = np.empty(raw.shape, dtype=np.float32)
    for dy, dx, c in cfa_sites(cfa_pattern):
        out[dy::2, dx::2] = op(raw[dy::2, dx::2].astype(np.float32, copy=False), c)
    return out


def _normalise_into(raw, facts, black, out) -> np.ndarray:
    """:func:`normalise` with ``black`` (3,) DN in place of ``facts.black_dn``, written into ``out`` (float32, the
    shape of ``raw`` after its checks; e.g. the interior of a padded buffer): the same float32 operations, so the
    same numbers."""
    black = np.asarray(black, dtype=np.float64)
    scale = 1.0 / (facts.white_dn - black)
    if facts.cfa_pattern is None:
        raw = _check_image(raw, "raw")
        sites = [(Ellipsis, c, c) for c in range(3)]
        take = [(c,) for c in range(3)]
    else:
        raw = _check_mosaic(raw, facts.cfa_pattern)
        sites = [(dy, dx, c) for dy, dx, c in cfa_sites(facts.cfa_pattern)]
        take = [(slice(dy, None, 2), slice(dx, None, 2)) for dy, dx, _ in sites]
    for index, (*_, c) in zip(take, sites):
        target = out[index]
        np.multiply(raw[index].astype(np.float32, copy=False), np.float32(scale[c]), out=target)
        target -= np.float32(black[c] * scale[c])
    return out


# ---------------------------------------------------------------------------------------------------- white balance
def _grid(wavelengths_nm):
    from camsim.light.spectra import WavelengthGrid

    wl = np.asarray(wavelengths_nm, dtype=np.float64)
    step = float(wl[1] - wl[0])
    if not np.allclose(np.diff(wl), step, rtol=1e-6, atol=1e-9):
        raise CamsimError("the camera's wavelength grid is not uniform: cannot white-balance to a named illuminant")
    return WavelengthGrid(float(wl[0]), float(wl[-1]), step)


def illuminant_neutral(facts, name: str) -> np.ndarray:
    """The camera's response to the perfect white under the illuminant ``name`` (colour-science's), shape (3,),
    largest component 1: from the camera's QE (as camsim's AsShotNeutral is computed), or else from ColorMatrix1
    applied to the illuminant's white XYZ."""
    if facts.qe is not None:
        from camsim.colour.rawcolour import as_shot_neutral

        return as_shot_neutral(name, facts.qe, _grid(facts.wavelengths_nm))
    from camsim.light.spectra import import_colour

    colour = import_colour()
    if name not in colour.SDS_ILLUMINANTS:
        raise CamsimError(f"unknown white balance {name!r}: use {', '.join(WHITE_BALANCE_MODES)} or an illuminant "
                          f"name (e.g. D65, A, FL2)")
    xyz = colour.sd_to_XYZ(colour.SDS_ILLUMINANTS[name])
    neutral = facts.color_matrix1 @ (xyz / xyz[1])
    return neutral / neutral.max()


def _neutral(facts, white_balance: str) -> np.ndarray:
    """The camera neutral (3,) the white balance is made for; None for ``"none"``."""
    if white_balance == "as-shot":
        return np.asarray(facts.as_shot_neutral, dtype=np.float64)
    if white_balance == "none":
        return None
    if not isinstance(white_balance, str):
        raise CamsimError(f"white balance must be a name, got {white_balance!r}")
    return illuminant_neutral(facts, white_balance)


def white_balance_gains(facts, name: str) -> np.ndarray:
    """The white-balance gains (3,) per channel R, G, B: 1 / neutral, normalised to green (green's gain is 1).

    ``name``: ``"as-shot"`` (the frame's as-shot neutral: the camera's response to the perfect white under the
    frame's illuminant), ``"none"`` (gains 1) or a colour-science illuminant name (the camera's response to the
    perfect white under that illuminant). The perfect white's camera values times the gains are equal.
    """
    neutral = _neutral(facts, name)
    if neutral is None:
        return np.ones(3)
    if not (np.all(np.isfinite(neutral)) and np.all(neutral > 0)):
        raise CamsimError(f"cannot white-balance: the neutral {neutral.tolist()} is not positive")
    return neutral[1] / neutral


def apply_white_balance(x, gains, cfa_pattern) -> np.ndarray:
    """Each channel times its gain: per plane of a (3, H, W) image (``cfa_pattern`` None), per CFA site of an
    (H, W) mosaic. float32, same shape."""
    gains = np.asarray(gains, dtype=np.float64).reshape(3)
    return _per_site(x, cfa_pattern, gains, lambda v, g: v * g)


# -------------------------------------------------------------------------------------------------------- demosaic
#: Pixels of mirrored mosaic added along each edge before demosaicing (an even number: the mirror, which leaves the
#: edge row out, keeps the Bayer phase), and cut off after: colour-demosaicing's own boundary handling mirrors
#: through the edge pixel, which breaks the pattern there (bilinear gives 2.25 × a constant mosaic's value in a
#: corner and 1.5 × along the edges).
DEMOSAIC_PAD = 4


def _colour_demosaicing(function_name):
    def method(mosaic, cfa_pattern):
        import colour_demosaicing

        pad, mode = DEMOSAIC_PAD, "reflect"
        if min(mosaic.shape) <= DEMOSAIC_PAD:  # a mirror needs more rows than it adds
            if mosaic.shape[0] % 2 == 0 and mosaic.shape[1] % 2 == 0:
                mode = "wrap"  # whole 2 × 2 cells repeated: the phase holds
            else:
                pad = (min(mosaic.shape) - 1) // 2 * 2
        padded = np.pad(mosaic, pad, mode=mode) if pad else mosaic
        rgb = getattr(colour_demosaicing, function_name)(padded, cfa_pattern)
        height, width = mosaic.shape
        out = np.empty((3, height, width), dtype=np.float32)
        for c in range(3):
            out[c] = rgb[pad:pad + height, pad:pad + width, c]
        return out

    method.__doc__ = f"colour-demosaicing's ``{function_name}``."
    return method


def _bilinear(mosaic, cfa_pattern, out=None) -> np.ndarray:
    """Bilinear demosaicing by slicing, in float32: at each site the missing colours are the mean of the nearest
    sites of that colour (the 2 beside it, the 2 above and below, or the 4 on the diagonals; green: the 4 beside,
    above and below), with the ISP's border rule (:data:`DEMOSAIC_PAD`: the mosaic mirrored without its edge row,
    which keeps the Bayer phase). Equal to colour-demosaicing's ``demosaicing_CFA_Bayer_bilinear`` on the padded
    mosaic within float32 rounding: its 2-site means are the same numbers (float64 sums of two float32 values,
    rounded once), its 4-site means differ by less than one unit in the last place of the largest of the four
    (three float32 roundings instead of one). Mosaics of 4 pixels or fewer on a side go to colour-demosaicing
    (:data:`DEMOSAIC_PAD`'s rules for them).

    Parameters
    ----------
    mosaic : numpy.ndarray, shape (H, W)
    cfa_pattern : str
    out : numpy.ndarray, shape (3, H, W), float32, optional
        Where to write the result.

    Returns
    -------
    numpy.ndarray, shape (3, H, W), float32
    """
    mosaic = np.asarray(mosaic)
    height, width = mosaic.shape
    if min(height, width) <= DEMOSAIC_PAD:
        rgb = _colour_demosaicing("demosaicing_CFA_Bayer_bilinear")(mosaic, cfa_pattern)
        if out is None:
            return rgb
        out[...] = rgb
        return out
    padded = _workspace("bilinear.padded", (height + 2, width + 2))
    padded[1:-1, 1:-1] = mosaic
    return _bilinear_padded(padded, cfa_pattern, out)


def _mirror_edges(padded) -> np.ndarray:
    """Fill the 1-pixel border of ``padded`` (H + 2, W + 2) from its interior as ``np.pad(mode="reflect")`` does
    (the mirror without the edge row, which keeps the Bayer phase)."""
    padded[0, 1:-1] = padded[2, 1:-1]
    padded[-1, 1:-1] = padded[-3, 1:-1]
    padded[:, 0] = padded[:, 2]
    padded[:, -1] = padded[:, -3]
    return padded


def _bilinear_padded(padded, cfa_pattern, out=None) -> np.ndarray:
    """:func:`_bilinear` of the mosaic in the interior of ``padded`` (H + 2, W + 2) float32, its border not yet
    filled (:func:`_mirror_edges` fills it): a 1-pixel mirror gives the 3 × 3 neighbourhoods that
    :data:`DEMOSAIC_PAD`'s 4-pixel mirror gives the interior."""
    p = _mirror_edges(padded)
    height, width = p.shape[0] - 2, p.shape[1] - 2
    if out is None:
        out = np.empty((3, height, width), dtype=np.float32)
    vertical_full = np.add(p[:-2], p[2:], out=_workspace("bilinear.vertical", (height, width + 2)))  # above + below
    vertical = vertical_full[:, 1:-1]
    horizontal = np.add(p[1:-1, :-2], p[1:-1, 2:], out=_workspace("bilinear.horizontal", (height, width)))
    diagonal = np.add(vertical_full[:, :-2], vertical_full[:, 2:],  # the 4 diagonal neighbours
                      out=_workspace("bilinear.diagonal", (height, width)))
    cross = np.add(horizontal, vertical, out=_workspace("bilinear.cross", (height, width)))  # beside, above, below
    m = p[1:-1, 1:-1]
    half, quarter = np.float32(0.5), np.float32(0.25)
    where = {"RGB".index(letter): (i // 2, i % 2) for i, letter in enumerate(cfa_pattern) if letter != "G"}
    for dy, dx, own in cfa_sites(cfa_pattern):
        site = (slice(dy, None, 2), slice(dx, None, 2))
        for c in range(3):
            target = out[(c,) + site]
            if c == own:
                target[...] = m[site]
            elif c == 1:  # green at a red or blue site
                np.multiply(cross[site], quarter, out=target)
            else:
                cy, cx = where[c]
                if cy == dy:  # the colour is beside this site
                    np.multiply(horizontal[site], half, out=target)
                elif cx == dx:  # above and below
                    np.multiply(vertical[site], half, out=target)
                else:
                    np.multiply(diagonal[site], quarter, out=target)
    return out


#: Images of at most this many values get their temporaries from a per-thread workspace (:func:`_workspace`).
WORKSPACE_MAX_VALUES = 1 << 20
_WORKSPACE = threading.local()


def _workspace(name: str, shape) -> np.ndarray:
    """A float32 buffer of ``shape`` kept per thread under ``name`` and reused by the next call with the same
    shape, for an ISP's temporaries: fresh memory costs page faults that, on a 256 × 256 pair, take as long as the
    arithmetic of a stage. Larger than :data:`WORKSPACE_MAX_VALUES`: a new array (nothing kept). The caller owns
    the buffer until its next call with the same name; it never leaves the ISP."""
    shape = tuple(int(n) for n in shape)
    if int(np.prod(shape)) > WORKSPACE_MAX_VALUES:
        return np.empty(shape, dtype=np.float32)
    buffers = getattr(_WORKSPACE, "buffers", None)
    if buffers is None:
        buffers = _WORKSPACE.buffers = {}
    found = buffers.get(name)
    if found is None or found.shape != shape:
        found = buffers[name] = np.empty(shape, dtype=np.float32)
    return found


def _bilinear_method(mosaic, cfa_pattern):
    """camsim's bilinear demosaicing by slicing (:func:`_bilinear`), equal to colour-demosaicing's
    ``demosaicing_CFA_Bayer_bilinear`` within float32 rounding."""
    return _bilinear(mosaic, cfa_pattern)


#: Demosaicing methods by name: ``f(mosaic (H, W) float, pattern) -> (3, H, W) float32``: bilinear by slicing
#: (:func:`_bilinear`, colour-demosaicing's within float32 rounding), the others colour-demosaicing's.
DEMOSAIC_METHODS = {
    "bilinear": _bilinear_method,
    "malvar2004": _colour_demosaicing("demosaicing_CFA_Bayer_Malvar2004"),
    "menon2007": _colour_demosaicing("demosaicing_CFA_Bayer_Menon2007"),
}
#: The demosaicing methods that are linear and per channel — each output colour a weighted sum of that colour's
#: sites only — so that white-balance gains (or any per-channel gains) before them equal the same gains after
#: them, and the white balance, the colour matrix and the digital gain become one 3 × 3 matrix after demosaicing
#: (:func:`camsim.isp.develop`). Bilinear is; Malvar 2004 mixes channels (its corrections add the other colours'
#: Laplacians) and Menon 2007 is not linear.
PER_CHANNEL_LINEAR = frozenset({"bilinear"})
#: Where each demosaicing method comes from (for the developed image's record).
DEMOSAIC_SOURCES = {"bilinear": "camsim (slicing; colour-demosaicing's demosaicing_CFA_Bayer_bilinear within "
                                "float32 rounding)",
                    "malvar2004": "colour-demosaicing", "menon2007": "colour-demosaicing"}


def demosaic(mosaic, cfa_pattern: str, method: str = "malvar2004") -> np.ndarray:
    """A Bayer mosaic to a three-chip image.

    Parameters
    ----------
    mosaic : array_like, shape (H, W) or (1, H, W)
        One value per pixel, the colour of each site given by ``cfa_pattern``.
    cfa_pattern : {"RGGB", "BGGR", "GRBG", "GBRG"}
    method : str
        A key of :data:`DEMOSAIC_METHODS`: ``"bilinear"``, ``"malvar2004"`` (Malvar, He and Cutler 2004,
        gradient-corrected linear interpolation), ``"menon2007"`` (Menon, Andriani and Calvagno 2007, directional
        filtering with a posteriori decision), the last two colour-demosaicing's; ``"bilinear"`` is camsim's own
        in float32, colour-demosaicing's bilinear within float32 rounding (:func:`_bilinear`).

    Returns
    -------
    numpy.ndarray, shape (3, H, W), float32
        R, G, B at every pixel, in the units of ``mosaic``.
    """
    if method not in DEMOSAIC_METHODS:
        raise CamsimError(f"unknown demosaicing method {method!r}; methods: {', '.join(DEMOSAIC_METHODS)}")
    mosaic = _check_mosaic(mosaic, cfa_pattern)
    return DEMOSAIC_METHODS[method](mosaic, cfa_pattern)


# ---------------------------------------------------------------------------------------------------------- matrix
#: The training reflectances of the ``"camera"`` matrix: colour-science's copy of the 190 patches of rawtoaces'
#: training data (``colour.characterisation.read_training_data_rawtoaces_v1``), not the ColorChecker.
TRAINING_SET = "rawtoaces v1 training data (190 reflectances)"


def _trained_camera_to_xyz(facts, illuminant: str) -> np.ndarray:
    """Least squares camera → XYZ over the :data:`TRAINING_SET` reflectances under ``illuminant``: the camera's
    values Σ_λ Qe ρ E λ (photons: the energy radiance ρ E over h c / λ; any common scale) against XYZ = Σ_λ
    (x̄, ȳ, z̄) ρ E, both on the frame's wavelength grid. Cached per camera, grid and illuminant (the frames of a
    dataset share them)."""
    qe = np.ascontiguousarray(facts.qe, dtype=np.float64)
    wl = np.ascontiguousarray(facts.wavelengths_nm, dtype=np.float64)
    return _trained_cached(qe.tobytes(), wl.tobytes(), illuminant).copy()


@functools.lru_cache(maxsize=32)
def _trained_cached(qe_bytes: bytes, wl_bytes: bytes, illuminant: str) -> np.ndarray:
    from camsim.light.spectra import cmfs_on_grid, illuminant_spd, import_colour

    colour = import_colour()
    wl = np.frombuffer(wl_bytes, dtype=np.float64)
    qe = np.frombuffer(qe_bytes, dtype=np.float64).reshape(3, wl.size)
    grid = _grid(wl)
    shape = colour.SpectralShape(float(wl[0]), float(wl[-1]), float(grid.step_nm))
    training = colour.characterisation.read_training_data_rawtoaces_v1().copy().align(shape)
    reflectances = np.asarray(training.values, dtype=np.float64).T  # (K, N)
    radiance = reflectances * illuminant_spd(illuminant, grid)
    camera = (radiance * wl) @ (qe / np.max(qe)).T
    xyz = radiance @ cmfs_on_grid(grid).T
    solution, *_ = np.linalg.lstsq(camera, xyz, rcond=None)  # xyz ≈ camera @ solution
    return solution.T


def _camera_to_xyz(facts, source: str, illuminant: str | None) -> tuple[np.ndarray, str]:
    """(C, what C is): see :func:`camera_to_xyz`."""
    if source not in ("camera", "paper", "dng"):
        raise CamsimError(f"unknown colour matrix {source!r}; matrices: {', '.join(MATRICES)}")
    if source in ("camera", "paper") and facts.qe is not None:
        from camsim.light.spectra import import_colour

        if source == "camera" and illuminant is not None and illuminant in import_colour().SDS_ILLUMINANTS:
            return (_trained_camera_to_xyz(facts, illuminant),
                    f"least squares on the {TRAINING_SET} under {illuminant}, from the camera's QE")
        from camsim.colour.colorimetry import camera_to_xyz_matrix

        try:
            return (camera_to_xyz_matrix(facts.qe, facts.wavelengths_nm, 1.0, method="paper"),
                    "Eq. 15 projection of the camera's QE on the CIE 1931 CMFs")
        except ValueError as exc:
            raise CamsimError(f"no colour matrix for this camera: {exc}") from None
    if source == "paper":
        raise CamsimError("matrix 'paper' needs the camera's spectral sensitivities (a sidecar's qe)")
    if facts.color_matrix1 is None:
        raise CamsimError("matrix 'dng' needs the frame's ColorMatrix1, which its metadata lacks")
    try:
        return np.linalg.inv(facts.color_matrix1), "inverse of ColorMatrix1"
    except np.linalg.LinAlgError:
        raise CamsimError("the DNG's ColorMatrix1 is singular: no colour matrix") from None


def _white_balance_illuminant(facts, white_balance: str) -> str | None:
    """The illuminant the white balance is made for: the frame's for ``"as-shot"`` and ``"none"``, else the
    name given."""
    return facts.illuminant if white_balance in WHITE_BALANCE_MODES else white_balance


def camera_to_xyz(facts, source: str = "camera", illuminant: str | None = None) -> np.ndarray:
    """The 3 × 3 matrix C from (black-subtracted, normalised) camera R, G, B to CIE 1931 XYZ, any scale
    (``xyz = C @ rgb``).

    ``source``:

    * ``"camera"``: from the camera's spectral sensitivities (the sidecar's QE) and ``illuminant`` (a
      colour-science name): the least-squares fit of the XYZ of :data:`TRAINING_SET` (190 reflectances, not the
      ColorChecker) under that light to the camera's values of the same light; without a known illuminant, as
      ``"paper"``; without a QE (a DNG alone), as ``"dng"``;
    * ``"paper"``: the paper's Eq. 15 projection of the QE on the colour-matching functions, which does not depend
      on the light (:func:`camsim.colour.colorimetry.camera_to_xyz_matrix`, method ``"paper"``);
    * ``"dng"``: the inverse of the DNG's ColorMatrix1 (camsim's: a least-squares fit on the ColorChecker under
      D65), as raw converters use it.
    """
    return _camera_to_xyz(facts, source, illuminant)[0]


def srgb_matrix(facts, white_balance: str = "as-shot", source: str = "camera") -> np.ndarray:
    """The 3 × 3 matrix from white-balanced camera R, G, B to linear sRGB (``rgb_srgb = M @ rgb_wb``).

    Built as M = XYZ→sRGB · A · C · diag(n / n_G), normalised so that M · (1, 1, 1) = (1, 1, 1):

    * C: camera → XYZ, :func:`camera_to_xyz` with ``source`` (``"camera"``: fitted on training reflectances
      under the white-balance illuminant; ``"paper"``: Eq. 15; ``"dng"``: ColorMatrix1⁻¹);
    * n: the camera neutral of the white balance (the camera's response to the perfect white under the
      white-balance illuminant: the as-shot neutral, or the named illuminant's); diag(n / n_G) undoes the
      white-balance gains, so M acts on white-balanced values;
    * A: von Kries chromatic adaptation in Bradford cone space from the white C · n (the perfect white under the
      white-balance illuminant) to D65, the sRGB white (colour-science's
      ``matrix_chromatic_adaptation_VonKries``);
    * XYZ→sRGB: the inverse of the normalised primary matrix of the sRGB primaries and D65 white (IEC 61966-2-1;
      colour-science's ``normalised_primary_matrix``).

    So the perfect white under the white-balance illuminant — (1, 1, 1) after the white balance — maps to sRGB
    white (1, 1, 1), and a camera value at level v of the white level, neutral, maps to v. With
    ``white_balance="none"`` no adaptation is made: M = XYZ→sRGB · C, scaled so that the as-shot neutral at
    green level 1 has luminance Y = 1 (the scene's white keeps its colour).
    """
    return _srgb_matrix(facts, white_balance, source)[0]


def _srgb_matrix(facts, white_balance: str, source: str) -> tuple[np.ndarray, str]:
    from camsim.light.spectra import import_colour

    colour = import_colour()
    to_xyz, what = _camera_to_xyz(facts, source, _white_balance_illuminant(facts, white_balance))
    srgb = colour.RGB_COLOURSPACES["sRGB"]
    # XYZ → sRGB from the primaries and the D65 white point themselves (the colourspace's stored matrix is rounded
    # to 4 decimals, which would leave the white 2e-4 off (1, 1, 1))
    xyz_to_srgb = np.linalg.inv(colour.normalised_primary_matrix(srgb.primaries, srgb.whitepoint))
    neutral = _neutral(facts, white_balance)
    if neutral is None:
        white = to_xyz @ (facts.as_shot_neutral / facts.as_shot_neutral[1])
        if not (np.isfinite(white[1]) and white[1] > 0):
            raise CamsimError(f"no colour matrix: the camera's white maps to XYZ {white.tolist()}")
        return xyz_to_srgb @ to_xyz / white[1], what
    white = to_xyz @ neutral
    if not (np.all(np.isfinite(white)) and white[1] > 0):
        raise CamsimError(f"cannot white-balance: the camera's white maps to XYZ {white.tolist()}")
    d65 = colour.xy_to_XYZ(srgb.whitepoint)
    adapt = colour.adaptation.matrix_chromatic_adaptation_VonKries(white / white[1], d65 / d65[1],
                                                                   transform=CHROMATIC_ADAPTATION)
    m = xyz_to_srgb @ adapt @ to_xyz @ np.diag(neutral / neutral[1])
    return m / np.mean(m.sum(axis=1)), what


def apply_matrix(rgb, m) -> np.ndarray:
    """``out[c] = Σ_j m[c, j] · rgb[j]`` on a (3, H, W) image, in float32, element by element. Returns (3, H, W)
    float32."""
    rgb = _check_image(rgb, "rgb")
    m = np.asarray(m, dtype=np.float64)
    if m.shape != (3, 3) or not np.all(np.isfinite(m)):
        raise CamsimError(f"colour matrix must be a finite 3 × 3, got {m.shape}")
    m32 = m.astype(np.float32)
    out = np.empty(rgb.shape, dtype=np.float32)
    term = np.empty(rgb.shape[1:], dtype=np.float32)
    for c in range(3):
        np.multiply(rgb[0], m32[c, 0], out=out[c])
        for j in (1, 2):
            np.multiply(rgb[j], m32[c, j], out=term)
            out[c] += term
    return out


def apply_gain(x, gain: float) -> np.ndarray:
    """A digital gain on normalised linear values: ``x · gain`` (float32)."""
    if not (np.isfinite(gain) and gain > 0):
        raise CamsimError(f"gain must be a positive number, got {gain!r}")
    x = np.asarray(x, dtype=np.float32)
    return x * np.float32(gain)


# ------------------------------------------------------------------------------------------------------ tone curves
def _srgb(x, out=None, scratch=None):
    """IEC 61966-2-1 (sRGB) transfer function, on values clipped to [0, 1]: 12.92 x for x ≤ 0.0031308, else
    1.055 x^(1/2.4) − 0.055. float32. ``out`` (float32, the shape of ``x``; it may be ``x`` itself) receives the
    result; ``scratch`` (the same) is a buffer it may overwrite.

    The same numbers as the formula taken branch by branch in float32 (checked on every float32 in [0, 1]),
    without its slow parts: the power is taken of max(x, 0.0031308) (numpy's power is slow on zeros), and the
    branch is chosen without a masked select (``where=``, which costs three times the power itself on noisy
    images): the power branch is divided by x > 0.0031308 (a boolean: ÷ 1 keeps it, ÷ 0 makes it +∞ at and below
    the threshold) and the smaller of it and 12.92 x kept — above the threshold the power branch is below 12.92 x
    for every float32 (the curve's slope there, about 12.7, is below 12.92)."""
    x = np.clip(np.asarray(x, dtype=np.float32), np.float32(0.0), np.float32(1.0), out=out)
    y = np.maximum(x, _SRGB_THRESHOLD, out=None if out is None else _workspace("srgb.power", x.shape))
    np.power(y, np.float32(1 / 2.4), out=y)
    y *= np.float32(1.055)
    y -= np.float32(0.055)
    with np.errstate(divide="ignore"):
        np.divide(y, x > _SRGB_THRESHOLD, out=y)  # +∞ at and below the threshold (y > 0 there)
    low = np.multiply(x, np.float32(12.92), out=scratch)
    return np.minimum(y, low, out=y if out is None else x)


_SRGB_THRESHOLD = np.float32(0.0031308)


def _filmic(x):
    """Narkowicz's 2015 fit of the ACES filmic tone curve (K. Narkowicz, "ACES Filmic Tone Mapping Curve", 2015),
    f(x) = x (2.51 x + 0.03) / (x (2.43 x + 0.59) + 0.14), clipped to [0, 1], then the sRGB transfer function.
    f(1) ≈ 0.80 and f reaches 1 at x ≈ 7.2: highlights up to about 7 × the white level roll off instead of
    clipping."""
    x = np.maximum(np.asarray(x, dtype=np.float32), 0.0)
    y = x * (np.float32(2.51) * x + np.float32(0.03)) / (x * (np.float32(2.43) * x + np.float32(0.59))
                                                          + np.float32(0.14))
    return _srgb(y)


def _linear(x):
    """No curve: the linear values, clipped to [0, 1]."""
    return np.clip(np.asarray(x, dtype=np.float32), 0.0, 1.0)


#: Tone curves by name: linear sRGB (1 = white) → encoded values in [0, 1].
TONE_CURVES = {"srgb": _srgb, "filmic": _filmic, "linear": _linear}


def tone_curve(rgb, name: str = "srgb") -> np.ndarray:
    """The tone curve ``name`` (:data:`TONE_CURVES`) on linear values; result float32 in [0, 1].

    * ``"srgb"``: the IEC 61966-2-1 transfer function (values clipped to [0, 1] first);
    * ``"filmic"``: Narkowicz 2015's ACES fit, x (2.51 x + 0.03) / (x (2.43 x + 0.59) + 0.14), then sRGB's;
    * ``"linear"``: the values clipped to [0, 1].
    """
    if name not in TONE_CURVES:
        raise CamsimError(f"unknown tone curve {name!r}; curves: {', '.join(TONE_CURVES)}")
    return TONE_CURVES[name](rgb)
