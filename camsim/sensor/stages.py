"""The sensor's physical stages (Eqs. 4–12), one pure array function each: the only implementation of each.

Every sampling method composes these (:mod:`camsim.methods`): the exact and the moment-matched methods run them
fused per channel, straight to digital numbers; ``spectral`` runs them in sequence on electrons. Work stays in
electrons until :func:`electrons_to_dn`.

The functions take numpy or CuPy arrays (:mod:`camsim.core.xp`: the namespace follows the arrays, the random draws the
generator): the device path (:mod:`camsim.render.backends.array_path`) composes the same functions on a GPU. A
frame's parameters (full well, read-noise σ and Tukey shape, gain, row-noise σ, bits, pedestal) are numbers, or, for a
batch of frames drawn at once (:mod:`camsim.pairs`), host arrays broadcasting against the values, one value per
frame (:func:`camsim.core.xp.on_device`); a number gives exactly the result it always gave. Two CPU
kernels are used only where the CPU's block renderer asks for them — the histogram sampler of one mean over a
rectangle (``size`` with a scalar mean) and float32 Box–Muller (``work`` scratch) — and two numpy calls that CuPy
does not take with the same keywords (a casting rule) have a CuPy form with the same casts.

=============================  ====================================  ===========
stage                          function                              unit
=============================  ====================================  ===========
photons + dark current         :func:`collect_charge_e`              e⁻
  (with PRNU and the dark-     ``gain``, ``dark_gain``
  current DSNU: per-pixel
  factors on S̄ and D̄)
  (its saturation cap)         :func:`saturating_mean_e`,            e⁻
                               :func:`cap_mean_e`,
                               :func:`saturation_level_e`
offset DSNU (fixed offset)     :func:`add_offset_e`                  e⁻
full well (Eq. 8)              :func:`saturate_e`                    e⁻
read noise (Eqs. 7, 10)        :func:`draw_read_noise_e`,            e⁻
                               :func:`add_read_noise_e`
row noise                      :func:`add_row_noise`                 any
gain G · G_Ve⁻ (Eq. 11)        :func:`electrons_to_dn`               e⁻ → DN
black-level error (per frame)  :func:`draw_black_level_error_dn`,    DN
                               :func:`add_black_level_error_dn`
ADC, nb bits (Eq. 11)          :func:`quantise_dn`                   DN
stuck pixels (after the ADC)   :func:`set_stuck_dn`                  DN
=============================  ====================================  ===========

Issue 28's fixed patterns need no stage of their own: the dark shading and column FPN are offsets (the offset
map of :func:`add_offset_e`), hot and dead pixels factors of the charge's means (``gain``, ``dark_gain`` of
:func:`collect_charge_e`); :mod:`camsim.sensor.fixed_pattern` folds them into those maps.
"""

from __future__ import annotations

import numpy as np

from camsim.core.xp import namespace_of, on_device
from camsim.sensor.cfa import cfa_sites
from camsim.sensor.kernels import poisson, poisson_run, standard_normal_f32, tukey_lambda

#: ε of the saturation cap: a pixel whose mean charge is at or above :func:`saturating_mean_e` stays below its
#: full well with probability at most ε, and drawing it at that mean changes the law of its value by at most ε in
#: total variation.
SATURATION_CAP_TAIL = 1e-30


def saturating_mean_e(level_e, step_e=1.0):
    """The mean charge M at and above which a charge stays below ``level_e`` with probability at most ε.

    For a charge that is a sum of independent scaled Poisson counts, S = Σ wᵢ Nᵢ with wᵢ ≥ 0 (one Poisson count,
    w = 1; the ``paper`` statistics' s · Poisson(S̄ / s); the ``spectral`` method's per-bin sums), of mean S̄ and
    variance V = s · S̄, Chernoff's bound with e⁻ˣ ≤ 1 − x + x²/2 gives P(S ≤ L) ≤ exp(−(S̄ − L)² / (2 s S̄)) for
    S̄ ≥ L. That is at most ε = e⁻ᵃ (a = ln 1/ε, ε = :data:`SATURATION_CAP_TAIL`) when

        S̄ ≥ M = L + a s + √(a² s² + 2 a s L).

    For one Poisson count and L = 9000 e⁻ (Table I's full well), M = 10 186 e⁻, and the exact
    P(Poisson(M) ≤ 9000) is 2e-32.

    Parameters
    ----------
    level_e : float or numpy.ndarray
        L, the charge at and above which the pixel is saturated: the full well minus the pixel's DSNU offset
        (negative L counts as 0). Unit: e⁻.
    step_e : float or numpy.ndarray
        s = Var S / S̄: 1 for Poisson counts of electrons. Unit: e⁻.

    Returns
    -------
    float or numpy.ndarray
        M. Unit: e⁻.
    """
    xp = namespace_of(level_e, step_e)
    a = -np.log(SATURATION_CAP_TAIL)
    level = xp.maximum(level_e, 0.0)
    return level + a * step_e + xp.sqrt((a * step_e) ** 2 + 2 * a * step_e * level)


