"""Fixed-pattern noise maps (the two kinds of DSNU, and PRNU), beyond the paper.

The maps belong to the sensor, not the frame: they are drawn from ``sensor_seed`` alone, so that frames of the
same sensor share them while their temporal noise changes (as in ISETCam and the ELD low-light noise model).

Two kinds of dark-signal non-uniformity:

* the offset DSNU (``dsnu_e``): a fixed charge o(x) added to each pixel, Gaussian, the same whatever the
  exposure time T;
* the dark-current DSNU (``dsnu_dark_current_percent`` = p): each pixel's dark-current rate is σ²_dark · d(x), so
  it collects Poisson(σ²_dark · T · d(x)) dark electrons; the spatial σ of its mean dark charge, p/100 · σ²_dark · T,
  grows ∝ T. d is log-normal with mean 1 and σ = p/100: d = exp(s z − s²/2), z standard normal, s² = ln(1 + (p/100)²).
  Log-normal because a dark-current rate is positive and its spread skewed to the high side: real sensors show a
  tail of hot pixels far above the median rate, never a negative one.

Issue 28's fixed patterns, each from its own child of the sensor's fixed-pattern sequence
(:func:`camsim.core.seeding.fixed_pattern_generator`), each off by default (and then no map changes):

* **dark shading** (``dark_shading_e``): a fixed dark-level pattern, the sum of a row profile (one N(0, 1) per
  row), a column profile (one per column) and a smooth 2-D shading (a quadratic a + b x + c y + d x² + e xy + f y² on
  x, y ∈ [−1, 1] with N(0, 1) coefficients), each made of mean 0 and RMS 1 over the frame, their sum then scaled to
  RMS ``dark_shading_e`` exactly (mean 0) — as PMN (Feng et al., ACM MM 2022) describes it: a fixed pattern of the
  dark frame with row, column and smooth structure. It is an offset in e⁻, added to the charge like the offset
  DSNU, so in DN it scales with the gain by itself; it does not grow with the exposure (the part that does is the
  dark-current DSNU, ``dsnu_dark_current_percent``, and the hot pixels), nor does its shape change with the ISO.
  ``dark_shading_map`` (a .npy file, e⁻ per pixel, e.g. ``camsim calibrate``'s) adds a measured pattern. A Bayer
  sensor has one pattern per physical pixel (its three planes hold the same values: each site reads its own
  channel's); a three-chip sensor one per chip.
* **column FPN** (``column_fpn_e`` = σ): one N(0, σ²) offset per column (per chip of a three-chip sensor), added like
  the dark shading.
* **defects**: each pixel (each chip's pixel of a three-chip sensor) draws one uniform u; u < f_hot is hot, f_hot ≤ u
  < f_hot + f_dead dead, f_hot + f_dead ≤ u < f_hot + f_dead + f_stuck stuck (disjoint populations; each count
  binomial in the number of pixels). A **hot** pixel has an extra dark current h, exponential of mean
  ``hot_pixel_dark_e_per_s`` (EMVA 1288 Release 4.0 shows the dark signal's non-uniformity as a histogram on a
  logarithmic axis, where hot pixels form a tail; its straight line there is the exponential law), at the reference
  temperature; ``hot_pixel_map`` (e⁻/s per pixel) adds a measured one. It joins the dark-current DSNU factor: d' = d +
  h / σ²_dark,κ (σ²_dark,κ the channel's dark current at the reference temperature), so the pixel collects
  Poisson(σ²_dark T d + h T) scaled by the temperature's factor like every dark electron — one implementation of the
  dark charge (a channel whose ``dark_current_e_per_s`` is 0 takes ``HOT_PIXEL_BASE_E_PER_S`` = 10⁻¹² e⁻/s as its
  ordinary rate: :attr:`SensorParams.dark_current_base_e_per_s`). A **dead** pixel has a PRNU gain 0
  and a dark factor 0: it collects nothing, yet is read out (its offsets, read and row noise, the ADC's pedestal): it
  reads black. A **stuck** pixel reads a fixed level, uniform on the integers 0 … 2^nb − 1 DN, in every frame, without
  noise: written over the frame's values (the float layer and the ADC's output) after every other stage.
"""

