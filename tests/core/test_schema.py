"""The parameter schema: one declaration per parameter, and every consumer derived from it.

For every sensor parameter (whatever is declared in ``SensorParams`` today or later) a non-default value must
reach the scene-file reader, the dataset spec, the command line, the sidecar and the analysis grouping keys, and
a bad value must be refused by each with one message.
"""

import dataclasses

import numpy as np
import pytest

from camsim.analysis.grouping import GROUP_KEYS
from camsim.core.errors import CamsimError
from camsim.core.schema import Param
from camsim.dataset.spec_parts import PARAMETERS
from camsim.methods import METHOD_NAMES, METHODS, get_method
from camsim.scene.scene_file import RENDER_PARAMS, load_scene
from camsim.sensor.params import SENSOR_PARAMS, STAGES, SensorParams

#: A valid value different from the default, for each kind of parameter.
OTHER = {"float": lambda p: (p.low if p.low is not None else 0) + 0.25 if p.default == 0 else p.default * 0.5,
         "int": lambda p: p.default + 1, "bool": lambda p: not p.default}


def other_value(p: Param):
    """A valid value of ``p`` other than its default, as a TOML literal and as the value SensorParams holds."""
    if p.kind == "str" and p.choices is None:  # a file name (issue 28's maps): absolute, so taken as written
        return '"/maps/map.npy"', "/maps/map.npy"
    if p.default is None and p.kind == "float":  # an optional number (temperature_c)
        return "20.0", 20.0
    if p.kind == "str":
        value = next(c for c in p.choices if c != p.default)
        return f'"{value}"', value
    if p.kind == "rgb":
        return "[1.5, 2.5, 3.5]", (1.5, 2.5, 3.5)
    value = OTHER[p.kind](p)
    if p.name == "tukey_lambda":
        value = 0.05
    return (str(value).lower() if p.kind == "bool" else repr(value)), value


def test_sensor_params_are_declared_once_with_unit_and_help():
    names = [p.name for p in SENSOR_PARAMS]
    assert names == [f.name for f in dataclasses.fields(SensorParams)]
    assert STAGES == ("photon_noise", "dark_current", "saturation", "read_noise", "quantisation")
    for p in SENSOR_PARAMS:
        assert p.doc, p.name
        assert p.kind in ("float", "int", "bool", "str", "rgb")
        assert getattr(SensorParams(), p.name) == (tuple(p.default) if p.kind == "rgb" else p.default)


@pytest.mark.parametrize("p", SENSOR_PARAMS, ids=lambda p: p.name)
def test_every_sensor_parameter_reaches_every_consumer(p, tmp_path):
    literal, value = other_value(p)
    # the Tukey shape is recorded only with the Tukey read noise: set that law on both sides
    context = {"read_noise_model": "tukey-lambda"} if p.name == "tukey_lambda" else {}
    # scene file [sensor] table
    scene_file = tmp_path / "s.toml"
    lines = "".join(f'{k} = "{v}"\n' for k, v in context.items())
    scene_file.write_text(f"[chart]\n[sensor]\n{lines}{p.name} = {literal}\n")
    sensor = load_scene(scene_file).sensor
    assert getattr(sensor, p.name) == value != getattr(SensorParams(), p.name)
    # dataset spec parameter (same typing as the schema)
    assert PARAMETERS[p.name].coerce(value if p.kind != "rgb" else list(value), "spec") == (
        list(value) if p.kind == "rgb" else value)
    # command line: --sensor NAME=VALUE
    from camsim.cli import build_parser
    from camsim.cli.commands.render import sensor_overrides

    args = build_parser().parse_args(["render", "macbeth_26", "--sensor", f"{p.name}={literal.strip(chr(34))}"])
    assert getattr(SensorParams(**context, **{p.name: sensor_overrides(args)[p.name]}), p.name) == value
    # sidecar and grouping keys: every key the parameter writes is a grouping key
    record = sensor.sidecar_record()
    written = set(p.record(sensor)) if not p.stage else {"stages"}
    assert written <= set(record) and written <= set(GROUP_KEYS)
    baseline = SensorParams(**context).sidecar_record()
    if p.omit_default:  # written only when set: absent at the default (readers take absent as the default)
        assert not written & set(baseline), p.name
    assert any(record[key] != baseline.get(key) for key in written), p.name


@pytest.mark.parametrize("p", [p for p in SENSOR_PARAMS if p.kind in ("float", "int", "str")], ids=lambda p: p.name)
def test_a_bad_value_is_refused_by_the_scene_reader_and_the_dataclass(p, tmp_path):
    bad = '"nonsense"' if p.kind != "str" else "3"
    scene_file = tmp_path / "s.toml"
    scene_file.write_text(f"[chart]\n[sensor]\n{p.name} = {bad}\n")
    with pytest.raises(CamsimError, match=p.name):
        load_scene(scene_file)
    with pytest.raises(CamsimError, match=p.name):
        SensorParams(**{p.name: "nonsense" if p.kind != "str" else 3})


def test_ranges_come_from_the_schema():
    with pytest.raises(CamsimError, match="exposure_s must be a positive number"):
        SensorParams(exposure_s=0.0)
    with pytest.raises(CamsimError, match="read_noise_e must be ≥ 0"):
        SensorParams(read_noise_e=-1.0)
    with pytest.raises(CamsimError, match="prnu_percent must be ≥ 0 and < 30 %"):
        SensorParams(prnu_percent=30.0)
    with pytest.raises(CamsimError, match="bits must be"):
        SensorParams(bits=17)
    with pytest.raises(CamsimError, match="cfa must be one of RGGB"):
        SensorParams(cfa="RGBG")
    assert SensorParams(exposure_s=2).exposure_s == 2.0 and isinstance(SensorParams(exposure_s=2).exposure_s, float)
    assert SensorParams(dark_current_e_per_s=5).dark_current_e_per_s == (5.0, 5.0, 5.0)
    assert SensorParams(cfa="none").cfa is None


def test_render_settings_and_methods_share_one_registry(tmp_path):
    method = next(p for p in RENDER_PARAMS if p.name == "method")
    assert method.choices == METHOD_NAMES == tuple(METHODS) == ("poisson", "table", "spectral", "gaussian", "auto")
    assert PARAMETERS["method"].choices == METHOD_NAMES
    with pytest.raises(CamsimError, match="unknown sampling method 'magic'; methods: poisson, table, spectral"):
        get_method("magic")
    scene_file = tmp_path / "s.toml"
    scene_file.write_text('[chart]\n[render]\nmethod = "magic"\n')
    with pytest.raises(CamsimError, match="method must be one of poisson, table, spectral, gaussian, auto"):
        load_scene(scene_file)
    scene_file.write_text('[chart]\n[render]\ntolerance = 1\n')
    with pytest.raises(CamsimError, match="tolerance must be > 0 and < 1"):
        load_scene(scene_file)


def test_sidecar_keys_of_the_table1_sensor_are_the_documented_ones():
    record = SensorParams().sidecar_record()
    assert record["dark_level_dn"] == pytest.approx(np.array([195.0, 230.0, 218.0]) * 0.0002 * 141.67)
    assert record["black_level_dn"] == SensorParams().black_level_dn.tolist()  # the floor's: tests/test_black_level
    assert record["white_level_dn"] == 255 and record["sensor_layout"] == "three-chip"
    assert record["stages"] == dict.fromkeys(STAGES, True)
    assert record["tukey_lambda"] is None  # only with the Tukey lambda read noise
    assert SensorParams(read_noise_model="tukey-lambda").sidecar_record()["tukey_lambda"] == -0.1
