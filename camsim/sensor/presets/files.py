"""Camera preset files (TOML), as ``camsim calibrate`` writes them and ``--preset PATH.toml`` reads them.

::

    [preset]
    name = "my-camera"
    source = "camsim calibrate: 8 dark frames, 6 flat pairs, 2026-11-23"
    bits = 14
    pedestal_dn = 512
    cfa = "RGGB"                      # omitted: a three-chip (or monochrome) sensor
    read_noise_model = "tukey-lambda"
    # optional: title, full_well_e, conversion_gain_v_per_e, dark_current_e_per_s, dual_gain_iso

    [[iso]]                           # one table per calibrated ISO, lowest first
    iso = 3200
    k_dn_per_e = 3.06
    tukey_lambda = -0.035
    tukey_scale_dn = 2.04
    gaussian_sigma_dn = 3.92
    row_sigma_dn = 0.445
    dsnu_dn = 0.0                     # optional
    prnu_percent = 0.0                # optional
    # optional, the sensor effects of issue 28 (sensor parameters of the same names):
    dark_shading_map = "dark_shading.npy"   # e⁻ per pixel, relative to this file
    hot_pixel_map = "hot_pixels.npy"        # e⁻/s per pixel (0 where not hot), relative to this file
    column_fpn_e = 0.0
    black_level_error_dn = 0.0

An ``[[iso]]`` table's sensor effects hold at its ISO only (a map is measured at one gain and exposure): a preset
renders them at that ISO, and refuses an ISO between points where one of them states effects. The maps must be
``.npy`` files of finite numbers (the hot-pixel map ≥ 0), both of one shape: (H, W) for a Bayer sensor (H, W even),
(H, W) or (3, H, W) for a three-chip one; the frame's shape is checked against them when one is rendered.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from camsim.core.errors import CamsimError
from camsim.core.names import safe_component
from camsim.core.schema import read_toml, typed
from camsim.sensor.cfa import CFA_PATTERNS
from camsim.sensor.params import SensorParams, with_overrides
from camsim.sensor.presets.model import CameraPreset, IsoPoint

_PRESET_KEYS = {"name": str, "title": str, "source": str, "bits": int, "pedestal_dn": int, "cfa": str,
                "read_noise_model": str, "full_well_e": float, "conversion_gain_v_per_e": float,
                "dark_current_e_per_s": float, "dual_gain_iso": float}
_REQUIRED = ("name", "source", "bits")
_ISO_KEYS = {f.name: f for f in dataclasses.fields(IsoPoint)}
#: An [[iso]] table's sensor effects (issue 28): sensor parameters of these names, unless :class:`IsoPoint` has them.
_EFFECT_KEYS = {k: kind for k, kind in (("dark_shading_map", str), ("hot_pixel_map", str), ("column_fpn_e", float),
                                         ("black_level_error_dn", float)) if k not in _ISO_KEYS}
_MAP_KEYS = ("dark_shading_map", "hot_pixel_map")


@dataclass(frozen=True)
class FilePreset(CameraPreset):
    """A camera preset read from a file: a :class:`CameraPreset` whose ISO points may carry sensor effects.

    Attributes
    ----------
    effects : tuple of (float, dict)
        (ISO, {sensor parameter: value}) for each ISO point that states effects; a map's value is its absolute path.
    """

    effects: tuple = ()

    def effects_at(self, iso: float | None) -> dict:
        """The sensor effects at ``iso`` (None: the default ISO): those of the ISO point it is, {} where no point
        states any.

        Raises
        ------
        CamsimError
            For an ISO between points where one states effects (they are not interpolated).
        """
        if not self.effects:
            return {}
        iso = self.default_iso if iso is None else iso
        for at, values in self.effects:
            if math.isclose(at, iso, rel_tol=1e-9):
                return dict(values)
        if any(p.iso == iso for p in self.iso_points):
            return {}
        stated = ", ".join(f"{at:g}" for at, _ in self.effects)
        raise CamsimError(f"camera preset {self.name}: its sensor effects hold at ISO {stated} only (measured there, "
                          f"not interpolated); ISO {iso:g} lies between its points")

    def sensor(self, iso: float | None = None, read_noise_model: str | None = None,
               point: IsoPoint | None = None) -> SensorParams:
        """:meth:`CameraPreset.sensor` with the effects of its ISO point (:meth:`effects_at`)."""
        base = super().sensor(iso, read_noise_model, point)
        values = self.effects_at(point.iso if point is not None else iso)
        return with_overrides(base, **values) if values else base


#: Values of a map file checked at a time (:func:`_map_shape`): 64 MB of float64, whatever the map's size.
_MAP_CHECK_VALUES = 8_000_000


def _map_shape(path: Path, key: str, at: str) -> tuple:
    """The shape of a map file, checked: a .npy array of finite numbers, ≥ 0 for the hot-pixel map.

    The path is checked first (:func:`camsim.core.input_files.check_input`: a regular file, no NUL byte), then the
    header (:func:`camsim.core.npy_header.npy_header`: at most three planes of
    :data:`camsim.core.pixel_limit.MAX_PIXELS`, and the data the file holds), then the values, memory-mapped a block
    of rows at a time.
    """
    from camsim.core.input_files import check_input
    from camsim.core.npy_header import npy_header
    from camsim.core.pixel_limit import MAX_PIXELS

    def check_shape(shape):  # before the data is mapped: a header may claim any shape
        if math.prod(shape) > 3 * MAX_PIXELS:
            raise CamsimError(f"{key} {path} holds {math.prod(shape)} values, more than a frame of {MAX_PIXELS} "
                              "pixels (three planes) has")

    try:
        check_input(path, f"{key} file")
        npy_header(path, key, check_shape)
    except CamsimError as exc:
        raise CamsimError(f"{at}: {exc}") from None
    try:
        array = np.load(path, mmap_mode="r", allow_pickle=False)
    except (OSError, ValueError) as exc:
        raise CamsimError(f"{at}: {key} {path} is not a .npy array ({exc})") from None
    if array.ndim not in (2, 3) or (array.ndim == 3 and array.shape[0] != 3) or array.dtype.kind not in "fiu":
        raise CamsimError(f"{at}: {key} {path} must hold numbers of shape (H, W) or (3, H, W), got "
                          f"{array.dtype} {array.shape}")
    flat = array.reshape(-1, order="A")  # a view of the file in its own order (C or Fortran)
    for start in range(0, flat.size, _MAP_CHECK_VALUES):
        values = np.asarray(flat[start:start + _MAP_CHECK_VALUES], np.float64)
        if not np.all(np.isfinite(values)):
            raise CamsimError(f"{at}: {key} {path} holds a NaN or an infinity")
        if key == "hot_pixel_map" and np.any(values < 0):
            raise CamsimError(f"{at}: {key} {path} holds a negative dark current")
    return tuple(array.shape)


def _effects(row: dict, base: Path, cfa: str | None, at: str) -> dict:
    """An [[iso]] table's sensor effects, the map paths made absolute (relative to ``base``) and their shapes
    checked against each other and the sensor's layout; the keys are taken out of ``row``."""
    values = {}
    for key, kind in _EFFECT_KEYS.items():
        if key in row:
            values[key] = typed(row, key, kind, None, at)
            del row[key]
    shapes = {}
    for key in _MAP_KEYS:
        if key in values:
            path = Path(values[key])
            path = path if path.is_absolute() else base / path
            shapes[key] = _map_shape(path, key, at)  # checks the path (a NUL byte) before it is resolved
            values[key] = str(path.resolve())
    if len(set(shapes.values())) > 1:
        raise CamsimError(f"{at}: the maps' shapes differ: " + ", ".join(f"{k} {v}" for k, v in shapes.items()))
    for key, shape in shapes.items():
        if cfa and (len(shape) != 2 or shape[0] % 2 or shape[1] % 2):
            raise CamsimError(f"{at}: {key} of a {cfa} sensor must be a mosaic (H, W) of even sides, got {shape}")
    scalars = {k: v for k, v in values.items() if k not in _MAP_KEYS}
    try:
        with_overrides(SensorParams(), **scalars)  # the schema's ranges (a negative σ …)
    except CamsimError as exc:
        raise CamsimError(f"{at}: {exc}") from None
    return values


