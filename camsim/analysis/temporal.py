"""Temporal and spatial noise of a sequence of frames of a static scene (EMVA 1288 Release 4.0's method).

A **sequence** is two or more frames of one static scene taken by one sensor: their sidecars agree on the scene, the
light (illuminant, F), the camera, the exposure and every sensor key — ``sensor_seed`` included, so the
fixed-pattern maps are the same — and differ in their temporal noise: their ``seed`` (or, for the frames of a scene
file's ``[sequence]``, their ``frame_index`` within one ``sequence``). Frames of two sensors (two
``sensor_seed``) are never grouped. A sequence whose sidecars record a ``homography`` (or a rolling shutter's
``row_homographies``) other than the identity is not of a static scene, and one whose ``flicker_factor`` or
``flicker_row_factor`` is not 1 not under a steady light: either is left out (with one line that says so).

For a stack of N frames y_j(x) (DN) and a region of n pixels of one channel (a patch less the border, or the whole
frame; a Bayer frame: that colour's sites), with the per-pixel mean over frames ȳ(x):

* **temporal variance** (EMVA 1288 4.0, Eq. 43's stack form): the mean over the region's pixels of each pixel's
  unbiased variance over the frames, σ²_y,temp = 1/n Σ_x 1/(N − 1) Σ_j (y_j(x) − ȳ(x))². Its standard error is
  taken over rows (each row's sum, a ratio estimator as in :mod:`camsim.analysis.frame_stats`): row noise — one
  offset per row and frame, temporal but the same along a row — makes a row's pixels vary together, which a
  per-pixel standard error would hide;
* **spatial variance** (EMVA 1288 4.0, Eq. 45): the variance over the region's pixels of the mean image less the
  temporal noise left in it, s²_y,spat = s²_ȳ − σ²_y,temp / N, s²_ȳ = 1/(n − 1) Σ_x (ȳ(x) − ⟨ȳ⟩)². Its standard
  error treats the pixels of the mean image as independent (delta method on the second and fourth sample moments:
  SE²(s²_ȳ) = (m₄ − s⁴_ȳ) / n) and adds that of the temporal correction, SE(σ²_y,temp) / N. This is right for the
  per-pixel patterns (DSNU, PRNU) and the temporal noise; a structured pattern varies less freely (C columns of
  column FPN: a relative spread of √(2 / C) between sensors) and row noise enters the mean image as one offset per
  row of variance σ²_row / N, which the correction removes up to (C − 1) / (n − 1) of it (a bias of about
  −σ²_row / (N R) over R rows).

The model's predictions, from the sidecar alone (a frame of the sequence):

* temporal: per pixel k² (Var(S + D) + σ_read² + σ_row²) + 1/12 DN² for a DNG
  (:func:`camsim.analysis.frame_stats.predicted_var_dn2`, averaged over the region; Var(S + D) = the clean value / k
  under ``pixel`` statistics), plus the per-frame black-level error's σ² (``black_level_error_dn``), which moves
  every pixel of a frame together and so is temporal too. The clean value is the EXR's clean layer where there is
  one (the exact expectation of each pixel), else the patch's ``signal_e`` + ``dark_e`` of the sidecar (the whole
  frame without an EXR: none). None under ``paper`` statistics;
* spatial, the expectation over sensors of the region's pixel variance, k² (σ_o² + σ_col² + (S̄ σ_PRNU)² +
  (D̄ σ_d)²) — ``dsnu_e`` σ_o, ``column_fpn_e`` σ_col, ``prnu_percent`` / 100 σ_PRNU on the patch's mean signal S̄,
  ``dsnu_dark_current_percent`` / 100 σ_d on its mean dark charge D̄ — and for the whole frame of a flat target
  ``dark_shading_e``² too (its pattern has exactly that RMS over the frame; over a patch it depends on where the
  patch lies: not predicted). Not predicted either: hot, dead and stuck pixels (their populations' variance is
  dominated by a few pixels), ``dark_shading_map`` and a scene whose region is not uniform (the whole frame of a
  chart or an image). ``spatial_model_terms`` and ``spatial_not_modelled`` name which;
* spatial, this sensor's pattern: the variance over the region of the EXR's clean layer (each pixel's expectation,
  with every fixed pattern and the scene's own structure in it), where there is one.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from camsim.analysis.columns import TEMPORAL_COLUMNS as COLUMN_TEXTS
from camsim.analysis.frame_stats import _row_mean_se, load_clean_dn, predicted_var_dn2
from camsim.analysis.grouping import group_key
from camsim.colour.colorimetry import CHANNELS
from camsim.core.errors import CamsimError
from camsim.core.optional_numbers import finite_or_none
from camsim.render.frame_files import load_frame, read_frame_meta

#: The file ``camsim analyze`` writes when it finds a sequence: one row per sequence × region × channel.
TEMPORAL_CSV_NAME = "temporal.csv"

#: temporal.csv's columns, in order (each explained in :data:`camsim.analysis.columns.TEMPORAL_COLUMNS`).
TEMPORAL_COLUMNS = tuple(COLUMN_TEXTS)

#: Sidecar keys that differ between the frames of one sequence (not part of its key).
PER_FRAME_KEYS = ("seed", "frame_index", "time_s", "homography", "files")

#: A homography entry farther than this from the identity's makes a sequence not static. Unitless (pixels for the
#: translation terms).
STATIC_TOLERANCE = 1e-9


@dataclass
class Sequence:
    """The frames of one sequence, in order (``frame_index``, then ``seed``, then path).

    Attributes
    ----------
    key : str
        What the frames' sidecars agree on (:func:`sequence_key`).
    paths : list of Path
    metas : list of dict
    """

    key: str
    paths: list = field(default_factory=list)
    metas: list = field(default_factory=list)


def sequence_key(meta: dict, source: str) -> str:
    """The key that the frames of one sequence share: the measurement's grouping key
    (:func:`camsim.analysis.grouping.group_key`: scene, light, camera, every sensor key and ``sensor_seed``), F,
    the exposure time, the patches' rectangles, the target, the ``sequence`` stem (frames of a scene file's
    ``[sequence]``) and the file kind measured."""
    return json.dumps([group_key(meta), meta.get("intensity_factor"), meta.get("exposure_s"),
                       [p.get("rect_xywh") for p in meta.get("patches") or []], meta.get("target"),
                       meta.get("sequence"), source], sort_keys=True)


def _index(meta: dict, key: str) -> int:
    """A sidecar's ``seed`` or ``frame_index`` as an int, −1 where it has none (the schema allows a null seed)."""
    value = meta.get(key)
    return value if isinstance(value, int) and not isinstance(value, bool) else -1


