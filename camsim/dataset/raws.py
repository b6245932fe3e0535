"""Datasets from folders of raw files: a spec's ``[raws]`` table, its frames planned and rendered.

Each frame is a crop of a real camera's raw file made darker (or brighter) with a target sensor's noise, as a scene
file's ``[raw]`` table makes one (:mod:`camsim.scene.sources.raw`, :mod:`camsim.render.raw_render`)::

    name = "sid_like"
    seed = 0

    [raws]
    folder = "raws"                    # relative to the spec file
    pattern = "*.dng"                  # glob in the folder (default: every raw suffix LibRaw reads, any case:
                                       # RAW_SUFFIXES); relative to it and without "..": it never leaves the folder
    crop = [512, 512]                  # the frame size: width, height in pixels, both even
    flips = true                       # random horizontal and vertical flips that keep the Bayer pattern
    photon_law = "add"                 # "add" (default) or "thin" (camsim.sensor.raw_laws)
    preset = "sony-a7s2"               # the source camera (optional: per file from its Make and Model)

    [grid]
    ratio = [100, 250, 300]            # the SID convention: T = T_source / ratio, intensity factor 1
    iso = [3200, 6400]

    [random]
    count = 4
    preset = { choice = ["sony-a7s2", "nikon-d850"] }   # the target camera

No ``scene`` file: a ``[raws]`` spec's light and colour are each raw file's own (no illuminant, camera curves or
spectral grid apply), and its sensor is set by the spec's parameters on top of these defaults, per file, as a
scene file's ``[raw]`` table sets them: the target sensor is the source camera's preset (``preset`` sets another:
a camera preset, a model preset or a ``camsim calibrate`` preset file, relative to the spec; or
``[virtual_camera]``), at the file's ISO (``iso`` sets another; a virtual camera's own point otherwise), exposed as
long as the source (``exposure_s``, or ``ratio``: T = T_source / ratio), with the file's colour filter array.
Every sensor parameter (``read_noise_e``, ``dark_current`` …), ``intensity_factor`` (F, default 1), ``iso``,
``preset``, ``exposure_s``, ``ratio`` and ``photon_law`` may be fixed, a grid axis or random. The source camera (its
gain K at the file's ISO turns DN into electrons) is the ``[raws]`` table's ``preset``, else the built-in preset of
each file's Make and Model; a file of an unknown camera with no ``preset`` is refused when the spec is read. So the
frame expects F · T / T_source · (DN − black) / K_source electrons at each site, and its mean in DN is that times
K_target plus the target's black level (:func:`camsim.render.raw_render.frame_fraction`).
``illuminant``, ``camera``, ``cfa``, the render settings (``method``, ``exposure`` …) and ``[frame]`` do not apply.

Crops and flips. Each grid point's draw (its repeats share it) picks a file (uniformly, in name order), the crop's
offset (x, y even, uniform over every position of whole 2 × 2 cells inside the visible image) and, with ``flips``,
whether the frame is mirrored left-right and upside-down (each with probability 1/2), each from its own stream
(:func:`camsim.core.seeding.dataset_parameter_generator` of ``raws.file``, ``raws.x``, ``raws.y``,
``raws.flip_horizontal``, ``raws.flip_vertical``). An unflipped crop starts at even x, y: its pattern is the file's.
A mirror swaps the columns (rows) of every 2 × 2 cell, so a flipped frame is read from a window one column (row)
further in — x + 1, or x − 1 where x + 1 would leave the image — and then mirrored: the window's pattern is the
file's shifted by one, and the mirror shifts it back, so every frame, flipped or not, has its file's pattern
(the offsets are picked so that the flipped crop keeps the pattern). ``crop_x``, ``crop_y`` in the record are the
window's offset in the file as read (odd along a flipped axis). With ``flips``, a file needs one column and one row
more than the crop. Files of different patterns may share a folder: each frame's sensor has its file's pattern
(the record's ``cfa``).

The record of each frame holds :data:`camsim.dataset.spec_parts.RAW_KEYS` (the file name relative to the folder, its
SHA-256, ``crop_x``, ``crop_y``, ``flip_horizontal``, ``flip_vertical``), the source's camera, ISO and exposure
(``source_preset``, ``source_iso``, ``source_exposure_s``), the photon law, the ratio (where set) and the target
sensor's every parameter, so that the id changes with the file's bytes. The frame's files are a raw scene's
(:func:`camsim.render.raw_render.write_raw_frame`): ``ID.dng`` (the source's CFA, colour matrices, as-shot neutral,
Make/Model and orientation), ``ID.exr`` (the noisy mosaic ``noisy.CFA`` and the clean layer, the expectation of each
site: the SID-style pair of a dark noisy input and its clean target), ``ID.json`` (``raw_source``: the file, crop,
flips, fraction, masked sites) and ``ID_mask.png`` where the crop has saturated source sites. Each worker process
reads a raw file once and keeps it (a few files at a time) for the crops that follow.
With ``srgb`` (``png``, ``png16``), the noisy and clean mosaics are developed through one ISP
(:func:`camsim.dataset.srgb.develop_raw_frame`: the source's colour matrix and as-shot neutral, gain
1 / (F · T / T_source), the exposure ratio). The file layout only: a Zarr store (``--format zarr``) is refused for
``[raws]`` specs.

Bursts. ``burst_frames`` and the motion's parameters (:data:`camsim.dataset.spec_parts.BURST_PARAMS`) make each item a
burst of its crop (:func:`render_raw_burst_files`): a raw scene's ``[sequence]``
(:func:`camsim.render.raw_sequence.render_raw_sequence_frames`) with the item's seed, ``ID_fNNN.dng/.exr/.json``
(``_mask.png`` where masked) and the reference ``ID_ref.exr/.json``, the manifest's ``burst`` and the record's burst
keys as a scene burst's. The flips come before the motion: the homographies are in the files' (flipped crop's)
pixels. ``thin`` with motion or flicker, and exposures (with a rolling shutter's readout) longer than the frame
interval, are refused when the spec is read; :func:`raw_burst_warnings` says where the source's own noise, common to
a burst's frames, is more than 1 % of a frame's shot-noise variance. Zarr stores stay refused (the sequence store's
arrays are a spectral frame's).
"""

