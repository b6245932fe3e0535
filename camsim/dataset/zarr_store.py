"""A dataset as one Zarr store (``camsim dataset SPEC --format zarr``): chunked arrays for training loaders that
read arrays, not files.

Layout of ``OUT``::

    OUT/dataset.zarr/            the store (Zarr format 3; consolidated metadata)
        noisy     (frame, channel, y, x) float32   the EXR's noisy layer (or (frame, cfa, y, x): the mosaic), DN
        clean     (frame, channel, y, x) float32   the EXR's clean.R, clean.G, clean.B, DN
        digital   (frame, channel, y, x) uint8/16  the DNG's digital numbers (if any frame is quantised)
        srgb_noisy, srgb_clean (frame, channel, y, x) uint8/16   with ``--srgb png|png16``: the noisy and clean
                                                   layers developed through one ISP (camsim.dataset.srgb)
        sidecar   (frame,) str                     each frame's sidecar, as JSON (as the file layout's ID.json)
        done      (frame,) bool                    whether the frame is complete (written after its chunks)
        records   (frame,) str                     each frame's parameters, as JSON (a manifest line, less its
                                                   arrays): the whole parameter table
        <key>     (frame,) or (frame, channel)     one array per parameter of the records with one scalar (or R,
                                                   G, B) value per frame: id, illuminant, intensity_factor, seed,
                                                   read_noise_e, … (coordinates of the frame dimension in xarray)
        channel   (channel,) str                   R, G, B
      a spec of bursts (``burst_frames``, one length): noisy, clean, digital (frame, burst_frame, plane, y, x), one
      chunk per item, and
        reference  (frame, channel, y, x) float32   each burst's clean reference (the file layout's ID_ref.exr)
        homography (frame, burst_frame, 3, 3) float64   each frame's, reference pixel → frame pixel
        time_s     (frame, burst_frame) float64     each frame's exposure start
        sidecar    (frame,) str                     {"reference": ID_ref.json, "frames": [ID_f000.json, …]}
        srgb_reference (frame, channel, y, x) uint8/16   with ``--srgb``: the reference developed (the file
                                                   layout's ID_ref_srgb_clean.png); srgb_noisy and srgb_clean are
                                                   then (frame, burst_frame, …), every frame developed one way, its
                                                   burst's reference's
    OUT/records/<id>.done        each complete frame's record (atomic, written after its chunks)
    OUT/manifest.jsonl           one line per complete frame, in frame order (as for the file layout)

One chunk is one frame of one layer (so that a loader reads a frame with one request per layer, and workers write
distinct chunks: no two processes write one chunk), compressed by Blosc LZ4 with byte shuffle
(:data:`COMPRESSORS`: about 22 % off the float layers and half of the digital numbers' 16-bit containers, at
nearly the speed of no compression: ``python tools/bench_exr_compression.py`` measures it beside the EXR
compressions). Frames not yet rendered read as NaN (float layers), 0 (digital numbers) and "" (sidecar), with
``done`` False.

Resuming works as for the file layout (:mod:`camsim.dataset.manifest`): a frame is complete when its record in
``OUT/records`` describes the same frame and every chunk it lists is there with the recorded size and (``verify =
"sha256"``) its array's bytes have the recorded SHA-256. Chunks are written by zarr under temporary names and
renamed (zarr's local store), then flushed to disk (``fsync``), before the record is written; ``done`` is
rewritten from the records when a run starts and ends, and set as each frame is recorded. A store holds frames of
one size and one kind of sensor (three-chip, or a colour filter array): a spec that mixes them is refused.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import warnings
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from camsim.core.errors import CamsimError, output_error
from camsim.core.input_files import read_input
from camsim.dataset.manifest import DONE_SUFFIX, append_manifest, frame_record, manifest_line
from camsim.dataset.srgb import SRGB_LAYERS
from camsim.io import atomic  # atomic.fsync_path: one flush, which tests can fail as a full disk does

__all__ = ["STORE_NAME", "RECORDS_DIR", "LAYERS", "BURST_LAYERS", "SRGB_REFERENCE", "COMPRESSORS", "StoreLayout",
           "store_layout", "open_store", "burst_arrays", "write_frame_arrays", "verified_record", "store_result",
           "write_done", "frame_arrays", "record_path", "held_srgb"]

STORE_NAME = "dataset.zarr"
#: The largest root ``zarr.json`` read for what a store holds: the consolidated metadata of its arrays (the layers
#: and one table per frame parameter: a few hundred of about 2 kB each), with room to spare. Unit: bytes.
MAX_STORE_METADATA_BYTES = 16_000_000
RECORDS_DIR = "records"
#: The arrays of a store of bursts besides the frame arrays (which gain a ``burst_frame`` dimension): each item's
#: clean reference, its frames' homographies and start times.
BURST_LAYERS = ("reference", "homography", "time_s")
#: The array of a store of bursts with an sRGB output: each item's reference, developed (the file layout's
#: ``ID_ref_srgb_clean.png``).
SRGB_REFERENCE = "srgb_reference"
#: The frame arrays of the store, one chunk per frame (per item of a store of bursts) each.
LAYERS = ("noisy", "clean", "digital", *SRGB_LAYERS, *BURST_LAYERS, SRGB_REFERENCE)
#: Arrays that are not parameters of the records (their names are taken).
_RESERVED = frozenset({*LAYERS, "sidecar", "done", "records", "channel", "cfa", "frame", "y", "x", "srgb",
                       "burst_frame", "row", "column"})
#: Frames per chunk of ``done`` and ``records`` (written by the main process only).
TABLE_CHUNK = 4096
_KEY_ENCODING = {"name": "default", "separator": "."}  # c.<frame>.0.0.0: one flat folder per array
CHANNELS = ("R", "G", "B")


def compressors():
    """The chunks' compressor: Blosc LZ4, level 5, byte shuffle (measured: see the module docstring)."""
    from zarr.codecs import BloscCodec

    return [BloscCodec(cname="lz4", clevel=5, shuffle="shuffle")]


