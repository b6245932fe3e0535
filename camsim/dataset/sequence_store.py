"""A sequence as one Zarr store (``camsim render SCENE --format zarr`` for a scene with a ``[sequence]``, issue 29).

Each illuminant × F of the scene (stem STEM, :func:`camsim.render.frame_files.frame_stem`) becomes ``OUT/STEM.zarr``
(Zarr format 3, consolidated metadata), the frames that the file layout writes as ``STEM_fNNN.dng/.exr/.json`` and
``STEM_ref.exr/.json`` (:mod:`camsim.render.sequence`, which renders them: the same arrays, bit for bit)::

    noisy       (frame, channel, y, x) float32   each frame's EXR noisy layer (or (frame, cfa, y, x): the mosaic), DN
    clean       (frame, channel, y, x) float32   each frame's own expectation (its EXR's clean.R, clean.G, clean.B), DN
    digital     (frame, channel|cfa, y, x) uint8/16   the DNG's digital numbers (a quantised sensor only)
    sidecar     (frame,) str                     each frame's sidecar (STEM_fNNN.json), as JSON
    time_s      (frame,) float64                 each exposure's start (s, from the first frame's)
    homography  (frame, 3, 3) float64            reference pixel → frame pixel at the exposure's middle
    done        (frame,) bool                    whether the frame's chunks are written (set after them)
    reference   (channel, y, x) float32          the clean reference: the static scene (STEM_ref.exr's clean layer)
    channel     (channel,) str                   R, G, B

The reference's sidecar (``STEM_ref.json``) is the group attribute ``camsim.reference_sidecar`` (JSON text). The
frame arrays have one chunk per frame and layer, compressed and keyed as a dataset's store
(:mod:`camsim.dataset.zarr_store`: :func:`~camsim.dataset.zarr_store.compressors`, one flat folder per array),
written by the same :func:`~camsim.dataset.zarr_store.write_frame_arrays`.

Atomic: the store is written under a temporary name (``OUT/.STEM.zarr.PID.partial``, removed by the next run if the
process is killed) and renamed to ``STEM.zarr`` once every frame's ``done`` flag is set and the attribute
``camsim.complete`` is true; a store of an earlier run is replaced only then. A ``STEM.zarr`` is therefore always
whole; a reader checks ``done`` all true (and ``complete``) all the same.
"""

from __future__ import annotations

import json
import os
import shutil
import warnings
from pathlib import Path

import numpy as np

from camsim.core.errors import CamsimError
from camsim.dataset import zarr_store
from camsim.io import atomic

__all__ = ["STORE_SUFFIX", "render_sequence_store", "read_sequence_store"]

STORE_SUFFIX = ".zarr"


def render_sequence_store(scene, out_dir, *, workers: int | None = None, progress: bool = True) -> list[Path]:
    """Render every illuminant × F of ``scene`` (which has a ``[sequence]``) into one Zarr store each (module
    docstring); returns the stores' paths.

    Raises
    ------
    CamsimError
        A scene without a ``[sequence]``, or one a sequence cannot render
        (:func:`camsim.render.sequence.check_sequence_scene`); zarr not installed.
    """
    from tqdm import tqdm

    from camsim.io.output_folder import output_folder
    from camsim.render.sequence import check_sequence_scene, sequence_jobs
    from camsim.sensor.camera import load_camera

    if scene.sequence is None:
        raise CamsimError("--format zarr writes a sequence as one array: the scene needs a [sequence] table (other "
                          "scenes are written as files)")
    if scene.source.table == "raw":
        raise CamsimError("--format zarr: a raw scene's sequence is written as files only (STEM_fNNN.dng/.exr/.json "
                          "and STEM_ref); leave out --format zarr")
    check_sequence_scene(scene)
    try:
        import zarr  # noqa: F401
    except ImportError:
        raise CamsimError("--format zarr needs the zarr package (3 or newer): pip install zarr") from None
    seq = scene.sequence
    stores = []
    with output_folder(out_dir) as out_dir:
        out_dir = Path(out_dir)
        camera = load_camera(scene.camera, scene.grid, scene.sensitivity_basis, scene.base_dir)
        bar = tqdm(total=len(scene.illuminants) * len(scene.intensity_factors) * (seq.frames + 1),
                   desc=f"rendering {scene.name}", unit="frame", disable=not progress)
        with bar:
            for factor, lit, sensor, stem, base in sequence_jobs(scene, camera):
                stores.append(_write_store(out_dir, stem, scene, lit, sensor, factor, base, workers, bar.update))
    return stores


