"""The frame sidecar as input: parsed within limits and checked against the one schema before anything uses it.

A sidecar (``STEM.json``, or an EXR header's ``camsim:metadata``) is read back by ``analyze``, ``denoise-eval``
and ``--dark``, and a file on disk may say anything. :func:`parse_sidecar` turns JSON text into a dict, with
the JSON parser's own limits (nesting deeper than Python's recursion limit, an integer of more than 4300 digits)
reported as bad input; :func:`check_sidecar` checks every key the readers use for its type, its shape, its range
and finiteness. The sensor's keys are checked by their declaration in :class:`camsim.sensor.params.SensorParams`
(:meth:`camsim.core.schema.Param.coerce`); the frame's own keys (the scene, the patches, the camera's curves, the
derived levels) are declared here, in :data:`FRAME_KEYS`. A sidecar that passes gives finite numbers of the
expected shapes to every computation of the analysis.
"""

from __future__ import annotations

import json
import math
import re

from camsim.core.errors import CamsimError

#: Keys every frame's sidecar has (a sidecar without one is not a camsim frame's).
REQUIRED = ("illuminant", "intensity_factor", "photon_statistics", "dn_per_electron", "black_level_dn",
            "wavelengths_nm", "qe_e_m2_sr_per_photon", "patches", "stages", "bits", "white_level_dn", "width_px",
            "height_px", "full_well_e", "read_noise_e", "exposure_s")
#: Keys of :data:`REQUIRED` a raw scene's frame (``"scene_source": "raw"``) does without: a real camera's raw has
#: no spectral curves in camsim (its colour is its ColorMatrix1).
RAW_OPTIONAL = ("wavelengths_nm", "qe_e_m2_sr_per_photon")
#: Most wavelength samples a sidecar may hold (camsim's finest grid is 1 nm over 360–830 nm: 471).
MAX_WAVELENGTHS = 100_000
_SHOWN = 60  # characters of a bad value shown in a message
#: Largest magnitude of a sidecar's number, and smallest of one that must be positive: products and quotients of a
#: few of them stay finite in float64 (far outside any physical value a frame records).
MAX_MAGNITUDE, MIN_POSITIVE = 1e60, 1e-60
#: The largest sidecar camsim parses (a file, or an EXR header's ``camsim:metadata``): a chart frame's sidecar is
#: about 30 kB, a 36 000-row rolling-shutter frame's (a homography per row) about 7 MB; 64 MB parses in about a
#: second. Unit: bytes.
MAX_SIDECAR_BYTES = 64_000_000
#: The most values (counted by their separating commas, before parsing) a sidecar may hold: 2 × 10⁶, six times a
#: 36 000-row rolling-shutter frame's per-row homographies (9 numbers a row); a chart's sidecar holds about 2 000.
#: It keeps each of the few parses a command makes of a sidecar (``analyze``: up to 7) near half a second.
#: Unit: values.
MAX_SIDECAR_VALUES = 2_000_000


class _Bad(Exception):
    """A value that does not fit; its text says what it must be."""


def _shown(value) -> str:
    text = repr(value)
    return text if len(text) <= _SHOWN else text[: _SHOWN - 1] + "…"


def _number(value, low=None, above=None, below=None) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise _Bad("a number")
    try:
        v = float(value)
    except OverflowError:  # an integer beyond the float range
        raise _Bad("a finite number") from None
    if not math.isfinite(v):
        raise _Bad("a finite number")
    if abs(v) > MAX_MAGNITUDE:
        raise _Bad(f"a number within ±{MAX_MAGNITUDE:g}")
    if above == 0 and v < MIN_POSITIVE:
        raise _Bad(f"a positive number of at least {MIN_POSITIVE:g}")
    if low is not None and not v >= low:
        raise _Bad(f"≥ {low:g}")
    if above is not None and not v > above:
        raise _Bad(f"> {above:g}")
    if below is not None and not v < below:
        raise _Bad(f"< {below:g}")
    return v


