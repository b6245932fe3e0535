"""Dataset spec files (TOML): which frames a dataset holds, each with its parameters, id and seed.

A spec names one or more scene files and the parameters to vary over them::

    name = "denoise_small"
    scene = "macbeth_26.toml"          # or a list; relative to the spec file, or a built-in scene's name
    seed = 0                           # the random draws and every frame's noise derive from it
    repeats = 1                        # noisy realisations of each parameter set (each its own seed)
    exr_compression = "none"           # optional: the EXR files' lossless compression (camsim.io.exr_compression)
    srgb = "png"                       # optional: developed noisy and clean sRGB per frame (SRGB_OUTPUTS)

    [frame]                            # frame size in pixels (default 256 x 192)
    width = 256
    height = 192

    [fixed]                            # one value for every frame
    preset = "emva-12bit"

    [grid]                             # lists: every combination is a frame (last key varies fastest)
    illuminants = ["D65", "A", "FL2"]
    read_noise_model = ["gaussian", "tukey-lambda"]

    [random]                           # `count` draws per grid point
    count = 8
    intensity_factor = { log_uniform = [1e-3, 1.0] }
    read_noise_e = { uniform = [1.5, 6.0] }

Parameters (in ``[fixed]``, ``[grid]`` or ``[random]``, at most one of them each): ``illuminant`` (``illuminants``
in ``[grid]`` too), ``intensity_factor`` (``intensity_factors``), ``statistics``, ``method``, ``tolerance``,
``camera``, ``preset`` and every sensor parameter of a scene file's ``[sensor]`` table (``read_noise_e``,
``exposure_s``, ``dark_current`` …; ``cfa = "none"`` is the three-chip sensor). A parameter the spec does not set
keeps the scene file's value; the scene's ``illuminants`` and ``intensity_factors`` lists then become grid axes
(outermost, after the scene), as in ``camsim render``. The scene file's ``[render] seed`` is not used.

Distributions of ``[random]``: ``uniform = [a, b]``, ``log_uniform = [a, b]`` (a > 0), ``integers = [a, b]``
(inclusive) and ``choice = [v, ...]``. Each parameter draws from its own stream,
:func:`camsim.core.seeding.dataset_parameter_generator`, one value per frame in frame order, so
the frame list is the same on every run and adding a parameter leaves the others' draws unchanged.

Scenes may come from a folder of images (an ``[images]`` table): each frame is a random crop of a randomly chosen
image, lit, seen and sensed as the ``scene`` file says (its light, camera, sensor, spectral grid and luminance; its
chart, cube or image replaced by the crop, a reflectance image: :class:`camsim.scene.sources.image.ImageSource`)::

    [images]
    folder = "images"                  # relative to the spec file
    pattern = "*.png"                  # glob in the folder (default: *.png, *.jpg, *.jpeg, *.tif, *.tiff, *.exr);
                                       # relative to it and without "..": it never leaves the folder
    crop = [256, 192]                  # the frame size: width, height in pixels (no [frame] table then)
    flips = true                       # random horizontal and vertical flips (default false)

Each grid point's draw (its repeats share it: noise2noise pairs of one crop) picks an image (uniformly among the
files, in name order), the crop's offset (x, y uniform over every position inside the image) and, with
``flips``, whether it is flipped left-right and upside-down (each with probability 1/2), each from its own stream
(:func:`camsim.core.seeding.dataset_parameter_generator` of ``images.file``, ``images.x``, ``images.y``,
``images.flip_horizontal``, ``images.flip_vertical``). The frame's record holds them (:data:`IMAGE_KEYS`: the file
name relative to the folder, its SHA-256, ``crop_x``, ``crop_y``, ``flip_horizontal``, ``flip_vertical``), so that
the id changes with the image's bytes. A crop is of the file as stored; a flip mirrors the cropped frame.

Scenes may also be crops of a folder of a real camera's raw files (a ``[raws]`` table: ``folder``, ``pattern``,
``crop``, ``flips``, ``photon_law``, ``preset``), which need no ``scene`` file: the light and colour are each file's
own, and the frames' parameters include ``ratio`` and ``photon_law`` (:data:`RAWS_PARAMS`). :mod:`camsim.dataset.raws`
describes them.

Frame order: scene, the scene's inherited axes, the ``[grid]`` keys in file order, the random draw, the repeat.
Each frame gets an id ``<index>-<hash>`` (the hash covers every resolved parameter, the scene file's bytes and the
seed) and its own seed, a function of the spec seed and the id alone, so that a frame's content does not depend
on the other frames, on the order they are rendered in or on the machine. The index is zero-padded to five digits,
or to the digits of the last index where a spec has more than 100 000 frames (``000000-…`` to ``119999-…``), so
that every id of a spec has the same width and the ids sort in frame order.

Planning is cheap per frame: frames that differ only in parameters that enter them through their own value alone
(:data:`OWN_VALUE_PARAMS`: the light level, the read noise, the exposure …) share one resolved and checked scene
and sensor (:class:`FrameGroup`), so that a spec of 10⁵ frames is planned in seconds and little memory;
:func:`plan_spec` makes the frames one by one (``camsim dataset --dry-run`` streams them).
"""

from __future__ import annotations

import dataclasses
import hashlib
import itertools
import json
import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path, PurePosixPath

from camsim.scene.builtin_scenes import resolve_scene_file, resolve_spec_file
from camsim.sensor.camera import load_camera
from camsim.core.errors import CamsimError
from camsim.render.pipeline import check_frame, exposure_record, frame_sensor, light_scene
from camsim.render.run import check_scene
from camsim.io.dng import MIN_SIZE
from camsim.io.exr_compression import check_exr_compression
from camsim.core.names import safe_component
from camsim.core.schema import INT64_MAX, Param, check_frame_size, params_of
from camsim.scene.scene_file import FRAME_PARAMS, RENDER_PARAMS, Scene, check_intensity_factor, load_scene, read_toml
from camsim.scene.sequence import SequenceParams, check_timing
from camsim.core.seeding import dataset_frame_seeds, dataset_parameter_generator
from camsim.sensor.params import MAP_FILE_PARAMS, SENSOR_PARAMS, with_checked_values
from camsim.scene.sources.image import ImageSource
from camsim.sensor.presets.virtual import VIRTUAL_KEYS
from camsim.sensor.raw_laws import PHOTON_LAWS

DEFAULT_WIDTH, DEFAULT_HEIGHT = 256, 192
MAX_FRAMES = 1_000_000