def cap_mean_e(mean_e, level_e, step_e=1.0):
    """The saturation cap: ``mean_e`` where it is below :func:`saturating_mean_e` (``level_e``, ``step_e``), else M.

    A pixel saturates when its charge reaches the level L; its value is then the full well whatever more it
    collects. If two means are both at least M, each law puts probability at least 1 − ε on the full well, so the
    laws of the saturated value — and of everything computed from it (read noise, gain, ADC) — differ by at most
    ε = :data:`SATURATION_CAP_TAIL` in total variation, per pixel and channel. Drawing a mean above M at M keeps
    every draw within the exact sampler's range (numpy refuses Poisson means above 9.2e18) and in float64, however
    bright the light. Means at or below M are returned as given (the same object: no draw changes).

    Unit: e⁻ (``mean_e`` float or array; the result has its shape).
    """
    cap = saturating_mean_e(level_e, step_e)
    xp = namespace_of(mean_e, cap)
    cap = on_device(xp, cap)
    if bool(xp.all(xp.asarray(mean_e) <= cap)):
        return mean_e
    return xp.minimum(mean_e, cap)


def saturation_level_e(full_well_e, offset_e=None):
    """The charge at and above which every pixel is saturated: the full well minus the most negative of the pixels'
    DSNU offsets ``offset_e`` (None: no offsets). The level of :func:`collect_charge_e`'s saturation cap. Unit: e⁻.

    ``full_well_e`` a number gives a float; a host array (a batch's full wells, one per frame) gives that array less
    the batch's most negative offset (a level at least each pixel's own: the cap stays as exact).
    """
    full_well_e = float(full_well_e) if np.ndim(full_well_e) == 0 else np.asarray(full_well_e, dtype=np.float64)
    if offset_e is None:
        return full_well_e
    return full_well_e - min(0.0, float(namespace_of(offset_e).min(offset_e)))