def _integer(value, low=None) -> int:
    if isinstance(value, bool) or not isinstance(value, int):
        raise _Bad("an integer")
    if low is not None and value < low:
        raise _Bad(f"an integer ≥ {low}")
    return value


def _string(value, choices=None) -> str:
    if not isinstance(value, str):
        raise _Bad("a string")
    if choices is not None and value not in choices:
        raise _Bad("one of " + ", ".join(choices))
    return value


def _numbers(value, length: int, low=None, what="numbers") -> list:
    """A list of ``length`` finite numbers (each ≥ ``low``)."""
    if not isinstance(value, list) or len(value) != length:
        raise _Bad(f"a list of {length} {what}")
    try:
        return [_number(v, low=low) for v in value]
    except _Bad as exc:
        raise _Bad(f"a list of {length} {what}, each {exc}") from None


def _rgb(low=None):
    return lambda value: _numbers(value, 3, low, "numbers (R, G, B)")


def _optional(check):
    return lambda value: None if value is None else check(value)


def _matrix(rows: int, columns: int, low=None):
    def check(value):
        if not isinstance(value, list) or len(value) != rows:
            raise _Bad(f"a {rows} × {columns} list of lists of numbers")
        return [_numbers(row, columns, low) for row in value]
    return check


def _stages(value) -> dict:
    from camsim.sensor.params import STAGES

    if not isinstance(value, dict):
        raise _Bad("an object of the sensor's stage switches (" + ", ".join(STAGES) + ")")
    for name in STAGES:
        if not isinstance(value.get(name), bool):
            raise _Bad(f"an object with {name} true or false")
    return value


def _sequence(value):
    """A frame of a ``[sequence]``: its record, an object whose ``stem`` names the sequence."""
    if value is None:
        return None
    if not isinstance(value, dict) or not isinstance(value.get("stem"), str):
        raise _Bad("null or an object with a stem (the sequence's name)")
    return value


def _raw_source(value):
    """A raw scene's frame's source record: an object; its mask counts (``masked_px``, and a sequence frame's
    ``masked_partial_px``: sites partly from masked source sites, camsim.render.raw_sequence) integers ≥ 0."""
    if not isinstance(value, dict):
        raise _Bad("an object (the raw source's record; its masked_px and a sequence frame's masked_partial_px "
                   "integers ≥ 0)")
    for key in ("masked_px", "masked_partial_px"):
        if key in value:
            try:
                _integer(value[key], low=0)
            except _Bad as exc:
                raise _Bad(f"an object whose {key} is {exc}") from None
    return value


def _per_row(value, check, what: str) -> list:
    """A list of one entry per row (its length is checked against ``height_px`` by :func:`check_sidecar`)."""
    if not isinstance(value, list) or not value:
        raise _Bad(f"a list of {what}, one per row")
    for item in value:
        try:
            check(item)
        except _Bad:
            raise _Bad(f"a list of {what}, one per row") from None
    return value