from __future__ import annotations

import math
import os
import threading
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from camsim.core.errors import CamsimError
from camsim.core.seeding import fixed_pattern_generator, fixed_pattern_generators
from camsim.sensor.params import CHARGE_MAX_E, DARK_CHARGE_MAX_E, DARK_CURRENT_MAX_E_PER_S, SensorParams


@dataclass(frozen=True)
class FixedPattern:
    """Per-pixel maps of a sensor, shape (3, H, W) float32 each, or None where off.

    Attributes
    ----------
    offset_e : numpy.ndarray or None
        Offset DSNU, plus the dark shading and column FPN: dark offset added to the charge. Unit: e⁻.
    gain : numpy.ndarray or None
        PRNU: factor on the mean signal, around 1 (0 at a dead pixel). Unitless.
    dark_gain : numpy.ndarray or None
        Dark-current DSNU: factor d on the mean dark charge σ²_dark · T, log-normal of mean 1 (plus h / σ²_dark
        at a hot pixel, 0 at a dead one). Unitless.
    gain_excess : numpy.ndarray or None
        ``gain - 1`` (float32, the same values), kept with the maps so that each frame's clean layer does not
        compute it again; None where ``gain`` is None or it was not kept. Unitless.
    stuck_index : numpy.ndarray or None
        Flat indices of the stuck pixels into the frame's values (planes, H, W) (one plane for a Bayer sensor,
        three for a three-chip one), int64, increasing; None where there are none.
    stuck_level_dn : numpy.ndarray or None
        Their levels, float32 integers in [0, 2^nb − 1]. Unit: DN.
    defect_counts : dict or None
        ``{"hot": n, "dead": n, "stuck": n}``, pixels of each population (a hot-pixel map's nonzero pixels
        included); None where no defect is on.
    """

    offset_e: np.ndarray | None
    gain: np.ndarray | None
    dark_gain: np.ndarray | None = None
    gain_excess: np.ndarray | None = None
    stuck_index: np.ndarray | None = None
    stuck_level_dn: np.ndarray | None = None
    defect_counts: dict | None = None


def lognormal_log_sigma(relative_sigma: float) -> float:
    """s, the σ of ln d for a log-normal d of mean 1 and standard deviation ``relative_sigma``: s² = ln(1 + σ²)."""
    return math.sqrt(math.log1p(relative_sigma**2))


def dark_gain_at(sensor: SensorParams, z: float) -> float:
    """The dark-current DSNU factor d = exp(s z − s²/2) of a pixel whose normal deviate is ``z`` (1 when off).

    The map's margins: its d lies within [``dark_gain_at(sensor, −m)``, ``dark_gain_at(sensor, m)``] wherever its
    normal is within m σ, as the offset and gain maps' margins of m σ assume. Unitless.
    """
    s = lognormal_log_sigma(sensor.dsnu_dark_current_percent / 100)
    return math.exp(s * z - s * s / 2)


@lru_cache(maxsize=2)
def _unit_maps(sensor_seed: int, shape: tuple) -> tuple:
    offset_rng, gain_rng, _ = fixed_pattern_generators(sensor_seed)
    offset = offset_rng.standard_normal((3, *shape), dtype=np.float32)
    gain = gain_rng.standard_normal((3, *shape), dtype=np.float32)
    return offset, gain


def prnu_gain(xp, unit_gain, prnu_percent: float):
    """The PRNU gain map g = max(1 + z σ, 0) of unit normals ``z`` (σ = ``prnu_percent`` / 100), float32 on ``xp``'s
    device: a pixel collects no negative charge, so the normal's far tail below 0 (z < −100 / ``prnu_percent``: at a
    PRNU of 20 % and more) is a pixel that collects nothing. Unitless."""
    return xp.maximum(1 + unit_gain * np.float32(prnu_percent / 100), np.float32(0))


