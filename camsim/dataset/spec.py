"""Dataset spec files (TOML): which frames a dataset holds, each with its parameters, id and seed.

A spec names one or more scene files and the parameters to vary over them::

    name = "denoise_small"
    scene = "macbeth_26.toml"          # or a list; relative to the spec file
    seed = 0                           # the random draws and every frame's noise derive from it
    repeats = 1                        # noisy realisations of each parameter set (each its own seed)

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
:func:`camsim.seeding.dataset_parameter_generator`, one value per frame in frame order, so
the frame list is the same on every run and adding a parameter leaves the others' draws unchanged.

Frame order: scene, the scene's inherited axes, the ``[grid]`` keys in file order, the random draw, the repeat.
Each frame gets an id ``<index:05d>-<hash>`` (the hash covers every resolved parameter, the scene file's bytes
and the seed) and its own seed, a function of the spec seed and the id alone, so that a frame's content does not
depend on the other frames, on the order they are rendered in or on the machine.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import math
from dataclasses import dataclass
from pathlib import Path


from camsim.camera import load_camera
from camsim.errors import CamsimError
from camsim.run import check_scene
from camsim.scene import FRAME_PARAMS, RENDER_PARAMS, Scene, load_scene, read_toml
from camsim.seeding import dataset_frame_seed, dataset_parameter_generator
from camsim.sensor import SENSOR_PARAMS

DEFAULT_WIDTH, DEFAULT_HEIGHT = 256, 192
MAX_FRAMES = 1_000_000
MAX_PIXELS = 200_000_000

#: Every parameter a spec may set, by name: the frame's choices, the render settings and the sensor's (the schema).
PARAMETERS = {p.name: p for p in (*FRAME_PARAMS, *RENDER_PARAMS, *SENSOR_PARAMS) if p.name != "seed"}
#: Plural spellings accepted in [grid] (the scene file's [light] names).
GRID_ALIASES = {"illuminants": "illuminant", "intensity_factors": "intensity_factor"}
DISTRIBUTIONS = ("uniform", "log_uniform", "integers", "choice")
_TOP_KEYS = {"name", "description", "scene", "seed", "repeats", "frame", "fixed", "grid", "random"}


@dataclass(frozen=True)
class FrameSpec:
    """One frame of a dataset: everything a worker needs to render it, as plain picklable data.

    Attributes
    ----------
    index : int
        Position in the spec's frame list.
    id : str
        ``<index:05d>-<hash>``: the file stem under ``OUT/frames/``.
    seed : int
        The frame's seed (< 2**53): its generator is
        ``camsim.seeding.frame_seed_sequence(seed, illuminant, intensity_factor)``, as for ``camsim render``.
    scene_path : str
        Absolute path of the scene file.
    width, height : int
        Frame size in pixels.
    scene_changes : dict
        ``Scene.replace`` arguments (illuminant list, statistics, method, tolerance, camera, preset_name).
    sensor_overrides : dict
        Sensor parameters on top of the scene's preset and ``[sensor]`` table.
    record : dict
        The frame's manifest entry without its files: id, index, repeat, scene, every resolved parameter, seed.
    """

    index: int
    id: str
    seed: int
    scene_path: str
    width: int
    height: int
    illuminant: str
    intensity_factor: float
    scene_changes: dict
    sensor_overrides: dict
    record: dict

    @property
    def megapixels(self) -> float:
        return self.width * self.height / 1e6


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

    def __len__(self) -> int:
        return len(self.frames)

    @property
    def size_text(self) -> str:
        """``WxH`` of the frames (a cube scene's frames have the cube's size), or ``mixed sizes``."""
        sizes = {(f.width, f.height) for f in self.frames}
        if len(sizes) != 1:
            return "mixed sizes"
        (width, height), = sizes
        return f"{width}x{height}"


# --- values --------------------------------------------------------------------------------------------------


def _coerce(name: str, value, where: str):
    """One parameter value, type-checked and typed (ints to floats where needed) by the schema; its range is
    checked when the frame's scene and sensor are built."""
    return PARAMETERS[name].coerce(value, where, check_range=False)