#: The parameters of the frames of a ``[raws]`` spec only (:mod:`camsim.dataset.raws`): what a frame draws from its
#: raw source.
RAWS_PARAMS = (
    Param("ratio", "float", None, "[raws] only: the exposure ratio of the SID convention, the frame's exposure "
          "T = T_source / ratio (with intensity_factor 1: the frame expects 1/ratio of the source's electrons); "
          "none: T is exposure_s (default the source's)", above=0, optional=True),
    Param("photon_law", "str", "add", "[raws] only: how a frame's electrons are drawn from the source's: 'add' = "
          "Poisson of the expectation (the source noise-free), 'thin' = binomial thinning of the source's count "
          "(cannot brighten); default the [raws] table's", choices=PHOTON_LAWS),
)
_SEQUENCE = {p.name: p for p in params_of(SequenceParams)}
#: The parameters of a burst (:mod:`camsim.scene.sequence`'s ``[sequence]``, declared there): ``burst_frames`` makes
#: each dataset item a burst of that many frames with camera motion; the others are the motion's. A spec that sets
#: none of them keeps the scene file's ``[sequence]``, if it has one (a burst of its frames).
#: A burst's rolling shutter and flickering light (the [sequence]'s keys of the same names).
_LIGHT_AND_SHUTTER = ("rolling_shutter_row_s", "flicker_hz", "flicker_depth", "flicker_phase_deg")
BURST_PARAMS = (
    Param("burst_frames", "int", None, "frames of each item's burst (the scene file's [sequence] frames): "
          "ID_fNNN.dng/.exr/.json and the clean reference ID_ref.exr/.json; none: one frame per item",
          low=1, optional=True),
    *(dataclasses.replace(_SEQUENCE[name], doc="burst: " + _SEQUENCE[name].doc)
      for name in ("frame_interval_s", "shake_px", "shake_deg")),
    Param("pan_x_px_per_s", "float", 0.0, "burst: constant pan, horizontal (the [sequence]'s pan_px_per_s[0])",
          "px/s"),
    Param("pan_y_px_per_s", "float", 0.0, "burst: constant pan, vertical (the [sequence]'s pan_px_per_s[1])",
          "px/s"),
    *(dataclasses.replace(_SEQUENCE[name], doc="burst: " + _SEQUENCE[name].doc)
      for name in ("blur_subsamples", *_LIGHT_AND_SHUTTER)),
)
#: Every parameter a spec may set, by name: the frame's choices, the render settings and the sensor's (the schema),
#: those of ``[raws]`` frames (:data:`RAWS_PARAMS`) and of bursts (:data:`BURST_PARAMS`).
PARAMETERS = {p.name: p for p in (*FRAME_PARAMS, *RENDER_PARAMS, *SENSOR_PARAMS, *RAWS_PARAMS, *BURST_PARAMS)
              if p.name != "seed"}
#: The render settings of :class:`camsim.scene.scene_file.Scene` a frame takes from its spec (all but the seed: a frame has
#: its own).
RENDER_KEYS = tuple(p.name for p in RENDER_PARAMS if p.name != "seed")
#: Plural spellings accepted in [grid] (the scene file's [light] names).
GRID_ALIASES = {"illuminants": "illuminant", "intensity_factors": "intensity_factor"}
DISTRIBUTIONS = ("uniform", "log_uniform", "integers", "choice")
_TOP_KEYS = {"name", "description", "scene", "seed", "repeats", "frame", "fixed", "grid", "random", "images",
             "raws", "virtual_camera", "exr_compression", "srgb"}
#: What a spec's ``srgb`` (and ``camsim dataset --srgb``) may be: ``none``, or each frame's noisy and clean layers
#: developed through one camera ISP (:mod:`camsim.dataset.srgb`) as 8-bit (``png``) or 16-bit (``png16``) sRGB:
#: PNG files in the file layout, uint8 or uint16 arrays in a Zarr store.
SRGB_OUTPUTS = ("none", "png", "png16")
#: Keys of a ``[virtual_camera]`` table.
VIRTUAL_CAMERA_TABLE_KEYS = ("cameras", "k_range", "read_noise_model")
#: Keys of an ``[images]`` table.
IMAGES_TABLE_KEYS = ("folder", "pattern", "crop", "flips")
#: File name suffixes an ``[images]`` folder is searched for without a ``pattern`` (any case).
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".exr")
#: A frame's own values when its scene is a crop of an image of an ``[images]`` folder (after the others).
IMAGE_KEYS = ("image_file", "image_sha256", "crop_x", "crop_y", "flip_horizontal", "flip_vertical")
#: Keys of a ``[raws]`` table (:mod:`camsim.dataset.raws`).
RAWS_TABLE_KEYS = ("folder", "pattern", "crop", "flips", "photon_law", "preset")
#: File name suffixes a ``[raws]`` folder is searched for without a ``pattern`` (any case): the raw formats LibRaw
#: reads.
RAW_SUFFIXES = (".dng", ".arw", ".srf", ".sr2", ".nef", ".nrw", ".cr2", ".cr3", ".crw", ".raf", ".orf", ".rw2",
                ".pef", ".srw", ".raw", ".rwl", ".3fr", ".fff", ".iiq", ".mos", ".mef", ".mrw", ".erf", ".kdc",
                ".dcr", ".x3f", ".gpr")
#: A frame's own values when its scene is a crop of a raw file of a ``[raws]`` folder (after the others).
RAW_KEYS = ("raw_file", "raw_sha256", "crop_x", "crop_y", "flip_horizontal", "flip_vertical")
#: Digits of a frame id's index at least (more where a spec has more than 10**ID_DIGITS frames).
ID_DIGITS = 5

_COUPLED = frozenset({
    "analog_gain_dn_per_v", "conversion_gain_v_per_e",  # their product is the record's dn_per_electron
    "prnu_percent",  # checked against the method
    "quantisation",  # checked against the frame size
})
#: Parameters that enter a frame through their own value alone: range-checked by themselves, copied as they are
#: into the frame's record and sensor overrides, with no derived value and no check across parameters. Frames that
#: differ only in these share one :class:`FrameGroup` (a test checks each against a frame resolved in full).
OWN_VALUE_PARAMS = frozenset({"intensity_factor"} | {p.name for p in SENSOR_PARAMS
                                                      if p.kind in ("float", "int", "bool")} - _COUPLED
                             # recorded only when set (Param.omit_default): not a key of every record of a group
                             - {p.name for p in SENSOR_PARAMS if p.omit_default})
_FACTOR = 1  # position of the intensity factor in FrameSpec.values: repeat, factor, own-value sensor parameters
_BATCH = 1024  # frames whose seeds are computed together


@dataclass(frozen=True)
class FrameGroup:
    """What the frames that differ only in their own-value parameters (:data:`OWN_VALUE_PARAMS`) share: one
    resolved and checked scene and sensor, held once for all of them.

    Attributes
    ----------
    scene_path : str
        Absolute path of the scene file.
    width, height : int
        Frame size in pixels.
    illuminant : str
    scene_changes : dict
        ``Scene.replace`` arguments (statistics, method, tolerance, camera, preset_name).
    sensor_overrides : dict
        Sensor parameters on top of the scene's preset and ``[sensor]`` table; the keys of ``value_keys`` hold one
        frame's values.
    record : dict
        A frame's record without id, index and seed; the keys of ``value_keys`` hold one frame's values.
    value_keys : tuple of str
        Names of :attr:`FrameSpec.values`: ``repeat``, ``intensity_factor``, then sensor parameters.
    canonical_parts : tuple of str
        ``"key":value`` of every key of ``record``, sorted: the canonical JSON the frame ids hash, but for the
        frames' own values.
    canonical_slots : tuple
        ``(position in canonical_parts, '"key":')`` of each of ``value_keys``.
    image_folder : str or None
        Absolute path of the ``[images]`` folder whose crops the frames are (their last own values are then
        :data:`IMAGE_KEYS`), or None.
    raws : object or None
        What the frames of a ``[raws]`` spec share (:class:`camsim.dataset.raws.RawGroup`: the folder, the source's
        camera, the target's preset and ISO, the photon law); their last own values are then :data:`RAW_KEYS`.
    """

    scene_path: str
    width: int
    height: int
    illuminant: str
    scene_changes: dict
    sensor_overrides: dict
    record: dict
    value_keys: tuple
    canonical_parts: tuple
    canonical_slots: tuple
    image_folder: str | None = None
    raws: object = None

    @property
    def sensor_keys(self) -> tuple:
        """The names of the own values that are sensor parameters."""
        end = len(self.value_keys) - (len(IMAGE_KEYS) if self.image_folder is not None else 0)
        if self.raws is not None:  # a [raws] frame's own values end with its varied ratio, if any, and RAW_KEYS
            end -= len(RAW_KEYS) + ("ratio" in self.value_keys)
        return self.value_keys[_FACTOR + 1:end]

    def canonical(self, values: tuple) -> str:
        """The canonical JSON (:func:`_canonical`) of the record of a frame with ``values``, without its id,
        index and seed: what the frame's id hashes."""
        parts = list(self.canonical_parts)
        for (position, prefix), value in zip(self.canonical_slots, values):
            parts[position] = prefix + _canonical_scalar(value)
        return "{" + ",".join(parts) + "}"