def _write_store(out_dir: Path, stem: str, scene, lit, sensor, factor: float, base, workers, tick) -> Path:
    """One illuminant × F's store: written under a temporary name, renamed into place when complete."""
    final = out_dir / f"{stem}{STORE_SUFFIX}"
    for stale in out_dir.glob(f".{stem}{STORE_SUFFIX}.*.partial"):  # a killed run's (we hold the folder's lock)
        shutil.rmtree(stale, ignore_errors=True)
    partial = out_dir / f".{stem}{STORE_SUFFIX}.{os.getpid()}.partial"
    try:
        _fill_store(partial, stem, scene, lit, sensor, factor, base, workers, tick)
        if final.exists():  # an earlier run's store: replaced only by a complete one
            old = out_dir / f".{stem}{STORE_SUFFIX}.{os.getpid()}.old.partial"
            os.replace(final, old)
            os.replace(partial, final)
            shutil.rmtree(old, ignore_errors=True)
        else:
            os.replace(partial, final)
        atomic.fsync_path(out_dir, directory=True)
    except BaseException:
        shutil.rmtree(partial, ignore_errors=True)
        raise
    finally:
        zarr_store.release_arrays()  # the temporary path's arrays, opened by write_frame_arrays
    return final


def _fill_store(path: Path, stem: str, scene, lit, sensor, factor: float, base, workers, tick) -> None:
    import zarr

    from camsim.render.frame_files import sidecar
    from camsim.render.sequence import frame_digits, render_sequence_frames, sequence_frame_info

    seq = scene.sequence
    height, width = lit.labels.shape
    quantised = sensor.quantisation
    layout = zarr_store.StoreLayout(
        path=str(path.resolve()), frames=seq.frames, planes=1 if sensor.cfa is not None else 3, height=height,
        width=width, digital=None if not quantised else np.dtype(np.uint8 if sensor.bits <= 8 else np.uint16).name)
    group = zarr.open_group(path, mode="w", zarr_format=3)
    _create_arrays(group, layout)
    digits = frame_digits(seq.frames)
    for index, frame, extra in render_sequence_frames(scene, lit, sensor, factor, workers=workers):
        name, info = sequence_frame_info(stem, index, digits, extra, base)
        meta = sidecar(frame, info, None)
        if index == "ref":
            group["reference"][...] = np.asarray(frame.clean_dn(), dtype=np.float32)
            group.attrs["camsim"] = {**group.attrs["camsim"], "reference_sidecar": _json(meta)}
        else:
            meta = meta | {"zarr": {"store": f"{stem}{STORE_SUFFIX}", "index": index}}
            data, _ = zarr_store.frame_arrays(frame, layout)
            zarr_store.write_frame_arrays(layout, index, data, _json(meta), workers or 1)
            group["time_s"][index] = extra["time_s"]
            group["homography"][index] = np.asarray(extra["homography"], dtype=np.float64)
            group["done"][index] = True
        tick()
    group.attrs["camsim"] = {**group.attrs["camsim"], "complete": True}
    with warnings.catch_warnings():  # consolidated metadata: zarr-python's extension of format 3 (zarr_store's)
        warnings.filterwarnings("ignore", message="Consolidated metadata", category=UserWarning)
        zarr.consolidate_metadata(path)
    for folder in (path, *(p for p in path.iterdir() if p.is_dir())):
        for file in folder.iterdir():
            if file.is_file():
                atomic.fsync_path(file)
        atomic.fsync_path(folder, directory=True)