COMPRESSORS = "blosc lz4 clevel 5, byte shuffle"


@dataclass(frozen=True)
class StoreLayout:
    """The shape of a spec's store: what a worker needs to write a frame into it (plain picklable data).

    Attributes
    ----------
    path : str
        Absolute path of the store (``OUT/dataset.zarr``).
    frames : int
        Frames of the spec.
    planes : int
        Planes of ``noisy`` and ``digital``: 3 (R, G, B) or 1 (a colour filter array's mosaic).
    height, width : int
        Frame size. Unit: pixels.
    digital : str or None
        NumPy dtype name of the digital numbers (``uint8`` for at most 8 bits, else ``uint16``), or None if no
        frame is quantised.
    srgb : str or None
        The sRGB output (``png``: uint8 arrays ``srgb_noisy``, ``srgb_clean``; ``png16``: uint16), or None.
    burst_frames : int or None
        Frames of each item's burst (``burst_frames``): the frame arrays are then (frame, burst_frame, plane, y,
        x) and the store has :data:`BURST_LAYERS`; None: one frame per item.
    """

    path: str
    frames: int
    planes: int
    height: int
    width: int
    digital: str | None
    srgb: str | None = None
    burst_frames: int | None = None

    def shape(self, layer: str) -> tuple:
        burst = () if self.burst_frames is None else (self.burst_frames,)
        if layer == "homography":
            return (self.frames, *burst, 3, 3)
        if layer == "time_s":
            return (self.frames, *burst)
        if layer in ("reference", SRGB_REFERENCE):
            return (self.frames, 3, self.height, self.width)
        planes = 3 if layer == "clean" or layer in SRGB_LAYERS else self.planes
        return (self.frames, *burst, planes, self.height, self.width)

    def dims(self, layer: str) -> tuple:
        burst = () if self.burst_frames is None else ("burst_frame",)
        if layer == "homography":
            return ("frame", *burst, "row", "column")
        if layer == "time_s":
            return ("frame", *burst)
        if layer in ("reference", SRGB_REFERENCE):
            return ("frame", "channel", "y", "x")
        plane = "channel" if layer == "clean" or layer in SRGB_LAYERS or self.planes == 3 else "cfa"
        return ("frame", *burst, plane, "y", "x")

    def layers(self) -> tuple:
        """The frame arrays of this layout's store."""
        return tuple(name for name in LAYERS if not (name == "digital" and self.digital is None)
                     and not (name in SRGB_LAYERS and self.srgb is None)
                     and not (name in BURST_LAYERS and self.burst_frames is None)
                     and not (name == SRGB_REFERENCE and (self.srgb is None or self.burst_frames is None)))

    def dtype(self, layer: str) -> str:
        from camsim.dataset.srgb import srgb_dtype

        if layer == "digital":
            return self.digital
        if layer in ("homography", "time_s"):
            return "float64"
        return srgb_dtype(self.srgb) if layer in (*SRGB_LAYERS, SRGB_REFERENCE) else "float32"

    def describe(self) -> dict:
        """The layout as the store's attributes record it (without its path; ``srgb`` and ``burst_frames`` only
        when set, so that a store written before they existed has the same layout)."""
        return {k: v for k, v in asdict(self).items()
                if k != "path" and not (k in ("srgb", "burst_frames") and v is None)}