def _is_static(meta: dict) -> bool:
    for key in ("homography", "row_homographies"):
        h = meta.get(key)
        if h is None:
            continue
        try:
            h = np.asarray(h, dtype=np.float64).reshape(-1, 3, 3)
            with np.errstate(divide="ignore", invalid="ignore"):
                if not np.all(np.abs(h / h[:, 2:, 2:] - np.eye(3)) <= STATIC_TOLERANCE):
                    return False
        except (TypeError, ValueError, ZeroDivisionError):
            return False
    return True


def _is_steady(meta: dict) -> bool:
    """Whether the frame's light was steady: no ``flicker_factor`` / ``flicker_row_factor`` other than 1."""
    for key in ("flicker_factor", "flicker_row_factor"):
        value = meta.get(key)
        if value is None:
            continue
        try:
            if not np.all(np.abs(np.asarray(value, dtype=np.float64) - 1) <= STATIC_TOLERANCE):
                return False
        except (TypeError, ValueError):
            return False
    return True


def find_sequences(paths, source: str = "dng", warn=None) -> list[Sequence]:
    """Group the frame files ``paths`` into sequences of two or more frames (see the module's notes).

    Parameters
    ----------
    paths : iterable of Path
        Frame files (already found and checked, e.g. those ``camsim analyze`` measured).
    source : {'dng', 'exr'}
        Unused: each file is measured as what it is (a frame's DNG and its EXR, both named, hold the same noise
        and are never one sequence).
    warn : callable, optional
        Called with one line per frame left out: a second frame of the same seed (not independent), a sequence
        that moves or flickers.

    Returns
    -------
    list of Sequence
        In order of their first frame's path.
    """
    groups: dict[str, Sequence] = {}
    for path in sorted(Path(p) for p in paths):
        try:
            meta = read_frame_meta(path)
        except CamsimError:
            continue  # told by the frame analysis
        key = sequence_key(meta, path.suffix.lower().lstrip("."))  # a DNG and an EXR are never one sequence
        groups.setdefault(key, Sequence(key)).paths.append(path)
        groups[key].metas.append(meta)
    sequences = []
    for group in groups.values():
        if len(group.paths) < 2:
            continue
        if not all(_is_static(m) for m in group.metas):
            if warn is not None:
                warn(f"{group.paths[0].parent}: the sequence of {group.paths[0].name} ({len(group.paths)} frames) "
                     "moves (a homography other than the identity): no temporal analysis")
            continue
        if not all(_is_steady(m) for m in group.metas):
            if warn is not None:
                warn(f"{group.paths[0].parent}: the sequence of {group.paths[0].name} ({len(group.paths)} frames) "
                     "is lit by a flickering light (a flicker factor other than 1): no temporal analysis")
            continue
        seen: dict = {}
        kept = Sequence(group.key)
        copies = []  # frames of the same noise as one kept: told only where the others make a sequence
        order = sorted(zip(group.paths, group.metas),
                       key=lambda pm: (_index(pm[1], "frame_index"), _index(pm[1], "seed"), str(pm[0])))
        for path, meta in order:
            identity = (_index(meta, "seed"), _index(meta, "frame_index"))
            if identity in seen:
                copies.append(f"{path}: the same scene, sensor and seed as {seen[identity]} (the same noise): left "
                              "out of its sequence's temporal analysis")
                continue
            seen[identity] = path
            kept.paths.append(path)
            kept.metas.append(meta)
        if len(kept.paths) >= 2:
            sequences.append(kept)
            for line in copies if warn is not None else ():
                warn(line)
    return sequences