@dataclass(frozen=True)
class FileCrop:
    """A window of a file, perhaps mirrored: the scene of a frame of an ``[images]`` spec (:class:`ImageCrop`) or a
    ``[raws]`` spec (:class:`camsim.dataset.raws.RawCrop`).

    Attributes
    ----------
    path : str
        Absolute path of the file.
    x, y : int
        Offset of the window's top-left corner in the file (column, row). Unit: pixels.
    width, height : int
        The window's size: the frame's. Unit: pixels.
    flip_horizontal, flip_vertical : bool
        Whether the frame is the window mirrored left-right, upside-down.
    """

    path: str
    x: int
    y: int
    width: int
    height: int
    flip_horizontal: bool
    flip_vertical: bool

    @property
    def window(self) -> tuple:
        """(x, y, width, height) of the window in the file."""
        return (self.x, self.y, self.width, self.height)


@dataclass(frozen=True)
class ImageCrop(FileCrop):
    """The scene of a frame of an ``[images]`` spec: a crop of an image file, perhaps flipped (:class:`FileCrop`)."""

    def source(self) -> ImageSource:
        """The (unflipped) crop as a scene source: a reflectance image."""
        return ImageSource(path=Path(self.path), crop=self.window)

    def flip(self, labels):
        """``labels`` (H, W), mirrored as the frame is (a new contiguous array; the same one without flips)."""
        if not (self.flip_horizontal or self.flip_vertical):
            return labels
        rows = slice(None, None, -1) if self.flip_vertical else slice(None)
        columns = slice(None, None, -1) if self.flip_horizontal else slice(None)
        return labels[rows, columns].copy()


@dataclass(frozen=True, slots=True)
class FrameSpec:
    """One frame of a dataset: everything a worker needs to render it, as plain picklable data.

    A frame holds its index, id, seed and own values; the rest is its :class:`FrameGroup`'s, shared with the
    frames that differ from it only in those values.

    Attributes
    ----------
    index : int
        Position in the spec's frame list.
    id : str
        ``<index>-<hash>``: the file stem under ``OUT/frames/`` (the index zero-padded to the same width for
        every frame of the spec, at least five digits).
    seed : int
        The frame's seed (< 2**53): its generator is
        ``camsim.core.seeding.frame_seed_sequence(seed, illuminant, intensity_factor)``, as for ``camsim render``.
    group : FrameGroup
    values : tuple
        The frame's own values, named by ``group.value_keys``: repeat, intensity factor, sensor parameters.
    scene_path : str
        Absolute path of the scene file.
    width, height : int
        Frame size in pixels.
    illuminant : str
    intensity_factor : float
    scene_changes : dict
        ``Scene.replace`` arguments (statistics, method, tolerance, camera, preset_name).
    sensor_overrides : dict
        Sensor parameters on top of the scene's preset and ``[sensor]`` table.
    record : dict
        The frame's manifest entry without its files: id, index, repeat, scene, every resolved parameter, seed
        (a new dict at each access).
    """

    index: int
    id: str
    seed: int
    group: FrameGroup
    values: tuple

    @property
    def scene_path(self) -> str:
        return self.group.scene_path

    @property
    def width(self) -> int:
        return self.group.width

    @property
    def height(self) -> int:
        return self.group.height

    @property
    def illuminant(self) -> str:
        return self.group.illuminant

    @property
    def intensity_factor(self) -> float:
        return self.values[_FACTOR]

    @property
    def scene_changes(self) -> dict:
        return self.group.scene_changes

    @property
    def sensor_overrides(self) -> dict:
        overrides = dict(self.group.sensor_overrides)
        overrides.update(zip(self.group.sensor_keys, self.values[_FACTOR + 1:]))
        return overrides

    @property
    def image(self) -> ImageCrop | None:
        """The crop of an ``[images]`` folder's image that is the frame's scene, or None (the scene file's own)."""
        folder = self.group.image_folder
        if folder is None:
            return None
        name, _, x, y, flip_h, flip_v = self.values[-len(IMAGE_KEYS):]
        return ImageCrop(path=str(Path(folder) / name), x=x, y=y, width=self.width, height=self.height,
                         flip_horizontal=flip_h, flip_vertical=flip_v)

    @property
    def raw(self):
        """The crop of a raw file of a ``[raws]`` folder that is the frame's source
        (:class:`camsim.dataset.raws.RawCrop`), or None."""
        if self.group.raws is None:
            return None
        from camsim.dataset.raws import RawCrop

        name, digest, x, y, flip_h, flip_v = self.values[-len(RAW_KEYS):]
        return RawCrop(path=str(Path(self.group.raws.folder) / name), x=x, y=y, width=self.width,
                       height=self.height, flip_horizontal=flip_h, flip_vertical=flip_v)

    @property
    def record(self) -> dict:
        record = {"id": self.id, "index": self.index, **self.group.record}
        record.update(zip(self.group.value_keys, self.values))
        record["seed"] = self.seed
        return record

    def get(self, key: str):
        """``record[key]``, without making the record (``KeyError`` for a key it does not have)."""
        if key in ("id", "index", "seed"):
            return getattr(self, key)
        keys = self.group.value_keys
        return self.values[keys.index(key)] if key in keys else self.group.record[key]

    @property
    def burst(self) -> SequenceParams | None:
        """The frame's burst (:data:`BURST_PARAMS`: its frames and camera motion), or None: one frame."""
        return self.group.scene_changes.get("sequence")

    @property
    def megapixels(self) -> float:
        return self.width * self.height / 1e6 * (1 if self.burst is None else self.burst.frames)


def _size_text(sizes) -> str:
    """``WxH`` of frames of one size, or ``mixed sizes``."""
    sizes = set(sizes)
    if len(sizes) != 1:
        return "mixed sizes"
    (width, height), = sizes
    return f"{width}x{height}"


@dataclass(frozen=True)
class DatasetSpec:
    """A parsed, validated dataset spec and its frame list."""

    name: str
    path: Path
    seed: int
    width: int
    height: int
    frames: tuple
    axes: dict  # parameter -> "fixed" | "grid" | "random" | "scene": how it is set
    exr_compression: str | None = None  # the spec's exr_compression, if it sets one (the files, not the frames)
    srgb: str | None = None  # the spec's srgb (SRGB_OUTPUTS), if it sets one (outputs, not the frames)

    def __len__(self) -> int:
        return len(self.frames)

    @property
    def size_text(self) -> str:
        """``WxH`` of the frames (a cube scene's frames have the cube's size), or ``mixed sizes``."""
        return _size_text((f.width, f.height) for f in self.frames)


@dataclass(frozen=True)
class SpecPlan:
    """A parsed spec before its frames are made: what :func:`load_spec` knows before the first frame.

    :meth:`frames` makes and validates the frames one by one, in order (a frame that camsim cannot render raises
    :class:`CamsimError` when it is reached); :meth:`spec` makes them all.
    """

    name: str
    path: Path
    seed: int
    width: int
    height: int
    axes: dict  # parameter -> "fixed" | "grid" | "random" | "scene": how it is set
    count: int  # frames
    sizes: tuple  # the frames' (width, height), without repetition
    make_frames: Callable[[], Iterator[FrameSpec]] = field(repr=False, compare=False)
    exr_compression: str | None = None  # the spec's exr_compression, if it sets one (the files, not the frames)
    srgb: str | None = None  # the spec's srgb (SRGB_OUTPUTS), if it sets one (outputs, not the frames)

    def __len__(self) -> int:
        return self.count

    @property
    def size_text(self) -> str:
        """``WxH`` of the frames (a cube scene's frames have the cube's size), or ``mixed sizes``."""
        return _size_text(self.sizes)

    def frames(self) -> Iterator[FrameSpec]:
        """The frames, in order, each validated as it is made."""
        return self.make_frames()

    def spec(self) -> DatasetSpec:
        """The spec with every frame made and validated."""
        return DatasetSpec(name=self.name, path=self.path, seed=self.seed, width=self.width, height=self.height,
                           frames=tuple(self.frames()), axes=self.axes, exr_compression=self.exr_compression,
                           srgb=self.srgb)