def held_srgb(out_dir: Path) -> str | None:
    """The sRGB output (``png``, ``png16``) of the store in ``out_dir``, read from its metadata; None where there is
    no store, or one without sRGB arrays (a metadata file that is no regular file of at most
    :data:`MAX_STORE_METADATA_BYTES` holding JSON counts as none)."""
    try:
        path = Path(out_dir) / STORE_NAME / "zarr.json"
        meta = json.loads(read_input(path, "Zarr store metadata", MAX_STORE_METADATA_BYTES).decode("utf-8"))
        return meta["attributes"]["camsim"]["layout"].get("srgb")
    except (CamsimError, OSError, ValueError, RecursionError, KeyError, TypeError, AttributeError):
        return None


def store_layout(spec, out_dir: Path, srgb: str = "none") -> StoreLayout:
    """The layout of ``spec``'s store in ``out_dir`` (with the sRGB output ``srgb``: ``none``, ``png``, ``png16``);
    :class:`CamsimError` for a spec whose frames differ in size or in the kind of sensor (three-chip or colour
    filter array), which one store cannot hold."""
    sizes = sorted({(f.width, f.height) for f in spec.frames})
    if len(sizes) > 1:
        raise CamsimError(f"--format zarr needs frames of one size (one array per layer), but {spec.name} has "
                          f"{', '.join(f'{w}x{h}' for w, h in sizes)}: write it as files (--format files) or split "
                          "the spec by size")
    kinds = {f.get("cfa") is not None for f in spec.frames}
    if len(kinds) > 1:
        raise CamsimError(f"--format zarr needs one kind of sensor, but {spec.name} mixes three-chip frames and "
                          "colour filter array (mosaic) frames: write it as files (--format files) or split the spec")
    bursts = {None if f.burst is None else f.burst.frames for f in spec.frames}
    if len(bursts) > 1:
        shown = ", ".join("single frames" if n is None else f"bursts of {n}" for n in sorted(bursts, key=str))
        raise CamsimError(f"--format zarr needs one burst length (one array per layer), but {spec.name} has "
                          f"{shown}: write it as files (--format files) or split the spec")
    bits = [f.get("bits") for f in spec.frames if f.get("quantisation")]
    (width, height), = sizes or [(spec.width, spec.height)]
    (burst_frames,) = bursts or {None}
    return StoreLayout(path=str(Path(out_dir).resolve() / STORE_NAME), frames=len(spec.frames),
                       planes=1 if kinds == {True} else 3, height=height, width=width,
                       digital=None if not bits else np.dtype(np.uint8 if max(bits) <= 8 else np.uint16).name,
                       srgb=None if srgb == "none" else srgb, burst_frames=burst_frames)


# --- the main process: the store, its parameter table and its done flags ---------------------------------------


