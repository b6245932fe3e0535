"""Scene files (TOML): what is in front of the camera, and the camera and sensor that look at it.

A scene is either a *chart* (a reflectance set laid out as a grid of patches on a surround: a label map plus
K spectra) or a hyperspectral *cube* (a ``.npy`` array H × W × N of reflectance or radiance). The full schema
is documented in the README; unknown keys are errors, so a typo never goes unnoticed.
"""

from __future__ import annotations

import dataclasses
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from camsim.builtin_scenes import resolve_scene_file
from camsim.camera import DEFAULT_CAMERA, AnchorScale, PhysicalScale
from camsim.chart import ChartGeometry
from camsim.errors import CamsimError
from camsim.sensor import SensorParams, preset
from camsim.spectra import WavelengthGrid

STATISTICS = ("pixel", "paper")
NORMALISATIONS = ("chart", "per-spectrum")
CUBE_KINDS = ("reflectance", "radiance")


@dataclass(frozen=True)
class ChartSpec:
    """A reflectance chart: its reflectance set, geometry and surround."""

    reflectances: str = "ColorChecker N Ohta"
    geometry: ChartGeometry = field(default_factory=ChartGeometry)
    surround_reflectance: float = 0.05


@dataclass(frozen=True)
class CubeSpec:
    """A hyperspectral cube scene: ``path`` holds an H × W × N array on the scene's wavelength grid."""

    path: Path
    kind: str = "reflectance"


@dataclass(frozen=True)
class Scene:
    """Everything a render needs, resolved from a scene file and the command line.

    Attributes
    ----------
    intensity_factors : tuple of float
        F values: the light level is F · L (F > 0; F > 1 saturates).
    luminance_cd_m2 : float
        Luminance of the perfect white (``chart`` normalisation) or of each spectrum (``per-spectrum``) at F = 1.
    width, height : int
        Frame size in pixels (charts; a cube's size is its own).
    """

    name: str
    grid: WavelengthGrid
    illuminants: tuple
    intensity_factors: tuple = (1.0,)
    luminance_cd_m2: float = 100.0
    normalisation: str = "chart"
    chart: ChartSpec | None = None
    cube: CubeSpec | None = None
    width: int = 600
    height: int = 400
    camera: str = DEFAULT_CAMERA
    sensitivity_basis: str = "energy"
    scale: AnchorScale | PhysicalScale = field(default_factory=AnchorScale)
    preset_name: str = "paper-table1"
    sensor_overrides: tuple = ()
    statistics: str = "pixel"
    method: str = "poisson"
    tolerance: float = 0.01
    seed: int = 0
    base_dir: Path | None = None

    def __post_init__(self):
        if (self.chart is None) == (self.cube is None):
            raise CamsimError("a scene needs exactly one of [chart] or [cube]")
        if not self.illuminants:
            raise CamsimError("scene lists no illuminants")
        for f in self.intensity_factors:
            if not (isinstance(f, (int, float)) and np.isfinite(f) and f > 0):
                raise CamsimError(f"intensity factor must be a positive number, got {f!r}")
        if not (np.isfinite(self.luminance_cd_m2) and self.luminance_cd_m2 > 0):
            raise CamsimError(f"luminance_cd_m2 must be positive, got {self.luminance_cd_m2!r}")
        if self.normalisation not in NORMALISATIONS:
            raise CamsimError(f"normalisation must be one of {NORMALISATIONS}, got {self.normalisation!r}")
        if self.statistics not in STATISTICS:
            raise CamsimError(f"photon statistics must be one of {STATISTICS}, got {self.statistics!r}")
        if not (isinstance(self.tolerance, float) and 0 < self.tolerance < 1):
            raise CamsimError(f"auto tolerance must be a KS distance in (0, 1), got {self.tolerance!r}")
        if not (isinstance(self.seed, int) and self.seed >= 0):
            raise CamsimError(f"seed must be a non-negative integer, got {self.seed!r}")
        self.sensor  # validate the preset and overrides now

    @property
    def sensor(self) -> SensorParams:
        """The sensor: the named preset with the scene's (and the command line's) overrides applied."""
        return preset(self.preset_name, **dict(self.sensor_overrides))

    def with_sensor(self, **overrides) -> Scene:
        """A copy with more sensor overrides (later ones win)."""
        merged = dict(self.sensor_overrides) | overrides
        return dataclasses.replace(self, sensor_overrides=tuple(sorted(merged.items())))

    def replace(self, **changes) -> Scene:
        return dataclasses.replace(self, **changes)