@dataclass(frozen=True)
class Stack:
    """Per-pixel moments over the frames of a sequence.

    Attributes
    ----------
    mean_dn : numpy.ndarray, shape (P, H, W)
        Each pixel's mean over the frames, float64 (P = 3 planes, or 1 for a Bayer mosaic). Unit: DN.
    var_dn2 : numpy.ndarray, shape (P, H, W)
        Each pixel's unbiased variance over the frames (ddof = 1), float64. Unit: DN².
    n_frames : int
    """

    mean_dn: np.ndarray
    var_dn2: np.ndarray
    n_frames: int


def stack_moments(frames) -> Stack:
    """Per-pixel mean and unbiased variance over frames given one at a time (an iterable of (P, H, W) arrays).

    Only three frame-sized float64 arrays are held (the first frame as a shift, the sums of the shifted values and
    of their squares), so memory does not grow with N; the shift keeps the sums exact for integer DN.

    Raises
    ------
    CamsimError
        Fewer than two frames, or frames of different shapes.
    """
    n, ref, s1, s2 = 0, None, None, None
    for pixels in frames:
        x = np.asarray(pixels, dtype=np.float64)
        if ref is None:
            ref, s1, s2 = x, np.zeros_like(x), np.zeros_like(x)
        elif x.shape != ref.shape:
            raise CamsimError(f"frames of a sequence differ in shape: {ref.shape} and {x.shape}")
        d = x - ref
        s1 += d
        s2 += d * d
        n += 1
    if n < 2:
        raise CamsimError(f"a temporal variance needs two frames or more, got {n}")
    mean = ref + s1 / n
    var = np.maximum(s2 - s1 * s1 / n, 0.0) / (n - 1)
    return Stack(mean, var, n)