def _optics(value):
    """A frame made through a scene's ``[optics]`` (:mod:`camsim.render.optics`): the table's keys (checked by its
    schema, :func:`camsim.optics.params.parse_optics`), ``channel_wavelength_weights`` (``wavelength_nm`` and three
    rows of weights ≥ 0 on them, each summing to 1), ``otf_model`` (text) and, where written, the clip at 0's
    ``negative_clipped_e`` and ``negative_clipped_fraction`` (3 numbers ≥ 0 each)."""
    from camsim.core.errors import CamsimError
    from camsim.optics.params import parse_optics

    what = ("an object of the [optics] keys, channel_wavelength_weights, otf_model and the clip at 0's "
            "negative_clipped_e and negative_clipped_fraction")
    if not isinstance(value, dict):
        raise _Bad(what)
    clipped = ("negative_clipped_e", "negative_clipped_fraction")
    table = {k: v for k, v in value.items() if k not in ("channel_wavelength_weights", "otf_model") + clipped}
    if table.get("relative_illumination", 0) is None:
        del table["relative_illumination"]
    try:
        parse_optics(table)
    except CamsimError as exc:
        raise _Bad(f"{what} ({exc})") from None
    weights = value.get("channel_wavelength_weights")
    if not isinstance(weights, dict) or not isinstance(weights.get("wavelength_nm"), list):
        raise _Bad(f"{what}: channel_wavelength_weights an object of wavelength_nm and weights")
    count = len(weights["wavelength_nm"])
    _numbers(weights["wavelength_nm"], count, low=0)
    rows = _matrix(3, count, low=0)(weights.get("weights"))
    if any(abs(sum(row) - 1) > 1e-6 for row in rows):
        raise _Bad(f"{what}: each channel's weights summing to 1")
    _string(value.get("otf_model"))
    for key in clipped:
        if key in value:
            _numbers(value[key], 3, low=0, what=f"numbers ({key})")
    return value


def _surround(value):
    if value is None:
        return None
    if not isinstance(value, dict):
        raise _Bad("null or an object with signal_e")
    _rgb(low=0)(value.get("signal_e"))
    return value


def _noise_profile(value):
    if value is None:
        return None
    return _matrix(3, 2)(value)


#: The frame's own keys (besides the sensor's, checked by their schema): key → check (raises :class:`_Bad`).
#: Keys absent from a sidecar are not checked (older sidecars lack some); :data:`REQUIRED` names those it must have.
FRAME_KEYS = {
    "camsim_version": _string,
    "scene": _string,
    "scene_source": lambda v: _string(v, ("raw",)),
    "illuminant": _string,
    "intensity_factor": lambda v: _number(v, above=0),
    "seed": _optional(lambda v: _integer(v, low=0)),
    "photon_statistics": lambda v: _string(v, ("pixel", "paper")),
    "method": _string,
    "auto_tolerance_ks": _optional(lambda v: _number(v, low=0, below=1)),
    "exposure": _string,
    "exposure_target_e": _optional(lambda v: _number(v, above=0)),
    "exposure_max_s": _optional(lambda v: _number(v, above=0)),
    "camera": _string,
    "sensitivity_basis": _string,
    "reflectances": _string,
    "width_px": lambda v: _integer(v, low=1),
    "height_px": lambda v: _integer(v, low=1),
    "sensor_layout": lambda v: _string(v, ("three-chip", "bayer")),
    "white_level_dn": lambda v: _number(v, above=0),
    "dn_per_electron": lambda v: _number(v, above=0),
    "black_level_dn": _rgb(),
    "dark_level_dn": _rgb(),
    "black_level_tag_dn": _rgb(),
    "stages": _stages,
    "noise_profile": _noise_profile,
    "luminance_cd_m2": _optional(lambda v: _number(v, low=0)),
    "color_matrix1_xyz_to_camera": _matrix(3, 3),
    "as_shot_neutral": _rgb(),
    "surround": _surround,
    "white_signal_e": _optional(_rgb(low=0)),
    "iso": _optional(lambda v: _number(v, above=0)),
    # issue 28's per-frame records (present only where their effect is on)
    "black_level_error_drawn_dn": _rgb(),
    "dark_current_effective_e_per_s": _rgb(low=0),
    "defect_counts": lambda v: _defect_counts(v),
    # a [sequence]'s frame (camsim.render.sequence): its index, start time, homography from the reference, record
    "frame_index": _optional(lambda v: _integer(v, low=0)),
    "time_s": _optional(lambda v: _number(v, low=0)),
    "homography": _optional(_matrix(3, 3)),
    "sequence": _sequence,
    "raw_source": _raw_source,
    # a rolling shutter's (row r exposed from time_s + r · rolling_shutter_row_s) and a flickering light's frame
    "rolling_shutter_row_s": _optional(lambda v: _number(v, low=0)),
    "row_homographies": _optional(lambda v: _per_row(v, _matrix(3, 3), "3 × 3 matrices")),
    "flicker_factor": _optional(lambda v: _number(v, low=0)),
    "flicker_row_factor": _optional(lambda v: _per_row(v, lambda f: _number(f, low=0), "numbers ≥ 0")),
    # a scene's [optics] (camsim.render.optics): the table, each channel's wavelength weights, the OTF's statement
    "optics": _optics,
}

