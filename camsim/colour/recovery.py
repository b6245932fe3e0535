"""RGB → reflectance spectrum recovery, by method name from one registry (issue 12, for image scenes).

An image scene gives a colour per pixel, not a spectrum; the camera model needs spectra. This module turns
linear RGB into reflectance spectra on a :class:`camsim.light.spectra.WavelengthGrid` with colour-science's recovery
methods. :data:`RECOVERY_METHODS` maps each name to one function; :func:`rgb_to_distinct_spectra` (the full
record) and :func:`rgb_to_spectra` (the spectra alone) are the entry points that dispatch.

Input: linear (not gamma-encoded) RGB in a named colour-science colourspace (``colour.RGB_COLOURSPACES``,
default ``"sRGB"``), shape (..., 3), reflectance-like (1 = the perfect white, reflectance 1 at every
wavelength). Output: reflectance factors on the grid, unitless.

Methods
-------
``"Mallett 2019"`` (the default)
    spectrum = rgb_sRGB,linear · B, with B the three basis spectra of
    ``colour.recovery.MSDS_BASIS_FUNCTIONS_sRGB_MALLETT2019`` (:func:`mallett_basis`, shape (3, N)). Linear in
    RGB: whatever is integrated against a spectrum (illuminant × Qe × photon factor) is one 3 × 3 matrix applied
    to the RGB (:func:`basis_matrix`), so a renderer never needs an H × W × N cube. Defined for sRGB only: other
    colourspaces are converted to linear sRGB first (``colour.RGB_to_RGB``, CAT02).
``"Otsu 2018"`` and ``"Jakob 2019"``
    Non-linear, one colour at a time through CIE XYZ (``colour.recovery.XYZ_to_sd_Otsu2018`` and
    ``find_coefficients_Jakob2019`` / ``sd_Jakob2019``). Images go through :func:`rgb_to_distinct_spectra`:
    each distinct (optionally quantised) colour is recovered once, and kept in a cache across calls
    (:data:`CACHE_SIZE` entries, least recently used first out).

The XYZ convention (colour-science's own for these methods): CIE 1931 2° observer, illuminant D65, XYZ scaled
so that the perfect white has Y = 1. Linear RGB goes to XYZ with ``colour.RGB_to_XYZ`` relative to D65's
chromaticity (0.3127, 0.3290); a colourspace with another white (e.g. ProPhoto RGB, D50) is adapted to D65
with CAT02. Otsu's reconstruction and Jakob's optimisation then integrate the CIE 1931 2° functions and
colour-science's D65 on their own grids (Otsu: 380–730 nm every 10 nm; Jakob: 360–780 nm every 5 nm).

Resampling to the grid. Mallett's basis (380–780 nm, 5 nm) and Otsu's spectra (380–730 nm, 10 nm) are
resampled with colour-science's linear interpolator (no overshoot: [0, 1] data stays in [0, 1], and Mallett's
basis keeps summing to 1). Beyond a method's range, its end values are held (colour-science's default
``Constant`` extrapolation of a ``SpectralDistribution``): with the default 380–780 nm grid that is Otsu's
730–780 nm. Jakob's sigmoid is evaluated on the grid's wavelengths directly (no resampling).

Out of gamut (what each method does, recorded, never silent)
------------------------------------------------------------
* Non-finite or negative input components are refused (:class:`CamsimError`): a reflectance-like colour has
  none in its own colourspace; clip noise before recovery if it is wanted.
* Black (0, 0, 0) gives a zero spectrum with every method (Otsu and Jakob cannot reach 0 themselves).
* RGB above 1 (brighter than the perfect white, e.g. a highlight): Mallett is linear, so it is exact and the
  reflectance exceeds 1 where the basis asks. Otsu and Jakob are bounded to [0, 1] reflectance; a colour whose
  largest component s exceeds 1 is recovered at 1/s of its brightness and the spectrum is multiplied by s
  (exact in XYZ, which is linear in the spectrum), so its reflectance may exceed 1 too.
* Colours outside sRGB with Mallett (from another colourspace): negative linear sRGB components are clipped to
  0 (the nearest non-negative mixture of the basis; the spectrum would otherwise go negative, which a photon
  rate cannot) and the colour is flagged ``outside`` where a component is below −:data:`OUTSIDE_SRGB_TOLERANCE`
  times the largest (the rounding of sRGB's standard matrices leaves −4.8e-5 on Display P3's blue, which is
  sRGB's: no colour outside). An image
  scene records what fell outside in its frames' sidecars (``recovery``) and ``camsim render`` warns once per
  frame (:mod:`camsim.scene.sources.image`).
* Otsu: the reconstruction is clipped to [0, 1] (colour-science's ``clip=True``) and the colour is flagged
  ``outside`` when the clip changed it — this happens for saturated colours, for colours outside the spectral
  locus (Otsu's cluster tree picks the nearest dataset cluster anyway), and for the perfect white itself
  (Otsu's dataset of measured reflectances has nothing flat at 1).
* Jakob: the sigmoid spectrum lies strictly inside (0, 1); a colour it cannot reach (outside the spectral locus,
  too bright for its chromaticity, or at white/black limits) ends with the optimiser's error above
  :data:`JAKOB2019_MAX_ERROR` and is flagged ``outside``.
* For every method and colour, :attr:`RecoveredSpectra.delta_e` records the CIE 2000 ΔE of the recovered
  spectrum (integrated on the grid under D65) against the requested colour, so any miss is measured;
  ``max_delta_e`` turns a miss beyond a bound into a refusal.
"""