# --- values --------------------------------------------------------------------------------------------------


def _coerce(name: str, value, where: str):
    """One parameter value, type-checked and typed (ints to floats where needed) by the schema; its range is
    checked when the frame's scene and sensor are built."""
    return PARAMETERS[name].coerce(value, where, check_range=False)


def _canonical(value) -> str:
    return json.dumps(value, sort_keys=True, separators=(",", ":"), allow_nan=False, ensure_ascii=True)


def _canonical_scalar(value) -> str:
    """:func:`_canonical` of a value, faster for the finite floats and the ints of a frame's own values."""
    kind = type(value)
    if kind is float and math.isfinite(value):
        return float.__repr__(value)  # what json writes
    if kind is int:
        return int.__repr__(value)
    return _canonical(value)


def _draw(name: str, dist: dict, n: int, seed: int, where: str) -> list:
    """``n`` draws of a parameter from its distribution, from the parameter's own stream."""
    if not isinstance(dist, dict) or len(dist) != 1:
        raise CamsimError(f"{where}: {name} must be a table with one distribution, e.g. "
                          f"{name} = {{ uniform = [a, b] }}; distributions: {', '.join(DISTRIBUTIONS)}")
    (kind, args), = dist.items()
    if kind not in DISTRIBUTIONS:
        raise CamsimError(f"{where}: unknown distribution {kind!r} for {name}; distributions: "
                          f"{', '.join(DISTRIBUTIONS)}")
    if not isinstance(args, list) or not args:
        raise CamsimError(f"{where}: {name} {kind} needs a list, got {args!r}")
    param_kind = PARAMETERS[name].kind
    if kind == "choice":
        values = [_coerce(name, v, where) for v in args]
    else:
        if len(args) != 2:
            raise CamsimError(f"{where}: {name} {kind} needs [low, high], got {args!r}")
        low, high = args
        if kind == "integers":
            if param_kind != "int" or any(isinstance(v, bool) or not isinstance(v, int) for v in args):
                raise CamsimError(f"{where}: {kind} draws integers: {name} is {param_kind}, bounds {args!r}")
        else:
            if param_kind not in ("float", "rgb"):
                raise CamsimError(f"{where}: {name} takes {param_kind} values; use choice (or integers) instead of "
                                  f"{kind}")
            low, high = (_coerce(name, v, where) for v in args)
            if isinstance(low, list) or isinstance(high, list):
                raise CamsimError(f"{where}: {name} {kind} bounds must be numbers")
        if not low <= high:
            raise CamsimError(f"{where}: {name} {kind} needs low ≤ high, got {args!r}")
        if kind == "log_uniform" and not low > 0:
            raise CamsimError(f"{where}: {name} log_uniform needs positive bounds, got {args!r}")
    # uniform variates only, consumed one per frame: a longer list starts with the shorter one's values
    u = dataset_parameter_generator(seed, name).random(n)
    if kind == "uniform":
        return [float(low + (high - low) * x) for x in u]
    if kind == "log_uniform":
        a, b = math.log(low), math.log(high)
        return [float(min(high, max(low, math.exp(a + (b - a) * x)))) for x in u]
    if kind == "integers":
        span = high - low + 1
        return [int(low + min(span - 1, int(x * span))) for x in u]
    return [values[min(len(values) - 1, int(x * len(values)))] for x in u]


# --- the spec file -------------------------------------------------------------------------------------------


def _table(doc: dict, key: str, where: str) -> dict:
    table = doc.get(key, {})
    if not isinstance(table, dict):
        raise CamsimError(f"{where}: [{key}] must be a table")
    return table


def _param_names(table: dict, key: str, where: str, aliases: dict | None = None, extra: set = frozenset()) -> dict:
    """{canonical parameter name: spec key} of a parameter table; unknown keys are errors."""
    names = {}
    for spec_key in table:
        if spec_key in extra:
            continue
        name = (aliases or {}).get(spec_key, spec_key)
        if name not in PARAMETERS:
            known = sorted(PARAMETERS) + sorted(aliases or {}) + sorted(extra)
            raise CamsimError(f"{where}: unknown key {spec_key!r} in [{key}]; known: {', '.join(known)}")
        if name in names:
            raise CamsimError(f"{where}: [{key}] sets {name} twice ({names[name]!r} and {spec_key!r})")
        names[name] = spec_key
    return names


def _scene_sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


@dataclass(frozen=True)
class _ImageFolder:
    """An ``[images]`` table, checked: the folder as the spec gives it and its absolute path, its image files
    (name relative to the folder, width, height, SHA-256), the crop size and whether frames are flipped."""

    text: str
    folder: Path
    files: tuple  # (name, width, height, sha256)
    width: int
    height: int
    flips: bool


@dataclass(frozen=True)
class FolderTable:
    """The checks an ``[images]`` or a ``[raws]`` table shares: its folder (as the spec gives it, ``text``, and
    absolute), the files in it (sorted by their name relative to the folder), the crop size and the flips."""

    text: str
    folder: Path
    paths: tuple
    width: int
    height: int
    flips: bool


def folder_table(table, base: Path, where: str, name: str, keys: tuple, suffixes: tuple, what: str,
                 example: str, even: bool = False) -> FolderTable:
    """Check the keys a folder table (``[name]``: ``[images]``, ``[raws]``) shares and list its files.

    ``keys`` are the table's keys, ``suffixes`` the file suffixes searched for without a ``pattern``, ``what`` the
    files' kind in messages ("image", "raw"), ``example`` a suffix for the messages' globs; ``even``: the crop is whole
    2 × 2 cells. A pattern is a glob relative to the folder and never leaves it.

    Raises
    ------
    CamsimError
        An unknown key, a value of the wrong type, a missing folder or one without such files.
    """
    at = f"{where}: [{name}]"
    if not isinstance(table, dict):
        raise CamsimError(f"{at} must be a table")
    unknown = set(table) - set(keys)
    if unknown:
        raise CamsimError(f"{where}: unknown key(s) in [{name}]: {', '.join(sorted(unknown))}; "
                          f"known: {', '.join(keys)}")
    text = table.get("folder")
    if not isinstance(text, str) or not text:
        raise CamsimError(f"{at} needs folder = \"FOLDER\" (of {what} files, relative to the spec)")
    pattern = table.get("pattern")
    if pattern is not None and (not isinstance(pattern, str) or not pattern):
        raise CamsimError(f"{at} pattern must be a glob pattern such as \"*{example}\", got {pattern!r}")
    if pattern is not None and (PurePosixPath(pattern).is_absolute() or ".." in PurePosixPath(pattern).parts):
        raise CamsimError(f"{at} pattern {pattern!r} must stay inside the folder: a glob relative to it "
                          f"(\"*{example}\", \"**/*{example}\"), without '..'; another folder is folder = \"...\"")
    crop = table.get("crop")
    low = 2 if even else 1
    if (not isinstance(crop, list) or len(crop) != 2
            or any(isinstance(v, bool) or not isinstance(v, int) or v < low or (even and v % 2) for v in crop)):
        kind = ("even positive integers in pixels: whole 2x2 cells of the colour filter array" if even
                else "positive integers in pixels")
        raise CamsimError(f"{at} needs crop = [width, height] (the frame size, {kind}), got {crop!r}")
    width, height = crop
    check_frame_size(width, height, f"{at} crop")
    flips = table.get("flips", False)
    if not isinstance(flips, bool):
        raise CamsimError(f"{at} flips must be true or false, got {flips!r}")
    folder = (base / text).resolve()
    if not folder.is_dir():
        raise CamsimError(f"{at} folder {text!r} is not a folder ({folder})")
    if pattern is None:
        paths = [p for p in folder.iterdir() if p.suffix.lower() in suffixes and not p.name.startswith(".")]
    else:
        try:
            paths = list(folder.glob(pattern))
        except (ValueError, NotImplementedError) as exc:  # e.g. "**" inside a component
            raise CamsimError(f"{at} pattern {pattern!r} is not a glob pattern: {exc}") from None
    paths = sorted((p for p in paths if p.is_file()), key=lambda p: p.relative_to(folder).as_posix())
    if not paths:
        wanted = f"matching {pattern!r}" if pattern is not None else f"({', '.join(suffixes)}, any case)"
        raise CamsimError(f"{at} folder {folder} holds no {what} files {wanted}")
    return FolderTable(text, folder, tuple(paths), width, height, flips)


