"""The one parameter schema: each parameter's name, type, unit, default, range and help, declared once.

A parameter is declared where its dataclass is (``SensorParams`` in :mod:`camsim.sensor.params`, the render settings of
:class:`camsim.scene.scene_file.Scene`) with :func:`param`, which stores a :class:`Param` in the field's metadata.
Everything else is derived from it: the dataclass's own validation (:func:`validate`), the scene-file reader's
``[sensor]`` and ``[render]`` tables, the dataset spec's parameter types and choices, the command line's choices and its
``--sensor NAME=VALUE`` option, the sidecar's keys and the analysis's grouping keys. So a new sensor parameter is
one field in :class:`camsim.sensor.params.SensorParams` (plus the physics that uses it).
"""

from __future__ import annotations

import dataclasses
import functools
import math
import tomllib
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from camsim.core.errors import CamsimError
from camsim.core.input_files import open_input
from camsim.core.pixel_limit import check_pixel_count

KINDS = ("float", "int", "bool", "str", "rgb")
#: The integers camsim takes anywhere in its input: numpy's int64. A larger one (TOML has no bound) is refused where
#: it is read, as a float beyond float64's range is (a float made from it would be infinite).
INT64_MIN, INT64_MAX = -(2**63), 2**63 - 1
#: The largest TOML file camsim reads (a scene file, a dataset spec, a camera preset file): the largest shipped is a
#: few kilobytes, and a file of thousands of regions or ISO points is still under a megabyte, so a file over this
#: is not one of them, and is refused before its parser holds it (with its tables) in memory. Unit: bytes.
MAX_TOML_BYTES = 16_000_000
_KIND_TEXT = {"float": "a number", "int": "an integer", "bool": "true or false", "str": "a string",
              "rgb": "a number or a list of three numbers (R, G, B)"}