@lru_cache(maxsize=1)
def _scaled_maps(sensor_seed: int, shape: tuple, dsnu_e: float, prnu_percent: float) -> tuple:
    """The offset DSNU map o (e⁻), the PRNU gain map g and g − 1 (unitless), float32, read-only (None where
    off): the unit maps scaled, once per sensor and frame size: consecutive frames of a dataset share them (one
    entry: a spec whose frames draw their own DSNU or PRNU scales them per frame, as before)."""
    unit_offset, unit_gain = _unit_maps(sensor_seed, shape)
    offset = unit_offset * np.float32(dsnu_e) if dsnu_e > 0 else None
    gain = prnu_gain(np, unit_gain, prnu_percent) if prnu_percent > 0 else None
    excess = None if gain is None else gain - 1
    for array in (offset, gain, excess):
        if array is not None:
            array.setflags(write=False)  # cached: shared by every frame of the sensor
    return offset, gain, excess


@lru_cache(maxsize=2)
def _dark_gain_map(sensor_seed: int, shape: tuple, relative_sigma: float) -> np.ndarray:
    """d = exp(s z − s²/2) on the third fixed-pattern stream's standard normals z, float32, read-only."""
    _, _, dark_rng = fixed_pattern_generators(sensor_seed)
    z = dark_rng.standard_normal((3, *shape), dtype=np.float32)
    s = lognormal_log_sigma(relative_sigma)
    z *= np.float32(s)
    z -= np.float32(s * s / 2)
    d = np.exp(z, out=z)
    d.setflags(write=False)  # cached: shared by every frame of the sensor
    return d


def _normalised(field: np.ndarray) -> np.ndarray:
    """``field`` less its mean, over its RMS (float64; zeros where it is constant)."""
    field = field - field.mean()
    rms = math.sqrt(float(np.mean(field * field)))
    return field / rms if rms > 0 else field


def dark_shading_pattern(sensor_seed: int, planes: int, shape: tuple) -> np.ndarray:
    """The unit dark-shading pattern, (planes, H, W) float64, each plane of mean 0 and RMS 1 exactly: the normalised
    sum of a row profile, a column profile and a smooth quadratic shading, each itself normalised (the module's
    docstring). Scaled by ``dark_shading_e`` it is the dark shading in e⁻."""
    height, width = shape
    rng = fixed_pattern_generator(sensor_seed, 6)
    y = np.linspace(-1.0, 1.0, height)[:, None] if height > 1 else np.zeros((1, 1))
    x = np.linspace(-1.0, 1.0, width)[None, :] if width > 1 else np.zeros((1, 1))
    out = np.empty((planes, height, width))
    for p in range(planes):
        rows = _normalised(np.broadcast_to(rng.standard_normal((height, 1)), shape))
        columns = _normalised(np.broadcast_to(rng.standard_normal((1, width)), shape))
        a = rng.standard_normal(6)
        smooth = _normalised(np.broadcast_to(a[0] + a[1] * x + a[2] * y + a[3] * x * x + a[4] * x * y + a[5] * y * y,
                                             shape))
        out[p] = _normalised(rows + columns + smooth)
    return out


def column_fpn_pattern(sensor_seed: int, planes: int, width: int) -> np.ndarray:
    """One N(0, 1) per column of each plane, (planes, 1, W) float64: column FPN of σ 1 e⁻ (scaled by
    ``column_fpn_e``)."""
    return fixed_pattern_generator(sensor_seed, 7).standard_normal((planes, 1, width))


