"""The parts of a dataset spec that its two kinds share: the parameters a spec may set and the tables that set
them, their random draws, and the frames a plan makes, with their ids and seeds.

A spec of scene files (:mod:`camsim.dataset.spec`) and a spec of crops of raw files (a ``[raws]`` table,
:mod:`camsim.dataset.raws`) are planned from these parts; this module imports neither of them, and
:func:`camsim.dataset.spec.plan_spec` hands a ``[raws]`` spec to :func:`camsim.dataset.raws.plan_raws`, so the imports
go one way: ``spec`` → ``raws`` → ``spec_parts``. What they share:

- the parameters: :data:`PARAMETERS` (the frame's, the render settings, the sensor's, :data:`RAWS_PARAMS` and
  :data:`BURST_PARAMS`), :data:`OWN_VALUE_PARAMS`, the ``[fixed]``, ``[grid]`` and ``[random]`` tables
  (:func:`parameter_tables`), a ``[random]`` distribution's draws (:func:`draw_parameter`) and ``[virtual_camera]``'s
  (:func:`virtual_camera_draws`), a frame's sensor overrides (:func:`frame_sensor_overrides`) and burst
  (:func:`burst_sequence`, :func:`burst_record`);
- a folder table's checks (:func:`folder_table`: ``[images]``, ``[raws]``) and the crops of its files
  (:class:`FileCrop`, :class:`ImageCrop`, :class:`RawCrop`);
- the frames: a group's shared scene and sensor (:class:`FrameGroup`), one frame (:class:`FrameSpec`), the ids and
  seeds of a planner's frames (:func:`frames_with_ids`, :func:`frame_id_digits`, :func:`canonical_json`), the plan
  (:class:`SpecPlan`) and the spec (:class:`DatasetSpec`).
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path, PurePosixPath

from camsim.core.errors import CamsimError
from camsim.core.schema import Param, check_frame_size, params_of
from camsim.core.seeding import dataset_frame_seeds, dataset_parameter_generator
from camsim.scene.scene_file import FRAME_PARAMS, RENDER_PARAMS, Scene
from camsim.scene.sequence import SequenceParams
from camsim.scene.sources.image import ImageSource
from camsim.sensor.params import MAP_FILE_PARAMS, SENSOR_PARAMS
from camsim.sensor.presets.virtual import VIRTUAL_KEYS
from camsim.sensor.raw_laws import PHOTON_LAWS

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
#: The render settings of :class:`camsim.scene.scene_file.Scene` a frame takes from its spec (all but the seed: a
#: frame has its own).
RENDER_KEYS = tuple(p.name for p in RENDER_PARAMS if p.name != "seed")
#: Plural spellings accepted in [grid] (the scene file's [light] names).
GRID_ALIASES = {"illuminants": "illuminant", "intensity_factors": "intensity_factor"}
DISTRIBUTIONS = ("uniform", "log_uniform", "integers", "choice")
#: Keys of a ``[virtual_camera]`` table.
VIRTUAL_CAMERA_TABLE_KEYS = ("cameras", "k_range", "read_noise_model")
#: A frame's own values when its scene is a crop of an image of an ``[images]`` folder (after the others).
IMAGE_KEYS = ("image_file", "image_sha256", "crop_x", "crop_y", "flip_horizontal", "flip_vertical")
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
FACTOR_INDEX = 1  # position of the intensity factor in FrameSpec.values: repeat, factor, own-value sensor parameters
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
        return self.value_keys[FACTOR_INDEX + 1:end]

    def canonical(self, values: tuple) -> str:
        """The canonical JSON (:func:`canonical_json`) of the record of a frame with ``values``, without its id,
        index and seed: what the frame's id hashes."""
        parts = list(self.canonical_parts)
        for (position, prefix), value in zip(self.canonical_slots, values):
            parts[position] = prefix + _canonical_scalar(value)
        return "{" + ",".join(parts) + "}"


