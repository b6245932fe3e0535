"""``calibrate``: a camera's noise parameters from its dark frames and pairs of flat frames (raw files).

The files are read twice each, so that memory stays a few images whatever the number of frames: the darks once for
exact per-pixel sums, once for their residuals about each pixel's mean; the flats once for their levels (and the
checks), once pair by pair. Every estimate is a pure function of :mod:`camsim.calibration.dark`,
:mod:`camsim.calibration.ptc` or :mod:`camsim.calibration.tukey`, per plane (:mod:`camsim.calibration.rawfiles`),
then combined over the planes for the preset.
"""

from __future__ import annotations

import datetime
import math
import os
from dataclasses import dataclass, field

import numpy as np

from camsim.calibration import dark, flats, ptc, tukey
from camsim.calibration import fixed_pattern as fp
from camsim.calibration.estimate import Estimate, ratio, sqrt_estimate
from camsim.calibration.rawfiles import Layout, check_same_exposure, check_same_layout, read_raw
from camsim.core.errors import CamsimError
from camsim.core.names import name_problem, safe_component
from camsim.sensor.kernels import tukey_lambda_variance

#: Fewest dark frames: the per-pixel mean needs two to leave a residual.
MIN_DARKS = 2
#: At most this many read-noise samples per plane go to the PPCC (frames in order, then the rows of the last).
MAX_PPCC_SAMPLES = 1 << 22
#: Below this read noise (DN) the quantiser's error depends on each pixel's level: Sheppard's correction and the
#: PPCC's model of the ADC (a uniform error) no longer hold.
MIN_READ_NOISE_DN = 0.6
#: The read noise is called Gaussian when its λ is within this of the Gaussian-like 0.1349 (or within two of its
#: standard errors, if more).
GAUSSIAN_LAMBDA_TOLERANCE = 0.02
#: ISO when neither --iso nor the files give one.
DEFAULT_ISO = 100
#: Preset name when neither --name nor the files give one.
DEFAULT_NAME = "calibrated"


@dataclass(frozen=True)
class FlatPair:
    """One pair of flat frames and what each plane says of it.

    Attributes
    ----------
    files : tuple of str
    level : int
        The pair's level, 0 the darkest.
    mean_dn : numpy.ndarray, shape (planes,)
        μ per plane (mean − black). Unit: DN.
    variance_dn2 : numpy.ndarray, shape (planes,)
        var(A − B)/2 per plane. Unit: DN².
    prnu_percent : tuple of Estimate
        The PRNU of each plane at this pair's level. Unit: %.
    """

    files: tuple
    level: int
    mean_dn: np.ndarray
    variance_dn2: np.ndarray
    prnu_percent: tuple


@dataclass(frozen=True)
class PlaneResult:
    """The estimates of one plane (one CFA site, or one colour of a stack).

    Attributes
    ----------
    name, colour : str
        E.g. ``"Gr"`` and ``"G"``.
    black_dn : Estimate
        Mean of the dark frames. Unit: DN.
    dark_variance_dn2 : Estimate
        Dark temporal variance (read, row, quantisation). Unit: DN².
    pixel_variance_dn2 : float
        σ_Y²: a pixel's temporal variance without the row noise, quantisation included. Unit: DN².
    read_dn : Estimate
        σ_read (Sheppard-corrected). Unit: DN.
    row_dn : Estimate
        Row noise over this plane's sites of each row. Unit: DN.
    dsnu_dn : Estimate
        Unit: DN.
    tukey : tukey.TukeyFit
        The matched PPCC (the law of the samples: read noise blurred by the ADC and the per-pixel mean).
    tukey_plain : tukey.TukeyFit
        ELD's plain PPCC on the same samples, for comparison.
    ptc : ptc.PtcFit
    prnu_percent : Estimate
        At the brightest level of the fit. Unit: %.
    prnu_pair : int
        That pair's index into :attr:`Calibration.pairs`.
    pixels : int
    probability_plot : tuple of numpy.ndarray
        (quantiles of the fitted law, sorted samples), thinned for the plot. Unit: DN.
    """

    name: str
    colour: str
    black_dn: Estimate
    dark_variance_dn2: Estimate
    pixel_variance_dn2: float
    read_dn: Estimate
    row_dn: Estimate
    dsnu_dn: Estimate
    tukey: tukey.TukeyFit
    tukey_plain: tukey.TukeyFit
    ptc: ptc.PtcFit
    prnu_percent: Estimate
    prnu_pair: int
    pixels: int
    probability_plot: tuple