def open_store(layout: StoreLayout, spec, echo=None):
    """Create the store of ``layout`` (or open the one there, checking that it has this layout, and resizing it to
    the spec's frame count), write the parameter table of ``spec`` and consolidate the metadata. Returns the
    ``zarr.Group``.

    Raises
    ------
    CamsimError
        The folder holds something else than a camsim store, or a store of frames of another size or sensor.
    """
    try:
        import zarr
    except ImportError:
        raise CamsimError("--format zarr needs the zarr package (3 or newer): pip install zarr") from None

    root = Path(layout.path)
    _remove_partials(root)
    if root.exists() and not (root / "zarr.json").is_file():
        raise CamsimError(f"{root} exists but is not a Zarr store: remove it or choose another --out")
    group = zarr.open_group(root, mode="a", zarr_format=3)
    held = group.attrs.get("camsim", {}).get("layout")
    if held is not None:
        here = layout.describe()
        blank = {"srgb": "none"}  # how a layout without the key reads in the message
        mismatch = {k: (held.get(k, blank.get(k)), here.get(k, blank.get(k))) for k in sorted(set(here) | set(held))
                    if k != "frames" and held.get(k) != here.get(k)}
        if mismatch:
            differences = ", ".join(f"{k} {there} there, {here} here" for k, (there, here) in mismatch.items())
            raise CamsimError(f"{root} holds frames of another layout ({differences}): choose another --out, or "
                              "remove the store")
    members = set(group.array_keys())
    columns = parameter_columns([frame.record for frame in spec.frames])
    coordinates = " ".join(columns)
    for layer in layout.layers():
        dtype = layout.dtype(layer)
        units = ("DN" if layer not in (*SRGB_LAYERS, SRGB_REFERENCE)
                 else f"sRGB (IEC 61966-2-1) code values, 0 to {np.iinfo(dtype).max}")
        units = {"homography": "", "time_s": "s"}.get(layer, units)
        attributes = {"units": units, "description": _DESCRIPTIONS[layer], "coordinates": coordinates}
        _frame_array(group, members, layer, layout.shape(layer), (1, *layout.shape(layer)[1:]), dtype,
                     np.nan if dtype in ("float32", "float64") else 0, layout.dims(layer), attributes)
    _frame_array(group, members, "sidecar", (layout.frames,), (1,), str, "", ("frame",),
                 {"description": "each frame's sidecar (the file layout's ID.json), as JSON; '' until rendered"
                                 + ("; a burst's: {\"reference\": ID_ref.json, \"frames\": [ID_f000.json, …]}"
                                    if layout.burst_frames is not None else ""),
                  "coordinates": coordinates})
    _frame_array(group, members, "done", (layout.frames,), (min(layout.frames, TABLE_CHUNK),), bool, False,
                 ("frame",), {"description": "whether the frame is complete (set after its chunks are written)",
                              "coordinates": coordinates})
    _table_array(group, "records", np.array([json.dumps(frame.record, ensure_ascii=False, allow_nan=False)
                                             for frame in spec.frames], dtype=object), ("frame",),
                 {"description": "each frame's parameters (a manifest line without its arrays), as JSON"})
    _table_array(group, "channel", np.array(CHANNELS, dtype=object), ("channel",), {})
    for name in members - set(LAYERS) - {"sidecar", "done", "records", "channel"} - set(columns):
        del group[name]  # a parameter of an earlier spec
    for name, values in columns.items():
        dims = ("frame",) if values.ndim == 1 else ("frame", "channel")
        _table_array(group, name, values, dims, {"description": f"the records' {name}, frame by frame"})
    group.attrs["camsim"] = {"layout": layout.describe(), "spec": spec.name, "spec_seed": spec.seed,
                             "compressors": COMPRESSORS, "records_dir": RECORDS_DIR}
    with warnings.catch_warnings():  # consolidated metadata is zarr-python's extension of format 3: said in the docs
        warnings.filterwarnings("ignore", message="Consolidated metadata", category=UserWarning)
        zarr.consolidate_metadata(root)
    return zarr.open_group(root, mode="r+", zarr_format=3, use_consolidated=False)


