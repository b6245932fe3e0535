"""Scene files (TOML): what is in front of the camera, and the camera and sensor that look at it.

What is in front of the camera is a scene *source* read from its own table (:data:`camsim.scene.sources.SOURCES`:
``[chart]``, a reflectance set laid out as a grid of patches on a surround, a label map plus K spectra;
``[cube]``, a hyperspectral cube file of reflectance or radiance (``.npy``, ENVI or ``.mat``); ``[image]``, an RGB
picture whose colours are recovered as spectra; or ``[target]``, a synthetic dead-leaves chart or slanted edge, also a
label map plus K spectra). Every key is listed in the docs' reference (scene-file keys);
unknown keys are errors, so a typo never goes unnoticed.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from camsim.core.errors import CamsimError
from camsim.core.names import safe_component
from camsim.core.schema import Param, check_frame_size, finite_float, param, params_of, read_toml, typed, validate
from camsim.light.spectra import WavelengthGrid
from camsim.methods import METHOD_NAMES
from camsim.methods.tolerance import DEFAULT_TOLERANCE
from camsim.scene.builtin_scenes import resolve_scene_file
from camsim.scene.regions import Region, check_regions, parse_regions
from camsim.scene.sources import SOURCES, ChartSource, SceneSource
from camsim.sensor.camera import DEFAULT_CAMERA, AnchorScale, PhysicalScale
from camsim.sensor.params import CHARGE_MAX_E, EXPOSURE_MAX_S, MAP_FILE_PARAMS, SENSOR_PARAMS, SensorParams
from camsim.sensor.presets import camera_preset, sensor_preset

if TYPE_CHECKING:  # the annotation only: camsim.scene.sequence is imported where a scene has a sequence
    from camsim.optics.params import OpticsParams
    from camsim.scene.sequence import SequenceParams

STATISTICS = ("pixel", "paper")
#: A raw scene's frames are under its own light, as shot (:mod:`camsim.scene.sources.raw`).
RAW_SCENE_ILLUMINANTS = ("as-shot",)
EXPOSURE_MODES = ("fixed", "auto")
NORMALISATIONS = ("chart", "per-spectrum")


@dataclass(frozen=True)
class Scene:
    """Everything a render needs, resolved from a scene file and the command line.

    Attributes
    ----------
    intensity_factors : tuple of float
        F values: the light level is F · L (F > 0; F > 1 saturates).
    luminance_cd_m2 : float
        Luminance of the perfect white (``chart`` normalisation) or of each spectrum (``per-spectrum``) at F = 1.
    source : SceneSource
        What is in front of the camera (:data:`camsim.scene.sources.SOURCES`): a chart by default.
    width, height : int
        Frame size in pixels (unless the source has a size of its own, as a cube has).
    preset_name : str
        The sensor preset (:func:`camsim.sensor.presets.sensor_preset`): a model preset, a camera preset or a
        camera preset file (``.toml``, relative to the scene file).
    iso : float or None
        The camera preset's ISO (None: its default, ISO 100 where published).
    regions : tuple of camsim.scene.regions.Region
        Named rectangles (``[[region]]``) that become the frame's patches, for a source without patches of its own
        (an image, a cube, a dead-leaves target); empty by default.
    """

    name: str
    grid: WavelengthGrid
    illuminants: tuple
    intensity_factors: tuple = (1.0,)
    luminance_cd_m2: float = 100.0
    normalisation: str = "chart"
    source: SceneSource = field(default_factory=ChartSource)
    width: int = 600
    height: int = 400
    camera: str = DEFAULT_CAMERA
    sensitivity_basis: str = "energy"
    scale: AnchorScale | PhysicalScale = field(default_factory=AnchorScale)
    preset_name: str = "paper-table1"
    iso: float | None = None
    sensor_overrides: tuple = ()
    statistics: str = param("pixel", "str", "photon statistics: 'pixel' = photons per pixel thinned by QE (exact "
                            "Poisson electrons; the docs' model page); 'paper' = Eq. 4 literally, per m²·sr",
                            choices=STATISTICS)
    method: str = param("poisson", "str", "sampling method (see the docs' model page)", choices=METHOD_NAMES)
    tolerance: float = param(DEFAULT_TOLERANCE, "float", "auto's tolerance: the largest Kolmogorov–Smirnov distance "
                             "between a pixel value's exact law and its Gaussian replacement", above=0, below=1)
    seed: int = param(0, "int", "random seed; the same seed gives byte-identical files", low=0)
    exposure: str = param("fixed", "str", "exposure time per frame: 'fixed' = the sensor's exposure_s for every "
                          "frame; 'auto' = each frame's T chosen so that the perfect white under the frame's "
                          "illuminant, at its F, reaches exposure_target_e in the strongest channel (dark current "
                          "scales with T; Qe never changes)", choices=EXPOSURE_MODES)
    exposure_target_e: float = param(8000.0, "float", "auto exposure: signal electrons of the perfect white in the "
                                     "strongest channel", "e⁻", above=0, high=CHARGE_MAX_E)
    exposure_max_s: float | None = param(None, "float", "auto exposure: the longest exposure time allowed (frames "
                                         "that need more are exposed this long, and darker); none = no limit", "s",
                                         above=0, high=EXPOSURE_MAX_S, optional=True)
    base_dir: Path | None = None
    regions: tuple = ()
    sequence: SequenceParams | None = None  # a [sequence] table: frames with camera motion (camsim.scene.sequence)
    optics: OpticsParams | None = None  # an [optics] table: the lens in front of the sensor (camsim.optics)

    def __post_init__(self):
        if not isinstance(self.source, SceneSource):
            raise CamsimError(f"a scene's source must be a scene source, got {self.source!r}")
        safe_component(self.name, "scene name")  # it names the frames' files: camsim.core.names
        if not self.illuminants:
            raise CamsimError("scene lists no illuminants")
        if not self.intensity_factors:
            raise CamsimError("scene lists no intensity factors")
        for f in self.intensity_factors:
            check_intensity_factor(f)
        check_frame_size(self.width, self.height, "scene's frame")
        if not (np.isfinite(self.luminance_cd_m2) and self.luminance_cd_m2 > 0):
            raise CamsimError(f"luminance_cd_m2 must be positive, got {self.luminance_cd_m2!r}")
        if self.normalisation not in NORMALISATIONS:
            raise CamsimError(f"normalisation must be one of {NORMALISATIONS}, got {self.normalisation!r}")
        validate(self, "scene")
        if not all(isinstance(r, Region) for r in self.regions):
            raise CamsimError(f"a scene's regions must be camsim.scene.regions.Region, got {self.regions!r}")
        if self.regions and not self.source.has_own_size:  # else checked when the source gives its size
            check_regions(self.regions, self.width, self.height, "scene")
        self.sensor  # validate the preset and overrides now

    @cached_property
    def sensor(self) -> SensorParams:
        """The sensor: the named preset (at the scene's ISO) with the scene's (and the command line's) overrides.

        Made once per scene (a frozen value; :meth:`replace` and :meth:`with_sensor` make new scenes)."""
        return sensor_preset(self.preset_name, self.iso, self.base_dir, **dict(self.sensor_overrides))

    def with_sensor(self, **overrides) -> Scene:
        """A copy with more sensor overrides (later ones win)."""
        return dataclasses.replace(self, sensor_overrides=_frozen(dict(self.sensor_overrides) | overrides))

    def replace(self, **changes) -> Scene:
        return dataclasses.replace(self, **changes)


def check_intensity_factor(value) -> float:
    """``value`` if it is an intensity factor F: a positive finite number (a scene's, a dataset frame's)."""
    number = finite_float(value) if isinstance(value, (int, float)) and not isinstance(value, bool) else None
    if number is None or not number > 0:
        raise CamsimError(f"intensity factor must be a positive number, got {value!r}")
    return value


def _frozen(overrides: dict) -> tuple:
    """Sensor overrides as a Scene holds them: sorted (name, value) pairs, lists (R, G, B) as tuples (hashable)."""
    return tuple(sorted((k, tuple(v) if isinstance(v, list) else v) for k, v in overrides.items()))


#: The render settings of a scene file's ``[render]`` table (and the command line's options of the same names).
RENDER_PARAMS = params_of(Scene)
#: What one frame of a scene is taken under: a scene file lists illuminants and intensity factors, a dataset
#: spec gives each frame one of each (and may change the camera and the sensor preset).
FRAME_PARAMS = (
    Param("illuminant", "str", "D65", "colour-science illuminant name"),
    Param("intensity_factor", "float", 1.0, "F: the light is F × the scene radiance (F > 1 saturates)"),
    Param("camera", "str", DEFAULT_CAMERA, "colour-science camera name or a CSV of wavelength_nm, R, G, B"),
    Param("preset", "str", "paper-table1", "sensor preset: a model preset, a camera preset (camsim list) or a "
          "camera preset file PATH.toml"),
    Param("iso", "float", None, "ISO of a camera preset (none: its default, ISO 100 where published)", above=0,
          optional=True),
)


_FRAME_PARAMS = {p.name: p for p in FRAME_PARAMS}
_TOP_KEYS = {"name", "description", "spectral", "light", "frame", "camera", "sensor", "render", "region", "sequence",
             "optics", *SOURCES}


def _table(doc: dict, key: str, allowed: set, where: str) -> dict:
    table = doc.get(key, {})
    if not isinstance(table, dict):
        raise CamsimError(f"{where}: [{key}] must be a table")
    unknown = set(table) - allowed
    if unknown:
        raise CamsimError(f"{where}: unknown key(s) in [{key}]: {', '.join(sorted(unknown))}")
    return table




def _raw_scene_defaults(source, light: dict, frame: dict, sensor_table: dict, given: str | None, iso: float | None,
                        where: str):
    """A raw scene's source, illuminants, preset and ISO, and its sensor's defaults (set in ``sensor_table``).

    The light is the file's: no illuminants (:data:`RAW_SCENE_ILLUMINANTS`). The source camera's preset is resolved
    now (``[raw] preset``, else the file's Make and Model, else ``[sensor] preset``) and kept in the source, so that
    a preset given later for the frames (``--preset``) changes the frames' sensor, not the source's gain. The frames'
    sensor is the source camera's unless ``[sensor] preset`` names another, at the file's ISO unless ``[sensor] iso``
    says, exposed as long as the source unless ``[sensor] exposure_s`` says, with the file's colour filter array."""
    if "illuminants" in light:
        raise CamsimError(f"{where}: a raw scene is lit by its own light: [light] illuminants does not apply")
    if frame:
        raise CamsimError(f"{where}: a raw scene's frame is its file's (or [raw] crop's): [frame] does not apply")
    source = dataclasses.replace(source, preset=source.source_preset(given))
    source.source_gain_dn_per_e()  # the source camera has a gain at the raw's ISO
    preset_name = given if given is not None else source.preset
    if iso is None and camera_preset(preset_name, source.base_dir) is not None:
        iso = source.source_iso
    sensor_table.setdefault("exposure_s", source.source_exposure_s)
    if sensor_table.setdefault("cfa", source.cfa) != source.cfa:
        raise CamsimError(f"{where}: a raw scene's colour filter array is its file's ({source.cfa}), got [sensor] "
                          f"cfa = {sensor_table['cfa']!r}")
    return source, list(RAW_SCENE_ILLUMINANTS), preset_name, iso


def _sequence(table):
    """A ``[sequence]`` table's :class:`camsim.scene.sequence.SequenceParams` (imported here: only sequences need it,
    not the command line's start-up)."""
    from camsim.scene.sequence import parse_sequence

    return parse_sequence(table)


def _optics(table):
    """An ``[optics]`` table's :class:`camsim.optics.params.OpticsParams` (imported here: only scenes with optics
    need it)."""
    from camsim.optics.params import parse_optics

    return parse_optics(table)


def load_scene(path: str | Path) -> Scene:
    """Read and validate a scene file, given by its path or by a built-in scene's name (``macbeth_26``).

    An existing file always wins; a name (no ``/``, no ``.toml``) is looked up in :mod:`camsim.scene.builtin_scenes`.

    Raises
    ------
    CamsimError
        For a missing or malformed file, an unknown name, unknown keys, or values of the wrong type or range.
    """
    path = resolve_scene_file(path)
    where = str(path)
    doc = read_toml(path, "scene file")
    unknown = set(doc) - _TOP_KEYS
    if unknown:
        raise CamsimError(f"{where}: unknown top-level key(s): {', '.join(sorted(unknown))}")
    typed(doc, "description", str, "", where)  # free text for the reader, but text: a list or number is a mistake
    base_dir = path.resolve().parent
    name = safe_component(typed(doc, "name", str, path.stem, where), f"{where}: name")  # before any work

    spectral = _table(doc, "spectral", {"start_nm", "end_nm", "step_nm"}, where)
    grid = WavelengthGrid(
        typed(spectral, "start_nm", float, 380.0, where),
        typed(spectral, "end_nm", float, 780.0, where),
        typed(spectral, "step_nm", float, 4.0, where),
    )
    light = _table(doc, "light", {"illuminants", "luminance_cd_m2", "intensity_factors", "normalisation"}, where)
    illuminants = typed(light, "illuminants", list, ["D65"], where)
    if not all(isinstance(name, str) for name in illuminants):
        raise CamsimError(f"{where}: illuminants must be a list of names")
    factors = typed(light, "intensity_factors", list, [1.0], where)
    frame = _table(doc, "frame", {"width", "height"}, where)
    width, height = typed(frame, "width", int, 600, where), typed(frame, "height", int, 400, where)
    check_frame_size(width, height, f"{where}: [frame]")
    tables = [name for name in SOURCES if name in doc]
    if len(tables) != 1:
        raise CamsimError(f"{where}: a scene needs exactly one of " + " or ".join(f"[{n}]" for n in SOURCES))
    source_cls = SOURCES[tables[0]]
    source = source_cls.from_table(_table(doc, source_cls.table, source_cls.keys, where), base_dir, where)

    camera = _table(doc, "camera", {"name", "sensitivity_basis", "scale"}, where)
    scale_table = camera.get("scale", {})
    if not isinstance(scale_table, dict):
        raise CamsimError(f"{where}: [camera.scale] must be a table")
    scale_kind = scale_table.get("kind", "anchor")
    scale_classes = {"anchor": AnchorScale, "physical": PhysicalScale}
    if scale_kind not in scale_classes:
        raise CamsimError(f"{where}: [camera.scale] kind must be 'anchor' or 'physical', got {scale_kind!r}")
    scale_cls = scale_classes[scale_kind]
    scale_fields = {f.name for f in dataclasses.fields(scale_cls)}
    unknown = set(scale_table) - scale_fields - {"kind"}
    if unknown:
        raise CamsimError(f"{where}: unknown key(s) in [camera.scale] ({scale_kind}): {', '.join(sorted(unknown))}")
    scale = scale_cls(**{k: typed(scale_table, k, str if k == "reference_illuminant" else float, None, where)
                         for k in scale_table if k != "kind"})

    sensor_table = dict(_table(doc, "sensor", {"preset", "iso"} | {p.name for p in SENSOR_PARAMS}, where))
    preset_name = sensor_table.pop("preset", "paper-table1")
    if not isinstance(preset_name, str):
        raise CamsimError(f"{where}: [sensor] preset must be a name")
    iso = _FRAME_PARAMS["iso"].coerce(sensor_table.pop("iso", None), f"{where} [sensor]")
    sensor_table = {p.name: p.coerce(sensor_table[p.name], f"{where} [sensor]")
                    for p in SENSOR_PARAMS if p.name in sensor_table}
    for key in MAP_FILE_PARAMS:  # a map file named by the scene file: relative to it
        if sensor_table.get(key) is not None:
            sensor_table[key] = str(base_dir / Path(sensor_table[key]).expanduser())
    if source.table == "raw":
        given = doc.get("sensor", {}).get("preset")  # (checked above to be a name)
        source, illuminants, preset_name, iso = _raw_scene_defaults(source, light, frame, sensor_table, given,
                                                                    iso, where)

    regions = parse_regions(doc["region"], where) if "region" in doc else ()
    if regions and not source.has_own_size:  # an image's or a cube's size is checked when it is read
        check_regions(regions, width, height, where)

    render = _table(doc, "render", {p.name for p in RENDER_PARAMS}, where)
    render = {p.name: p.coerce(render[p.name], f"{where} [render]") for p in RENDER_PARAMS if p.name in render}
    return Scene(
        name=name,
        grid=grid,
        illuminants=tuple(illuminants),
        intensity_factors=tuple(float(check_intensity_factor(f)) for f in factors),
        luminance_cd_m2=typed(light, "luminance_cd_m2", float, 100.0, where),
        normalisation=typed(light, "normalisation", str, "chart", where),
        source=source,
        width=width,
        height=height,
        camera=typed(camera, "name", str, DEFAULT_CAMERA, where),
        sensitivity_basis=typed(camera, "sensitivity_basis", str, "energy", where),
        scale=scale,
        preset_name=preset_name,
        iso=iso,
        sensor_overrides=_frozen(sensor_table),
        base_dir=base_dir,
        regions=regions,
        sequence=_sequence(doc["sequence"]) if "sequence" in doc else None,
        optics=_optics(doc["optics"]) if "optics" in doc else None,
        **render,
    )