def _canonical(value) -> str:
    return json.dumps(value, sort_keys=True, separators=(",", ":"), allow_nan=False, ensure_ascii=True)


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


def load_spec(path: str | Path) -> DatasetSpec:
    """Read a dataset spec, build its frame list and validate every frame before anything is rendered.

    Raises
    ------
    CamsimError
        A missing or malformed file, an unknown key, a value of the wrong type or range, a name that does not
        resolve (scene, illuminant, camera, preset) or a frame camsim cannot render.
    """
    path = Path(path)
    where = str(path)
    doc = read_toml(path, "dataset spec")
    unknown = set(doc) - _TOP_KEYS
    if unknown:
        raise CamsimError(f"{where}: unknown top-level key(s): {', '.join(sorted(unknown))}; "
                          f"known: {', '.join(sorted(_TOP_KEYS))}")
    base = path.resolve().parent

    name = doc.get("name", path.stem)
    if not isinstance(name, str) or not name:
        raise CamsimError(f"{where}: name must be a non-empty string")
    if not isinstance(doc.get("description", ""), str):
        raise CamsimError(f"{where}: description must be a string")
    seed = doc.get("seed", 0)
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise CamsimError(f"{where}: seed must be an integer ≥ 0, got {seed!r}")
    repeats = doc.get("repeats", 1)
    if isinstance(repeats, bool) or not isinstance(repeats, int) or repeats < 1:
        raise CamsimError(f"{where}: repeats must be an integer ≥ 1, got {repeats!r}")
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
    for key, value in (("width", width), ("height", height)):
        if isinstance(value, bool) or not isinstance(value, int) or value < 1:
            raise CamsimError(f"{where}: [frame] {key} must be a positive integer (pixels), got {value!r}")
    if width * height > MAX_PIXELS:
        raise CamsimError(f"{where}: [frame] {width}x{height} is over {MAX_PIXELS // 1_000_000} megapixels")

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

    scenes = []
    for scene_file in scene_files:
        scene_path = (base / scene_file).resolve()
        scene = load_scene(scene_path)
        if scene.source.has_own_size and "frame" in doc:
            raise CamsimError(f"{where}: [frame] sets a size, but {scene_file} is a {scene.source.table} scene, "
                              "whose size is its own")
        if scene.source.has_own_size:  # a cube's size is its own: read it from the file's header
            try:
                width_px, height_px = scene.source.own_size()
            except CamsimError as exc:
                raise CamsimError(f"{where}: {exc}") from None
        else:
            width_px, height_px = width, height
        scenes.append((scene_file, scene_path, scene.replace(width=int(width_px), height=int(height_px)),
                       _scene_sha256(scene_path)))

    # the frame list: per scene, its inherited axes, then [grid] in file order; then the draws and repeats
    points = []
    for s, (_, _, scene, _) in enumerate(scenes):
        axes_here = {}
        if "illuminant" not in axes:
            axes_here["illuminant"] = list(scene.illuminants)
        if "intensity_factor" not in axes:
            axes_here["intensity_factor"] = list(scene.intensity_factors)
        axes_here.update(grid)
        n = math.prod(len(v) for v in axes_here.values()) * count * repeats
        if len(points) + n > MAX_FRAMES:
            raise CamsimError(f"{where}: more than {MAX_FRAMES} frames")
        for combo in itertools.product(*axes_here.values()):
            for draw in range(count):
                points.append((s, dict(zip(axes_here, combo)), draw))
    for param in ("illuminant", "intensity_factor"):
        axes.setdefault(param, "scene")
    random_values = {p: _draw(p, random_table[k], len(points), seed, f"{where} [random]")
                     for p, k in random_names.items()}

    frames = []
    checked: dict = {}
    for point_index, (s, combo, draw) in enumerate(points):
        scene_file, scene_path, scene, scene_digest = scenes[s]
        params = dict(fixed)
        params.update(combo)
        params.update({p: values[point_index] for p, values in random_values.items()})
        for repeat in range(repeats):
            index = len(frames)
            frames.append(_frame(index, repeat, params, scene_file, scene_path, scene, scene_digest, seed, base,
                                 checked, where))
    return DatasetSpec(name=name, path=path, seed=seed, width=width, height=height, frames=tuple(frames),
                       axes=axes)