_DESCRIPTIONS = {
    "noisy": "the noisy signal before quantisation (the EXR's noisy.R, noisy.G, noisy.B, or noisy.CFA: the "
             "mosaic), NaN until rendered",
    "clean": "its expected value per pixel (the EXR's clean.R, clean.G, clean.B), NaN until rendered",
    "digital": "the quantised digital numbers I (the DNG's), 0 until rendered or where not quantised",
    "srgb_noisy": "the noisy layer developed through the camera ISP (the file layout's ID_srgb_noisy.png; the "
                  "ISP's record in the frame's record, key srgb), 0 until rendered",
    "srgb_clean": "the clean layer developed through the same ISP (same white balance, matrix, gain and tone curve; "
                  "the file layout's ID_srgb_clean.png), 0 until rendered",
    "reference": "a burst's clean reference: the static scene's expectation, no motion, no noise (the file layout's "
                 "ID_ref.exr clean layer), NaN until rendered",
    SRGB_REFERENCE: "a burst's clean reference developed, the burst's one development for all its frames (the file "
                    "layout's ID_ref_srgb_clean.png), 0 until rendered",
    "homography": "each burst frame's homography, reference pixel → frame pixel at the exposure's middle, NaN until "
                  "rendered",
    "time_s": "each burst frame's exposure start, from the burst's first frame's, NaN until rendered",
}


def _frame_array(group, members, name, shape, chunks, dtype, fill, dims, attributes):
    """The array ``name``: created if missing, resized to ``shape`` along the frame axis if it has another count."""
    if name in members:
        array = group[name]
        if array.shape != shape:
            array.resize(shape)
        array.update_attributes(attributes)
        return array
    return group.create_array(name, shape=shape, chunks=chunks, dtype=dtype, fill_value=fill,
                              compressors=compressors(), chunk_key_encoding=_KEY_ENCODING, dimension_names=dims,
                              attributes=attributes)


def _table_array(group, name, values, dims, attributes):
    """Write ``values`` as the array ``name`` (replacing any array of that name)."""
    dtype = str if values.dtype == object else values.dtype
    array = group.create_array(name, shape=values.shape, chunks=(min(len(values), TABLE_CHUNK), *values.shape[1:]),
                               dtype=dtype, compressors=compressors() if dtype is not str else "auto",
                               chunk_key_encoding=_KEY_ENCODING, dimension_names=dims, attributes=attributes,
                               overwrite=True)
    array[...] = values
    return array


def parameter_columns(records: list) -> dict:
    """The per-key arrays of the parameter table: every key that all ``records`` have with a value of one kind —
    bool, int (int64), number (float64), str, or a list of three numbers (float64, (frames, 3)); keys with a None or
    another value somewhere are left to the ``records`` array."""
    columns = {}
    for key in records[0] if records else ():
        if key in _RESERVED or not all(key in r for r in records):
            continue
        values = [r[key] for r in records]
        kinds = {type(v) for v in values}
        if kinds == {bool}:
            columns[key] = np.array(values, dtype=bool)
        elif kinds == {int} and all(-2**63 <= v < 2**63 for v in values):
            columns[key] = np.array(values, dtype=np.int64)
        elif kinds <= {int, float} and kinds:
            columns[key] = np.array(values, dtype=np.float64)
        elif kinds == {str}:
            columns[key] = np.array(values, dtype=object)
        elif kinds == {list} and all(len(v) == 3 and all(type(x) in (int, float) for x in v) for v in values):
            columns[key] = np.array(values, dtype=np.float64)
    return columns


def write_done(group, records: dict) -> None:
    """Rewrite ``done`` from the records of the complete frames (``{index: record}``)."""
    done = np.zeros(group["done"].shape, dtype=bool)
    done[[i for i in records if i < len(done)]] = True
    with _writing(_member_path(group, "done")):
        group["done"][...] = done


def _member_path(group, name: str) -> str:
    """The path of the store's array ``name`` (for a message)."""
    return str(Path(str(group.store.root)) / name) if hasattr(group.store, "root") else name


@contextlib.contextmanager
def _writing(path):
    """Zarr's errors on writing (a full disk: ``OSError`` without a file name) as one line naming ``path``."""
    try:
        yield
    except OSError as exc:
        raise output_error(path, exc) from None