from __future__ import annotations

import hashlib
import itertools
import json
import math
from collections.abc import Iterator
from dataclasses import dataclass, replace
from functools import lru_cache, partial
from pathlib import Path

import numpy as np

from camsim.core.errors import CamsimError
from camsim.core.input_files import open_input
from camsim.core.seeding import dataset_parameter_generator
from camsim.dataset.spec_parts import (
    FACTOR_INDEX,
    MAX_FRAMES,
    OWN_VALUE_PARAMS,
    PARAMETERS,
    RAW_KEYS,
    RENDER_KEYS,
    FrameGroup,
    FrameSpec,
    RawCrop,
    SpecPlan,
    burst_record,
    burst_sequence,
    canonical_json,
    draw_parameter,
    folder_table,
    frame_id_digits,
    frame_sensor_overrides,
    frames_with_ids,
    parameter_tables,
    spec_path,
    virtual_camera_draws,
)
from camsim.io.dng import MAX_EXPOSURE_S, MIN_SIZE
from camsim.scene.scene_file import check_intensity_factor
from camsim.scene.sequence import check_timing
from camsim.sensor.params import SENSOR_PARAMS, with_checked_values
from camsim.sensor.presets.virtual import VIRTUAL_KEYS
from camsim.sensor.raw_laws import PHOTON_LAWS

__all__ = ["RAWS_TABLE_KEYS", "RAW_SUFFIXES", "RawGroup", "plan_raws", "raw_burst_warnings", "render_raw_files",
           "render_raw", "render_raw_burst_files"]

#: Parameters a ``[raws]`` spec may not set: the light, the camera curves and the render settings are a
#: spectral scene's; the pattern is the file's.
_NOT_FOR_RAWS = ("illuminant", "camera", "cfa", *RENDER_KEYS)
#: How many raw files a worker process keeps read (full mosaics: 2 bytes a pixel each).
_KEPT_FILES = 4
#: Keys of a ``[raws]`` table.
RAWS_TABLE_KEYS = ("folder", "pattern", "crop", "flips", "photon_law", "preset")
#: File name suffixes a ``[raws]`` folder is searched for without a ``pattern`` (any case): the raw formats LibRaw
#: reads.
RAW_SUFFIXES = (".dng", ".arw", ".srf", ".sr2", ".nef", ".nrw", ".cr2", ".cr3", ".crw", ".raf", ".orf", ".rw2",
                ".pef", ".srw", ".raw", ".rwl", ".3fr", ".fff", ".iiq", ".mos", ".mef", ".mrw", ".erf", ".kdc",
                ".dcr", ".x3f", ".gpr")