@dataclass(frozen=True)
class DarkEffects:
    """What the darks say of the effects of issue 28 (:mod:`camsim.calibration.fixed_pattern`).

    Attributes
    ----------
    shading_e : numpy.ndarray, float32
        The dark-shading map: per pixel the mean of the darks less its plane's black level (hot pixels: their
        neighbourhood's median, where :attr:`hot_e_per_s` holds their excess), ÷ K; (H, W) for a mosaic or a
        monochrome sensor, (3, H, W) for a stack. Unit: e⁻.
    shading_se_e : float
        Its per-pixel standard error √((σ_Y² + σ_row²) / n) / K (the planes' root mean square). Unit: e⁻.
    shading_rms_e : Estimate
        The RMS of the fixed pattern the map holds, its temporal noise removed (the planes' RMS). Unit: e⁻.
    hot_e_per_s : numpy.ndarray or None
        Per pixel the hot pixels' extra dark current (excess ÷ K ÷ exposure; 0 where not hot), the layout of
        :attr:`shading_e`; None where the darks' exposure is unknown. Unit: e⁻/s.
    hot_count : int
    hot_fraction : Estimate
        The share of hot pixels, binomial standard error.
    hot_threshold_dn : tuple of float
        Per plane: the excess over the local level beyond which a pixel is hot. Unit: DN.
    column_fpn_dn : Estimate
        σ of the fixed per-column offset (per chip, the chips' RMS). Unit: DN.
    black_level_error_dn : Estimate
        σ of the per-frame, per-colour offset. Unit: DN.
    exposure_s : float or None
        The darks' exposure. Unit: s.
    """

    shading_e: np.ndarray
    shading_se_e: float
    shading_rms_e: Estimate
    hot_e_per_s: np.ndarray | None
    hot_count: int
    hot_fraction: Estimate
    hot_threshold_dn: tuple
    column_fpn_dn: Estimate
    black_level_error_dn: Estimate
    exposure_s: float | None


@dataclass(frozen=True)
class Calibration:
    """Everything ``camsim calibrate`` measured, per plane and combined into the preset's values.

    The combined values: K, the inverse-variance weighted mean of the planes'; the black level, the mean of the
    planes'; read noise, DSNU and PRNU, the root mean square of the planes'; λ and the Tukey scale, the mean of the
    planes' (standard error from their spread); row noise, over whole physical rows (both colours of a Bayer row).
    """

    dark_files: tuple
    flat_files: tuple
    layout: Layout
    name: str
    iso: float | int
    date: str
    planes: tuple
    pairs: tuple
    k_dn_per_e: Estimate
    black_dn: Estimate
    read_dn: Estimate
    row_dn: Estimate
    dsnu_dn: Estimate
    prnu_percent: Estimate
    tukey_lambda: Estimate
    tukey_scale_dn: Estimate
    read_noise_model: str
    row_spectrum: tuple
    row_white_level_dn2: float
    effects: DarkEffects | None = None
    warnings: tuple = field(default=())

    @property
    def pedestal_dn(self) -> int:
        """The integer pedestal P for camsim's ADC, which adds P + ½ before its floor so that an unlit pixel's mean
        (with no dark current) is P: the black level rounded to the nearest integer. Unit: DN."""
        return int(math.floor(self.black_dn.value + 0.5))

    @property
    def read_e(self) -> Estimate:
        """σ_read / K, with both errors propagated. Unit: e⁻."""
        return ratio(self.read_dn, self.k_dn_per_e)

    @property
    def row_e(self) -> Estimate:
        """σ_row / K. Unit: e⁻."""
        return ratio(self.row_dn, self.k_dn_per_e)

    @property
    def dsnu_e(self) -> Estimate:
        """DSNU / K. Unit: e⁻."""
        return ratio(self.dsnu_dn, self.k_dn_per_e)

    @property
    def source(self) -> str:
        """The preset's ``source``: what was measured, from which files, when."""
        names = [os.path.basename(f) for f in (*self.dark_files, *self.flat_files)]
        files = names[0] if len(names) == 1 else f"{names[0]} … {names[-1]}"
        levels = len({pair.level for pair in self.pairs})
        return (f"camsim calibrate: {len(self.dark_files)} dark frames, {len(self.pairs)} flat pairs at {levels} "
                f"levels (files {files}), {self.date}")