def region_planes(array: np.ndarray, rect, border: int, pattern: str | None, channel: int) -> list[np.ndarray]:
    """The 2-D blocks (rows × columns) of one channel of ``array`` (P, H, W) inside ``rect`` less ``border``: one
    block for a three-chip frame, one per site of that colour for a Bayer mosaic (their rows are distinct physical
    rows)."""
    x, y, w, h = rect
    if 2 * border >= min(w, h):
        return []
    if not pattern:
        return [array[channel, y + border : y + h - border, x + border : x + w - border]]
    from camsim.sensor.cfa import cfa_sites

    block = array[0, y + border : y + h - border, x + border : x + w - border]
    return [block[(dy - y - border) % 2 :: 2, (dx - x - border) % 2 :: 2]
            for dy, dx, c in cfa_sites(pattern) if c == channel]


def temporal_spatial(mean_blocks, var_blocks, n_frames: int) -> dict:
    """The EMVA 1288 temporal and spatial variances of one region and channel, with their standard errors.

    Parameters
    ----------
    mean_blocks, var_blocks : list of numpy.ndarray (rows, columns)
        The region's blocks of the per-pixel mean image and per-pixel variance (:func:`region_planes` of a
        :class:`Stack`). Unit: DN, DN².
    n_frames : int
        N.

    Returns
    -------
    dict
        ``n_pixels``, ``mean_dn`` (the mean image's mean), ``temporal_var_dn2`` and ``temporal_var_se_dn2`` (over
        rows), ``mean_image_var_dn2`` (s²_ȳ), ``spatial_var_dn2`` (s²_ȳ − σ²_temp / N) and ``spatial_var_se_dn2``.
    """
    sums = np.concatenate([b.sum(axis=1) for b in var_blocks])
    counts = np.concatenate([np.full(b.shape[0], b.shape[1]) for b in var_blocks])
    temporal, temporal_se = _row_mean_se(sums, counts)
    values = np.concatenate([b.ravel() for b in mean_blocks])
    n = values.size
    mean = float(values.mean())
    centred = values - mean
    mean_image_var = float(np.sum(centred**2) / (n - 1))
    m2, m4 = float(np.mean(centred**2)), float(np.mean(centred**4))
    spatial_se2 = max(m4 - m2**2, 0.0) / n + ((temporal_se or 0.0) / n_frames) ** 2
    return {"n_pixels": int(n), "mean_dn": mean, "temporal_var_dn2": temporal, "temporal_var_se_dn2": temporal_se,
            "mean_image_var_dn2": mean_image_var, "spatial_var_dn2": mean_image_var - temporal / n_frames,
            "spatial_var_se_dn2": float(np.sqrt(spatial_se2))}


def spatial_model(meta: dict, channel: int, signal_e: float | None, dark_e: float | None,
                  whole_flat_frame: bool) -> tuple[float | None, list[str], list[str]]:
    """The model's spatial variance of a uniform region, from the sidecar's fixed-pattern keys (see the module's
    notes). Unit: DN².

    Parameters
    ----------
    signal_e, dark_e : float or None
        The region's mean signal and dark charge (e⁻); None: the region is not uniform (no prediction).
    whole_flat_frame : bool
        The region is the whole frame of a uniform scene (``dark_shading_e`` predicted).

    Returns
    -------
    model_dn2 : float or None
    terms : list of str
        The sidecar keys whose patterns the prediction holds (those set).
    not_modelled : list of str
        The keys set whose patterns it does not hold.
    """
    k = float(meta["dn_per_electron"])
    if signal_e is None:
        on = [key for key in ("dsnu_e", "prnu_percent", "column_fpn_e", "dsnu_dark_current_percent",
                              "dark_shading_e", "dark_shading_map", "hot_pixel_fraction", "hot_pixel_map",
                              "dead_pixel_fraction", "stuck_pixel_fraction") if meta.get(key)]
        return None, [], ["scene-not-uniform", *on]
    terms, missing, var_e2 = [], [], 0.0
    parts = {"dsnu_e": float(meta.get("dsnu_e") or 0.0) ** 2,
             "column_fpn_e": float(meta.get("column_fpn_e") or 0.0) ** 2,
             "prnu_percent": (signal_e * float(meta.get("prnu_percent") or 0.0) / 100.0) ** 2,
             "dsnu_dark_current_percent": (dark_e * float(meta.get("dsnu_dark_current_percent") or 0.0) / 100.0)
             ** 2}
    if whole_flat_frame:
        parts["dark_shading_e"] = float(meta.get("dark_shading_e") or 0.0) ** 2
    elif meta.get("dark_shading_e"):
        missing.append("dark_shading_e")
    for key, value in parts.items():
        if meta.get(key):
            terms.append(key)
            var_e2 += value
    missing += [key for key in ("dark_shading_map", "hot_pixel_fraction", "hot_pixel_map", "dead_pixel_fraction",
                                "stuck_pixel_fraction") if meta.get(key)]
    return k**2 * var_e2, terms, missing