@dataclass(frozen=True)
class RawGroup:
    """What the frames of a group of a ``[raws]`` spec share (:attr:`camsim.dataset.spec_parts.FrameGroup.raws`).

    Attributes
    ----------
    folder : str
        Absolute path of the ``[raws]`` folder.
    base_dir : str
        The spec's folder (preset files are relative to it).
    scene_name : str
        The frames' scene name (the spec's name): the sidecar's ``scene``.
    source_preset : str
        The source camera's preset (its gain K at ``source_iso`` turns DN into electrons).
    source_iso, source_exposure_s : float
        The source's ISO and exposure time (s).
    preset : str
        The target sensor's preset.
    iso : float or None
        The target preset's ISO (None: its default, or a model preset).
    photon_law : str
        One of :data:`camsim.sensor.raw_laws.PHOTON_LAWS`.
    """

    folder: str
    base_dir: str
    scene_name: str
    source_preset: str
    source_iso: float
    source_exposure_s: float
    preset: str
    iso: float | None
    photon_law: str


@dataclass(frozen=True)
class _RawFile:
    """A raw file of the folder: its name relative to the folder, visible size, SHA-256, pattern and source."""

    name: str
    width: int
    height: int
    sha256: str
    cfa: str
    source_preset: str
    source_iso: float
    source_exposure_s: float


@dataclass(frozen=True)
class _RawFolder:
    """A ``[raws]`` table, checked."""

    text: str
    folder: Path
    files: tuple  # _RawFile
    width: int
    height: int
    flips: bool
    photon_law: str


def _sha256(path: Path) -> str:
    """SHA-256 of a raw file's bytes, as hex; a path that no longer names a regular file (replaced by a FIFO since
    its header was read) is refused on one line rather than waited on."""
    with open_input(path, "raw file") as handle:
        return hashlib.file_digest(handle, "sha256").hexdigest()


def _raws(table, base: Path, where: str) -> _RawFolder:
    """Read and check a ``[raws]`` table: its folder, the raw files in it (each one's header, source camera, ISO and
    exposure) and the crop size.

    Raises
    ------
    CamsimError
        An unknown key, a value of the wrong type, a missing or empty folder, a file LibRaw cannot read as a Bayer
        raw, a file of an unknown camera with no ``preset``, a file without ISO or exposure time, or a file smaller
        than the crop (naming the file).
    """
    from camsim.scene.sources.raw import RawSource

    at = f"{where}: [raws]"
    checked = folder_table(table, base, where, "raws", RAWS_TABLE_KEYS, RAW_SUFFIXES, "raw", ".dng", even=True)
    folder, paths, width, height, flips, text = (checked.folder, checked.paths, checked.width, checked.height,
                                                 checked.flips, checked.text)
    if min(width, height) < MIN_SIZE:
        raise CamsimError(f"{at} crop {width}x{height} is smaller than {MIN_SIZE}x{MIN_SIZE} pixels, which raw "
                          "readers (LibRaw) refuse")
    law = table.get("photon_law", "add")
    if law not in PHOTON_LAWS:
        raise CamsimError(f"{at} photon_law must be one of {', '.join(PHOTON_LAWS)}, got {law!r}")
    preset = table.get("preset")
    if preset is not None and (not isinstance(preset, str) or not preset):
        raise CamsimError(f"{at} preset must be the source camera's preset (camsim list) or a camsim calibrate "
                          f"preset file, got {preset!r}")
    spare = 1 if flips else 0  # a flipped window is one column (row) further in
    files = []
    for path in paths:
        try:
            source = RawSource(path=path, preset=preset, base_dir=base)
            source = replace(source, preset=source.source_preset(None))
            source.source_gain_dn_per_e()  # the source camera has a gain at the file's ISO: refused now, not mid-run
            file_width, file_height = source.header.size
            cell_width, cell_height = file_width - file_width % 2, file_height - file_height % 2
            if cell_width < width or cell_height < height or file_width < width + spare \
                    or file_height < height + spare:
                more = " (and one column and row more, for flips)" if flips else ""
                raise CamsimError(f"{path} is {file_width}x{file_height} pixels, smaller than the crop "
                                  f"{width}x{height}{more}")
            files.append(_RawFile(
                name=path.relative_to(folder).as_posix(), width=file_width, height=file_height,
                sha256=_sha256(path), cfa=source.header.cfa, source_preset=source.preset,
                source_iso=source.source_iso, source_exposure_s=source.source_exposure_s))
        except CamsimError as exc:
            raise CamsimError(f"{at}: {exc}") from None
    return _RawFolder(text=text, folder=folder, files=tuple(files), width=width, height=height, flips=flips,
                      photon_law=law)


def _window_start(start: int, flipped: bool, size: int, file_size: int) -> int:
    """The window's first column (row) in the file for an even ``start``: ``start``, or, along a flipped axis, one
    further in (start + 1, or start − 1 where start + 1 + size would leave the file's ``file_size``)."""
    if not flipped:
        return start
    return start + 1 if start + 1 + size <= file_size else start - 1