@dataclass(frozen=True)
class FileCrop:
    """A window of a file, perhaps mirrored: the scene of a frame of an ``[images]`` spec (:class:`ImageCrop`) or a
    ``[raws]`` spec (:class:`RawCrop`).

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


@dataclass(frozen=True)
class RawCrop(FileCrop):
    """The source of a frame of a ``[raws]`` spec: a window of a raw file, perhaps mirrored (:class:`FileCrop`).

    Its ``x``, ``y`` are even, or odd along a flipped axis (the window one column or row further in, so that the
    mirrored frame has the file's pattern); ``width``, ``height`` are even.
    """


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
        return self.values[FACTOR_INDEX]

    @property
    def scene_changes(self) -> dict:
        return self.group.scene_changes

    @property
    def sensor_overrides(self) -> dict:
        overrides = dict(self.group.sensor_overrides)
        overrides.update(zip(self.group.sensor_keys, self.values[FACTOR_INDEX + 1:]))
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
    def raw(self) -> RawCrop | None:
        """The crop of a raw file of a ``[raws]`` folder that is the frame's source (:class:`RawCrop`), or None."""
        if self.group.raws is None:
            return None
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


def canonical_json(value) -> str:
    return json.dumps(value, sort_keys=True, separators=(",", ":"), allow_nan=False, ensure_ascii=True)


def _canonical_scalar(value) -> str:
    """:func:`canonical_json` of a value, faster for the finite floats and the ints of a frame's own values."""
    kind = type(value)
    if kind is float and math.isfinite(value):
        return float.__repr__(value)  # what json writes
    if kind is int:
        return int.__repr__(value)
    return canonical_json(value)


def draw_parameter(name: str, dist: dict, n: int, seed: int, where: str) -> list:
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


def frame_id_digits(count: int) -> int:
    """The digits of the index of the frame ids of a spec of ``count`` frames: :data:`ID_DIGITS`, or those of the
    last index where it needs more (every id of a spec has one width, and the ids sort in frame order)."""
    return max(ID_DIGITS, len(str(count - 1)))


# --- the tables ----------------------------------------------------------------------------------------------


def spec_table(doc: dict, key: str, where: str) -> dict:
    """The spec's ``[key]`` table (empty where it has none); a ``key`` that is not a table is a :class:`CamsimError`."""
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


def spec_path(base: Path, text: str, what: str) -> Path:
    """The absolute path that a spec's ``text`` names, relative to the spec's folder ``base``; a text with a NUL byte,
    which no file name holds (and which ``resolve()`` raises ``ValueError`` for), is a :class:`CamsimError`."""
    if "\x00" in text:
        raise CamsimError(f"{what} path {text!r} holds a NUL byte, which no file name can")
    return (base / text).resolve()


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
    folder = spec_path(base, text, f"{at} folder")
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


def parameter_tables(doc: dict, where: str) -> tuple:
    """The spec's ``[fixed]``, ``[grid]`` and ``[random]`` tables, checked: (axes, fixed, grid, random table,
    random names, count), ``axes`` saying where each parameter is set."""
    fixed_table = spec_table(doc, "fixed", where)
    grid_table = spec_table(doc, "grid", where)
    random_table = spec_table(doc, "random", where)
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
        canon = [canonical_json(v) for v in values]
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


def virtual_camera_draws(table, points: int, seed: int, axes: dict, where: str) -> list:
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


def frames_with_ids(job, frame_values: Callable[[object], Iterator[tuple]]) -> Iterator[FrameSpec]:
    """Make the frames of a spec, in order, a batch at a time (their seeds are computed together): those of
    ``frame_values(job)`` (index, own values and group of each frame: :func:`camsim.dataset.spec._frame_values`,
    :func:`camsim.dataset.raws._raw_frame_values`), each with its id (the index, ``job.id_digits`` wide, and the hash
    of the frame's canonical record: :meth:`FrameGroup.canonical`) and its seed (of ``job.seed`` and the id)."""
    batch = []
    for index, values, group in frame_values(job):
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
            overrides[key] = str(spec_path(base, str(Path(overrides[key]).expanduser()), key))
    return overrides


__all__ = ["MAX_FRAMES", "RAWS_PARAMS", "BURST_PARAMS", "PARAMETERS", "RENDER_KEYS", "GRID_ALIASES", "DISTRIBUTIONS",
           "VIRTUAL_CAMERA_TABLE_KEYS", "IMAGE_KEYS", "RAW_KEYS", "ID_DIGITS", "OWN_VALUE_PARAMS", "FACTOR_INDEX",
           "FrameGroup", "FileCrop", "ImageCrop", "RawCrop", "FrameSpec", "DatasetSpec", "SpecPlan", "canonical_json",
           "draw_parameter", "frame_id_digits", "spec_table", "FolderTable", "folder_table", "parameter_tables",
           "virtual_camera_draws", "frames_with_ids", "burst_sequence", "burst_record", "frame_sensor_overrides",
           "spec_path"]