#: The keys with one entry per row of the frame (``height_px`` of them).
PER_ROW_KEYS = ("row_homographies", "flicker_row_factor")


def _defect_counts(value) -> dict:
    """``{"hot": n, "dead": n, "stuck": n}``, counts ≥ 0."""
    if not isinstance(value, dict) or set(value) != {"hot", "dead", "stuck"}:
        raise _Bad("an object with hot, dead and stuck counts")
    for count in value.values():
        _integer(count, low=0)
    return value


def _check_curves(meta: dict) -> None:
    """``wavelengths_nm`` (increasing) and ``qe_e_m2_sr_per_photon`` (3 rows on them, ≥ 0)."""
    wavelengths = meta["wavelengths_nm"]
    if not isinstance(wavelengths, list) or not 2 <= len(wavelengths) <= MAX_WAVELENGTHS:
        raise _Bad(f"a list of 2 to {MAX_WAVELENGTHS} wavelengths", "wavelengths_nm", wavelengths)
    values = _checked_at(wavelengths, "wavelengths_nm", lambda v: _numbers(v, len(v), low=0))
    if any(b <= a for a, b in zip(values, values[1:])):
        raise _Bad("increasing", "wavelengths_nm", wavelengths)
    try:
        _matrix(3, len(values), low=0)(meta["qe_e_m2_sr_per_photon"])
    except _Bad as exc:
        raise _Bad(f"{exc} (R, G, B on wavelengths_nm), ≥ 0", "qe_e_m2_sr_per_photon",
                   meta["qe_e_m2_sr_per_photon"]) from None


def _check_patch(patch, index: int, width: int, height: int) -> None:
    key = f"patches[{index}]"
    if not isinstance(patch, dict):
        raise _Bad("an object", key, patch)
    checks = {"name": _string, "signal_e": _rgb(low=0), "dark_e": _rgb(low=0), "signal_var_e2": _rgb(low=0),
              "clean_dn": _rgb()}
    for name, check in checks.items():
        if name not in patch:
            raise _Bad("present", f"{key}.{name}", None)
        _checked_at(patch[name], f"{key}.{name}", check)
    for name, check in (("xyz_cd_m2", _optional(_rgb())), ("gaussian_ks", _ks_distances)):
        if name in patch:
            _checked_at(patch[name], f"{key}.{name}", check)
    rect = patch.get("rect_xywh")
    if (not isinstance(rect, list) or len(rect) != 4 or any(isinstance(v, bool) or not isinstance(v, int)
                                                            for v in rect)):
        raise _Bad("a list of 4 integers (x, y, width, height)", f"{key}.rect_xywh", rect)
    x, y, w, h = rect
    if x < 0 or y < 0 or w < 1 or h < 1 or x + w > width or y + h > height:
        raise _Bad(f"a rectangle inside the {width}x{height} frame", f"{key}.rect_xywh", rect)


def _ks_distances(value) -> list:
    """A patch's ``gaussian_ks``: per channel a KS distance (≥ 0) or null."""
    if not isinstance(value, list) or len(value) != 3:
        raise _Bad("a list of 3 numbers or nulls")
    return [None if v is None else _number(v, low=0) for v in value]


#: Deepest nesting of lists and objects a sidecar may have (its own deepest is 4: ``patches[i].signal_e``).
MAX_DEPTH = 16


_JSON_STRING = re.compile(r'"(?:[^"\\]|\\.)*"')
_NOT_BRACKET = re.compile(r"[^\[\]{}]+")
_INNERMOST = re.compile(r"\[\]|\{\}")