def _images(table, base: Path, where: str) -> _ImageFolder:
    """Read and check an ``[images]`` table (:func:`folder_table`): its folder, the images in it and the crop size.

    Raises
    ------
    CamsimError
        An unknown key, a value of the wrong type, a missing or empty folder, a file that is not an image camsim
        reads, or an image smaller than the crop (naming the file).
    """
    checked = folder_table(table, base, where, "images", IMAGES_TABLE_KEYS, IMAGE_SUFFIXES, "image", ".png")
    folder, paths, width, height, flips, text = (checked.folder, checked.paths, checked.width, checked.height,
                                                 checked.flips, checked.text)
    files = []
    for path in paths:
        name = path.relative_to(folder).as_posix()
        try:
            file_width, file_height = ImageSource(path=path).own_size()
        except CamsimError as exc:
            raise CamsimError(f"{where}: [images] {exc}") from None
        if file_width < width or file_height < height:
            raise CamsimError(f"{where}: [images] image {path} is {file_width}x{file_height} pixels, smaller than "
                              f"the crop {width}x{height}")
        files.append((name, file_width, file_height, _scene_sha256(path)))
    return _ImageFolder(text=text, folder=folder, files=tuple(files), width=width, height=height, flips=flips)


def _image_draws(images: _ImageFolder, n: int, seed: int) -> list:
    """The image values (:data:`IMAGE_KEYS`) of ``n`` grid-point draws: an image, the crop's offset and the flips,
    each from its own stream (uniform variates, one per draw: a longer list starts with the shorter one's)."""
    streams = {name: dataset_parameter_generator(seed, f"images.{name}").random(n)
               for name in ("file", "x", "y", "flip_horizontal", "flip_vertical")}
    count = len(images.files)
    draws = []
    for u_file, u_x, u_y, u_h, u_v in zip(*streams.values()):
        name, file_width, file_height, digest = images.files[min(count - 1, int(u_file * count))]
        span_x, span_y = file_width - images.width + 1, file_height - images.height + 1
        x, y = min(span_x - 1, int(u_x * span_x)), min(span_y - 1, int(u_y * span_y))
        draws.append((name, digest, x, y, bool(images.flips and u_h < 0.5), bool(images.flips and u_v < 0.5)))
    return draws


def load_spec(path: str | Path) -> DatasetSpec:
    """Read a dataset spec (a file, or a built-in spec's name: ``denoise_small``), build its frame list and validate
    every frame before anything is rendered.

    Raises
    ------
    CamsimError
        A missing or malformed file, an unknown key, a value of the wrong type or range, a name that does not
        resolve (scene, illuminant, camera, preset) or a frame camsim cannot render.
    """
    return plan_spec(path).spec()


def check_srgb(value) -> str:
    """``value`` if it is one of :data:`SRGB_OUTPUTS`, else :class:`CamsimError`."""
    if value not in SRGB_OUTPUTS:
        raise CamsimError(f"sRGB output must be one of {', '.join(SRGB_OUTPUTS)}, got {value!r}")
    return value


def _checked_key(doc: dict, key: str, check, where: str):
    """The spec's ``key`` (None when absent), checked by ``check``; its error names the spec and the key."""
    value = doc.get(key)
    if value is not None:
        try:
            check(value)
        except CamsimError as exc:
            raise CamsimError(f"{where}: {key}: {exc}") from None
    return value


def _parameter_tables(doc: dict, where: str) -> tuple:
    """The spec's ``[fixed]``, ``[grid]`` and ``[random]`` tables, checked: (axes, fixed, grid, random table,
    random names, count), ``axes`` saying where each parameter is set."""
    fixed_table = _table(doc, "fixed", where)
    grid_table = _table(doc, "grid", where)
    random_table = _table(doc, "random", where)
    fixed_names = _param_names(fixed_table, "fixed", where)
    grid_names = _param_names(grid_table, "grid", where, GRID_ALIASES)
    random_names = _param_names(random_table, "random", where, extra={"count"})
    axes = {}
    for source, names in (("fixed", fixed_names), ("grid", grid_names), ("random", random_names)):
        for param in names:
            if param in axes:
                raise CamsimError(f"{where}: {param} is set in both [{axes[param]}] and [{source}]")
            axes[param] = source

    fixed = {p: _coerce(p, fixed_table[k], f"{where} [fixed]") for p, k in fixed_names.items()}
    grid = {}
    for param, key in grid_names.items():
        values = grid_table[key]
        if not isinstance(values, list) or not values:
            raise CamsimError(f"{where}: [grid] {key} must be a non-empty list (use [fixed] for one value)")
        values = [_coerce(param, v, f"{where} [grid]") for v in values]
        canon = [_canonical(v) for v in values]
        if len(set(canon)) != len(canon):
            raise CamsimError(f"{where}: [grid] {key} lists a value twice (use repeats for more noisy "
                              "realisations of the same parameters)")
        grid[param] = values
    count = 1
    if random_table:
        count = random_table.get("count")
        if isinstance(count, bool) or not isinstance(count, int) or count < 1:
            raise CamsimError(f"{where}: [random] needs count = N (frames per grid point, an integer ≥ 1), "
                              f"got {count!r}")

    return axes, fixed, grid, random_table, random_names, count


def _refuse_raws_params(axes: dict, where: str) -> None:
    """Refuse the parameters of ``[raws]`` frames (:data:`RAWS_PARAMS`) in a spec without ``[raws]``."""
    for p in RAWS_PARAMS:
        if p.name in axes:
            raise CamsimError(f"{where}: [{axes[p.name]}] {p.name} applies to the frames of a [raws] spec (crops of "
                              "raw files) only")