@dataclass(frozen=True)
class Param:
    """One parameter.

    Attributes
    ----------
    name : str
        Its key everywhere (scene files, dataset specs, ``--sensor``, sidecars), with its unit in the name.
    kind : {'float', 'int', 'bool', 'str', 'rgb'}
        ``rgb``: a number or a list of three (one per channel).
    default : object
    doc : str
        One line for help texts.
    unit : str
        Unit, as printed ("" for unitless, names and switches).
    low : float, optional
        Smallest allowed value (inclusive).
    above : float, optional
        The value must be greater than this.
    below : float, optional
        The value must be less than this.
    high : float, optional
        Largest allowed value (inclusive): the physics' bound where the parameter has one (no full well holds
        more, no exposure lasts longer), so that nothing derived from an accepted value overflows.
    choices : tuple of str, optional
        Allowed names (``kind = 'str'``).
    optional : bool
        None is allowed (written ``"none"`` in files and on the command line).
    stage : bool
        A sensor stage switch (grouped under ``stages`` in the sidecar; ``--disable`` on the command line).
    sidecar : callable, optional
        ``sidecar(obj) -> dict``: the sidecar keys this parameter writes (default ``{name: value}``).
    omit_default : bool
        Written to records (the sidecar, :meth:`camsim.sensor.params.SensorParams.to_dict`) only when its value differs
        from the default: for a parameter added later whose default is off, so that the records of everything
        made without it — and the dataset frame ids that hash them — stay byte for byte as they were. An absent
        key then means the default.
    """

    name: str
    kind: str
    default: object
    doc: str = ""
    unit: str = ""
    low: float | None = None
    above: float | None = None
    below: float | None = None
    high: float | None = None
    choices: tuple | None = None
    optional: bool = False
    stage: bool = False
    sidecar: Callable[[object], dict] | None = None
    omit_default: bool = False

    def coerce(self, value, where: str = "", check_range: bool = True):
        """``value`` checked and typed for this parameter (ints become floats where a float is meant).

        ``check_range=False`` checks the type (and finiteness) only: for the bounds of a distribution.

        Raises
        ------
        CamsimError
            ``"<where>: <name> must be …, got …"`` for a value of the wrong type or out of range.
        """
        def bad(what):
            return CamsimError(f"{where + ': ' if where else ''}{self.name} must be {what}, got {shown(value)}")

        if value is None or (self.optional and value == "none"):
            if self.optional:
                return None
            raise bad(_KIND_TEXT[self.kind])
        if self.kind in ("float", "rgb"):
            items = value if self.kind == "rgb" and isinstance(value, (list, tuple)) else [value]
            if (self.kind == "rgb" and len(items) not in (1, 3)) or any(
                    isinstance(v, bool) or not isinstance(v, (int, float)) for v in items):
                raise bad(_KIND_TEXT[self.kind])
            items = [finite_float(v) for v in items]
            for v in items:
                if v is None:
                    raise bad("a finite number")
                if check_range:
                    self._check_range(v, bad)
            return items[0] if len(items) == 1 else items
        if self.kind == "int":
            if isinstance(value, bool) or not isinstance(value, int):
                raise bad("an integer")
            if not INT64_MIN <= value <= INT64_MAX:
                raise bad("an integer within int64 (±9.2e18)")
            if check_range:
                self._check_range(value, bad)
            return value
        if self.kind == "bool":
            if not isinstance(value, bool):
                raise bad("true or false")
            return value
        if not isinstance(value, str):
            raise bad("a string")
        if self.choices is not None and value not in self.choices:
            raise bad("one of " + ", ".join(self.choices))
        return value

    def _check_range(self, v, bad) -> None:
        unit = f" {self.unit}" if self.unit else ""
        if self.above == 0 and self.below is None and not (v > 0 and (self.high is None or v <= self.high)):
            raise bad("a positive number" + ("" if self.high is None else f" ≤ {self.high:g}{unit}"))
        if self.low is not None and not v >= self.low and self.high is None:
            raise bad(f"≥ {self.low:g}{unit}")
        if ((self.above is not None and not v > self.above) or (self.below is not None and not v < self.below)
                or (self.high is not None and not v <= self.high)
                or (self.low is not None and not v >= self.low)):
            low = "" if self.above is None else f"> {self.above:g}"
            low = low if self.low is None else f"≥ {self.low:g}"
            high = "" if self.below is None else f"< {self.below:g}"
            high = high if self.high is None else f"≤ {self.high:g}"
            raise bad(" and ".join(filter(None, (low, high))) + unit)

    def parse_text(self, text: str, where: str = ""):
        """A command-line value (a TOML literal such as ``2.5``, ``[1, 2, 3]``, ``true``, or a bare name)."""
        try:
            value = tomllib.loads(f"v = {text}")["v"]
        except ValueError:  # TOMLDecodeError, or an integer of more than 4300 digits
            value = text  # a bare name: RGGB, tukey-lambda, none
        except RecursionError:
            raise CamsimError(f"{where + ': ' if where else ''}{self.name}: the value is nested too deeply") from None
        return self.coerce(value, where)

    def help_text(self) -> str:
        """``name (unit): doc [choices]`` for help texts."""
        unit = f" ({self.unit})" if self.unit else ""
        choices = f" [{', '.join(self.choices)}{', none' if self.optional else ''}]" if self.choices else ""
        return f"{self.name}{unit}: {self.doc}{choices}"

    def record(self, obj) -> dict:
        """The sidecar keys of this parameter's value in ``obj``."""
        if self.sidecar is not None:
            return self.sidecar(obj)
        value = getattr(obj, self.name)
        if self.omit_default and value == self.default:
            return {}
        return {self.name: list(value) if isinstance(value, tuple) else value}


#: The most values of an array :func:`shown` writes out.
SHOWN_VALUES = 6


def shown(value) -> str:
    """``repr(value)`` for a message, but an integer of more than 24 digits as its size (``an integer of 401
    digits``) and a numpy array as its first :data:`SHOWN_VALUES` values and their count (``[1, 2, 3, …
    (255 values)]``): a message stays one short line."""
    if isinstance(value, int) and not isinstance(value, bool) and value.bit_length() > 80:
        return f"an integer of about {math.ceil(value.bit_length() * math.log10(2))} digits"
    if getattr(value, "ndim", 0) >= 1 and hasattr(value, "tolist"):  # a numpy array (no numpy import here)
        flat = value.reshape(-1).tolist()
        head = ", ".join(f"{v:.6g}" if isinstance(v, float) else repr(v) for v in flat[:SHOWN_VALUES])
        return f"[{head}{f', … ({len(flat)} values)' if len(flat) > SHOWN_VALUES else ''}]"
    return repr(value)


def finite_float(value) -> float | None:
    """``value`` (an int or a float) as a float, or None where that is not finite: NaN, ±infinity, or an integer
    beyond float64's range (``float()`` would raise ``OverflowError``)."""
    try:
        number = float(value)
    except OverflowError:
        return None
    return number if math.isfinite(number) else None