def _raw_draws(raws: _RawFolder, n: int, seed: int) -> list:
    """The raw values (:data:`RAW_KEYS`) of ``n`` grid-point draws, with the index of the file of each: a file,
    the window's offset and the flips, each from its own stream (uniform variates, one per draw)."""
    streams = {name: dataset_parameter_generator(seed, f"raws.{name}").random(n)
               for name in ("file", "x", "y", "flip_horizontal", "flip_vertical")}
    count = len(raws.files)
    draws = []
    for u_file, u_x, u_y, u_h, u_v in zip(*streams.values()):
        index = min(count - 1, int(u_file * count))
        file = raws.files[index]
        flip_h, flip_v = bool(raws.flips and u_h < 0.5), bool(raws.flips and u_v < 0.5)
        # even offsets of whole cells inside the visible image: (W - W % 2 - w) / 2 + 1 of them
        cells_x = (file.width - file.width % 2 - raws.width) // 2 + 1
        cells_y = (file.height - file.height % 2 - raws.height) // 2 + 1
        x = 2 * min(cells_x - 1, int(u_x * cells_x))
        y = 2 * min(cells_y - 1, int(u_y * cells_y))
        x = _window_start(x, flip_h, raws.width, file.width)
        y = _window_start(y, flip_v, raws.height, file.height)
        draws.append((index, (file.name, file.sha256, x, y, flip_h, flip_v)))
    return draws


# --- the plan --------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class _RawJob:
    """What :func:`camsim.dataset.spec_parts.frames_with_ids` needs to make the frames of a ``[raws]`` spec."""

    where: str
    base: Path
    name: str
    seed: int
    repeats: int
    count: int
    raws: _RawFolder
    fixed: dict
    grid: dict
    random_values: dict
    virtual: bool  # the target camera is a [virtual_camera] draw
    value_keys: tuple
    id_digits: int
    raw_values: list  # (file index, RAW_KEYS values) of each grid point and draw

    @property
    def sensor_keys(self) -> tuple:
        """The own values that are sensor parameters (:attr:`camsim.dataset.spec_parts.FrameGroup.sensor_keys`)."""
        return self.value_keys[FACTOR_INDEX + 1:len(self.value_keys) - len(RAW_KEYS) - ("ratio" in self.value_keys)]


def plan_raws(doc: dict, path: Path, base: Path, *, name: str, seed: int, repeats: int, exr_compression,
              srgb) -> SpecPlan:
    """The plan of a spec with a ``[raws]`` table (:func:`camsim.dataset.spec.plan_spec` hands it here, its common
    keys checked): the folder's files read and checked, the draws made; the frames are made one by one.

    Raises
    ------
    CamsimError
        A key that does not apply (``scene``, ``[frame]``, ``[images]``, ``illuminant`` …), a bad ``[raws]`` table
        or file (:func:`_raws`), ``ratio`` with ``exposure_s``, or more than
        :data:`camsim.dataset.spec_parts.MAX_FRAMES` frames.
    """
    where = str(path)
    for key, why in (("scene", "a [raws] spec's light and camera are each raw file's own: no scene file"),
                     ("frame", "the frames' size is [raws] crop = [width, height]"),
                     ("images", "a spec draws from [images] or from [raws], not both")):
        if key in doc:
            raise CamsimError(f"{where}: {'[' + key + ']' if key != 'scene' else key} does not apply: {why}")
    raws = _raws(doc["raws"], base, where)
    axes, fixed, grid, random_table, random_names, count = parameter_tables(doc, where)
    for param in _NOT_FOR_RAWS:
        if param in axes:
            raise CamsimError(f"{where}: [{axes[param]}] {param} does not apply to [raws] frames (the light, the "
                              "camera and the colour filter array are each raw file's own)")
    if "ratio" in axes and "exposure_s" in axes:
        raise CamsimError(f"{where}: set either ratio (T = T_source / ratio) or exposure_s, not both")
    points = math.prod(len(v) for v in grid.values()) * count
    if points * repeats > MAX_FRAMES:
        raise CamsimError(f"{where}: more than {MAX_FRAMES} frames")
    random_values = {p: draw_parameter(p, random_table[k], points, seed, f"{where} [random]")
                     for p, k in random_names.items()}
    virtual = "virtual_camera" in doc
    if virtual:
        drawn = virtual_camera_draws(doc["virtual_camera"], points, seed, axes, where)
        random_values.update({key: [d[key] for d in drawn] for key in VIRTUAL_KEYS})
        axes.update(dict.fromkeys(VIRTUAL_KEYS, "virtual_camera"))
    axes.setdefault("intensity_factor", "fixed")  # F = 1 unless the spec says
    varied = {p for p, how in axes.items() if how in ("grid", "random", "virtual_camera")}
    # a varied ratio is a frame's own value, and so is the exposure it sets (T_source / ratio): the frames of a file
    # that differ only in it share a group
    own_ratio = ("ratio",) if "ratio" in varied else ()
    own_sensor = tuple(p.name for p in SENSOR_PARAMS
                       if (p.name in varied or (own_ratio and p.name == "exposure_s")) and p.name in OWN_VALUE_PARAMS)
    shown = ("raw_file", "crop_x", "crop_y") + (("flip_horizontal", "flip_vertical") if raws.flips else ())
    axes.update(dict.fromkeys(shown, "raws"))
    job = _RawJob(where=where, base=base, name=name, seed=seed, repeats=repeats, count=count, raws=raws,
                  fixed=fixed, grid=grid, random_values=random_values, virtual=virtual,
                  value_keys=("repeat", "intensity_factor", *own_sensor, *own_ratio, *RAW_KEYS),
                  id_digits=frame_id_digits(points * repeats),
                  raw_values=_raw_draws(raws, points, seed))
    return SpecPlan(name=name, path=path, seed=seed, width=raws.width, height=raws.height, axes=axes,
                    count=points * repeats, sizes=((raws.width, raws.height),),
                    make_frames=partial(frames_with_ids, job, frame_values=_raw_frame_values),
                    exr_compression=exr_compression, srgb=srgb)