@lru_cache(maxsize=8)
def _load_map(path: str, mtime_ns: int, what: str) -> np.ndarray:
    from camsim.core.npy_header import npy_header
    from camsim.core.pixel_limit import MAX_PIXELS

    def check_shape(shape):  # before the data is read: a header may claim any shape
        if math.prod(shape) > 3 * MAX_PIXELS:
            raise CamsimError(f"{what} {path} holds {math.prod(shape)} values, more than a frame of {MAX_PIXELS} "
                              "pixels (three planes) has")

    header = npy_header(path, what, check_shape)
    if header is not None and (header[1].hasobject or not np.issubdtype(header[1], np.number)
                               or np.issubdtype(header[1], np.complexfloating)):
        raise CamsimError(f"{what} {path} must hold a real number array, its header says {header[1]}")
    try:
        array = np.load(path, allow_pickle=False)
    except (OSError, ValueError) as exc:
        raise CamsimError(f"cannot read {what} {path}: {exc}") from None
    if not isinstance(array, np.ndarray) or not np.issubdtype(array.dtype, np.number) or np.iscomplexobj(array):
        raise CamsimError(f"{what} {path} must hold a real number array")
    array = array.astype(np.float64)
    if not np.isfinite(array).all():
        raise CamsimError(f"{what} {path} holds non-finite values")
    array.setflags(write=False)
    return array


def _map_mtime(path, what: str) -> int:
    """The modification time of a map file (the key of its cached load), once the path is known to name a regular
    file (:func:`camsim.core.input_files.open_input`: not a FIFO, a device, a directory or a path with a NUL byte).
    Unit: ns."""
    from camsim.core.input_files import open_input

    with open_input(path, what) as handle:
        return os.fstat(handle.fileno()).st_mtime_ns


def map_file_extreme(path: str, what: str) -> float:
    """The largest |value| of a map file (loaded once, as :func:`load_pixel_map` loads it). Unit: the map's."""
    array = _load_map(str(path), _map_mtime(path, what), what)
    return float(np.max(np.abs(array), initial=0.0))


def load_pixel_map(path: str, sensor: SensorParams, shape: tuple, what: str) -> np.ndarray:
    """A per-pixel map file (.npy) as (planes, H, W) float64: (H, W) for a Bayer sensor (one plane), (H, W) or
    (3, H, W) for a three-chip one (3 planes; an (H, W) map serves the three chips). Loaded once per file
    (cached by its path and modification time).

    Raises
    ------
    CamsimError
        A file that cannot be read, holds non-finite or non-numbers, or whose shape does not match the frame's.
    """
    array = _load_map(str(path), _map_mtime(path, what), what)
    _check_map_values(array, path, sensor, what)
    height, width = shape
    if array.shape == (height, width):
        return array[None] if sensor.cfa is not None else np.broadcast_to(array, (3, height, width))
    if sensor.cfa is None and array.shape == (3, height, width):
        return array
    wanted = f"({height}, {width})" + ("" if sensor.cfa is not None else f" or (3, {height}, {width})")
    raise CamsimError(f"{what} {path} has shape {array.shape}, the frame needs {wanted}")


#: A map's values have the bounds of the parameter they add to (:mod:`camsim.sensor.params`): map name → (largest
#: magnitude, unit).
MAP_BOUNDS = {"dark_shading_map": (CHARGE_MAX_E, "e⁻"), "hot_pixel_map": (DARK_CURRENT_MAX_E_PER_S, "e⁻/s")}


def _check_map_values(array: np.ndarray, path, sensor: SensorParams, what: str) -> None:
    """Refuse a map whose values pass its parameter's bounds (:data:`MAP_BOUNDS`), or a hot-pixel map whose extra
    dark charge in the exposure passes :data:`camsim.sensor.params.DARK_CHARGE_MAX_E`, as the parameters themselves
    are refused: a value of 1e300 would overflow the float32 maps (and float64's squares)."""
    bound, unit = MAP_BOUNDS.get(what, (None, ""))
    if bound is None:
        return
    extreme = float(np.max(np.abs(array), initial=0.0))
    if extreme > bound:
        raise CamsimError(f"{what} {path} holds a value of magnitude {extreme:.3g} {unit}, beyond the {bound:g} {unit} "
                          "its parameter allows")
    if what == "hot_pixel_map":
        charge = extreme * sensor.temperature_factor * sensor.exposure_s
        if charge > DARK_CHARGE_MAX_E:
            raise CamsimError(f"{what} {path} gives a dark charge of {charge:.3g} e⁻ in the {sensor.exposure_s:g} s "
                              f"exposure, over {DARK_CHARGE_MAX_E:.3g} e⁻ (2⁵³, beyond which float64 no longer "
                              "counts electrons)")