def typed(table: dict, key: str, kind, default, where: str):
    """``table[key]`` if it is of type ``kind`` (ints accepted for floats), else ``default`` when absent.

    A number must be finite and an integer within int64 (:data:`INT64_MIN` to :data:`INT64_MAX`): what TOML
    allows beyond that (``inf``, ``nan``, 10⁴⁰⁰) is refused where the table is read, not deep in the work.
    """
    if key not in table:
        return default
    value = table[key]
    if kind is float and isinstance(value, int) and not isinstance(value, bool):
        value = finite_float(value)
        if value is None:
            raise CamsimError(f"{where}: {key} must be a finite number, got {shown(table[key])}")
    if not isinstance(value, kind) or (kind is int and isinstance(value, bool)):
        name = kind.__name__ if isinstance(kind, type) else "/".join(k.__name__ for k in kind)
        raise CamsimError(f"{where}: {key} must be of type {name}, got {value!r}")
    if isinstance(value, float) and not math.isfinite(value):
        raise CamsimError(f"{where}: {key} must be a finite number, got {value!r}")
    if isinstance(value, int) and not isinstance(value, bool) and not INT64_MIN <= value <= INT64_MAX:
        raise CamsimError(f"{where}: {key} must be an integer within int64 (±9.2e18), got {shown(value)}")
    return value


def check_frame_size(width, height, where: str) -> None:
    """Refuse a frame size that is not two positive integers (pixels) of at most
    :data:`camsim.core.pixel_limit.MAX_PIXELS` in all.

    Raises
    ------
    CamsimError
        ``"<where> width must be a positive integer (pixels), got …"`` or ``"<where> WxH is over 200 megapixels"``.
    """
    for key, value in (("width", width), ("height", height)):
        if isinstance(value, bool) or not isinstance(value, int) or value < 1:
            raise CamsimError(f"{where} {key} must be a positive integer (pixels), got {value!r}")
    check_pixel_count(width, height, where)  # the one limit (camsim.core.pixel_limit), for files' headers too


def read_toml(path: str | Path, what: str) -> dict:
    """Parse a TOML file (a scene file, a dataset spec, a camera preset file); a missing, unreadable or malformed one
    is a :class:`CamsimError` naming ``what`` and the path.

    Malformed includes what the parser itself cannot take: values nested so deeply that it runs out of stack
    (``RecursionError``), an integer of more than 4300 digits (Python's limit for a decimal string).

    The file is opened by :func:`camsim.core.input_files.open_input`: a path with a NUL byte, a directory, a FIFO, a
    device, a socket or a file over :data:`MAX_TOML_BYTES` is refused before a byte is read.
    """
    with open_input(path, what, MAX_TOML_BYTES) as handle:
        try:
            return tomllib.load(handle)
        except (OSError, ValueError) as exc:  # TOMLDecodeError and UnicodeDecodeError are ValueErrors
            raise CamsimError(f"cannot read {what} {path}: {exc}") from None
        except RecursionError:
            raise CamsimError(f"cannot read {what} {path}: its values are nested too deeply") from None


def param(default, kind: str, doc: str, unit: str = "", **checks):
    """A dataclass field declaring a :class:`Param` (its name is the field's)."""
    if kind not in KINDS:
        raise ValueError(f"unknown parameter kind {kind!r}")
    return dataclasses.field(default=default, metadata={"param": Param("", kind, default, doc, unit, **checks)})


@functools.lru_cache(maxsize=None)
def params_of(cls) -> tuple[Param, ...]:
    """The :class:`Param` of every field of dataclass ``cls`` declared with :func:`param`, in field order (computed
    once per class: every validated instance asks)."""
    return tuple(dataclasses.replace(f.metadata["param"], name=f.name)
                 for f in dataclasses.fields(cls) if "param" in f.metadata)


def validate(obj, where: str) -> None:
    """Check and type every schema field of the frozen dataclass instance ``obj`` in place (``__post_init__``)."""
    for p in params_of(type(obj)):
        object.__setattr__(obj, p.name, p.coerce(getattr(obj, p.name), where))


def record(obj) -> dict:
    """The sidecar keys of every schema field of ``obj``, in field order; stage switches under ``stages``."""
    out = {}
    for p in params_of(type(obj)):
        if p.stage:
            out.setdefault("stages", {})[p.name] = getattr(obj, p.name)
        else:
            out.update(p.record(obj))
    return out