def _rms(estimates) -> Estimate:
    """Root mean square of the planes' values (their squares averaged), error propagated."""
    squares = [Estimate(e.value**2, None if e.standard_error is None else 2 * e.value * e.standard_error)
               for e in estimates]
    mean = float(np.mean([s.value for s in squares]))
    ses = [s.standard_error for s in squares]
    se = None if any(s is None for s in ses) else math.sqrt(sum(s * s for s in ses)) / len(ses)
    return sqrt_estimate(Estimate(mean, se))


def _mean_with_spread(values) -> Estimate:
    """The mean of the planes' values; its standard error from their spread (None for one plane)."""
    values = np.asarray(values, dtype=np.float64)
    if values.size < 2:
        return Estimate(float(values[0]), None)
    return Estimate(float(values.mean()), float(values.std(ddof=1) / math.sqrt(values.size)))


def _bar(items, desc: str, progress: bool):
    from tqdm import tqdm

    return tqdm(items, desc=desc, unit="file", leave=False, disable=not progress)


def _check_inputs(dark_files, flat_files) -> None:
    if len(dark_files) < MIN_DARKS:
        raise CamsimError(f"camsim calibrate needs at least {MIN_DARKS} dark frames (--dark), got "
                          f"{len(dark_files)}; shoot 8 or more with the lens capped, at the exposure and ISO of "
                          "the flats")
    if len(flat_files) < 2 * flats.MIN_LEVELS:
        raise CamsimError(f"camsim calibrate needs at least {flats.MIN_LEVELS} pairs of flat frames (--flat: "
                          f"{2 * flats.MIN_LEVELS} files or more, two per level), got {len(flat_files)}")
    seen = {}
    for name in (*dark_files, *flat_files):
        key = os.path.realpath(name)
        if key in seen:
            raise CamsimError(f"{name} is given twice (as {seen[key]} too): every frame must be a separate exposure")
        seen[key] = name


def _dark_pass(dark_files, progress):
    """First pass over the darks: exact per-pixel sums (and the sum of the even-numbered frames, for the hot pixels'
    test in halves), the layout, the metadata of the first file."""
    first = None
    total = squares = even = None
    for i, name in enumerate(_bar(dark_files, "dark frames (1/2)", progress)):
        frame = read_raw(name, metadata=first is None)
        if first is None:
            first = frame
            total = np.zeros(frame.image.shape, np.int64)
            squares = np.zeros(frame.image.shape, np.int64)
            even = np.zeros(frame.image.shape, np.int64)
        else:
            check_same_layout(first, frame)
            check_same_exposure(first, frame, "dark frames")
        x = frame.image.astype(np.int64)
        total += x
        squares += x * x
        if i % 2 == 0:
            even += x
    return first, total, squares, even