def _defects(sensor: SensorParams, planes: int, shape: tuple):
    """(hot extra dark current e⁻/s, dead mask, stuck flat indices, stuck levels, counts) on (planes, H, W), or
    None where no defect is on."""
    f_hot, f_dead, f_stuck = sensor.hot_pixel_fraction, sensor.dead_pixel_fraction, sensor.stuck_pixel_fraction
    if not (sensor.hot_pixels or f_dead > 0 or f_stuck > 0):
        return None
    full = (planes, *shape)
    hot = np.zeros(full)
    dead = stuck_index = stuck_level = None
    counts = {"hot": 0, "dead": 0, "stuck": 0}
    if f_hot > 0 or f_dead > 0 or f_stuck > 0:
        u = fixed_pattern_generator(sensor.sensor_seed, 3).random(full)
        if f_hot > 0:
            is_hot = u < f_hot
            n = int(np.count_nonzero(is_hot))
            hot[is_hot] = fixed_pattern_generator(sensor.sensor_seed, 4).standard_exponential(n) * \
                sensor.hot_pixel_dark_e_per_s
        if f_dead > 0:
            dead = (u >= f_hot) & (u < f_hot + f_dead)
            counts["dead"] = int(np.count_nonzero(dead))
        if f_stuck > 0:
            stuck_index = np.flatnonzero((u >= f_hot + f_dead) & (u < f_hot + f_dead + f_stuck))
            stuck_level = fixed_pattern_generator(sensor.sensor_seed, 5).integers(
                0, 2**sensor.bits, stuck_index.size).astype(np.float32)
            counts["stuck"] = int(stuck_index.size)
    if sensor.hot_pixel_map is not None:
        hot += load_pixel_map(sensor.hot_pixel_map, sensor, shape, "hot_pixel_map")
        if np.any(hot < 0):
            raise CamsimError(f"hot_pixel_map {sensor.hot_pixel_map} holds negative dark currents")
    if dead is not None:
        hot[dead] = 0.0
    counts["hot"] = int(np.count_nonzero(hot))
    return hot, dead, stuck_index, stuck_level, counts


def _effect_key(sensor: SensorParams) -> tuple:
    """The sensor's fields that issue 28's maps depend on (besides the seed and the shape)."""
    return (sensor.cfa is None, sensor.dsnu_e, sensor.prnu_percent, sensor.dsnu_dark_current_percent,
            sensor.dark_shading_e, sensor.dark_shading_map, sensor.column_fpn_e, sensor.hot_pixel_fraction,
            sensor.hot_pixel_dark_e_per_s, sensor.hot_pixel_map, sensor.dead_pixel_fraction,
            sensor.stuck_pixel_fraction, sensor.bits, sensor.dark_current_e_per_s,
            *(_mtime(p) for p in (sensor.dark_shading_map, sensor.hot_pixel_map)))


def _mtime(path) -> int | None:
    try:
        return None if path is None else Path(path).stat().st_mtime_ns
    except (OSError, ValueError):  # ValueError: a NUL byte in the path
        return None  # refused where the map is loaded, with the reason


#: One entry, ``(seed, shape, key) -> FixedPattern``, of :func:`_effect_maps` (keyed by :func:`_effect_key`, so that
#: frames differing in other fields — their exposure — share it).
_EFFECT_CACHE: dict = {}
_EFFECT_LOCK = threading.Lock()


def _cached_effect_maps(sensor: SensorParams, shape: tuple) -> FixedPattern:
    key = (sensor.sensor_seed, shape, _effect_key(sensor))
    with _EFFECT_LOCK:
        maps = _EFFECT_CACHE.get(key)
        if maps is None:
            maps = _effect_maps(sensor, shape)
            _EFFECT_CACHE.clear()
            _EFFECT_CACHE[key] = maps
    return maps