def plan_spec(path: str | Path) -> SpecPlan:
    """Read and check a dataset spec (a file, or a built-in spec's name), its scenes (files relative to the spec,
    or built-in scenes' names) and its random draws; the frames are made by :meth:`SpecPlan.frames`, one by one
    (each validated as it is made).

    Raises
    ------
    CamsimError
        A missing or malformed file, an unknown key, a value of the wrong type, a name that does not resolve
        (scene) or more than :data:`MAX_FRAMES` frames.
    """
    path = resolve_spec_file(path)
    where = str(path)
    doc = read_toml(path, "dataset spec")
    unknown = set(doc) - _TOP_KEYS
    if unknown:
        raise CamsimError(f"{where}: unknown top-level key(s): {', '.join(sorted(unknown))}; "
                          f"known: {', '.join(sorted(_TOP_KEYS))}")
    base = path.resolve().parent

    name = safe_component(doc.get("name", path.stem), f"{where}: name")  # it names the default output folder
    if not isinstance(doc.get("description", ""), str):
        raise CamsimError(f"{where}: description must be a string")
    seed = doc.get("seed", 0)
    if isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed <= INT64_MAX:
        raise CamsimError(f"{where}: seed must be an integer from 0 to 2⁶³ − 1, got {seed!r}")
    repeats = doc.get("repeats", 1)
    if isinstance(repeats, bool) or not isinstance(repeats, int) or repeats < 1:
        raise CamsimError(f"{where}: repeats must be an integer ≥ 1, got {repeats!r}")
    exr_compression = _checked_key(doc, "exr_compression", check_exr_compression, where)
    srgb = _checked_key(doc, "srgb", check_srgb, where)
    if "raws" in doc:  # crops of a folder of raw files: their own camera and light
        from camsim.dataset.raws import plan_raws

        return plan_raws(doc, path, base, name=name, seed=seed, repeats=repeats, exr_compression=exr_compression,
                         srgb=srgb)
    scene_files = doc.get("scene")
    if scene_files is None:
        raise CamsimError(f"{where}: needs scene = \"SCENE.toml\" (or a list of scene files)")
    scene_files = scene_files if isinstance(scene_files, list) else [scene_files]
    if not scene_files or not all(isinstance(s, str) for s in scene_files):
        raise CamsimError(f"{where}: scene must be a scene file name or a non-empty list of them")
    if len(set(scene_files)) != len(scene_files):
        raise CamsimError(f"{where}: scene lists a file twice")

    frame = _table(doc, "frame", where)
    unknown = set(frame) - {"width", "height"}
    if unknown:
        raise CamsimError(f"{where}: unknown key(s) in [frame]: {', '.join(sorted(unknown))}; known: width, height")
    width, height = frame.get("width", DEFAULT_WIDTH), frame.get("height", DEFAULT_HEIGHT)
    check_frame_size(width, height, f"{where}: [frame]")

    images = None
    if "images" in doc:
        if "frame" in doc:
            raise CamsimError(f"{where}: [frame] sets a size, but the frames are [images] crops, whose size is "
                              "[images] crop = [width, height]")
        images = _images(doc["images"], base, where)
        width, height = images.width, images.height

    axes, fixed, grid, random_table, random_names, count = _parameter_tables(doc, where)
    _refuse_raws_params(axes, where)

    scenes = []
    for scene_file in scene_files:
        try:  # a file beside the spec, else a built-in scene's name ("macbeth_26")
            scene_path = resolve_scene_file(scene_file, base).resolve()
        except CamsimError as exc:
            raise CamsimError(f"{where}: scene: {exc}") from None
        scene = load_scene(scene_path)
        if images is not None:  # the first image's first crop stands for every crop in the checks
            first = images.folder / images.files[0][0]
            scene = scene.replace(source=ImageSource(path=first, crop=(0, 0, width, height)))
            width_px, height_px = width, height
        elif scene.source.has_own_size and "frame" in doc:
            raise CamsimError(f"{where}: [frame] sets a size, but {scene_file} is a {scene.source.table} scene, "
                              "whose size is its own")
        elif scene.source.has_own_size:  # a cube's size is its own: read it from the file's header
            try:
                width_px, height_px = scene.source.own_size()
            except CamsimError as exc:
                raise CamsimError(f"{where}: {exc}") from None
        else:
            width_px, height_px = width, height
        scenes.append(_SceneEntry(scene_file, scene_path, scene.replace(width=int(width_px), height=int(height_px)),
                                  _scene_sha256(scene_path), _scene_axes(scene, axes, grid)))

    # the frame list: per scene, its inherited axes, then [grid] in file order; then the draws and repeats
    points = sum(math.prod(len(v) for v in entry.axes.values()) * count for entry in scenes)
    if points * repeats > MAX_FRAMES:
        raise CamsimError(f"{where}: more than {MAX_FRAMES} frames")
    for param in ("illuminant", "intensity_factor"):
        axes.setdefault(param, "scene")
    if any(entry.scene.sequence is not None for entry in scenes):  # a scene file's [sequence]: bursts
        axes.setdefault("burst_frames", "scene")
    random_values = {p: _draw(p, random_table[k], points, seed, f"{where} [random]")
                     for p, k in random_names.items()}
    if "virtual_camera" in doc:  # each grid point and draw: a camera, its K and its noise scales
        drawn = _virtual_cameras(doc["virtual_camera"], points, seed, axes, where)
        random_values.update({key: [d[key] for d in drawn] for key in VIRTUAL_KEYS})
        axes.update(dict.fromkeys(VIRTUAL_KEYS, "virtual_camera"))
    varied = {p for p, how in axes.items() if how != "fixed"}
    own_sensor = tuple(p.name for p in SENSOR_PARAMS if p.name in varied and p.name in OWN_VALUE_PARAMS)
    if images is not None:
        shown = ("image_file", "crop_x", "crop_y") + (("flip_horizontal", "flip_vertical") if images.flips else ())
        axes.update(dict.fromkeys(shown, "images"))
    job = _Job(where=where, base=base, seed=seed, repeats=repeats, count=count, scenes=tuple(scenes), fixed=fixed,
               random_values=random_values,
               value_keys=("repeat", "intensity_factor", *own_sensor, *(IMAGE_KEYS if images else ())),
               id_digits=max(ID_DIGITS, len(str(points * repeats - 1))), images=images,
               image_values=_image_draws(images, points, seed) if images is not None else None)
    sizes = tuple(dict.fromkeys((entry.scene.width, entry.scene.height) for entry in scenes))
    return SpecPlan(name=name, path=path, seed=seed, width=width, height=height, axes=axes, count=points * repeats,
                    sizes=sizes, make_frames=partial(_frames, job), exr_compression=exr_compression,
                    srgb=srgb)


def _virtual_cameras(table, points: int, seed: int, axes: dict, where: str) -> list:
    """The ``[virtual_camera]`` draws (:func:`camsim.sensor.presets.virtual.draw_virtual_cameras`), one per grid
    point and draw, each parameter from its own stream (``virtual_camera.camera``, ``.k``, ``.shape`` and one per
    noise quantity)."""
    from camsim.sensor.presets import CAMERA_PRESETS
    from camsim.sensor.presets.virtual import K_RANGES, cameras_with_fits, draw_virtual_cameras

    at = f"{where} [virtual_camera]"
    if not isinstance(table, dict):
        raise CamsimError(f"{where}: [virtual_camera] must be a table")
    unknown = set(table) - set(VIRTUAL_CAMERA_TABLE_KEYS)
    if unknown:
        raise CamsimError(f"{at}: unknown key(s) {', '.join(sorted(unknown))}; known: "
                          f"{', '.join(VIRTUAL_CAMERA_TABLE_KEYS)}")
    clash = sorted(set(VIRTUAL_KEYS) & set(axes))
    if clash:
        raise CamsimError(f"{at} sets {', '.join(clash)}, which [{axes[clash[0]]}] sets too")
    usable = cameras_with_fits(CAMERA_PRESETS)
    names = table.get("cameras", "all")
    names = list(cameras_with_fits(CAMERA_PRESETS, distinct=True)) if names == "all" else names
    if not isinstance(names, list) or not names or not all(isinstance(n, str) for n in names):
        raise CamsimError(f"{at}: cameras must be \"all\" or a non-empty list of camera presets with noise fits "
                          f"({', '.join(usable)})")
    bad = [n for n in names if n not in usable]
    if bad:
        raise CamsimError(f"{at}: {', '.join(bad)} cannot be drawn from (no noise fits); cameras with fits: "
                          f"{', '.join(usable)}")
    k_range = table.get("k_range", "camera")
    if k_range not in K_RANGES:
        raise CamsimError(f"{at}: k_range must be one of {', '.join(K_RANGES)}, got {k_range!r}")
    model = table.get("read_noise_model")
    if model is not None:
        model = _coerce("read_noise_model", model, at)
    streams = {name: dataset_parameter_generator(seed, f"virtual_camera.{name}")
               for name in ("camera", "k", "shape", "tukey_scale_dn", "gaussian_sigma_dn", "row_sigma_dn")}
    return draw_virtual_cameras([CAMERA_PRESETS[n] for n in names], points, streams, k_range, model)