from __future__ import annotations

import functools
import time
from collections import OrderedDict
from dataclasses import dataclass

import numpy as np

from camsim.core.errors import CamsimError
from camsim.light.spectra import CMFS_NAME, WavelengthGrid, align_to_grid, cmfs_on_grid, illuminant_spd, import_colour

DEFAULT_METHOD = "Mallett 2019"
DEFAULT_COLOURSPACE = "sRGB"
#: The illuminant of the XYZ convention (colour-science's default for Otsu 2018 and Jakob 2019).
REFERENCE_ILLUMINANT = "D65"
#: Jakob 2019: the optimiser's error (colour-science's ``max_error``, its default) beyond which a colour is
#: flagged as outside the method's reach.
JAKOB2019_MAX_ERROR = 0.023
#: Mallett 2019: a colour counts as outside sRGB where a linear sRGB component is below −this × its largest one.
#: colour-science uses sRGB's standard matrices as given (4 decimals, IEC 61966-2-1; inverse to about 1e-4), which
#: leaves colours on sRGB's border slightly negative: Display P3's blue, which is sRGB's blue, converts to
#: (−4.8e-5, −2.6e-6, 1.098). Such a component is set to 0 all the same. Unitless.
OUTSIDE_SRGB_TOLERANCE = 1e-4
#: Distinct colours kept by the cache of the per-colour methods (about 13 MB at N = 101).
CACHE_SIZE = 16384


# --------------------------------------------------------------------------------------------------- checks


def _colourspace(name):
    """The colour-science ``RGB_Colourspace`` called ``name``; an unknown name is a :class:`CamsimError`."""
    colour = import_colour()
    if not isinstance(name, str) or name not in colour.RGB_COLOURSPACES:
        raise CamsimError(f"unknown RGB colourspace {name!r}; use a name of colour.RGB_COLOURSPACES "
                          "(e.g. 'sRGB', 'Display P3', 'Adobe RGB (1998)', 'ProPhoto RGB', 'ACES2065-1')")
    return colour.RGB_COLOURSPACES[name]


def _method(name):
    try:
        return RECOVERY_METHODS[name]
    except (KeyError, TypeError):
        raise CamsimError(f"unknown recovery method {name!r}; methods: {', '.join(RECOVERY_METHODS)}") from None


def _check_rgb(rgb) -> np.ndarray:
    try:
        values = np.asarray(rgb, dtype=np.float64)
    except (TypeError, ValueError):
        raise CamsimError("RGB values must be numbers") from None
    if values.ndim < 1 or values.shape[-1] != 3:
        raise CamsimError(f"RGB values must have shape (..., 3), got {values.shape}")
    if not np.all(np.isfinite(values)):
        raise CamsimError("RGB values contain NaN or infinite values")
    negative = values < 0
    if np.any(negative):
        raise CamsimError(f"linear RGB has {int(negative.sum())} negative components (min {values.min():.4g}); "
                          "recovery needs reflectance-like colours ≥ 0 (clip noise before recovery)")
    return values + 0.0  # -0.0 → 0.0, so that equal colours are equal bytes