def collect_charge_e(rng: np.random.Generator, signal_e, dark_e: float, signal_var_e2=None, *,
                     statistics: str = "pixel", photon_noise: bool = True, size=None, gain=None,
                     dark_gain=None, saturation_e=None) -> np.ndarray:
    """The charge S + D collected in the exposure, drawn exactly (Eqs. 4–6); capped where saturation hides it.

    Parameters
    ----------
    signal_e : float or numpy.ndarray
        Mean signal S̄ of each pixel (one value, with ``size`` giving the shape, or one per pixel). Unit: e⁻.
    dark_e : float or numpy.ndarray
        Mean dark charge D̄ = σ²_dark · T (one value, or one per pixel: a colour filter array's sites). Unit: e⁻.
    signal_var_e2 : float or numpy.ndarray, optional
        Var S under ``paper`` statistics (Eq. 4), shaped like ``signal_e``. Unit: e⁻².
    statistics : {'pixel', 'paper'}
        ``pixel``: photons thinned by QE, so S + D ~ Poisson(S̄ + D̄), one draw. ``paper``: S = s · Poisson(S̄ / s),
        s = Var S / S̄ (Eq. 4's mean and variance), plus D ~ Poisson(D̄).
    photon_noise : bool
        Off: S = S̄ exactly, plus D ~ Poisson(D̄).
    size : tuple, optional
        Shape of the draws when ``signal_e`` is one value (drawn as a histogram,
        :func:`camsim.sensor.kernels.poisson_run`).
    gain : numpy.ndarray, optional
        PRNU: a per-pixel factor on S̄ (and Var S), shape ``size``; the draws then have one mean per pixel.
    dark_gain : numpy.ndarray, optional
        Dark-current DSNU: a per-pixel factor d on D̄, shape ``size`` (or that of ``signal_e``), so that the dark
        charge is Poisson(D̄ · d): under ``pixel`` statistics S + D ~ Poisson(S̄ + D̄ d), one draw.
    saturation_e : float, optional
        Where the charge is then clipped at the full well (:func:`saturate_e`): the level L at and above which
        the pixel's value is the full well, the full well minus the pixel's DSNU offset (one value for all the
        pixels drawn: the largest). Each Poisson mean is then capped by :func:`cap_mean_e` — S̄ + D̄ under
        ``pixel`` statistics; S̄ (step s) and D̄ each on its own under ``paper`` statistics and without photon
        noise, as either alone saturates the pixel — which changes the law of the saturated value by at most
        :data:`SATURATION_CAP_TAIL` in total variation. None (no full well): the means are drawn as they are.

    Returns
    -------
    numpy.ndarray
        Unit: e⁻ (float32 histogram draws, int64 or float64 otherwise).
    """
    S, D = signal_e, dark_e
    shape = size if size is not None else getattr(signal_e, "shape", ())
    if gain is not None:  # per-pixel means: numpy's sampler, one mean per pixel
        S = S * gain
        size = None
    if dark_gain is not None:  # per-pixel dark means (the signal's draw keeps its size)
        D = D * dark_gain
    if photon_noise and statistics == "pixel":  # one draw covers photons and dark current
        total = S if dark_gain is None and isinstance(D, (int, float)) and D == 0 else S + D  # (no copy for D̄ = 0)
        lam = total if saturation_e is None else cap_mean_e(total, saturation_e)
        return poisson(rng, lam) if size is None or dark_gain is not None else poisson_run(rng, lam, size)
    if saturation_e is not None:
        D = cap_mean_e(D, saturation_e)
    xp = namespace_of(S, signal_var_e2, gain)
    if photon_noise:
        var = signal_var_e2 * (1 if gain is None else gain)
        with np.errstate(divide="ignore", invalid="ignore"):
            step = xp.where(S > 0, var / S, 0.0)
            if saturation_e is not None:
                S = cap_mean_e(S, saturation_e, step)
            lam = xp.where(step > 0, S / step, 0.0)
        charge = step * poisson(rng, lam, size=size)
    else:
        charge = xp.broadcast_to(xp.asarray(S, dtype=xp.float64), shape)
    return charge + poisson(rng, D, size=shape) if bool(namespace_of(dark_e).any(dark_e > 0)) else charge


def add_offset_e(charge_e: np.ndarray, offset_e: np.ndarray | None) -> np.ndarray:
    """DSNU: add each pixel's fixed dark offset to its charge (before saturation). Unit: e⁻."""
    return charge_e if offset_e is None else charge_e + offset_e


def saturate_e(electrons: np.ndarray, full_well_e: float, out: np.ndarray | None = None) -> np.ndarray:
    """f_sat: clip the collected charge at the full well (Eq. 8). Unit: e⁻ in, e⁻ out.

    Float arrays keep their type; an integer count array becomes float64 (a full well may be fractional).
    ``full_well_e``: a number, or a host array broadcasting against ``electrons`` (one per frame of a batch).
    """
    xp = namespace_of(electrons)
    well = float(full_well_e) if np.ndim(full_well_e) == 0 else on_device(xp, full_well_e, np.float64)
    return xp.minimum(electrons, well, out=out)


def draw_read_noise_e(rng: np.random.Generator, out: np.ndarray, read_noise_e: float, model: str = "gaussian",
                      tukey_shape: float = -0.1, work: np.ndarray | None = None) -> np.ndarray:
    """Fill ``out`` with white read noise of standard deviation σ_read (Eqs. 7 and 10, referred to the charge).

    The paper adds N(0, σ_read · G_Ve⁻) to the voltage; dividing by G_Ve⁻ gives this. ``gaussian``: with ``work``
    (float32 of at least half the size: the CPU block renderer's scratch) float32 arrays draw with
    :func:`camsim.sensor.kernels.standard_normal_f32` (Box–Muller); otherwise the generator's own normals
    (``standard_normal(size, dtype)``: numpy's ziggurat, CuPy's cuRAND normals). ``tukey-lambda``: the Tukey λ law
    of shape ``tukey_shape``, scaled to the same σ (heavier tails), by inverse CDF. ``read_noise_e`` and
    ``tukey_shape`` are numbers, or host arrays broadcasting against ``out`` (one per frame of a batch). Unit: e⁻.
    """
    if model == "tukey-lambda":
        return tukey_lambda(rng, out, tukey_shape, read_noise_e)
    if work is not None and out.dtype == np.float32:
        return standard_normal_f32(rng, out, work, read_noise_e)
    out[...] = rng.standard_normal(out.shape, dtype=out.dtype)
    out *= on_device(namespace_of(out), read_noise_e, out.dtype)
    return out