def _raw_frame_values(job: _RawJob) -> Iterator[tuple]:
    """Resolve and validate the frames of a ``[raws]`` spec, in order: (index, own values, group) of each; frames
    of one file that differ only in their own values share a group."""
    groups: dict = {}
    own_sensor = job.sensor_keys
    own_ratio = "ratio" in job.value_keys
    own_names = OWN_VALUE_PARAMS | ({"ratio"} if own_ratio else set())
    names = tuple(job.grid)
    shared_grid = [i for i, n in enumerate(names) if n not in own_names]
    shared_random = [p for p in job.random_values if p not in own_names]
    point = index = 0
    for combo in itertools.product(*(range(len(v)) for v in job.grid.values())):
        combo_params = {**job.fixed, **{n: job.grid[n][i] for n, i in zip(names, combo)}}
        combo_key = tuple(combo[i] for i in shared_grid)
        for _ in range(job.count):
            params = dict(combo_params)
            params.update({p: values[point] for p, values in job.random_values.items()})
            params.setdefault("intensity_factor", 1.0)
            file_index, raw = job.raw_values[point]
            if own_ratio:  # the frame's exposure, an own value
                params["exposure_s"] = job.raws.files[file_index].source_exposure_s / float(params["ratio"])
            key = (file_index, combo_key, *(canonical_json(params[p]) for p in shared_random))
            point += 1
            try:
                factor = check_intensity_factor(params["intensity_factor"])
                own = tuple(PARAMETERS[p].coerce(params[p], "sensor parameter") for p in own_sensor)
                entry = groups.get(key)
                if entry is None:
                    entry = groups[key] = _resolve_raw(params, job.raws.files[file_index], job)
                group, sensor = entry
                _check_raw_frame(group, sensor, factor, dict(zip(own_sensor, own)))
            except CamsimError as exc:
                label = f"{job.where}: frame {index} ({raw[0]}, {', '.join(f'{k}={v!r}' for k, v in params.items())})"
                raise CamsimError(f"{label}: {exc}") from None
            ratio = (params["ratio"],) if own_ratio else ()
            for repeat in range(job.repeats):
                yield index, (repeat, factor, *own, *ratio, *raw), group
                index += 1


def _check_raw_frame(group: FrameGroup, sensor, factor: float, own: dict) -> None:
    """Refuse a frame that cannot be drawn or written: its own sensor values out of range, an exposure longer than
    a DNG records, ``thin`` brightening (F · T above the source's exposure), a burst whose exposures (and a rolling
    shutter's readout) do not fit in its frame interval."""
    if own:
        sensor = with_checked_values(sensor, **own)
    raws = group.raws
    burst = group.scene_changes.get("sequence")
    if burst is not None:
        _check_burst(lambda: check_timing(burst, sensor.exposure_s, group.height))
    if sensor.quantisation and sensor.exposure_s > MAX_EXPOSURE_S:
        raise CamsimError(f"exposure T = {sensor.exposure_s:g} s is longer than a DNG records ({MAX_EXPOSURE_S} s)")
    if raws.photon_law == "thin" and factor * sensor.exposure_s > raws.source_exposure_s * (1 + 1e-12):
        raise CamsimError(f"photon_law 'thin' cannot brighten: F·T = {factor * sensor.exposure_s:g} s is more than "
                          f"the source's exposure {raws.source_exposure_s:g} s; lower F or T, or use photon_law = "
                          "'add'")


