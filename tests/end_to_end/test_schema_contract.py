"""The schema's ranges are the contract: any value the one parameter schema (:mod:`camsim.core.schema`) accepts for
a sensor, render, optics or sequence parameter renders a 60 × 40 frame; any other is refused on one line. Never a
traceback, never another exit status.

The values are drawn per parameter from its own declaration (its kind, bounds and choices): the bounds themselves
and just inside them, the extremes of float64 (1e300, 1e-300, the largest and the least subnormal), and any number,
so that both sides of every bound are tried. A frame that cannot be rendered with an accepted value is a defect of
the schema (a range wider than the physics) or of the code (a derived quantity that overflows).
"""

from __future__ import annotations

import math
import tomllib

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from camsim.cli import main
from camsim.core.schema import params_of
from camsim.optics.params import OpticsParams
from camsim.scene.builtin_scenes import builtin_scene_path
from camsim.scene.scene_file import Scene
from camsim.scene.sequence import SequenceParams
from camsim.sensor.params import MAP_FILE_PARAMS, SENSOR_PARAMS
from tests.support.fuzz import to_toml
from tests.support.profiles import examples

pytestmark = pytest.mark.slow

#: The schema's tables, as a scene file names them, and their parameters (map files are paths, not values: the
#: fuzz run's input-path cases try those).
TABLES = {
    "sensor": [p for p in SENSOR_PARAMS if p.name not in MAP_FILE_PARAMS],
    "render": list(params_of(Scene)),
    "optics": list(params_of(OpticsParams)),
    "sequence": list(params_of(SequenceParams)),
}
FLOAT_EXTREMES = (1e300, -1e300, 1e-300, -1e-300, 5e-324, 1.7976931348623157e308, 0.0, -0.0, 1.0, -1.0)


def _near(bound: float) -> list[float]:
    return [bound, math.nextafter(bound, math.inf), math.nextafter(bound, -math.inf), bound * 1.5, bound / 2]


def float_values(p):
    bounds = [b for b in (p.low, p.above, p.below) if b is not None]
    special = [v for b in bounds for v in _near(float(b))]
    return st.one_of(st.sampled_from(FLOAT_EXTREMES + tuple(special)),
                     st.floats(allow_nan=False, allow_infinity=False),
                     st.floats(min_value=-1e6, max_value=1e6))


def int_values(p):
    bounds = [int(b) for b in (p.low, p.above, p.below) if b is not None]
    special = [v for b in bounds for v in (b - 1, b, b + 1)]
    return st.one_of(st.sampled_from(tuple(special) + (0, 1, -1, 2**31, 2**53, 2**62, 2**63 - 1, -(2**63))),
                     st.integers(min_value=-(2**63), max_value=2**63 - 1), st.integers(0, 100))


def values_of(p):
    """A strategy for values of parameter ``p``, in range and out of it."""
    if p.kind == "float":
        base = float_values(p)
    elif p.kind == "rgb":
        base = float_values(p) | st.lists(float_values(p), min_size=3, max_size=3)
    elif p.kind == "int":
        base = int_values(p)
    elif p.kind == "bool":
        base = st.booleans()
    else:
        base = st.sampled_from(tuple(p.choices or ()) + ("none", "x"))
    return base | st.just("none") if p.optional else base


def _base_scene() -> dict:
    doc = tomllib.loads(builtin_scene_path("macbeth_26").read_text(encoding="utf-8"))
    doc["frame"] = {"width": 60, "height": 40}
    doc["light"].update(illuminants=["D65"], intensity_factors=[1.0])
    return doc


BASE = _base_scene()
#: What a table needs besides the drawn value: a sequence's frames (two, each 1 s exposure inside its interval).
REQUIRED = {"sequence": {"frames": 2, "frame_interval_s": 1.5}}


@st.composite
def edits(draw):
    """1 to 3 (table, name, value) edits of the schema's parameters."""
    out = []
    for _ in range(draw(st.integers(1, 3))):
        table = draw(st.sampled_from(sorted(TABLES)))
        p = draw(st.sampled_from(TABLES[table]))
        out.append((table, p.name, draw(values_of(p))))
    return out


@settings(max_examples=examples(150), suppress_health_check=[HealthCheck.function_scoped_fixture,
                                                             HealthCheck.too_slow])
@given(changes=edits())
def test_any_schema_value_renders_or_is_refused_on_one_line(changes, tmp_path_factory, capsys):
    doc = {key: (dict(value) if isinstance(value, dict) else value) for key, value in BASE.items()}
    for table, name, value in changes:
        doc.setdefault(table, dict(REQUIRED.get(table, {})))[name] = value
    folder = tmp_path_factory.mktemp("contract")
    scene = folder / "scene.toml"
    scene.write_text(to_toml(doc), encoding="utf-8")
    capsys.readouterr()
    rc = main(["render", str(scene), "--out", str(folder / "out"), "-q", "--workers", "1"])
    err = capsys.readouterr().err.strip().splitlines()
    if rc == 0:
        assert not [line for line in err if line.startswith("camsim: error")], err
        assert list((folder / "out").glob("*.json")), "a render that exits 0 writes its frame"
    else:
        assert rc == 2, (changes, rc, err)
        assert len(err) == 1 and err[0].startswith("camsim: error: "), (changes, err)