def add_read_noise_e(charge_e, noise_e: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """The charge plus its read noise (drawn by :func:`draw_read_noise_e`), into ``out`` if given (both cast to its
    type first). Unit: e⁻."""
    if out is None:
        return charge_e + noise_e
    if isinstance(out, np.ndarray):
        return np.add(charge_e, noise_e, out=out, dtype=out.dtype, casting="unsafe")
    out[...] = charge_e  # CuPy's ufuncs take no casting rule: the same casts, in two passes
    out += noise_e
    return out


def add_row_noise(values: np.ndarray, row_noise: float, rng: np.random.Generator) -> np.ndarray:
    """Temporal row noise: one Gaussian offset N(0, σ_row) per row of ``values`` (h, w), in place; for a stack of
    planes (…, h, w), one per row of each plane.

    Unit: that of ``values`` (σ_row in the same unit: e⁻ on charge, σ_row · G · G_Ve⁻ on digital numbers).
    ``row_noise``: a number, or a host array broadcasting against ``values`` (one per frame of a batch).
    """
    sigma = on_device(namespace_of(values), row_noise, values.dtype)
    values += rng.standard_normal(values.shape[:-1] + (1,), dtype=values.dtype) * sigma
    return values


def electrons_to_dn(electrons: np.ndarray, dn_per_electron: float, out: np.ndarray | None = None) -> np.ndarray:
    """Readout and gain: I = G · G_Ve⁻ · e (Eqs. 8, 11 before quantisation). Unit: e⁻ in, DN out.

    Float arrays keep their type; integer counts are converted to float64 first. ``dn_per_electron``: a number,
    or a host array broadcasting against ``electrons`` (one per frame of a batch).
    """
    if not np.issubdtype(electrons.dtype, np.floating):
        electrons = electrons.astype(np.float64)
    xp = namespace_of(electrons)
    return xp.multiply(electrons, on_device(xp, dn_per_electron, electrons.dtype), out=out)


def draw_black_level_error_dn(rng: np.random.Generator, sigma_dn: float) -> np.ndarray:
    """A frame's black-level error: one N(0, σ²) offset per channel R, G, B (ELD's colour bias), shape (3,) float64,
    drawn from ``rng`` (the frame's own stream, :func:`camsim.core.seeding.frame_effect_generator`). Unit: DN."""
    return rng.normal(0.0, float(sigma_dn), 3)


def add_black_level_error_dn(values, error_dn, cfa: str | None = None, channel: int = 0):
    """Add a frame's black-level error to DN before the ADC (after the gain and the row noise), in place.

    Parameters
    ----------
    values : array, shape (h, w) or (B, h, w), float
        One plane of a block or frame: channel ``channel``'s of a three-chip sensor, or (``cfa`` given) a Bayer
        mosaic whose first row is an even row of the frame, each site taking its channel's offset; or that plane of
        each of B frames. Unit: DN.
    error_dn : sequence of 3 floats, or array of shape (B, 3)
        The offsets of R, G and B (:func:`draw_black_level_error_dn`); for B frames, each frame's (numpy, or on
        ``values``' device). Unit: DN.
    """
    if np.ndim(error_dn) == 1:
        if cfa is None:
            values += values.dtype.type(error_dn[channel])
            return values
        for dy, dx, c in cfa_sites(cfa):
            values[dy::2, dx::2] += values.dtype.type(error_dn[c])
        return values
    per_frame = on_device(namespace_of(values), error_dn, values.dtype)[..., None, None]  # (B, 3, 1, 1)
    if cfa is None:
        values += per_frame[:, channel]
        return values
    for dy, dx, c in cfa_sites(cfa):
        values[..., dy::2, dx::2] += per_frame[:, c]
    return values


def stuck_float_dn(level_dn, pedestal_dn: int):
    """The value before the ADC that a stuck pixel's float layer holds for its ADC level L: L − the ADC's offset
    (:func:`adc_offset_dn`), which the ADC maps to L exactly. Unit: DN."""
    return level_dn - np.float32(adc_offset_dn(pedestal_dn))


def set_stuck_dn(values, index, level_dn):
    """Stuck pixels: write each one's fixed level over a frame's values, in place (no noise, every frame alike).

    ``values`` (planes, H, W), C-contiguous: the float layer (with :func:`stuck_float_dn`'s levels) or the ADC's
    output (with the levels themselves); ``index`` flat indices into it (numpy or on ``values``' device); ``level_dn``
    one level per index. Unit: DN."""
    xp = namespace_of(values)
    flat = values.reshape(-1)
    flat[xp.asarray(index)] = xp.asarray(level_dn).astype(values.dtype)
    return values


def adc_offset_dn(pedestal_dn: int) -> float:
    """The analogue offset the ADC adds before its floor, for a black-level pedestal P.

    With a pedestal (P > 0) the offset is P + ½: the ADC's output is floor(dn + ½) + P, a mid-tread quantiser
    around P, so an unlit pixel without dark charge reads P on average (its symmetric read noise rounds as often up
    as down), which is what a camera maker publishes as its black level. Without one (P = 0) the ADC is the paper's
    (Eq. 11): floor(dn), no offset.

    Parameters
    ----------
    pedestal_dn : int
        P. Unit: DN.

    Returns
    -------
    float
        P + ½ for P > 0, else 0. Unit: DN.
    """
    return pedestal_dn + 0.5 if pedestal_dn else 0.0


def quantise_dn(dn: np.ndarray, bits: int, out: np.ndarray | None = None, pedestal_dn: int = 0) -> np.ndarray:
    """nb-bit quantisation: the integer part of the DN (plus ½ and the pedestal), clipped to [0, 2^nb − 1] (Eq. 11).

    Parameters
    ----------
    dn : numpy.ndarray, float
        Unquantised digital numbers. Unit: DN.
    out : numpy.ndarray, optional
        Integer output array (uint8 for nb ≤ 8, uint16 otherwise).
    pedestal_dn : int
        Black-level pedestal P: the ADC's output is clip(floor(dn + ½) + P, 0, 2^nb − 1) for P > 0 (see
        :func:`adc_offset_dn`), clip(floor(dn), 0, 2^nb − 1) for P = 0. Computed exactly in the array's float type.

    ``bits`` and ``pedestal_dn`` are numbers, or host integer arrays broadcasting against ``dn`` (one per frame of
    a batch; the output's type then holds the most bits).

    Returns
    -------
    numpy.ndarray
        Quantised digital numbers. Unit: DN.
    """
    # clip straight into the integer output: for values in [0, 2^nb − 1] the cast's truncation is the floor
    xp = namespace_of(dn)
    bits, pedestal = np.asarray(bits), np.asarray(pedestal_dn)  # 0-d for one frame, or one per frame of a batch
    if out is None:
        out = xp.empty(dn.shape, dtype=dn_dtype(int(bits.max())))
    top = on_device(xp, (2 ** bits.astype(np.int64) - 1).astype(dn.dtype))
    if np.any(pedestal):  # floor(dn + ½) + P, exactly: dn − floor(dn) has no rounding error (Sterbenz), dn + ½ may
        whole = xp.floor(dn)
        up = (dn - whole) >= 0.5
        whole += on_device(xp, pedestal.astype(dn.dtype))
        if not np.all(pedestal):  # frames of a batch without a pedestal: ⌊dn⌋, no ½ (their P adds 0)
            up &= on_device(xp, pedestal != 0)
        whole += up
        dn = whole
    if isinstance(dn, np.ndarray):
        np.clip(dn, 0, top, out=out, casting="unsafe")
    else:  # CuPy's clip takes no casting rule: clip, then the assignment's cast (the same truncation)
        out[...] = xp.clip(dn, 0, top)
    return out


def dn_dtype(bits: int):
    """The smallest unsigned integer type holding ``bits``-bit digital numbers."""
    return np.uint8 if bits <= 8 else np.uint16