def _grid(grid) -> WavelengthGrid:
    return WavelengthGrid() if grid is None else grid


# ----------------------------------------------------------------------------------------------- resampling


def _resample(wavelengths_nm, values, grid: WavelengthGrid, what: str) -> np.ndarray:
    """Linear interpolation onto ``grid`` (colour-science), end values held beyond the data's range.

    ``values`` has shape (M,) or (M, C); the result (N,) or (N, C).
    """
    wl = np.asarray(wavelengths_nm, dtype=np.float64)
    vals = np.asarray(values, dtype=np.float64)
    target = grid.wavelengths_nm
    if target[0] < wl[0] - 1e-9:
        wl, vals = np.concatenate([[target[0]], wl]), np.concatenate([vals[:1], vals])
    if target[-1] > wl[-1] + 1e-9:
        wl, vals = np.concatenate([wl, [target[-1]]]), np.concatenate([vals, vals[-1:]])
    return align_to_grid(wl, vals, grid, what, zero_outside=False)


@functools.lru_cache(maxsize=8)
def _resampling_matrix(wavelengths: tuple, grid: WavelengthGrid) -> np.ndarray:
    """The (N, M) matrix of :func:`_resample` (it is linear): spectrum_on_grid = R @ values."""
    matrix = _resample(np.array(wavelengths), np.eye(len(wavelengths)), grid, "recovered spectrum")
    matrix.flags.writeable = False
    return matrix


# ----------------------------------------------------------------------------------------- colour conversions


def _d65_xy() -> np.ndarray:
    return np.asarray(import_colour().CCS_ILLUMINANTS[CMFS_NAME][REFERENCE_ILLUMINANT], dtype=np.float64)


def rgb_to_xyz(rgb, colourspace: str = DEFAULT_COLOURSPACE) -> np.ndarray:
    """CIE XYZ (1931 2°) of linear RGB, relative to D65, with the perfect white at Y = 1.

    Parameters
    ----------
    rgb : array_like, shape (..., 3)
        Linear RGB in ``colourspace``.
    colourspace : str
        A name of ``colour.RGB_COLOURSPACES``; its white is adapted to D65 with CAT02 when it differs.

    Returns
    -------
    numpy.ndarray, shape (..., 3)
    """
    colour = import_colour()
    space = _colourspace(colourspace)
    return np.asarray(colour.RGB_to_XYZ(np.asarray(rgb, dtype=np.float64), space, illuminant=_d65_xy(),
                                        chromatic_adaptation_transform="CAT02"), dtype=np.float64)


def linear_srgb(rgb, colourspace: str = DEFAULT_COLOURSPACE, return_clip: bool = False):
    """Linear sRGB of linear RGB in ``colourspace``, negative components clipped to 0.

    Parameters
    ----------
    rgb : array_like, shape (..., 3)
        Linear RGB in ``colourspace``, components ≥ 0.
    colourspace : str
        A name of ``colour.RGB_COLOURSPACES``. ``"sRGB"`` is returned unchanged (no conversion, nothing
        clipped); any other goes through ``colour.RGB_to_RGB`` (CAT02 between different whites).
    return_clip : bool
        Also return how much each colour lost.

    Returns
    -------
    srgb : numpy.ndarray, shape (..., 3)
        Linear sRGB, every component ≥ 0: Mallett 2019's weights.
    outside : numpy.ndarray of bool, shape (...)
        True where a component was below −:data:`OUTSIDE_SRGB_TOLERANCE` × the largest (the colour lies outside
        sRGB's gamut) and was clipped to 0.
    clip : numpy.ndarray, shape (...)
        Only with ``return_clip``: the most negative component's magnitude, max(0, −min(r, g, b)), set to 0.
        Unit: linear sRGB (1 = the perfect white's component).
    """
    space = _colourspace(colourspace)
    values = _check_rgb(rgb)
    if space.name == "sRGB":
        srgb = values
    else:
        colour = import_colour()
        srgb = np.asarray(colour.RGB_to_RGB(values, space, colour.RGB_COLOURSPACES["sRGB"],
                                            chromatic_adaptation_transform="CAT02"), dtype=np.float64)
    clip = np.maximum(-np.min(srgb, axis=-1), 0.0)
    outside = clip > OUTSIDE_SRGB_TOLERANCE * np.max(np.abs(srgb), axis=-1)
    clipped = srgb if space.name == "sRGB" else np.maximum(srgb, 0.0)
    return (clipped, outside, clip) if return_clip else (clipped, outside)


