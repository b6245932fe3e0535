"""argparse value types shared by the sub-commands: each rejects a bad value with a one-line message."""

from __future__ import annotations

import argparse
import math


def positive_float(text: str) -> float:
    """A finite number > 0."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"must be a positive finite number, got {text}")
    return value


def positive_float_or(names, message: str):
    """An argparse type: one of ``names`` (returned as given) or a finite number > 0; anything else is refused with
    ``message`` and the text given (e.g. a gain: ``"auto"``, ``"white"`` or a number)."""
    def parse(text: str):
        if text in names:
            return text
        try:
            return positive_float(text)
        except argparse.ArgumentTypeError:
            raise argparse.ArgumentTypeError(f"{message}, got {text!r}") from None

    return parse


def _integer(text: str) -> int:
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not an integer: {text!r}") from None


def _integer_at_least(text: str, low: int) -> int:
    value = _integer(text)
    if value < low:
        raise argparse.ArgumentTypeError(f"must be ≥ {low}, got {text}")
    return value


def non_negative_int(text: str) -> int:
    """An integer ≥ 0 (a seed, a border in pixels)."""
    return _integer_at_least(text, 0)


def positive_int(text: str) -> int:
    """An integer ≥ 1 (a count of workers or threads)."""
    return _integer_at_least(text, 1)


def integer_between(low: int, high: int, what: str):
    """An argparse type for an integer from ``low`` to ``high`` inclusive.

    Parameters
    ----------
    low, high : int
        The smallest and the largest value accepted.
    what : str
        The value's name in the message, e.g. ``"the side of the region of interest in pixels"``.

    Returns
    -------
    callable
        ``parse(text) -> int``, raising :class:`argparse.ArgumentTypeError` outside the range.
    """

    def parse(text: str) -> int:
        value = _integer(text)
        if not low <= value <= high:
            raise argparse.ArgumentTypeError(f"{what} must be {low} to {high}, got {text}")
        return value

    return parse


def file_name(what: str):
    """An argparse type for a name that becomes part of a file name (:func:`camsim.core.names.safe_component`).

    Parameters
    ----------
    what : str
        The name's label in the message, e.g. ``"the preset's name"``.
    """
    from camsim.core.errors import CamsimError
    from camsim.core.names import safe_component

    def parse(text: str) -> str:
        try:
            return safe_component(text, what)
        except CamsimError as exc:
            raise argparse.ArgumentTypeError(str(exc)) from None

    return parse


def schema_value(param):
    """The argparse type of a :class:`camsim.core.schema.Param`: its text parsed, typed and range-checked by the
    schema."""
    from camsim.core.errors import CamsimError

    def parse(text: str):
        try:
            return param.parse_text(text)
        except CamsimError as exc:
            raise argparse.ArgumentTypeError(str(exc)) from None

    parse.__name__ = param.name  # argparse names the type in its messages
    return parse


def exposure_setting(param):
    """The argparse type of ``--exposure``: ``auto``, or an exposure time in seconds typed by ``param``."""
    seconds = schema_value(param)

    def parse(text: str):
        if text.strip().lower() == "auto":
            return "auto"
        try:
            return seconds(text)
        except argparse.ArgumentTypeError as exc:
            raise argparse.ArgumentTypeError(f"{exc}; or 'auto'") from None

    parse.__name__ = "exposure"
    return parse


def optics_setting(text: str) -> tuple:
    """``NAME=VALUE`` for a key of a scene's ``[optics]`` (:func:`camsim.optics.params.optics_setting`)."""
    from camsim.core.errors import CamsimError
    from camsim.optics.params import optics_setting as parse

    try:
        return parse(text)
    except CamsimError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def sensor_setting(text: str) -> tuple:
    """``NAME=VALUE`` for a sensor parameter (:data:`camsim.sensor.params.SENSOR_PARAMS`), typed by the schema."""
    from camsim.core.errors import CamsimError
    from camsim.sensor.params import SENSOR_PARAMS

    name, sep, value = text.partition("=")
    params = {p.name: p for p in SENSOR_PARAMS}
    if not sep or name.strip() not in params:
        raise argparse.ArgumentTypeError(f"expected NAME=VALUE with NAME one of {', '.join(params)}, got {text!r}")
    try:
        value = params[name.strip()].parse_text(value.strip())
    except CamsimError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
    return name.strip(), value