# --- the frames ----------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class _SceneEntry:
    """A scene file of the spec: its name as the spec gives it, its path, the scene at the frame size, the file's
    SHA-256 and the axes of its frames (the scene's inherited lists, then [grid])."""

    file: str
    path: Path
    scene: Scene
    digest: str
    axes: dict


def _scene_axes(scene: Scene, axes: dict, grid: dict) -> dict:
    """The axes of a scene's frames: its illuminant and intensity factor lists unless the spec sets them, then
    the spec's [grid] (the last one varies fastest)."""
    here = {}
    if "illuminant" not in axes:
        here["illuminant"] = list(scene.illuminants)
    if "intensity_factor" not in axes:
        here["intensity_factor"] = list(scene.intensity_factors)
    here.update(grid)
    return here


@dataclass(frozen=True)
class _Job:
    """What :func:`_frames` needs to make the frames of a spec."""

    where: str
    base: Path
    seed: int
    repeats: int
    count: int  # random draws per grid point
    scenes: tuple  # _SceneEntry
    fixed: dict
    random_values: dict  # parameter -> one value per grid point and draw
    value_keys: tuple  # the frames' own values (FrameSpec.values)
    id_digits: int
    images: _ImageFolder | None = None
    image_values: list | None = None  # IMAGE_KEYS' values of each grid point and draw

    @property
    def sensor_keys(self) -> tuple:
        """The own values that are sensor parameters (:attr:`FrameGroup.sensor_keys`)."""
        return self.value_keys[_FACTOR + 1:len(self.value_keys) - (len(IMAGE_KEYS) if self.images else 0)]


def _frames(job, frame_values=None) -> Iterator[FrameSpec]:
    """Make the frames of a spec, in order, a batch at a time (their seeds are computed together): those of
    ``frame_values(job)`` (index, own values, group), by default :func:`_frame_values`' (a ``[raws]`` spec's:
    :func:`camsim.dataset.raws._raw_frame_values`)."""
    batch = []
    for index, values, group in (frame_values or _frame_values)(job):
        digest = hashlib.sha256(group.canonical(values).encode("ascii")).hexdigest()[:10]
        batch.append((f"{index:0{job.id_digits}d}-{digest}", index, values, group))
        if len(batch) == _BATCH:
            yield from _seeded(batch, job.seed)
            batch = []
    yield from _seeded(batch, job.seed)


def _seeded(batch: list, spec_seed: int) -> Iterator[FrameSpec]:
    """The frames of ``batch`` (id, index, values, group), with their seeds."""
    seeds = dataset_frame_seeds(spec_seed, [frame_id for frame_id, *_ in batch])
    for (frame_id, index, values, group), seed in zip(batch, seeds):
        yield FrameSpec(index=index, id=frame_id, seed=seed, group=group, values=values)


def _frame_values(job: _Job) -> Iterator[tuple]:
    """Resolve and validate the frames of a spec, in order: (index, own values, group) of each; the frames that
    differ only in their own values share a FrameGroup."""
    groups: dict = {}
    checks: dict = {}  # the _FrameCheck of each group
    checked: dict = {}  # memo of the costly checks (illuminants, cameras, lit scenes), across groups
    own_sensor = job.sensor_keys
    point = index = 0
    for s, entry in enumerate(job.scenes):
        names = tuple(entry.axes)
        shared_axes = [i for i, n in enumerate(names) if n not in OWN_VALUE_PARAMS]  # they tell groups apart
        shared_random = [p for p in job.random_values if p not in OWN_VALUE_PARAMS]
        for combo in itertools.product(*(range(len(v)) for v in entry.axes.values())):
            combo_params = {**job.fixed, **{n: entry.axes[n][i] for n, i in zip(names, combo)}}
            combo_key = (s, *(combo[i] for i in shared_axes))
            for _ in range(job.count):
                params = dict(combo_params)
                params.update({p: values[point] for p, values in job.random_values.items()})
                key = (combo_key, *(_canonical(params[p]) for p in shared_random))
                image = job.image_values[point] if job.image_values is not None else ()
                point += 1
                try:
                    factor = check_intensity_factor(params["intensity_factor"])
                    own = tuple(PARAMETERS[p].coerce(params[p], "sensor parameter") for p in own_sensor)
                    group = groups.get(key)
                    if group is None:
                        group, checks[key] = _resolve(params, entry, job, checked)
                        groups[key] = group
                    checks[key](factor, own)
                except CamsimError as exc:
                    label = f"{job.where}: frame {index} ({', '.join(f'{k}={v!r}' for k, v in params.items())})"
                    raise CamsimError(f"{label}: {exc}") from None
                for repeat in range(job.repeats):
                    yield index, (repeat, factor, *own, *image), group
                    index += 1


@dataclass
class _FrameCheck:
    """Checks the frames of one group as drawing each checks it first (:func:`camsim.render.pipeline.check_frame`: its
    expected signal finite, its values within float32, its exposure within a DNG's), so that a frame the run would
    refuse is refused when the spec is planned, by the dry run too. The group's lit scene stands for its frames' (an ``[images]`` spec's first
    crop for every crop, as in the other checks).

    With a fixed exposure every mean grows with F, so a frame with the same own sensor values as the last one
    checked, at no larger F, passes as that one did: a spec that varies only the light checks a handful of frames.
    """

    scene: Scene
    lit: object  # camsim.render.pipeline.LitScene
    sensor_keys: tuple
    last: tuple | None = None  # (own sensor values, the largest F checked with them)

    def __call__(self, factor: float, own: tuple) -> None:
        if (self.scene.exposure == "fixed" and self.last is not None and self.last[0] == own
                and factor <= self.last[1]):
            return
        sensor = with_checked_values(self.scene.sensor, **dict(zip(self.sensor_keys, own))) if own else None
        sensor = frame_sensor(self.scene, self.lit, factor, sensor)
        check_frame(self.lit, sensor, factor, self.scene.statistics)
        if self.scene.sequence is not None:  # a burst: each exposure (and a rolling shutter's readout) in its interval
            check_timing(self.scene.sequence, sensor.exposure_s, self.lit.labels.shape[0])
        if self.last is None or self.last[0] != own or factor > self.last[1]:
            self.last = (own, factor)