# ------------------------------------------------------------------------------------------------ Mallett


@functools.lru_cache(maxsize=8)
def mallett_basis(grid: WavelengthGrid | None = None) -> np.ndarray:
    """Mallett & Yuksel (2019)'s three sRGB basis spectra on ``grid`` (read-only).

    ``colour.recovery.MSDS_BASIS_FUNCTIONS_sRGB_MALLETT2019`` (380–780 nm, 5 nm), resampled linearly (end values
    held beyond 380–780 nm). They sum to 1 at every wavelength (to 1e-5 in colour-science's data), so the white
    (1, 1, 1) gives a flat unit reflectance, and every value lies in [0, 1].

    Parameters
    ----------
    grid : WavelengthGrid, optional
        Default: 380–780 nm every 4 nm.

    Returns
    -------
    numpy.ndarray, shape (3, N)
        Rows: the red, green and blue basis spectra; reflectance of linear sRGB (1, 0, 0), (0, 1, 0), (0, 0, 1).
        spectrum = rgb_srgb_linear @ basis.
    """
    colour = import_colour()
    data = colour.recovery.MSDS_BASIS_FUNCTIONS_sRGB_MALLETT2019
    basis = _resample(data.wavelengths, data.values, _grid(grid), "Mallett 2019 basis").T.copy()
    basis.flags.writeable = False
    return basis


def basis_matrix(basis, weights) -> np.ndarray:
    """Contract basis spectra with spectral weights: the matrix that replaces integrating every spectrum.

    With spectrum(λ) = Σ_j c_j basis_j(λ), any weighted sum over wavelength is linear in c:
    Σ_λ spectrum(λ) weights_κ(λ) = Σ_j M[κ, j] c_j, with M[κ, j] = Σ_λ weights_κ(λ) basis_j(λ). For a camera
    (weights_κ = E(λ) · Qe_κ(λ) · photon factor) this gives expected electrons = rgb @ M.T: one 3 × 3 matrix per
    camera and illuminant, never an H × W × N cube.

    Parameters
    ----------
    basis : array_like, shape (J, N)
        Basis spectra (e.g. :func:`mallett_basis`, J = 3), unitless reflectance.
    weights : array_like, shape (K, N)
        What each output integrates a spectrum against, per wavelength bin (unit: the output's per unit
        reflectance).

    Returns
    -------
    numpy.ndarray, shape (K, J)
        M, so that outputs (..., K) = coefficients (..., J) @ M.T.
    """
    basis = np.asarray(basis, dtype=np.float64)
    weights = np.asarray(weights, dtype=np.float64)
    if basis.ndim != 2 or weights.ndim != 2 or basis.shape[1] != weights.shape[1]:
        raise CamsimError(f"basis (J, N) and weights (K, N) must share N; got {basis.shape} and {weights.shape}")
    return weights @ basis.T


def _recover_mallett2019(rgb, colourspace, grid):
    """Mallett 2019 on (K, 3) colours: spectra (K, N) and the outside-sRGB flags (K,)."""
    srgb, outside = linear_srgb(rgb, colourspace)
    return srgb @ mallett_basis(grid), outside


# --------------------------------------------------------------------------------------- per-colour methods


def _per_colour(rgb, colourspace, grid, recover_one):
    """Run ``recover_one(xyz) -> (spectrum (N,), outside)`` per colour, with black and brightness handled.

    Black gives zeros; a colour whose largest component s exceeds 1 is recovered at 1/s of its brightness and its
    spectrum multiplied by s.
    """
    rgb = np.asarray(rgb, dtype=np.float64)
    xyz = rgb_to_xyz(rgb, colourspace)
    spectra = np.zeros((rgb.shape[0], grid.size))
    outside = np.zeros(rgb.shape[0], dtype=bool)
    for i in range(rgb.shape[0]):
        peak = rgb[i].max()
        if peak == 0.0:
            continue
        scale = max(1.0, peak)
        spectrum, outside[i] = recover_one(xyz[i] / scale)
        spectra[i] = spectrum * scale
    return spectra, outside