def _temporal_model(meta: dict, expected_dn: np.ndarray | None, quantised: bool, channel: int) -> float | None:
    """The model's temporal variance averaged over the region's expected values ``expected_dn`` (DN). Unit: DN²."""
    if expected_dn is None:
        return None
    var = predicted_var_dn2(meta, np.asarray(expected_dn, dtype=np.float64), quantised, channel)
    if var is None:
        return None
    return float(np.mean(var)) + float(meta.get("black_level_error_dn") or 0.0) ** 2


def analyse_sequence(sequence: Sequence, border_px: int = 3, progress=None) -> list[dict]:
    """Measure one sequence: one record per region (each patch less ``border_px``, then the whole frame) × channel,
    with the keys :data:`TEMPORAL_COLUMNS`.

    The frames are read one at a time (:func:`stack_moments`); the clean layer of the first frame's EXR, where
    there is one, gives the exact per-pixel expectation for the predictions (:func:`load_clean_dn`).

    Raises
    ------
    CamsimError
        A frame that cannot be read, or frames of different shapes.
    """
    def pixels():
        for path in sequence.paths:
            frame = load_frame(path)
            if progress is not None:
                progress()
            yield frame.pixels_dn

    first = load_frame(sequence.paths[0])
    meta, pattern, quantised = first.meta, first.cfa_pattern, first.quantised
    stack = stack_moments(pixels())
    clean, _ = load_clean_dn(first)
    black = first.expected_black_dn()
    k = float(meta["dn_per_electron"])
    first = None
    _, height, width = stack.mean_dn.shape
    flat = (meta.get("target") or {}).get("kind") == "flat"
    regions = [(i, p["name"], p["rect_xywh"], border_px, p) for i, p in enumerate(meta.get("patches") or [])]
    regions.append((None, "frame", [0, 0, width, height], 0, None))
    base = {"sequence": sequence.paths[0].parent.as_posix() + "/" + _stem(sequence), "scene": meta.get("scene"),
            "illuminant": meta.get("illuminant"), "intensity_factor": meta.get("intensity_factor"),
            "sensor_seed": meta.get("sensor_seed"), "n_frames": stack.n_frames,
            "first_frame": str(sequence.paths[0]), "source": "dng" if quantised else "exr"}
    rows = []
    for index, name, rect, border, patch in regions:
        for c, channel in enumerate(CHANNELS):
            means = region_planes(stack.mean_dn, rect, border, pattern, c)
            if sum(b.size for b in means) < 2:  # no spread over fewer than two pixels
                continue
            record = temporal_spatial(means, region_planes(stack.var_dn2, rect, border, pattern, c),
                                      stack.n_frames)
            expected = None
            if clean is not None:
                expected = _clean_values(clean, rect, border, pattern, c)
            elif patch is not None:
                expected = np.array([k * (float(patch["signal_e"][c]) + float(patch["dark_e"][c])
                                          if meta["stages"].get("dark_current") else k * float(patch["signal_e"][c]))])
            uniform = patch is not None or flat
            if patch is not None:
                signal, dark = float(patch["signal_e"][c]), float(patch["dark_e"][c])
            elif flat and meta.get("patches"):
                signal, dark = float(meta["patches"][0]["signal_e"][c]), float(meta["patches"][0]["dark_e"][c])
            else:
                signal = dark = None
            model, terms, missing = spatial_model(meta, c, signal if uniform else None, dark,
                                                  patch is None and flat)
            temporal_model = _temporal_model(meta, expected, quantised, c)
            spatial_clean = None
            if expected is not None and clean is not None and expected.size > 1:
                spatial_clean = float(np.var(expected.astype(np.float64), ddof=1))
            rows.append({**base, "region": name, "region_index": index, "channel": channel,
                         **record, "mean_dn": record["mean_dn"] - float(black[c]),
                         "temporal_model_dn2": temporal_model,
                         "temporal_ratio": finite_or_none(record["temporal_var_dn2"] / temporal_model)
                         if temporal_model else None,
                         "spatial_model_dn2": model, "spatial_model_terms": " ".join(terms),
                         "spatial_not_modelled": " ".join(missing), "spatial_clean_dn2": spatial_clean,
                         "temporal_e2": record["temporal_var_dn2"] / k**2,
                         "spatial_e2": record["spatial_var_dn2"] / k**2})
    return rows