def _dark_residuals(dark_files, layout: Layout, mean_image, progress, keep=None):
    """Second pass: per plane Σ(r − m)², its count, the plane-row means, the samples for the PPCC; the physical
    rows' means. ``keep`` (bool, the image's shape): the pixels that count — a hot pixel's residual is set to 0
    and left out of the sums and samples (its shot noise is the hot-pixel map's, not the read noise)."""
    n_planes = len(layout.plane_names)
    sq = np.zeros(n_planes)
    count = np.zeros(n_planes, np.int64)
    plane_rows = [[] for _ in range(n_planes)]
    rows = []
    samples = [[] for _ in range(n_planes)]
    kept = np.zeros(n_planes, np.int64)
    keep_planes = None if keep is None else layout.planes(keep)
    for name in _bar(dark_files, "dark frames (2/2)", progress):
        frame = read_raw(name)
        r = frame.image.astype(np.float64) - mean_image
        if keep is not None:
            r[~keep] = 0.0
        rows.append(layout.rows(r).mean(axis=1))
        for p, plane in enumerate(layout.planes(r)):
            m = plane.mean(axis=1)
            plane_rows[p].append(m)
            s = plane - m[:, None]
            room = MAX_PPCC_SAMPLES - kept[p]
            if keep_planes is None:
                sq[p] += float(np.sum(s * s))
                count[p] += s.size
                take = s if s.size <= room else s[: max(1, room // s.shape[1])]
            else:
                s = s[keep_planes[p]]
                sq[p] += float(np.sum(s * s))
                count[p] += s.size
                take = s[: max(room, 0)]
            if room > 0:
                samples[p].append(take.ravel().copy())
                kept[p] += take.size
    return sq, count, [np.array(m) for m in plane_rows], np.array(rows), [np.concatenate(s) for s in samples]


def _flat_levels(flat_files, first, blacks, progress):
    """First pass over the flats: checks, each file's signal per plane, and the pairs by level."""
    layout = first.layout
    signals = []
    black = float(np.mean(blacks))
    for name in _bar(flat_files, "flat frames (1/2)", progress):
        frame = read_raw(name)
        check_same_layout(first, frame)
        planes = layout.planes(frame.image)
        per_plane = np.array([float(np.mean(p)) for p in planes]) - blacks
        saturated = float(np.count_nonzero(frame.image >= layout.white_level_dn)) / frame.image.size
        signal = float(np.mean(per_plane))
        flats.check_flat(name, signal, saturated, layout.white_level_dn - black)
        signals.append(signal)
    return flats.group_levels(signals, list(flat_files))


def _flat_pairs(flat_files, levels, layout, blacks, dark_mean_planes, dark_var, dark_frames, row_var, progress):
    """Second pass: each pair's μ and var(A − B)/2 per plane, and its PRNU."""
    pairs = []
    todo = [(level, pair) for level, level_pairs in enumerate(levels) for pair in level_pairs]
    for level, (i, j) in _bar(todo, "flat pairs (2/2)", progress):
        frame_a, frame_b = read_raw(flat_files[i]), read_raw(flat_files[j])
        check_same_exposure(frame_a, frame_b, "the two flats of a pair")
        a, b = layout.planes(frame_a.image), layout.planes(frame_b.image)
        stats = [ptc.pair_statistics(pa, pb, black) for pa, pb, black in zip(a, b, blacks)]
        prnu = tuple(ptc.prnu(0.5 * (pa.astype(np.float64) + pb), dm, var, dv, dark_frames, row_var)
                     for pa, pb, dm, (_, var), dv in zip(a, b, dark_mean_planes, stats, dark_var))
        pairs.append(FlatPair((flat_files[i], flat_files[j]), level, np.array([s[0] for s in stats]),
                              np.array([s[1] for s in stats]), prnu))
    return pairs


def calibrate(dark_files, flat_files, *, iso: float | None = None, name: str | None = None,
              progress: bool = False) -> Calibration:
    """Measure a camera's noise parameters from raw dark frames and pairs of flat frames.

    Parameters
    ----------
    dark_files : sequence of str or os.PathLike
        At least 2 dark frames (capped lens), at one exposure and ISO.
    flat_files : sequence of str or os.PathLike
        Pairs of flat frames of equal exposure at 3 or more levels, in any order (paired by level,
        :func:`camsim.calibration.flats.group_levels`), none saturated.
    iso : float, optional
        The ISO the values belong to (default: the files', else :data:`DEFAULT_ISO`).
    name : str, optional
        The preset's name, a safe file name (:mod:`camsim.core.names`; default: the camera model in the files where it
        is one, else :data:`DEFAULT_NAME`).
    progress : bool
        Progress bars on stderr.

    Returns
    -------
    Calibration

    Raises
    ------
    CamsimError
        Too few files, a file that cannot be read, frames of different sizes or mosaics, saturated flats, a level
        without its pair, fewer than 3 levels, or a curve with no usable part.
    """
    if name:
        safe_component(name, "the preset's name")
    dark_files = tuple(str(os.fspath(f)) for f in dark_files)
    flat_files = tuple(str(os.fspath(f)) for f in flat_files)
    _check_inputs(dark_files, flat_files)
    n = len(dark_files)
    first, total, squares, even = _dark_pass(dark_files, progress)
    layout = first.layout
    mean_image, var_image = dark.pixel_moments(total, squares, n)
    del squares
    mean_planes = [np.ascontiguousarray(p) for p in layout.planes(mean_image)]
    var_planes = layout.planes(var_image)
    halves = (layout.planes(even / ((n + 1) // 2)), layout.planes((total - even) / (n // 2)))
    hot = [fp.find_hot_pixels(m, v, n, (a, b)) for m, v, a, b in zip(mean_planes, var_planes, *halves)]
    del even, total, halves
    keep = None
    if any(h.count for h in hot):
        keep = np.ones(mean_image.shape, bool)
        for plane, h in zip(layout.planes(keep), hot):
            plane[h.mask] = False
    sq, count, plane_rows, rows, samples = _dark_residuals(dark_files, layout, mean_image, progress, keep)
    plane_w = layout.plane_shape[1]

    dark_var = [dark.temporal_variance(v if not h.count else v[~h.mask], n) for v, h in zip(var_planes, hot)]
    # the photon transfer's σ²_dark: every pixel, as the flat pairs' var(A − B)/2 takes them
    flat_dark_var = [dark.temporal_variance(v, n).value for v in var_planes] if keep is not None else None
    for pname, dv in zip(layout.plane_names, dark_var):
        if not dv.value > 0:
            raise CamsimError(f"the dark frames do not vary from one to the next (plane {pname}): are they copies "
                              "of one frame? Temporal noise needs separate exposures")
    read = [dark.read_noise(sq[p], int(count[p]), n, plane_w) for p in range(len(mean_planes))]
    pixel_var = [r[1] for r in read]  # σ_Y², per plane
    # row noise: each frame's row means less their mean (per plane; per row pattern or chip for whole rows), so that
    # a per-frame offset of a colour (the black-level error) is not taken for row noise
    row_planes = [dark.row_noise(plane_rows[p], pixel_var[p], plane_w, np.zeros(plane_rows[p].shape[1], int))
                  for p in range(len(mean_planes))]
    blacks_est = [_black(m, v, n, row.value**2, h) for m, v, row, h in zip(mean_planes, var_planes, row_planes, hot)]
    blacks = np.array([b.value for b in blacks_est])
    dsnu = [dark.dsnu(m if not h.count else m[~h.mask], dv, n, row.value**2)
            for m, dv, row, h in zip(mean_planes, dark_var, row_planes, hot)]
    row_pixels = layout.shape[1]  # a physical row: both colours of a Bayer row; one chip's row of a stack
    row_all = dark.row_noise(rows, float(np.mean(pixel_var)), row_pixels, _row_groups(layout))
    spectrum = dark.row_power_spectrum(rows)
    black_all = dark.black_level(mean_image, var_image, n, row_all.value**2)  # the planes' mean; rows shared
    if keep is not None:
        black_all = Estimate(float(np.mean(blacks)), black_all.standard_error)
    effects_dn = _dark_effects(layout, mean_planes, hot, blacks, plane_rows, pixel_var, row_all, n)
    del var_image, var_planes

    levels = _flat_levels(flat_files, first, blacks, progress)
    dark_frames_var = flat_dark_var if flat_dark_var is not None else [d.value for d in dark_var]
    pairs = _flat_pairs(flat_files, levels, layout, blacks, mean_planes, dark_frames_var, n, row_all.value**2,
                        progress)
    full_scale = layout.white_level_dn - blacks

    planes = tuple(
        _plane_result(p, layout, pairs, full_scale[p], blacks_est[p], dark_var[p], read[p], row_planes[p], dsnu[p],
                      samples[p], mean_planes[p].size, n, plane_w)
        for p in range(len(layout.plane_names)))
    k = ptc.combine([pl.ptc.k_dn_per_e for pl in planes])
    if not k.value > 0:
        raise CamsimError(f"the photon transfer curve does not rise with the signal (K = {k.value:.3g} DN/e⁻): are "
                          "the flats lit, and each pair of one exposure?")
    lam = _mean_with_spread([pl.tukey.lam for pl in planes])
    scale = _mean_with_spread([pl.tukey.scale_dn for pl in planes])
    lam_tol = max(GAUSSIAN_LAMBDA_TOLERANCE, 2 * (lam.standard_error or 0.0))
    model = "gaussian" if abs(lam.value - tukey.GAUSSIAN_LAMBDA) <= lam_tol else "tukey-lambda"
    read_all = _rms([pl.read_dn for pl in planes])
    meta_iso = first.iso
    return Calibration(
        dark_files=dark_files, flat_files=flat_files, layout=layout,
        name=name if name else (first.model if name_problem(first.model) is None else DEFAULT_NAME),
        iso=_iso(iso if iso is not None else (meta_iso if meta_iso else DEFAULT_ISO)),
        date=datetime.date.today().isoformat(), planes=planes, pairs=tuple(pairs), k_dn_per_e=k,
        black_dn=black_all, read_dn=read_all, row_dn=row_all,
        dsnu_dn=_rms([pl.dsnu_dn for pl in planes]), prnu_percent=_rms([pl.prnu_percent for pl in planes]),
        tukey_lambda=lam, tukey_scale_dn=scale, read_noise_model=model, row_spectrum=spectrum,
        row_white_level_dn2=(1 - 1 / n) * (row_all.value**2 + float(np.mean(pixel_var)) / row_pixels),
        effects=_effects_in_electrons(effects_dn, k, first.exposure_s),
        warnings=tuple(_warnings(planes, read_all, k, len(levels), n)
                       + ([] if first.exposure_s else ["the dark frames do not say their exposure: no hot-pixel "
                                                       "map (its unit is e⁻/s)"])))


def _black(mean_dn, variance_dn2, frames, row_variance_dn2, hot) -> Estimate:
    """A plane's black level (:func:`camsim.calibration.dark.black_level`), its value the mean of the pixels that
    are not hot."""
    est = dark.black_level(mean_dn, variance_dn2, frames, row_variance_dn2)
    return est if not hot.count else Estimate(float(np.mean(mean_dn[~hot.mask])), est.standard_error)


def _row_groups(layout: Layout) -> np.ndarray:
    """Each physical row's group (:func:`camsim.calibration.dark.row_noise`): a Bayer mosaic's row parity (the
    two row patterns hold different colours), a stack's chip, else one group."""
    h = layout.shape[0]
    if layout.kind == "bayer":
        return np.arange(h) % 2
    if layout.kind == "stack":
        return np.repeat(np.arange(3), h)
    return np.zeros(h, int)


def _image_of_planes(layout: Layout, planes, dtype=np.float64) -> np.ndarray:
    """The planes put back into one array: (H, W) for a mosaic or monochrome, (3, H, W) for a stack."""
    if layout.kind == "stack":
        return np.stack(planes).astype(dtype)
    out = np.zeros(layout.shape, dtype)
    for view, plane in zip(layout.planes(out), planes):
        view[...] = plane
    return out


def _dark_effects(layout, mean_planes, hot, blacks, plane_rows, pixel_var, row_all, frames) -> dict:
    """The effects of issue 28 in DN (:mod:`camsim.calibration.fixed_pattern`)."""
    maps = [fp.shading_map(m, b, h) for m, b, h in zip(mean_planes, blacks, hot)]
    shading = _image_of_planes(layout, maps)
    temporal = [v + row_all.value**2 for v in pixel_var]  # σ_Y² + σ_row²: the map's noise × n, per plane
    se = math.sqrt(float(np.mean([fp.map_standard_error(v, frames) ** 2 for v in temporal])))
    rms = sqrt_estimate(fp.mean_of_squares(
        fp.fixed_pattern_variance(mp if not h.count else mp[~h.mask], v, frames)
        for mp, v, h in zip(maps, temporal, hot)))
    chips = list(shading) if layout.kind == "stack" else [shading]
    column = sqrt_estimate(fp.mean_of_squares(fp.column_fpn_variance(c) for c in chips))
    excess = _image_of_planes(layout, [h.excess_dn for h in hot])
    # the black-level error: per frame, the mean of each colour's planes (of the residuals: less a constant)
    colours = sorted(set(layout.plane_colours), key="RGBY".index)
    h = layout.shape[0]
    means, pixels, rows, var_y = [], [], [], []
    for c in colours:
        ps = [p for p, pc in enumerate(layout.plane_colours) if pc == c]
        means.append(np.mean([plane_rows[p].mean(axis=1) for p in ps], axis=0))
        pixels.append(sum(mean_planes[p].size - hot[p].count for p in ps))
        var_y.append(float(np.mean([pixel_var[p] for p in ps])))
        if layout.kind == "bayer":
            rows.append(len({p // 2 for p in ps}) * h // 2)  # a site's row pattern: p // 2 is its row in the cell
        else:
            rows.append(h)
    offset = fp.black_level_error(np.stack(means, axis=1), var_y, pixels, row_all.value**2, rows)
    count = sum(x.count for x in hot)
    return {"shading_dn": shading, "shading_se_dn": se, "shading_rms_dn": rms, "hot_excess_dn": excess,
            "hot_count": count, "hot_fraction": fp.hot_fraction(count, shading.size),
            "hot_threshold_dn": tuple(float(x.threshold_dn) for x in hot), "column_fpn_dn": column,
            "black_level_error_dn": offset}


def _effects_in_electrons(e: dict, k: Estimate, exposure_s: float | None) -> DarkEffects:
    """The maps ÷ K (and ÷ the exposure for the hot pixels' dark current)."""
    kv = k.value
    hot = None if not exposure_s else (e["hot_excess_dn"] / (kv * exposure_s)).astype(np.float32)
    # without an exposure there is no hot-pixel map: the dark-shading map keeps their charge (at this exposure)
    shading = e["shading_dn"] if hot is not None else e["shading_dn"] + e["hot_excess_dn"]
    return DarkEffects(
        shading_e=(shading / kv).astype(np.float32), shading_se_e=e["shading_se_dn"] / kv,
        shading_rms_e=ratio(e["shading_rms_dn"], k), hot_e_per_s=hot, hot_count=e["hot_count"],
        hot_fraction=e["hot_fraction"], hot_threshold_dn=e["hot_threshold_dn"], column_fpn_dn=e["column_fpn_dn"],
        black_level_error_dn=e["black_level_error_dn"], exposure_s=exposure_s)


def _plane_result(p, layout, pairs, full_scale_dn, black, dark_var, read, row, dsnu, samples, pixels, frames,
                  plane_w) -> PlaneResult:
    """One plane's photon transfer fit, PRNU and read-noise law, with its dark estimates."""
    name = layout.plane_names[p]
    mu = np.array([pair.mean_dn[p] for pair in pairs])
    var = np.array([pair.variance_dn2[p] for pair in pairs])
    used = ptc.fit_range(mu, var, full_scale_dn)
    if np.unique(np.round(mu[used], 6)).size < 2:
        raise CamsimError(f"plane {name}: only {np.count_nonzero(used)} flat pair(s) lie below "
                          f"{100 * ptc.FIT_FRACTION:g} % of saturation; shoot more levels below it")
    fit = ptc.fit_photon_transfer(mu, var, dark_var.value, pixels, used)
    brightest = int(np.flatnonzero(used)[np.argmax(mu[used])])
    fitted, plain, plot = _tukey_fits(samples, read[1], frames, plane_w)
    return PlaneResult(name, layout.plane_colours[p], black, dark_var, read[1], read[0], row, dsnu, fitted, plain,
                       fit, pairs[brightest].prnu_percent[p], brightest, pixels, plot)


def _iso(value: float):
    """An ISO speed: an int where it is one (3200), else a float."""
    value = float(value)
    return int(value) if value.is_integer() else value


#: Points of the probability plot drawn (thinned from the order statistics).
_PLOT_POINTS = 4000


def _tukey_fits(samples, pixel_var, frames, row_pixels):
    """The matched and the plain PPCC fits of one plane's samples, and its probability plot's points (the fitted
    law's quantiles and the sorted samples, DN). Without a read noise above 0.1 DN the ADC's step is all there is
    and the matched law has no scale: the plain fit stands for both."""
    values, p = tukey.order_statistics(samples)
    plain = tukey.fit_tukey(order=(values, p, samples.size))
    pick = np.unique(np.round(np.linspace(0, values.size - 1, _PLOT_POINTS)).astype(np.int64))
    read_var = dark.sheppard_read_variance_dn2(pixel_var)
    if not read_var > 0.1**2:
        return plain, plain, (tukey.tukey_quantiles(plain.lam, p[pick]) * plain.scale_dn, values[pick])
    matched = tukey.fit_tukey(order=(values, p, samples.size), variance_dn2=pixel_var, frames=frames,
                              row_pixels=row_pixels)
    shrink = (1 - 1 / frames) * (1 - 1 / row_pixels)
    a = math.sqrt(read_var / tukey_lambda_variance(matched.lam))  # the scale the blur was set with
    gauss = math.sqrt(pixel_var / (frames - 1) + pixel_var * frames / ((frames - 1) * row_pixels))
    q = tukey.blurred_tukey_quantiles(matched.lam, p[pick], 1.0 / a, gauss / a) * matched.scale_dn * shrink
    return matched, plain, (q, values[pick])


def _warnings(planes, read_all: Estimate, k: Estimate, levels: int, darks: int) -> list:
    """What the report and the command line should point out."""
    out = []
    if darks < 8:
        out.append(f"only {darks} dark frames: the read noise's law (λ) is blurred by the mean of so few; 8–16 make "
                   "it surer")
    if read_all.value < MIN_READ_NOISE_DN:
        out.append(f"the read noise is {read_all.value:.2f} DN, below {MIN_READ_NOISE_DN} DN: the ADC's step then "
                   "dominates the dark noise, and the read noise and its λ are uncertain beyond their standard errors")
    for pl in planes:
        fit = pl.ptc
        if fit.r_squared < 0.99:
            out.append(f"plane {pl.name}: the photon transfer fit has R² = {fit.r_squared:.4f}: the response is "
                       "not linear over the fit range, or the light changed between the frames of a pair")
        c = fit.intercept_dn2
        if (c.standard_error and abs(c.value) > 5 * c.standard_error
                and abs(c.value) > 0.05 * pl.dark_variance_dn2.value):
            out.append(f"plane {pl.name}: the photon transfer line meets μ = 0 at {c.value:.3g} DN², not 0 "
                       f"(± {c.standard_error:.2g}): the darks' noise differs from the flats' at zero signal (an "
                       "exposure or ISO that differs, or a dark current of the longer flats)")
    ks = [pl.ptc.k_dn_per_e for pl in planes]
    if len(ks) > 1 and k.standard_error:
        chi2 = sum((e.value - k.value) ** 2 / e.standard_error**2 for e in ks if e.standard_error)
        if chi2 / (len(ks) - 1) > 9:
            out.append("the planes' K differ more than their errors allow (" + ", ".join(
                f"{pl.name} {pl.ptc.k_dn_per_e.value:.4g}" for pl in planes) + " DN/e⁻): per-colour gains?")
    if levels < 5:
        out.append(f"only {levels} flat levels: 5 or more, from about 5 % to 70 % of the white level, make K surer")
    return out