def _recover_otsu2018(rgb, colourspace, grid):
    """Otsu 2018 on (K, 3) colours: spectra (K, N) and the flags (K,) of colours that its [0, 1] clip changed."""
    colour = import_colour()

    def one(xyz):
        sd = colour.recovery.XYZ_to_sd_Otsu2018(xyz, clip=False)
        values = sd.values
        clipped = bool(values.min() < 0.0 or values.max() > 1.0)
        matrix = _resampling_matrix(tuple(sd.wavelengths.tolist()), grid)
        return matrix @ np.clip(values, 0.0, 1.0), clipped

    return _per_colour(rgb, colourspace, grid, one)


def _recover_jakob2019(rgb, colourspace, grid):
    """Jakob 2019 on (K, 3) colours: spectra (K, N) and the flags (K,) of colours the optimiser did not reach."""
    colour = import_colour()
    shape = grid.shape()

    def one(xyz):
        coefficients, error = colour.recovery.find_coefficients_Jakob2019(xyz, max_error=JAKOB2019_MAX_ERROR)
        values = colour.recovery.sd_Jakob2019(coefficients, shape).values
        return values, bool(error > JAKOB2019_MAX_ERROR)

    return _per_colour(rgb, colourspace, grid, one)


#: Method name → function(rgb (K, 3) linear in the colourspace, colourspace name, grid) → (spectra (K, N),
#: outside (K,) bool). :func:`rgb_to_distinct_spectra` is the one entry point that dispatches on it.
RECOVERY_METHODS = {
    "Mallett 2019": _recover_mallett2019,
    "Otsu 2018": _recover_otsu2018,
    "Jakob 2019": _recover_jakob2019,
}
#: Methods recovered one colour at a time, and therefore cached per distinct colour.
PER_COLOUR_METHODS = ("Otsu 2018", "Jakob 2019")

_CACHE: OrderedDict = OrderedDict()


def clear_cache() -> None:
    """Empty the per-colour cache of Otsu 2018 and Jakob 2019."""
    _CACHE.clear()


# ------------------------------------------------------------------------------------------------- dispatch


def distinct_colours(rgb, colourspace: str = DEFAULT_COLOURSPACE, bits: int | None = None):
    """The distinct colours of an array, optionally after quantising their encoded values.

    Parameters
    ----------
    rgb : array_like, shape (..., 3)
        Linear RGB in ``colourspace``, components ≥ 0.
    colourspace : str
        A name of ``colour.RGB_COLOURSPACES``; its encoding (``cctf_encoding``) is what ``bits`` quantises.
    bits : int or None
        None: distinct float triples, exactly. 1 … 16: each component is encoded with the colourspace's transfer
        function, rounded to a multiple of 1 / (2^bits − 1) (values above 1 keep codes above 2^bits − 1), and
        decoded back: the representative colour of every pixel that shares the codes.

    Returns
    -------
    colours : numpy.ndarray, shape (K, 3)
        The distinct (representative) linear colours, in lexicographic order.
    labels : numpy.ndarray of intp, shape (...)
        Index into ``colours`` of every input colour.
    """
    values = _check_rgb(rgb)
    flat = values.reshape(-1, 3)
    if bits is None:
        colours, inverse = np.unique(flat, axis=0, return_inverse=True)
    else:
        if isinstance(bits, bool) or not isinstance(bits, (int, np.integer)) or not 1 <= bits <= 16:
            raise CamsimError(f"quantisation bits must be an integer 1 … 16 or None, got {bits!r}")
        space = _colourspace(colourspace)
        levels = float(2 ** int(bits) - 1)
        encode = space.cctf_encoding or (lambda x: x)
        decode = space.cctf_decoding or (lambda x: x)
        codes = np.rint(np.asarray(encode(flat), dtype=np.float64) * levels).astype(np.int64)
        unique_codes, inverse = np.unique(codes, axis=0, return_inverse=True)
        colours = np.maximum(np.asarray(decode(unique_codes / levels), dtype=np.float64), 0.0) + 0.0
    return colours, np.asarray(inverse).reshape(values.shape[:-1])