def _clean_values(clean: np.ndarray, rect, border: int, pattern: str | None, channel: int) -> np.ndarray:
    """The clean layer's values (DN) of one channel in a region: its plane, or a Bayer frame's sites of that
    colour read on that colour's plane."""
    if not pattern:
        return region_planes(clean, rect, border, None, channel)[0].ravel()
    plane = clean[channel : channel + 1]
    return np.concatenate([b.ravel() for b in region_planes(plane, rect, border, pattern, channel)])


def _stem(sequence: Sequence) -> str:
    """A name for a sequence: its ``sequence`` stem where the sidecars give one, else its first frame's stem."""
    stem = sequence.metas[0].get("sequence")
    if isinstance(stem, str):
        return stem
    return sequence.paths[0].stem


def analyse_sequences(paths, source: str = "dng", border_px: int = 3, warn=None) -> list[dict]:
    """Find the sequences among the frame files ``paths`` (:func:`find_sequences`) and measure each
    (:func:`analyse_sequence`); a sequence whose frames cannot be read is left out with one line to ``warn``.

    Returns
    -------
    list of dict
        One row per sequence × region × channel (:data:`TEMPORAL_COLUMNS`); empty when there is no sequence.
    """
    rows = []
    for sequence in find_sequences(paths, source, warn):
        try:
            with np.errstate(all="ignore"):
                rows += analyse_sequence(sequence, border_px)
        except CamsimError as exc:
            if warn is not None:
                warn(f"the sequence of {sequence.paths[0]} ({len(sequence.paths)} frames) left out of the "
                     f"temporal analysis: {exc}")
    return rows


def summary_lines(rows) -> list[str]:
    """One line per sequence for the printed summary: its frames and, for the G channel of its first region, the
    temporal and spatial variances with their model's."""
    fmt = lambda v, spec: "—" if v is None else format(v, spec)  # noqa: E731
    lines, seen = [], set()
    for row in rows:
        if row["sequence"] in seen or row["channel"] != "G":
            continue
        seen.add(row["sequence"])
        lines.append(f"sequence {row['sequence']}: {row['n_frames']} frames, {row['region']} G: temporal "
                     f"{row['temporal_var_dn2']:.4g} ± {fmt(row['temporal_var_se_dn2'], '.2g')} DN² (model "
                     f"{fmt(row['temporal_model_dn2'], '.4g')}), spatial {row['spatial_var_dn2']:.4g} ± "
                     f"{row['spatial_var_se_dn2']:.2g} DN² (model {fmt(row['spatial_model_dn2'], '.4g')})")
    return lines
