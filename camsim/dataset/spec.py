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
``images.flip_horizontal``, ``images.flip_vertical``). The frame's record holds them
(:data:`camsim.dataset.spec_parts.IMAGE_KEYS`: the file name relative to the folder, its SHA-256, ``crop_x``,
``crop_y``, ``flip_horizontal``, ``flip_vertical``), so that the id changes with the image's bytes. A crop is of the
file as stored; a flip mirrors the cropped frame.

Scenes may also be crops of a folder of a real camera's raw files (a ``[raws]`` table: ``folder``, ``pattern``,
``crop``, ``flips``, ``photon_law``, ``preset``), which need no ``scene`` file: the light and colour are each file's
own, and the frames' parameters include ``ratio`` and ``photon_law`` (:data:`camsim.dataset.spec_parts.RAWS_PARAMS`).
:mod:`camsim.dataset.raws` describes them and plans them (:func:`plan_spec` hands such a spec to
:func:`camsim.dataset.raws.plan_raws`).

Frame order: scene, the scene's inherited axes, the ``[grid]`` keys in file order, the random draw, the repeat.
Each frame gets an id ``<index>-<hash>`` (the hash covers every resolved parameter, the scene file's bytes and the
seed) and its own seed, a function of the spec seed and the id alone, so that a frame's content does not depend
on the other frames, on the order they are rendered in or on the machine. The index is zero-padded to five digits,
or to the digits of the last index where a spec has more than 100 000 frames (``000000-…`` to ``119999-…``), so
that every id of a spec has the same width and the ids sort in frame order.

Planning is cheap per frame: frames that differ only in parameters that enter them through their own value alone
(:data:`camsim.dataset.spec_parts.OWN_VALUE_PARAMS`: the light level, the read noise, the exposure …) share one
resolved and checked scene and sensor (:class:`camsim.dataset.spec_parts.FrameGroup`), so that a spec of 10⁵ frames
is planned in seconds and little memory; :func:`plan_spec` makes the frames one by one (``camsim dataset --dry-run``
streams them).

The parts both kinds of spec (this module's, of scene files, and :mod:`camsim.dataset.raws`') are made of, the
parameters, their tables and draws, the frames and their ids and seeds, are in :mod:`camsim.dataset.spec_parts`.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import math
from collections.abc import Iterator
from dataclasses import dataclass
from functools import partial
from pathlib import Path

from camsim.core.errors import CamsimError
from camsim.core.input_files import open_input
from camsim.core.names import safe_component
from camsim.core.schema import INT64_MAX, check_frame_size
from camsim.core.seeding import dataset_parameter_generator
from camsim.dataset.raws import plan_raws
from camsim.dataset.spec_parts import (
    FACTOR_INDEX,
    IMAGE_KEYS,
    MAX_FRAMES,
    OWN_VALUE_PARAMS,
    PARAMETERS,
    RAWS_PARAMS,
    RENDER_KEYS,
    DatasetSpec,
    FrameGroup,
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
    spec_table,
    virtual_camera_draws,
)
from camsim.io.dng import MIN_SIZE
from camsim.io.exr_compression import check_exr_compression
from camsim.render.pipeline import check_frame, exposure_record, frame_sensor, light_scene
from camsim.render.run import check_scene
from camsim.scene.builtin_scenes import resolve_scene_file, resolve_spec_file
from camsim.scene.scene_file import Scene, check_intensity_factor, load_scene, read_toml
from camsim.scene.sequence import check_timing
from camsim.scene.sources.image import ImageSource
from camsim.sensor.camera import load_camera
from camsim.sensor.params import SENSOR_PARAMS, with_checked_values
from camsim.sensor.presets.virtual import VIRTUAL_KEYS

DEFAULT_WIDTH, DEFAULT_HEIGHT = 256, 192
_TOP_KEYS = {"name", "description", "scene", "seed", "repeats", "frame", "fixed", "grid", "random", "images",
             "raws", "virtual_camera", "exr_compression", "srgb"}
#: What a spec's ``srgb`` (and ``camsim dataset --srgb``) may be: ``none``, or each frame's noisy and clean layers
#: developed through one camera ISP (:mod:`camsim.dataset.srgb`) as 8-bit (``png``) or 16-bit (``png16``) sRGB:
#: PNG files in the file layout, uint8 or uint16 arrays in a Zarr store.
SRGB_OUTPUTS = ("none", "png", "png16")
#: Keys of an ``[images]`` table.
IMAGES_TABLE_KEYS = ("folder", "pattern", "crop", "flips")
#: File name suffixes an ``[images]`` folder is searched for without a ``pattern`` (any case).
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".exr")