def burst_sequence(params: dict, scene: Scene) -> SequenceParams | None:
    """The burst of a frame with ``params`` (:data:`BURST_PARAMS`), each parameter the spec does not set taken from
    the scene file's ``[sequence]`` (else its default); None without ``burst_frames`` (and without a ``[sequence]``).

    Raises
    ------
    CamsimError
        A burst parameter out of range, motion set without ``burst_frames``, ``burst_frames`` that differs from the
        count of the scene's ``homographies``.
    """
    base = scene.sequence
    given = {p.name: p.coerce(params[p.name], "burst") for p in BURST_PARAMS if p.name in params}
    frames = given.get("burst_frames", base.frames if base is not None and "burst_frames" not in params else None)
    if frames is None:
        motion = sorted(k for k in given if k != "burst_frames")
        if motion:
            raise CamsimError(f"{', '.join(motion)} set a burst's motion, but burst_frames is not set (the frames "
                              "of each burst)")
        return None
    defaults = base if base is not None else SequenceParams(frames=frames)
    pan = (given.get("pan_x_px_per_s", defaults.pan_px_per_s[0]),
           given.get("pan_y_px_per_s", defaults.pan_px_per_s[1]))
    homographies = defaults.homographies if base is not None else None
    if homographies is not None and len(homographies) != frames:
        raise CamsimError(f"burst_frames {frames} differs from the {len(homographies)} homographies of the scene "
                          "file's [sequence]")
    try:
        return SequenceParams(frames=frames, pan_px_per_s=pan, homographies=homographies,
                              **{k: given.get(k, getattr(defaults, k))
                                 for k in ("frame_interval_s", "shake_px", "shake_deg", "blur_subsamples",
                                           *_LIGHT_AND_SHUTTER)})
    except CamsimError as exc:
        raise CamsimError(str(exc).replace("[sequence]: frames ", "burst_frames ").replace("[sequence]", "burst")) \
            from None


def burst_record(burst: SequenceParams) -> dict:
    """A burst frame's record keys (:data:`BURST_PARAMS`' names; ``burst_homographies`` where the scene file's
    ``[sequence]`` lists them)."""
    out = {"burst_frames": burst.frames, "frame_interval_s": burst.frame_interval_s, "shake_px": burst.shake_px,
           "shake_deg": burst.shake_deg, "pan_x_px_per_s": burst.pan_px_per_s[0],
           "pan_y_px_per_s": burst.pan_px_per_s[1], "blur_subsamples": burst.blur_subsamples,
           **{k: getattr(burst, k) for k in _LIGHT_AND_SHUTTER if getattr(burst, k)}}  # only where set: ids kept
    if burst.homographies is not None:
        out["burst_homographies"] = [list(map(list, h)) for h in burst.homographies]
    return out


def frame_sensor_overrides(params: dict, base: Path) -> dict:
    """The sensor parameters a frame's ``params`` set, map files (``dark_shading_map``, ``hot_pixel_map``) taken
    relative to the spec's folder ``base``, as a scene file's are to it."""
    overrides = {p.name: params[p.name] for p in SENSOR_PARAMS if p.name in params}
    for key in MAP_FILE_PARAMS:
        if overrides.get(key) is not None:
            overrides[key] = str((base / Path(overrides[key]).expanduser()).resolve())
    return overrides


def _resolve(params: dict, entry: _SceneEntry, job: _Job, checked: dict) -> tuple[FrameGroup, _FrameCheck]:
    """Resolve and validate the scene and sensor of a frame with ``params``: its group's, and the check of the
    group's frames."""
    changes = {"illuminants": (params["illuminant"],)}
    for key in RENDER_KEYS:  # the scene's render settings a spec may set
        if key in params:
            changes[key] = params[key]
    if "camera" in params:  # a camera CSV named in the spec is relative to the spec
        camera = params["camera"]
        changes["camera"] = str((job.base / camera).resolve()) if camera.lower().endswith(".csv") else camera
    if "preset" in params:
        camera = params["preset"]  # a camera preset file named in the spec is relative to the spec
        changes["preset_name"] = str((job.base / camera).resolve()) if camera.lower().endswith(".toml") else camera
    if params.get("iso") is not None:
        changes["iso"] = params["iso"]
    overrides = frame_sensor_overrides(params, job.base)
    scene = entry.scene
    burst = burst_sequence(params, scene)
    if burst is not None or scene.sequence is not None:
        changes["sequence"] = burst  # None: a scene file's [sequence] that the spec turns off (burst_frames = "none")
    frame_scene = scene.replace(intensity_factors=(params["intensity_factor"],), **changes)
    if overrides:
        frame_scene = frame_scene.with_sensor(**overrides)
    sensor = frame_scene.sensor
    if job.images is not None and sensor.quantisation and min(scene.width, scene.height) < MIN_SIZE:
        raise CamsimError(f"[images] crop {scene.width}x{scene.height} is smaller than {MIN_SIZE}x{MIN_SIZE} "
                          "pixels, which raw readers (LibRaw) refuse")
    key = ("scene", str(entry.path), frame_scene.illuminants, frame_scene.method, sensor.quantisation)
    if key not in checked:
        check_scene(frame_scene)
        checked[key] = True
    if burst is not None:
        from camsim.render.sequence import check_sequence_scene

        check_sequence_scene(frame_scene)
    key = ("camera", str(entry.path), frame_scene.camera)
    if key not in checked:
        checked[key] = load_camera(frame_scene.camera, frame_scene.grid, frame_scene.sensitivity_basis,
                                   frame_scene.base_dir)
    camera = checked[key]
    key = ("lit", str(entry.path), scene.width, scene.height, params["illuminant"], frame_scene.camera)
    if key not in checked:
        checked[key] = light_scene(frame_scene, params["illuminant"], camera)
    check = _FrameCheck(frame_scene, checked[key], job.sensor_keys)
    own_size = frame_scene.source.has_own_size and job.images is None  # a cube's: its own, checked when read
    if sensor.cfa is not None and not own_size and (scene.width % 2 or scene.height % 2):
        raise CamsimError(f"a {sensor.cfa} colour filter array needs an even frame size, got "
                          f"{scene.width}x{scene.height}")
    if sensor.prnu_percent > 0 and frame_scene.method == "spectral":
        raise CamsimError("PRNU needs a per-pixel mean: use method poisson, gaussian or auto, not spectral")

    record = {
        "scene": frame_scene.name,
        "scene_file": entry.file,
        "scene_sha256": entry.digest,
        "width_px": scene.width,
        "height_px": scene.height,
        "repeat": 0,
        "illuminant": params["illuminant"],
        "intensity_factor": params["intensity_factor"],
        "photon_statistics": frame_scene.statistics,
        "method": frame_scene.method,
        "tolerance": frame_scene.tolerance,
        "camera": camera.name,
        "preset": frame_scene.preset_name,
        **({"iso": frame_scene.iso} if frame_scene.iso is not None else {}),
        **sensor.to_dict(),
        # auto exposure only: a fixed exposure is the sensor's exposure_s (and frame ids stay those of earlier
        # versions); with auto, exposure_s is the sensor's setting and each frame's T is in its sidecar
        **(exposure_record(frame_scene) if frame_scene.exposure == "auto" else {}),
        **(burst_record(burst) if burst is not None else {}),  # a burst's keys: only then (other ids unchanged)
        "spec_seed": job.seed,
    }
    if job.images is not None:  # the frame's own image, crop and flips (IMAGE_KEYS) fill these in
        record.update({"image_folder": job.images.text, **dict.fromkeys(IMAGE_KEYS)})
    # as JSON gives it back (lists, not tuples), so that a record read from disk compares equal
    record = json.loads(json.dumps(record, allow_nan=False))
    keys = sorted(record)
    group = FrameGroup(
        scene_path=str(entry.path), width=scene.width, height=scene.height, illuminant=params["illuminant"],
        scene_changes={k: v for k, v in changes.items() if k != "illuminants"},
        sensor_overrides=overrides,
        record=record, value_keys=job.value_keys,
        canonical_parts=tuple(f"{_canonical(k)}:{_canonical(record[k])}" for k in keys),
        canonical_slots=tuple((keys.index(k), f"{_canonical(k)}:") for k in job.value_keys),
        image_folder=None if job.images is None else str(job.images.folder),
    )
    return group, check


__all__ = ["DatasetSpec", "FrameSpec", "FrameGroup", "ImageCrop", "SpecPlan", "PARAMETERS", "DISTRIBUTIONS",
           "OWN_VALUE_PARAMS", "IMAGE_KEYS", "IMAGE_SUFFIXES", "load_spec", "plan_spec"]