def _check_burst(check) -> None:
    """Run a burst's ``check`` (a raw ``[sequence]``'s), its error said in a spec's words (``burst``,
    ``burst_frames``)."""
    try:
        check()
    except CamsimError as exc:
        text = str(exc).replace("[sequence]: frames ", "burst_frames ").replace("[raw] photon_law", "photon_law")
        text = text.replace("a static [sequence]", "a burst without motion").replace("[sequence]", "burst")
        raise CamsimError(text) from None


def _resolve_raw(params: dict, file: _RawFile, job: _RawJob) -> tuple[FrameGroup, object]:
    """The group of the frames of ``file`` with ``params`` (their own values aside), and its target sensor."""
    from camsim.sensor.presets import camera_preset

    raws = job.raws
    preset = params.get("preset", file.source_preset)
    if "preset" in params and preset.lower().endswith(".toml"):  # a preset file named in the spec is relative to it
        preset = str(spec_path(job.base, preset, "camera preset file"))
    if params.get("iso") is not None:
        iso = float(params["iso"])
    elif job.virtual or camera_preset(preset, job.base) is None:
        iso = None  # a virtual camera's own point; a model preset has no ISO axis
    else:
        iso = file.source_iso
    overrides = frame_sensor_overrides(params, job.base)
    overrides["cfa"] = file.cfa
    ratio = params.get("ratio")
    if ratio is not None:
        overrides["exposure_s"] = file.source_exposure_s / float(ratio)
    else:
        overrides.setdefault("exposure_s", file.source_exposure_s)
    law = params.get("photon_law", raws.photon_law)
    group_raws = RawGroup(folder=str(raws.folder), base_dir=str(job.base), scene_name=job.name,
                          source_preset=file.source_preset, source_iso=file.source_iso,
                          source_exposure_s=file.source_exposure_s, preset=preset, iso=iso, photon_law=law)
    scene = frame_scene(group_raws, overrides, RawCrop(str(raws.folder / file.name), 0, 0, raws.width, raws.height,
                                                        False, False), float(params["intensity_factor"]))
    sensor = scene.sensor
    burst = burst_sequence(params, scene)
    if burst is not None:  # thin cannot move or flicker (one check: the raw scene's; timing per frame)
        from camsim.render.raw_sequence import check_raw_sequence

        moving = scene.replace(sequence=burst)
        _check_burst(lambda: check_raw_sequence(moving))
    record = {
        "scene": job.name,
        "scene_source": "raws",
        "raw_folder": raws.text,
        "width_px": raws.width,
        "height_px": raws.height,
        "repeat": 0,
        "illuminant": "as-shot",
        "intensity_factor": params["intensity_factor"],
        "photon_law": law,
        **({"ratio": ratio} if ratio is not None else {}),
        "source_preset": file.source_preset,
        "source_iso": file.source_iso,
        "source_exposure_s": file.source_exposure_s,
        "preset": preset,
        **({"iso": iso} if iso is not None else {}),
        **sensor.to_dict(),
        **(burst_record(burst) if burst is not None else {}),  # a burst's keys: only then (other ids unchanged)
        "spec_seed": job.seed,
        **dict.fromkeys(RAW_KEYS),
    }
    record = json.loads(json.dumps(record, allow_nan=False))
    keys = sorted(record)
    group = FrameGroup(
        scene_path=str(raws.folder / file.name), width=raws.width, height=raws.height, illuminant="as-shot",
        scene_changes={} if burst is None else {"sequence": burst}, sensor_overrides=overrides, record=record,
        value_keys=job.value_keys,
        canonical_parts=tuple(f"{canonical_json(k)}:{canonical_json(record[k])}" for k in keys),
        canonical_slots=tuple((keys.index(k), f"{canonical_json(k)}:") for k in job.value_keys),
        raws=group_raws)
    return group, sensor


# --- rendering -------------------------------------------------------------------------------------------------