def read_preset_file(path: str | Path) -> CameraPreset:
    """A camera preset from a TOML file (module docstring).

    Raises
    ------
    CamsimError
        For a missing or malformed file, unknown or missing keys, or values out of range.
    """
    path = Path(path)
    where = f"camera preset {path}"
    doc = read_toml(path, "camera preset file")
    unknown = set(doc) - {"preset", "iso"}
    if unknown:
        raise CamsimError(f"{where}: unknown table(s) {', '.join(sorted(unknown))}; a preset has [preset] and [[iso]]")
    head = doc.get("preset")
    if not isinstance(head, dict):
        raise CamsimError(f"{where}: needs a [preset] table")
    unknown = set(head) - set(_PRESET_KEYS)
    if unknown:
        raise CamsimError(f"{where}: unknown key(s) in [preset]: {', '.join(sorted(unknown))}")
    missing = [k for k in _REQUIRED if k not in head]
    if missing:
        raise CamsimError(f"{where}: [preset] lacks {', '.join(missing)}")
    fields = {k: typed(head, k, kind, None, where) for k, kind in _PRESET_KEYS.items() if k in head}
    safe_component(fields["name"], f"{where}: name")  # the rule of every name (camsim calibrate --name's too)
    if "cfa" in fields and fields["cfa"] not in CFA_PATTERNS:
        raise CamsimError(f"{where}: cfa must be one of {', '.join(CFA_PATTERNS)}, got {fields['cfa']!r}")
    fields.setdefault("cfa", None)
    fields.setdefault("title", fields["name"])
    rows = doc.get("iso")
    if not isinstance(rows, list) or not rows or not all(isinstance(r, dict) for r in rows):
        raise CamsimError(f"{where}: needs at least one [[iso]] table")
    points = []
    effects = []
    for i, row in enumerate(rows):
        at = f"{where} [[iso]] #{i + 1}"
        row = dict(row)
        values = _effects(row, path.parent, fields["cfa"], at)
        unknown = set(row) - set(_ISO_KEYS)
        if unknown:
            raise CamsimError(f"{at}: unknown key(s): {', '.join(sorted(unknown))}")
        missing = [f.name for f in _ISO_KEYS.values() if f.default is dataclasses.MISSING and f.name not in row]
        if missing:
            raise CamsimError(f"{at}: lacks {', '.join(missing)}")
        try:
            points.append(IsoPoint(**{k: typed(row, k, float, None, at) for k in row}))
        except CamsimError as exc:
            raise CamsimError(f"{at}: {exc}") from None
        if values:
            effects.append((points[-1].iso, tuple(sorted(values.items()))))
    points.sort(key=lambda p: p.iso)
    try:
        return FilePreset(iso_points=tuple(points), effects=tuple(sorted(effects)), **fields)
    except CamsimError as exc:
        raise CamsimError(f"{where}: {exc}") from None