@dataclass(frozen=True)
class RecoveredSpectra:
    """Spectra of the distinct colours of an RGB array, and what the recovery did to each.

    Attributes
    ----------
    spectra : numpy.ndarray, shape (K, N)
        Reflectance of each distinct colour on :attr:`grid`, unitless.
    labels : numpy.ndarray of intp, shape (...)
        The input's shape without its last axis: index into :attr:`spectra` of every input colour.
    colours : numpy.ndarray, shape (K, 3)
        The colours recovered (linear, in :attr:`colourspace`; the quantised representatives when ``bits``).
    outside : numpy.ndarray of bool, shape (K,)
        Outside the method's gamut, as the module docstring defines per method (clipped or not reached).
    delta_e : numpy.ndarray, shape (K,)
        CIE 2000 ΔE of each recovered spectrum (CIE 1931 2° under D65 on the grid, white = the unit reflectance)
        against its colour (``colour.RGB_to_XYZ`` relative to D65).
    method, colourspace : str
    grid : WavelengthGrid
    bits : int or None
    computed : int
        Distinct colours recovered in this call; the others (K − computed) came from the cache.
    seconds : float
        Wall time of recovering those ``computed`` colours. Unit: s.
    """

    spectra: np.ndarray
    labels: np.ndarray
    colours: np.ndarray
    outside: np.ndarray
    delta_e: np.ndarray
    method: str
    colourspace: str
    grid: WavelengthGrid
    bits: int | None
    computed: int
    seconds: float

    @property
    def seconds_per_colour(self) -> float:
        """Wall time per colour recovered in this call (NaN if none was). Unit: s."""
        return self.seconds / self.computed if self.computed else float("nan")

    def expand(self) -> np.ndarray:
        """Spectra per input colour, shape (..., N) — an H × W × N cube for an image: small inputs only."""
        return self.spectra[self.labels]


def recovery_delta_e(colours, spectra, colourspace: str = DEFAULT_COLOURSPACE,
                     grid: WavelengthGrid | None = None) -> np.ndarray:
    """CIE 2000 ΔE of reflectance spectra against the colours they were recovered from, under D65.

    Parameters
    ----------
    colours : array_like, shape (K, 3)
        Linear RGB in ``colourspace``.
    spectra : array_like, shape (K, N)
        Reflectance on ``grid``.

    Returns
    -------
    numpy.ndarray, shape (K,)
        ΔE00 between CIELAB of the spectrum (XYZ = Σ R E x̄ / Σ E ȳ on the grid, white: the unit reflectance)
        and CIELAB of the colour (``colour.RGB_to_XYZ``, white: D65's chromaticity).
    """
    colour = import_colour()
    grid = _grid(grid)
    weights = cmfs_on_grid(grid) * illuminant_spd(REFERENCE_ILLUMINANT, grid)
    weights = weights / weights[1].sum()
    xyz_recovered = np.asarray(spectra, dtype=np.float64) @ weights.T
    white_recovered = colour.XYZ_to_xy(weights.sum(axis=1))
    lab_recovered = colour.XYZ_to_Lab(xyz_recovered, white_recovered)
    lab_target = colour.XYZ_to_Lab(rgb_to_xyz(colours, colourspace), _d65_xy())
    return np.atleast_1d(np.asarray(colour.delta_E(lab_target, lab_recovered, method="CIE 2000"), dtype=float))