def _remove_partials(root: Path) -> None:
    """Remove the temporary files zarr's local store leaves when a write is killed (``NAME.HEX.partial``)."""
    if not root.is_dir():
        return
    for folder in (root, *(p for p in root.iterdir() if p.is_dir())):
        for path in folder.glob("*.partial"):
            with contextlib.suppress(OSError):
                path.unlink()


# --- a worker: one frame's chunks ------------------------------------------------------------------------------


def burst_arrays(frames: list, reference, layout: StoreLayout, extras: list,
                 reference_info=None) -> tuple[dict, dict | None]:
    """A rendered burst as the store's layers: its frames (:class:`camsim.render.frame.Frame`, in order) stacked,
    the ``reference`` frame's clean layer, and each frame's ``homography`` and ``time_s`` from its sidecar keys
    ``extras`` (:func:`camsim.render.sequence.render_sequence_frames`); where the layout has an sRGB output (which
    needs the reference's ``reference_info``), every frame's ``srgb_noisy`` and ``srgb_clean`` and the reference's
    ``srgb_reference``, developed one way, the reference's (:func:`camsim.dataset.srgb.burst_development`), and
    what those hold (the file layout's burst ``srgb`` record; None without)."""
    development = record = None
    if layout.srgb is not None:
        from camsim.dataset.srgb import burst_development, develop_burst_reference, quantise

        development = burst_development(reference, reference_info)
        images, record = develop_burst_reference(reference, layout.srgb, development)
    layers = [frame_arrays(frame, layout, development=development)[0] for frame in frames]
    digital = None if layers[0]["digital"] is None else np.stack([d["digital"] for d in layers])
    data = {"noisy": np.stack([d["noisy"] for d in layers]), "clean": np.stack([d["clean"] for d in layers]),
            "digital": digital, "reference": np.asarray(reference.clean_dn(), dtype=np.float32),
            "homography": np.array([e["homography"] for e in extras], dtype=np.float64),
            "time_s": np.array([e["time_s"] for e in extras], dtype=np.float64)}
    if record is None:
        return data, None
    from camsim.dataset.srgb import burst_srgb_record

    data.update({layer: np.stack([d[layer] for d in layers]) for layer in SRGB_LAYERS})
    data[SRGB_REFERENCE] = quantise(images["srgb_clean"], record["bits"])
    return data, burst_srgb_record(record)


def frame_arrays(rendered, layout: StoreLayout, info=None, development=None) -> tuple[dict, dict | None]:
    """A rendered :class:`camsim.render.frame.Frame` as the store's layers (``digital`` None where not quantised),
    with the developed ``srgb_noisy`` and ``srgb_clean`` where the layout has an sRGB output (which needs the
    frame's ``info``, or a burst frame's ``development``: its burst's, :func:`camsim.dataset.srgb.burst_development`);
    and what those hold (:func:`camsim.dataset.srgb.develop_frame`'s record, None without)."""
    digital = rendered.digital_dn
    data = {"noisy": rendered.noisy_dn, "clean": rendered.clean_dn(),
            "digital": None if digital is None else digital.astype(layout.digital, copy=False)}
    if layout.srgb is None:
        return data, None
    from camsim.dataset.srgb import develop_frame, quantise

    images, record = (develop_frame(rendered, info, layout.srgb) if development is None else
                      develop_frame(rendered, info, layout.srgb, development.settings, development.facts))
    data.update({layer: quantise(image, record["bits"]) for layer, image in images.items()})
    return data, record


_open_arrays: dict = {}  # store path -> {name: zarr.Array}, per process


def _arrays(path: str, threads: int) -> dict:
    """The store's frame arrays, opened once per process (``threads``: zarr's codec threads)."""
    arrays = _open_arrays.get(path)
    if arrays is None:
        import zarr

        zarr.config.set({"threading.max_workers": threads})
        group = zarr.open_group(path, mode="r+", zarr_format=3, use_consolidated=False)
        arrays = {name: group[name] for name in (*LAYERS, "sidecar") if name in group}
        _open_arrays.clear()  # one store at a time
        _open_arrays[path] = arrays
    return arrays