def read_toml(path: Path, what: str) -> dict:
    """Parse a TOML file; a missing or malformed one is a :class:`CamsimError` naming ``what`` and the path."""
    try:
        with open(path, "rb") as handle:
            return tomllib.load(handle)
    except FileNotFoundError:
        raise CamsimError(f"{what} not found: {path}") from None
    except (OSError, tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise CamsimError(f"cannot read {what} {path}: {exc}") from None


_TOP_KEYS = {"name", "description", "spectral", "chart", "cube", "light", "frame", "camera", "sensor", "render"}


def _table(doc: dict, key: str, allowed: set, where: str) -> dict:
    table = doc.get(key, {})
    if not isinstance(table, dict):
        raise CamsimError(f"{where}: [{key}] must be a table")
    unknown = set(table) - allowed
    if unknown:
        raise CamsimError(f"{where}: unknown key(s) in [{key}]: {', '.join(sorted(unknown))}")
    return table


def _typed(table: dict, key: str, kind, default, where: str):
    if key not in table:
        return default
    value = table[key]
    if kind is float and isinstance(value, int) and not isinstance(value, bool):
        value = float(value)
    if not isinstance(value, kind) or (kind is int and isinstance(value, bool)):
        name = kind.__name__ if isinstance(kind, type) else "/".join(k.__name__ for k in kind)
        raise CamsimError(f"{where}: {key} must be of type {name}, got {value!r}")
    return value


def load_scene(path: str | Path) -> Scene:
    """Read and validate a scene file, given by its path or by a built-in scene's name (``macbeth_26``).

    An existing file always wins; a name (no ``/``, no ``.toml``) is looked up in :mod:`camsim.builtin_scenes`.

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
    base_dir = path.resolve().parent

    spectral = _table(doc, "spectral", {"start_nm", "end_nm", "step_nm"}, where)
    grid = WavelengthGrid(
        _typed(spectral, "start_nm", float, 380.0, where),
        _typed(spectral, "end_nm", float, 780.0, where),
        _typed(spectral, "step_nm", float, 4.0, where),
    )
    light = _table(doc, "light", {"illuminants", "luminance_cd_m2", "intensity_factors", "normalisation"}, where)
    illuminants = _typed(light, "illuminants", list, ["D65"], where)
    if not all(isinstance(name, str) for name in illuminants):
        raise CamsimError(f"{where}: illuminants must be a list of names")
    factors = _typed(light, "intensity_factors", list, [1.0], where)
    frame = _table(doc, "frame", {"width", "height"}, where)
    chart = cube = None
    if "chart" in doc:
        table = _table(
            doc, "chart",
            {"reflectances", "columns", "rows", "gap_fraction", "margin_fraction", "surround_reflectance"}, where,
        )
        surround = _typed(table, "surround_reflectance", float, 0.05, where)
        if not 0 <= surround <= 1:
            raise CamsimError(f"{where}: surround_reflectance must be in [0, 1], got {surround}")
        chart = ChartSpec(
            reflectances=_typed(table, "reflectances", str, "ColorChecker N Ohta", where),
            geometry=ChartGeometry(
                columns=_typed(table, "columns", int, 6, where),
                rows=_typed(table, "rows", int, 4, where),
                gap_fraction=_typed(table, "gap_fraction", float, 0.15, where),
                margin_fraction=_typed(table, "margin_fraction", float, 0.04, where),
            ),
            surround_reflectance=surround,
        )
    if "cube" in doc:
        table = _table(doc, "cube", {"path", "kind"}, where)
        if "path" not in table:
            raise CamsimError(f"{where}: [cube] needs a path to an H × W × N .npy file")
        kind = _typed(table, "kind", str, "reflectance", where)
        if kind not in CUBE_KINDS:
            raise CamsimError(f"{where}: [cube] kind must be one of {CUBE_KINDS}, got {kind!r}")
        cube = CubeSpec(path=base_dir / _typed(table, "path", str, "", where), kind=kind)

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
    scale = scale_cls(**{k: _typed(scale_table, k, float, None, where) for k in scale_table if k != "kind"})

    if not isinstance(doc.get("sensor", {}), dict):
        raise CamsimError(f"{where}: [sensor] must be a table")
    sensor_table = dict(doc.get("sensor", {}))
    preset_name = sensor_table.pop("preset", "paper-table1")
    if "dark_current_e_per_s" in sensor_table:
        sensor_table["dark_current_e_per_s"] = tuple(sensor_table["dark_current_e_per_s"])
    for key in ("conversion_gain_v_per_e", "analog_gain_dn_per_v", "read_noise_e", "full_well_e", "exposure_s"):
        if isinstance(sensor_table.get(key), int) and not isinstance(sensor_table.get(key), bool):
            sensor_table[key] = float(sensor_table[key])
    if not isinstance(preset_name, str):
        raise CamsimError(f"{where}: [sensor] preset must be a name")

    render = _table(doc, "render", {"statistics", "method", "seed", "tolerance"}, where)
    return Scene(
        name=_typed(doc, "name", str, path.stem, where),
        grid=grid,
        illuminants=tuple(illuminants),
        intensity_factors=tuple(float(f) if isinstance(f, int) else f for f in factors),
        luminance_cd_m2=_typed(light, "luminance_cd_m2", float, 100.0, where),
        normalisation=_typed(light, "normalisation", str, "chart", where),
        chart=chart,
        cube=cube,
        width=_typed(frame, "width", int, 600, where),
        height=_typed(frame, "height", int, 400, where),
        camera=_typed(camera, "name", str, DEFAULT_CAMERA, where),
        sensitivity_basis=_typed(camera, "sensitivity_basis", str, "energy", where),
        scale=scale,
        preset_name=preset_name,
        sensor_overrides=tuple(sorted(sensor_table.items())),
        statistics=_typed(render, "statistics", str, "pixel", where),
        method=_typed(render, "method", str, "poisson", where),
        tolerance=_typed(render, "tolerance", float, 0.01, where),
        seed=_typed(render, "seed", int, 0, where),
        base_dir=base_dir,
    )