def _effect_maps(sensor: SensorParams, shape: tuple) -> FixedPattern:
    """The maps with issue 28's fixed patterns folded in (the module's docstring): computed once per sensor and
    frame size (:func:`_cached_effect_maps`)."""
    offset = gain = excess = None
    if sensor.dsnu_e > 0 or sensor.prnu_percent > 0:
        offset, gain, excess = _scaled_maps(sensor.sensor_seed, shape, sensor.dsnu_e, sensor.prnu_percent)
    p = sensor.dsnu_dark_current_percent
    dark_gain = _dark_gain_map(sensor.sensor_seed, shape, p / 100) if p > 0 else None
    planes = 1 if sensor.cfa is not None else 3
    full = (3, *shape)
    if sensor.dark_offsets:  # the dark shading and column FPN join the offset DSNU: one offset map
        extra = np.zeros((planes, *shape))
        if sensor.dark_shading_e > 0:
            extra += sensor.dark_shading_e * dark_shading_pattern(sensor.sensor_seed, planes, shape)
        if sensor.dark_shading_map is not None:
            extra += load_pixel_map(sensor.dark_shading_map, sensor, shape, "dark_shading_map")
        if sensor.column_fpn_e > 0:
            extra += sensor.column_fpn_e * column_fpn_pattern(sensor.sensor_seed, planes, shape[1])
        offset = np.broadcast_to(extra, full).astype(np.float32) if offset is None else offset + np.float32(extra)
    defects = _defects(sensor, planes, shape)
    stuck_index = stuck_level = counts = None
    if defects is not None:
        hot, dead, stuck_index, stuck_level, counts = defects
        if counts["hot"]:
            rate = np.asarray(sensor.dark_current_base_e_per_s, dtype=np.float64).reshape(3, 1, 1)
            base = np.ones(full) if dark_gain is None else dark_gain.astype(np.float64)
            dark_gain = (base + hot / rate).astype(np.float32)
        if dead is not None and counts["dead"]:
            dead3 = np.broadcast_to(dead, full)
            gain = np.ones(full, dtype=np.float32) if gain is None else gain.copy()
            gain[dead3] = 0
            excess = gain - 1
            dark_gain = np.ones(full, dtype=np.float32) if dark_gain is None else np.array(dark_gain)
            dark_gain[dead3] = 0
    for array in (offset, gain, excess, dark_gain, stuck_index, stuck_level):
        if array is not None and array.flags.writeable:
            array.setflags(write=False)  # cached: shared by every frame of the sensor
    return FixedPattern(offset, gain, dark_gain, excess, stuck_index, stuck_level, counts)


def fixed_pattern(sensor: SensorParams, shape) -> FixedPattern | None:
    """The sensor's DSNU (offset and dark-current) and PRNU maps for a frame of ``shape`` (H, W); None when all are
    off.

    The unit maps depend on ``sensor_seed`` and the shape only; their magnitudes scale them, so a sensor with more
    offset DSNU has the same pattern, stronger (the dark-current map's hot pixels are the same pixels at any p > 0).
    The dark-current map is kept whether or not the dark-current stage is on: it scales σ²_dark · T, which is then 0.
    """
    if not sensor.fixed_pattern:
        return None
    if sensor.dark_offsets or sensor.hot_pixels or sensor.dead_pixel_fraction > 0 or sensor.stuck_pixel_fraction > 0:
        return _cached_effect_maps(sensor, tuple(shape))
    offset = gain = excess = None
    if sensor.dsnu_e > 0 or sensor.prnu_percent > 0:
        offset, gain, excess = _scaled_maps(sensor.sensor_seed, tuple(shape), sensor.dsnu_e, sensor.prnu_percent)
    p = sensor.dsnu_dark_current_percent
    dark_gain = _dark_gain_map(sensor.sensor_seed, tuple(shape), p / 100) if p > 0 else None
    return FixedPattern(offset, gain, dark_gain, excess)