def _scene_sha256(path: Path) -> str:
    """The SHA-256 of a file the spec names (a scene file, an image), read in chunks through
    :func:`camsim.core.input_files.open_input` (a regular file, not a FIFO or a device, of at most
    :data:`camsim.core.pixel_limit.MAX_IMAGE_FILE_BYTES`: an 8 GiB sparse file is refused, not hashed)."""
    from camsim.core.pixel_limit import MAX_IMAGE_FILE_BYTES

    with open_input(path, "dataset input file", MAX_IMAGE_FILE_BYTES) as handle:
        try:
            return hashlib.file_digest(handle, "sha256").hexdigest()
        except OSError as exc:
            raise CamsimError(f"cannot read {path}: {exc.strerror or exc}") from None


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


def _refuse_raws_params(axes: dict, where: str) -> None:
    """Refuse the parameters of ``[raws]`` frames (:data:`camsim.dataset.spec_parts.RAWS_PARAMS`) in a spec without
    ``[raws]``."""
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
        (scene) or more than :data:`camsim.dataset.spec_parts.MAX_FRAMES` frames.
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

    frame = spec_table(doc, "frame", where)
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

    axes, fixed, grid, random_table, random_names, count = parameter_tables(doc, where)
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
    random_values = {p: draw_parameter(p, random_table[k], points, seed, f"{where} [random]")
                     for p, k in random_names.items()}
    if "virtual_camera" in doc:  # each grid point and draw: a camera, its K and its noise scales
        drawn = virtual_camera_draws(doc["virtual_camera"], points, seed, axes, where)
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
               id_digits=frame_id_digits(points * repeats), images=images,
               image_values=_image_draws(images, points, seed) if images is not None else None)
    sizes = tuple(dict.fromkeys((entry.scene.width, entry.scene.height) for entry in scenes))
    return SpecPlan(name=name, path=path, seed=seed, width=width, height=height, axes=axes, count=points * repeats,
                    sizes=sizes, make_frames=partial(frames_with_ids, job, _frame_values),
                    exr_compression=exr_compression, srgb=srgb)


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
    """What :func:`camsim.dataset.spec_parts.frames_with_ids` needs to make the frames of a spec."""

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
        """The own values that are sensor parameters (:attr:`camsim.dataset.spec_parts.FrameGroup.sensor_keys`)."""
        return self.value_keys[FACTOR_INDEX + 1:len(self.value_keys) - (len(IMAGE_KEYS) if self.images else 0)]


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
                key = (combo_key, *(canonical_json(params[p]) for p in shared_random))
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
    refuse is refused when the spec is planned, by the dry run too. The group's lit scene stands for its frames' (an
    ``[images]`` spec's first crop for every crop, as in the other checks).

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

def _resolve(params: dict, entry: _SceneEntry, job: _Job, checked: dict) -> tuple[FrameGroup, _FrameCheck]:
    """Resolve and validate the scene and sensor of a frame with ``params``: its group's, and the check of the
    group's frames."""
    changes = {"illuminants": (params["illuminant"],)}
    for key in RENDER_KEYS:  # the scene's render settings a spec may set
        if key in params:
            changes[key] = params[key]
    if "camera" in params:  # a camera CSV named in the spec is relative to the spec
        camera = params["camera"]
        changes["camera"] = str(spec_path(job.base, camera, "camera")) if camera.lower().endswith(".csv") else camera
    if "preset" in params:
        camera = params["preset"]  # a camera preset file named in the spec is relative to the spec
        changes["preset_name"] = (str(spec_path(job.base, camera, "camera preset file"))
                                  if camera.lower().endswith(".toml") else camera)
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
        canonical_parts=tuple(f"{canonical_json(k)}:{canonical_json(record[k])}" for k in keys),
        canonical_slots=tuple((keys.index(k), f"{canonical_json(k)}:") for k in job.value_keys),
        image_folder=None if job.images is None else str(job.images.folder),
    )
    return group, check


__all__ = ["SRGB_OUTPUTS", "IMAGES_TABLE_KEYS", "IMAGE_SUFFIXES", "check_srgb", "load_spec", "plan_spec"]