def _json(meta: dict) -> str:
    return json.dumps(meta, ensure_ascii=False, allow_nan=False)


def _create_arrays(group, layout) -> None:
    """The store's arrays (module docstring), empty: NaN, 0, "" and False until written."""
    frames = layout.frames
    for layer in layout.layers():
        shape = layout.shape(layer)
        dtype = layout.dtype(layer)
        zarr_store._frame_array(group, set(), layer, shape, (1, *shape[1:]), dtype,
                                np.nan if dtype == "float32" else 0, layout.dims(layer),
                                {"units": "DN", "description": _DESCRIPTIONS[layer], "coordinates": "time_s"})
    zarr_store._frame_array(group, set(), "sidecar", (frames,), (1,), str, "", ("frame",),
                            {"description": "each frame's sidecar (STEM_fNNN.json), as JSON; '' until written",
                             "coordinates": "time_s"})
    for name, shape, dtype, fill, dims, attributes in (
            ("time_s", (frames,), "float64", np.nan, ("frame",),
             {"units": "s", "description": "each exposure's start, from the first frame's"}),
            ("homography", (frames, 3, 3), "float64", np.nan, ("frame", "row", "column"),
             {"description": "reference pixel → frame pixel (x the column, y the row, pixel centres at integers), "
                             "at the exposure's middle"}),
            ("done", (frames,), "bool", False, ("frame",),
             {"description": "whether the frame is complete (set after its chunks are written)"}),
            ("reference", (3, layout.height, layout.width), "float32", np.nan, ("channel", "y", "x"),
             {"units": "DN", "description": "the clean reference: the static scene's expectation (no motion, no "
                                            "noise, the fixed pattern in), STEM_ref.exr's clean layer"})):
        group.create_array(name, shape=shape, chunks=shape, dtype=dtype, fill_value=fill,
                           compressors=zarr_store.compressors(), chunk_key_encoding=zarr_store._KEY_ENCODING,
                           dimension_names=dims, attributes=attributes)
    zarr_store._table_array(group, "channel", np.array(zarr_store.CHANNELS, dtype=object), ("channel",), {})
    group.attrs["camsim"] = {"layout": layout.describe(), "compressors": zarr_store.COMPRESSORS, "complete": False,
                             "reference_sidecar": None}


_DESCRIPTIONS = {
    "noisy": "each frame's noisy signal before quantisation (the EXR's noisy layer: R, G, B, or the mosaic), NaN "
             "until written",
    "clean": "each frame's own expectation, motion blur included (the EXR's clean.R, clean.G, clean.B), NaN until "
             "written",
    "digital": "the quantised digital numbers (the DNG's), 0 until written",
}


def read_sequence_store(path) -> dict:
    """A sequence store's arrays as numpy (``noisy``, ``clean``, ``digital`` or None, ``reference``, ``time_s``,
    ``homography``, ``done``), its frames' sidecars (``sidecars``, parsed) and its reference's
    (``reference_sidecar``).

    Raises
    ------
    CamsimError
        Not a complete sequence store.
    """
    import zarr

    try:
        group = zarr.open_group(Path(path), mode="r", zarr_format=3)
        attributes = group.attrs["camsim"]
    except Exception as exc:  # zarr raises several kinds for a folder that is not a store
        raise CamsimError(f"{path} is not a camsim sequence store: {exc}") from None
    done = np.asarray(group["done"][...])
    if not attributes.get("complete") or not done.all():
        raise CamsimError(f"{path} is not complete ({int(done.sum())} of {done.size} frames done)")
    out = {name: np.asarray(group[name][...]) for name in ("noisy", "clean", "reference", "time_s", "homography",
                                                          "done")}
    out["digital"] = np.asarray(group["digital"][...]) if "digital" in group else None
    out["sidecars"] = [json.loads(str(text)) for text in group["sidecar"][...]]
    out["reference_sidecar"] = json.loads(attributes["reference_sidecar"])
    return out