def frame_scene(raws: RawGroup, overrides: dict, crop: RawCrop, intensity_factor: float):
    """The raw scene of a frame (:class:`camsim.scene.scene_file.Scene` with a
    :class:`camsim.scene.sources.raw.RawSource` of the frame's window), its sensor the target's."""
    from camsim.light.spectra import WavelengthGrid
    from camsim.scene.scene_file import RAW_SCENE_ILLUMINANTS, Scene, _frozen
    from camsim.scene.sources.raw import RawSource

    source = RawSource(path=Path(crop.path), crop=crop.window, photon_law=raws.photon_law, preset=raws.source_preset,
                       iso=raws.source_iso, exposure_s=raws.source_exposure_s, base_dir=Path(raws.base_dir))
    return Scene(name=raws.scene_name, grid=WavelengthGrid(380.0, 780.0, 4.0), illuminants=RAW_SCENE_ILLUMINANTS,
                 intensity_factors=(float(intensity_factor),), source=source, width=crop.width, height=crop.height,
                 preset_name=raws.preset, iso=raws.iso, sensor_overrides=_frozen(overrides),
                 base_dir=Path(raws.base_dir))


@lru_cache(maxsize=_KEPT_FILES)
def _full_capture(path: str):
    """The whole visible mosaic of a raw file and its metadata, read once per worker process for the frames that
    crop it (:func:`camsim.io.raw_capture.read_raw_capture`)."""
    from camsim.io.raw_capture import read_raw_capture

    return read_raw_capture(path)


def flip_capture(capture, horizontal: bool, vertical: bool):
    """``capture`` (:class:`camsim.io.raw_capture.RawCapture`) with its mosaic mirrored left-right and/or
    upside-down: the pattern and the black level of each site of the top-left cell mirrored with it (the mosaic's
    width and height are even, so a mirror swaps the columns or rows of every 2 × 2 cell)."""
    if not (horizontal or vertical):
        return capture
    rows = slice(None, None, -1) if vertical else slice(None)
    columns = slice(None, None, -1) if horizontal else slice(None)
    cell = np.array(list(capture.cfa)).reshape(2, 2)[rows, columns]
    return replace(capture, mosaic=np.ascontiguousarray(capture.mosaic[rows, columns]), cfa="".join(cell.ravel()),
                   black_dn=np.ascontiguousarray(np.asarray(capture.black_dn)[rows, columns]))


def load_crop(frame: FrameSpec):
    """The frame's source (:class:`camsim.render.raw_render.LoadedRaw`): its window of the file (kept per worker,
    :func:`_full_capture`), mirrored as the frame is, in electrons of the source camera."""
    from camsim.io.raw_capture import crop_capture
    from camsim.render.raw_render import LoadedRaw, source_electrons
    from camsim.scene.sources.raw import source_gain_dn_per_e

    raws = frame.group.raws
    crop = frame.raw
    capture = flip_capture(crop_capture(_full_capture(crop.path), crop.window), crop.flip_horizontal,
                           crop.flip_vertical)
    k = source_gain_dn_per_e(raws.source_preset, raws.source_iso, raws.base_dir)
    electrons, masked = source_electrons(capture, k)
    return LoadedRaw(capture, electrons, masked, raws.source_preset, k, raws.source_iso, raws.source_exposure_s)


def render_raw(frame: FrameSpec, threads: int = 1):
    """Render one frame of a ``[raws]`` spec in memory: (draw, sidecar without files, source, scene)
    (:func:`camsim.render.raw_render.raw_scene_frame` with the frame's seed)."""
    from camsim.render.raw_render import raw_scene_frame, raw_sidecar

    crop = frame.raw
    scene = frame_scene(frame.group.raws, frame.sensor_overrides, crop, frame.intensity_factor)
    source = load_crop(frame)
    if source.capture.cfa != scene.sensor.cfa:  # the flips' construction: a frame keeps its file's pattern
        raise CamsimError(f"{crop.path}: window {list(crop.window)} reads a {source.capture.cfa} mosaic, not the "
                          f"frame's {scene.sensor.cfa}")
    draw, record = raw_scene_frame(scene, frame.intensity_factor, source=source, seed=frame.seed, workers=threads)
    record = {**record, "flip_horizontal": crop.flip_horizontal, "flip_vertical": crop.flip_vertical,
              "sha256": frame.get("raw_sha256")}
    meta = raw_sidecar(scene, draw, record, source, frame.intensity_factor, frame.seed, None)
    return draw, meta, source, scene