def _frame(index, repeat, params, scene_file, scene_path, scene: Scene, scene_digest, seed, base, checked, where):
    """Resolve and validate one frame; ``checked`` memoises the costly checks (illuminants, cameras)."""
    changes = {"illuminants": (params["illuminant"],)}
    for key in ("statistics", "method", "tolerance"):
        if key in params:
            changes[key] = params[key]
    if "camera" in params:  # a camera CSV named in the spec is relative to the spec
        camera = params["camera"]
        changes["camera"] = str((base / camera).resolve()) if camera.lower().endswith(".csv") else camera
    if "preset" in params:
        changes["preset_name"] = params["preset"]
    overrides = {p.name: params[p.name] for p in SENSOR_PARAMS if p.name in params}
    factor = params["intensity_factor"]
    label = f"{where}: frame {index} ({', '.join(f'{k}={v!r}' for k, v in params.items())})"
    try:
        frame_scene = scene.replace(intensity_factors=(factor,), **changes)
        if overrides:
            frame_scene = frame_scene.with_sensor(**overrides)
        sensor = frame_scene.sensor
        key = ("scene", str(scene_path), frame_scene.illuminants, frame_scene.method, sensor.quantisation)
        if key not in checked:
            check_scene(frame_scene)
            checked[key] = True
        key = ("camera", str(scene_path), frame_scene.camera)
        if key not in checked:
            checked[key] = load_camera(frame_scene.camera, frame_scene.grid, frame_scene.sensitivity_basis,
                                       frame_scene.base_dir).name
        if sensor.cfa is not None and not frame_scene.source.has_own_size and (scene.width % 2 or scene.height % 2):
            raise CamsimError(f"a {sensor.cfa} colour filter array needs an even frame size, got "
                              f"{scene.width}x{scene.height}")
        if sensor.prnu_percent > 0 and frame_scene.method == "spectral":
            raise CamsimError("PRNU needs a per-pixel mean: use method poisson, gaussian or auto, not spectral")
    except CamsimError as exc:
        raise CamsimError(f"{label}: {exc}") from None

    sensor_dict = sensor.to_dict()
    record = {
        "scene": frame_scene.name,
        "scene_file": scene_file,
        "scene_sha256": scene_digest,
        "width_px": scene.width,
        "height_px": scene.height,
        "repeat": repeat,
        "illuminant": params["illuminant"],
        "intensity_factor": factor,
        "photon_statistics": frame_scene.statistics,
        "method": frame_scene.method,
        "tolerance": frame_scene.tolerance,
        "camera": checked[("camera", str(scene_path), frame_scene.camera)],
        "preset": frame_scene.preset_name,
        **sensor_dict,
        "spec_seed": seed,
    }
    digest = hashlib.sha256(_canonical(record).encode("ascii")).hexdigest()[:10]
    frame_id = f"{index:05d}-{digest}"
    fseed = dataset_frame_seed(seed, frame_id)
    # as JSON gives it back (lists, not tuples), so that a record read from disk compares equal
    record = json.loads(json.dumps({"id": frame_id, "index": index, **record, "seed": fseed}, allow_nan=False))
    return FrameSpec(
        index=index, id=frame_id, seed=fseed, scene_path=str(scene_path), width=scene.width, height=scene.height,
        illuminant=params["illuminant"], intensity_factor=factor,
        scene_changes={k: v for k, v in changes.items() if k != "illuminants"},
        sensor_overrides=overrides, record=record,
    )


__all__ = ["DatasetSpec", "FrameSpec", "PARAMETERS", "DISTRIBUTIONS", "load_spec"]