def _too_deep(value, limit: int = MAX_DEPTH) -> bool:
    """Whether ``value`` nests lists and objects more than ``limit`` deep.

    Judged on its JSON text, by the C code of ``json`` and ``re``, not by a walk of its items in Python (seconds for
    a list of millions of empty lists): the strings dropped, then everything but the brackets, then the innermost
    ``[]`` and ``{}`` pairs removed ``limit`` times over; whatever is left nests deeper.
    """
    try:
        text = json.dumps(value, check_circular=False, allow_nan=True, default=str)
    except RecursionError:
        return True
    brackets = _NOT_BRACKET.sub("", _JSON_STRING.sub("", text))
    for _ in range(limit):
        if not brackets:
            return False
        brackets = _INNERMOST.sub("", brackets)  # one level a pass
    return bool(brackets)


def _check_sizes(meta: dict) -> None:
    """The sidecar's lists bounded by the frame it describes, before any item is looked at: a frame of at most
    :data:`camsim.core.pixel_limit.MAX_PIXELS`, one entry per row where a key has one, no more patches than the frame
    has pixels (each covers at least one), no more wavelength weights than :data:`MAX_WAVELENGTHS`."""
    from camsim.core.pixel_limit import MAX_PIXELS

    for key in ("width_px", "height_px"):
        _checked_at(meta[key], key, lambda v: _integer(v, low=1))
    width, height = meta["width_px"], meta["height_px"]
    if width * height > MAX_PIXELS:
        raise _Bad(f"a frame of at most {MAX_PIXELS // 1_000_000} megapixels with height_px {height}",
                   "width_px", width)
    for key in PER_ROW_KEYS:
        if isinstance(meta.get(key), list) and len(meta[key]) != height:
            raise _Bad(f"one entry per row (height_px {height})", key, _Length(len(meta[key])))
    patches = meta["patches"]
    if isinstance(patches, list) and len(patches) > width * height:
        raise _Bad(f"at most one patch per pixel of the {width}x{height} frame ({width * height})", "patches",
                   _Length(len(patches)))
    weights = meta.get("optics", {}).get("channel_wavelength_weights") if isinstance(meta.get("optics"), dict) \
        else None
    grid = weights.get("wavelength_nm") if isinstance(weights, dict) else None
    if isinstance(grid, list) and len(grid) > MAX_WAVELENGTHS:
        raise _Bad(f"at most {MAX_WAVELENGTHS} wavelengths", "optics.channel_wavelength_weights.wavelength_nm",
                   _Length(len(grid)))


class _Length(int):
    """A list's length, shown as what it is in a message (the list itself is too long to show)."""

    def __repr__(self):
        return f"a list of {int(self)}"


def _checked_at(value, key, check):
    """``check(value)``'s result; its :class:`_Bad` raised again naming ``key`` and ``value``."""
    try:
        return check(value)
    except _Bad as exc:
        raise _Bad(str(exc), key, value) from None