def render_raw_files(frame: FrameSpec, directory: Path, threads: int = 1,
                     exr_compression: str | None = None) -> tuple[dict, tuple]:
    """Render one frame of a ``[raws]`` spec (:func:`render_raw`) and write its files into ``directory``
    (:func:`camsim.render.raw_render.write_raw_frame`: ``ID.dng``, ``ID.exr``, ``ID_mask.png`` where masked, and
    ``ID.json`` last). Returns the file names by kind, and the draw and its sidecar (for the sRGB outputs)."""
    from camsim.io.exr_compression import DEFAULT_EXR_COMPRESSION
    from camsim.render.raw_render import write_raw_frame

    draw, meta, source, scene = render_raw(frame, threads)
    names = write_raw_frame(Path(directory), frame.id, draw, meta, source, scene.sensor,
                            exr_compression or DEFAULT_EXR_COMPRESSION)
    return names, (draw, meta)



def render_raw_burst_files(frame: FrameSpec, directory: Path, threads: int = 1,
                           exr_compression: str | None = None) -> tuple[dict, dict]:
    """Render a burst item of a ``[raws]`` spec (:attr:`FrameSpec.burst`) and write its files into ``directory``, as
    ``camsim render`` writes a raw scene's ``[sequence]``
    (:func:`camsim.render.raw_sequence.render_raw_sequence_frames`,
    :func:`camsim.render.raw_sequence.write_raw_sequence_frame`) with the item's seed (its motion and every frame's
    noise): ``<id>_ref.exr/.json`` (the crop's expectation, no motion, no noise), then ``<id>_fNNN.dng/.exr/.json``
    (and ``<id>_fNNN_mask.png`` where a site took a share of a saturated source site), each committed by its sidecar.

    The motion moves the frame's own source, the crop as the frame sees it (:func:`load_crop`: after its flips):
    each sidecar's ``homography`` maps the reference's pixels to the frame's in the files' own pixels (the crop's,
    mirrored as the frame is; x the column, y the row), not the raw file's.

    Returns
    -------
    names : dict
        File names by kind ``<frame>.<kind>``: ``ref.exr``, ``ref.json``, ``f000.dng`` (None without quantisation),
        ``f000.exr``, ``f000.json``, ``f000.mask`` (where masked) …
    burst : dict
        The manifest's ``burst``: ``frames`` (``f000`` …, in order) and ``reference`` (``ref``).
    """
    from camsim.io.exr_compression import DEFAULT_EXR_COMPRESSION
    from camsim.render.raw_render import frame_fraction
    from camsim.render.raw_sequence import render_raw_sequence_frames, write_raw_sequence_frame
    from camsim.render.sequence import frame_digits

    crop = frame.raw
    factor = frame.intensity_factor
    scene = frame_scene(frame.group.raws, frame.sensor_overrides, crop, factor)
    scene = scene.replace(sequence=frame.burst, seed=frame.seed)
    source = load_crop(frame)
    if source.capture.cfa != scene.sensor.cfa:  # the flips' construction: a frame keeps its file's pattern
        raise CamsimError(f"{crop.path}: window {list(crop.window)} reads a {source.capture.cfa} mosaic, not the "
                          f"frame's {scene.sensor.cfa}")
    law = scene.source.photon_law
    record = {**source.record(law, frame_fraction(scene.sensor, source, factor)),
              "flip_horizontal": crop.flip_horizontal, "flip_vertical": crop.flip_vertical,
              "sha256": frame.get("raw_sha256")}
    digits = frame_digits(frame.burst.frames)
    names, suffixes = {}, []
    for index, *drawn in render_raw_sequence_frames(scene, source, factor, workers=threads):
        suffix = "ref" if index == "ref" else f"f{index:0{digits}d}"
        files, _ = write_raw_sequence_frame(Path(directory), f"{frame.id}_{suffix}", frame.id, scene, source, factor,
                                            *drawn, record, exr_compression or DEFAULT_EXR_COMPRESSION)
        names.update({f"{suffix}.{kind}": value for kind, value in files.items()})
        if index != "ref":
            suffixes.append(suffix)
    return names, {"frames": suffixes, "reference": "ref"}


def raw_burst_warnings(frames) -> list[str]:
    """The warning (one line, or none) of a dataset's bursts of ``[raws]`` crops (``frames``: its
    :class:`FrameSpec`): the source's own noise is common to every frame of a burst
    (:func:`camsim.render.raw_sequence.common_noise_warnings`), at the largest fraction f = F · T / T_source of
    each photon law among the bursts."""
    from camsim.render.raw_sequence import common_noise_warnings

    largest: dict = {}
    for frame in frames:
        if frame.raw is None or frame.burst is None:
            continue
        law = frame.get("photon_law")
        f = frame.intensity_factor * float(frame.get("exposure_s")) / float(frame.get("source_exposure_s"))
        largest[law] = max(largest.get(law, 0.0), f)
    lines = [line for law, f in largest.items() for line in common_noise_warnings(f, law, "bursts of [raws] crops")]
    return lines[:1]