def release_arrays() -> None:
    """Forget the store arrays this process opened (:func:`write_frame_arrays`): for a writer whose store moves
    (a sequence's, renamed into place when complete: :mod:`camsim.dataset.sequence_store`)."""
    _open_arrays.clear()


def write_frame_arrays(layout: StoreLayout, index: int, data: dict, sidecar_text: str, threads: int = 1) -> dict:
    """Write frame ``index``'s chunks (``data``: :func:`frame_arrays`; its sidecar as JSON text), flush them to
    disk, and return what its record lists: per layer (and ``sidecar``) the chunk's name in the store, its size in
    bytes and the SHA-256 of the frame's array (C order; the sidecar's UTF-8 text), or None for a missing layer."""
    arrays = _arrays(layout.path, threads)
    root = Path(layout.path)
    entries = {}
    for name, value in (*data.items(), ("sidecar", sidecar_text)):
        if value is None:
            entries[name] = None
            continue
        array = arrays[name]
        key = array.metadata.encode_chunk_key((index,) + (0,) * (array.ndim - 1))
        chunk = root / name / key
        if name == "sidecar":
            digest = hashlib.sha256(value.encode("utf-8")).hexdigest()
        else:
            value = np.ascontiguousarray(value, dtype=array.dtype)
            digest = hashlib.sha256(memoryview(value).cast("B")).hexdigest()
        with _writing(chunk):
            array[index] = value
            atomic.fsync_path(chunk)
        entries[name] = {"chunk": f"{name}/{key}", "bytes": chunk.stat().st_size, "sha256": digest}
    for name in entries:
        atomic.fsync_path(root / name, directory=True)
    return entries


# --- resuming --------------------------------------------------------------------------------------------------


def record_path(out_dir: Path, frame_id: str) -> Path:
    return Path(out_dir) / RECORDS_DIR / f"{frame_id}{DONE_SUFFIX}"


def verified_record(out_dir: Path, group, frame, verify: str = "sha256") -> dict | None:
    """The frame's record if it is complete and verified in the store, else None: the record describes this very
    frame, and each chunk it lists is there with the recorded size and (``verify="sha256"``) the recorded SHA-256
    of its array."""
    record = frame_record(record_path(out_dir, frame.id), frame, ("arrays", "zarr", "srgb"))
    if record is None:
        return None
    entries = record.get("arrays")
    if not isinstance(entries, dict) or not entries.get("noisy") or not entries.get("sidecar"):
        return None
    if any(layer in group and not entries.get(layer) for layer in (*SRGB_LAYERS, *BURST_LAYERS, SRGB_REFERENCE)):
        return None  # the store has sRGB (or bursts') arrays, which this frame's record does not list
    root = Path(str(group.store.root))
    for name, entry in entries.items():
        if entry is None:
            continue
        try:
            if (root / entry["chunk"]).stat().st_size != entry["bytes"]:
                return None
            if verify == "sha256" and _digest(group[name], frame.index) != entry["sha256"]:
                return None
        except (OSError, KeyError, TypeError, ValueError):
            return None
    return record


def _digest(array, index: int) -> str:
    value = array[index]
    if array.ndim == 1:
        return hashlib.sha256(str(value).encode("utf-8")).hexdigest()
    return hashlib.sha256(memoryview(np.ascontiguousarray(value)).cast("B")).hexdigest()


def store_result(out_dir: Path, group, layout: StoreLayout, frame, result: dict, threads: int = 1) -> dict:
    """Record a rendered frame: write its chunks (if its arrays were sent back), then its record, then its
    ``done`` flag; returns the record."""
    entries = result.get("arrays")
    if entries is None:
        entries = write_frame_arrays(layout, frame.index, result["data"], result["sidecar"], threads)
    record = {**frame.record, **({"srgb": result["srgb"]} if "srgb" in result else {}), "arrays": entries}
    atomic.write_json_atomic(record_path(out_dir, frame.id), record)
    with _writing(_member_path(group, "done")):
        group["done"][frame.index] = True
    append_manifest(out_dir, manifest_line(record))  # the frame is committed: listed at once
    return record