def check_sidecar(meta, where) -> dict:
    """``meta`` if it is a camsim frame's sidecar whose every key the readers use is of the right type, shape and
    range, and finite; else :class:`~camsim.core.errors.CamsimError`.

    Parameters
    ----------
    meta : object
        The parsed sidecar (:func:`parse_sidecar`).
    where : str or Path
        The file it came from, for the message.

    Raises
    ------
    CamsimError
        ``"<where>: sidecar key <key> must be …, got …"`` (one line, the value shortened), or the keys a camsim
        frame's sidecar has that it lacks.
    """
    from camsim.sensor.params import SENSOR_PARAMS

    if not isinstance(meta, dict):
        raise CamsimError(f"{where}: metadata is not a JSON object")
    if _too_deep(meta):
        raise CamsimError(f"{where}: metadata nests lists and objects more than {MAX_DEPTH} deep (not a camsim frame)")
    # a raw scene's frame (scene_source "raw") has no spectral curves: its camera is a real one, known by its matrix
    raw = meta.get("scene_source") == "raw"
    missing = [key for key in REQUIRED if key not in meta and not (raw and key in RAW_OPTIONAL)]
    if missing:
        raise CamsimError(f"{where}: metadata lacks {', '.join(missing)} (not a camsim frame?)")
    try:
        _check_sizes(meta)
        for key, check in FRAME_KEYS.items():
            if key in meta:
                _checked_at(meta[key], key, check)
        for p in SENSOR_PARAMS:  # the sensor's own keys, by their declaration
            if p.stage or p.sidecar is not None and p.name not in ("bits",):
                continue
            if p.name in meta:
                try:
                    value = p.coerce(meta[p.name])
                except CamsimError as exc:
                    text = str(exc).removeprefix(f"{p.name} must be ")
                    raise _Bad(text.rsplit(", got ", 1)[0], p.name, meta[p.name]) from None
                for v in value if isinstance(value, list) else [value]:  # the sidecar's bounds on top
                    if isinstance(v, (int, float)) and not isinstance(v, bool):
                        try:
                            _number(v, above=0 if p.above == 0 else None)
                        except _Bad as exc:
                            raise _Bad(str(exc), p.name, meta[p.name]) from None
        if meta.get("cfa_pattern") is not None:
            from camsim.sensor.cfa import CFA_PATTERNS

            if meta["cfa_pattern"] not in CFA_PATTERNS:
                raise _Bad("null or one of " + ", ".join(CFA_PATTERNS), "cfa_pattern", meta["cfa_pattern"])
        if meta.get("tukey_lambda") is not None:
            _checked_at(meta["tukey_lambda"], "tukey_lambda", lambda v: _number(v, above=-0.5, below=1))
        if not raw or "wavelengths_nm" in meta or "qe_e_m2_sr_per_photon" in meta:
            _check_curves(meta)
        if not isinstance(meta["patches"], list):
            raise _Bad("a list of patches", "patches", meta["patches"])
        for index, patch in enumerate(meta["patches"]):
            _check_patch(patch, index, meta["width_px"], meta["height_px"])
    except _Bad as exc:
        what, key, value = exc.args
        got = "" if what == "present" else f", got {_shown(value)}"
        raise CamsimError(f"{where}: sidecar key {key} must be {what}{got}") from None
    return meta


def parse_sidecar(text: str, where) -> object:
    """The JSON value of a sidecar's ``text``; the parser's limits are bad input.

    Raises
    ------
    CamsimError
        Text over :data:`MAX_SIDECAR_BYTES` or :data:`MAX_SIDECAR_VALUES`, text that is not JSON, JSON nested
        deeper than Python's recursion limit, or an integer of more digits than Python converts (4300).
    """
    from camsim.core.input_files import size_text

    size = len(text.encode("utf-8", "surrogatepass")) if len(text) * 4 > MAX_SIDECAR_BYTES else len(text)
    if size > MAX_SIDECAR_BYTES:  # before the parser spends seconds and gigabytes on it
        raise CamsimError(f"cannot read sidecar {where}: it is {size_text(size)}, over the limit of "
                          f"{size_text(MAX_SIDECAR_BYTES)} for a frame's sidecar")
    values = text.count(",") + 1
    if values > MAX_SIDECAR_VALUES:
        raise CamsimError(f"cannot read sidecar {where}: it holds about {values} values, over the limit of "
                          f"{MAX_SIDECAR_VALUES} for a frame's sidecar")
    try:
        return json.loads(text)
    except RecursionError:
        raise CamsimError(f"cannot read sidecar {where}: JSON nested too deeply") from None
    except ValueError as exc:  # json.JSONDecodeError, and int()'s digit limit
        raise CamsimError(f"cannot read sidecar {where}: {str(exc).splitlines()[0][:200]}") from None