def rgb_to_distinct_spectra(rgb, method: str = DEFAULT_METHOD, colourspace: str = DEFAULT_COLOURSPACE,
                            grid: WavelengthGrid | None = None, bits: int | None = None,
                            max_delta_e: float | None = None) -> RecoveredSpectra:
    """Recover the reflectance spectrum of every distinct colour of an RGB array (the one dispatching entry point).

    Distinct colours are found with ``np.unique`` (:func:`distinct_colours`); for Otsu 2018 and Jakob 2019 each is
    looked up in a cache that outlives the call (keyed by method, colourspace, grid and the exact colour) and only
    the missing ones are recovered. Nothing per pixel is spectral: the result is K spectra and a label per pixel.

    Parameters
    ----------
    rgb : array_like, shape (..., 3)
        Linear RGB in ``colourspace``, components ≥ 0 (1 = the perfect white).
    method : str
        A name of :data:`RECOVERY_METHODS`.
    colourspace : str
        A name of ``colour.RGB_COLOURSPACES``.
    grid : WavelengthGrid, optional
        Default: 380–780 nm every 4 nm.
    bits : int or None
        Quantisation of the encoded values before finding distinct colours (:func:`distinct_colours`).
    max_delta_e : float, optional
        If given, a colour whose recovered spectrum misses it by more than this CIE 2000 ΔE is an error.

    Returns
    -------
    RecoveredSpectra

    Raises
    ------
    CamsimError
        Unknown method or colourspace; negative or non-finite components; a miss beyond ``max_delta_e``.
    """
    function = _method(method)
    space = _colourspace(colourspace)
    grid = _grid(grid)
    colours, labels = distinct_colours(rgb, space.name, bits)
    count = colours.shape[0]
    spectra = np.empty((count, grid.size))
    outside = np.zeros(count, dtype=bool)
    cached = method in PER_COLOUR_METHODS
    keys = [(method, space.name, grid, tuple(c)) for c in colours.tolist()] if cached else []
    missing = [i for i, key in enumerate(keys) if key not in _CACHE] if cached else list(range(count))
    for i, key in enumerate(keys):
        if key in _CACHE:
            _CACHE.move_to_end(key)
            spectra[i], outside[i] = _CACHE[key]
    start = time.perf_counter()
    if missing:
        new_spectra, new_outside = function(colours[missing], space.name, grid)
        spectra[missing], outside[missing] = new_spectra, new_outside
    seconds = time.perf_counter() - start
    if cached:
        for i in missing:
            _CACHE[keys[i]] = (spectra[i].copy(), bool(outside[i]))
        while len(_CACHE) > CACHE_SIZE:
            _CACHE.popitem(last=False)
    delta_e = recovery_delta_e(colours, spectra, space.name, grid) if count else np.zeros(0)
    if max_delta_e is not None and count and np.max(delta_e) > max_delta_e:
        bad = int(np.sum(delta_e > max_delta_e))
        raise CamsimError(f"{method}: {bad} of {count} colours are recovered with ΔE00 above {max_delta_e:g} "
                          f"(worst {np.max(delta_e):.3g}, at linear RGB "
                          f"{colours[np.argmax(delta_e)].round(4).tolist()})")
    return RecoveredSpectra(spectra=spectra, labels=labels, colours=colours, outside=outside, delta_e=delta_e,
                            method=method, colourspace=space.name, grid=grid, bits=bits, computed=len(missing),
                            seconds=seconds)


def rgb_to_spectra(rgb, method: str = DEFAULT_METHOD, colourspace: str = DEFAULT_COLOURSPACE,
                   grid: WavelengthGrid | None = None, bits: int | None = None,
                   max_delta_e: float | None = None) -> np.ndarray:
    """Reflectance spectra of linear RGB, shape (..., N): :func:`rgb_to_distinct_spectra`, expanded.

    For small arrays (a chart's patches, a test). An image goes through :func:`rgb_to_distinct_spectra` (K spectra
    and labels) or, with Mallett 2019, through :func:`mallett_basis` and :func:`basis_matrix`. Parameters, errors
    and the out-of-gamut behaviour are those of :func:`rgb_to_distinct_spectra`; its per-colour record
    (``outside``, ``delta_e``) is dropped here.

    Returns
    -------
    numpy.ndarray, shape (..., N)
        Reflectance, unitless.
    """
    return rgb_to_distinct_spectra(rgb, method, colourspace, grid, bits, max_delta_e).expand()


__all__ = ["CACHE_SIZE", "DEFAULT_COLOURSPACE", "DEFAULT_METHOD", "JAKOB2019_MAX_ERROR", "OUTSIDE_SRGB_TOLERANCE",
           "PER_COLOUR_METHODS", "RECOVERY_METHODS", "REFERENCE_ILLUMINANT", "RecoveredSpectra", "basis_matrix",
           "clear_cache", "distinct_colours", "linear_srgb", "mallett_basis", "recovery_delta_e",
           "rgb_to_distinct_spectra", "rgb_to_spectra", "rgb_to_xyz"]
