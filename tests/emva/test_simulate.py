"""``camsim emva``: the simulated EMVA 1288 measurement, analysed by the reference implementation (emva1288).

Tolerances follow from the size of each run (standard deviation of the relative error over seeds 0–19):

* 128 × 128 pixels, 60 steps, L = 100 (the command line's series on a smaller region): K and η 0.2 % (largest
  0.4 %), the dark noise 0.6 % (it rests on one dark pair; largest 1.3 %), DSNU and PRNU 0.3 % and 0.1 % around
  the realised maps, which differ from the configured 2 e⁻ / 1 % by −1.2 % / +0.8 % on this region. So the issue's
  targets are asserted as they are — 2 % for K, η and the dark noise, 5 % for DSNU and PRNU — all more than 3
  standard deviations away.
* 64 × 64 pixels, 35 steps, L = 16: K and η 0.75 %, the dark noise 1.4 %, DSNU 1.8 %, PRNU 0.5 %; asserted at
  3 %, 5 %, 10 % and 10 %.
"""

import json
import math

import numpy as np
import pytest

from camsim.cli import main
from camsim.emva import EmvaSetup, run
from camsim.emva.simulate import model_dark_temporal_dn, predicted_saturation_e
from camsim.sensor.params import PRESETS, preset

KEYS = ["K_dn_per_e", "dark_noise_e", "qe", "saturation_e", "dsnu_e", "prnu_percent"]
SMALL = EmvaSetup(size=64, steps=30, low_steps=5, stack_frames=16, seed=1)


def _rel(entry):
    return abs(entry["recovered"] / entry["configured"] - 1)


@pytest.mark.slow
def test_cli_writes_the_report_and_meets_the_targets(tmp_path, capsys):
    out = tmp_path / "emva"
    assert main(["emva", "--size", "128", "--seed", "3", "--out", str(out), "-q"]) == 0
    assert str(out / "report.md") in capsys.readouterr().out
    data = json.loads((out / "emva.json").read_text())
    assert list(data) == KEYS
    for key in KEYS:
        assert set(data[key]) == {"configured", "recovered", "relative_error"}
    sensor = PRESETS["emva-12bit"]
    assert data["K_dn_per_e"]["configured"] == pytest.approx(0.4)
    assert data["dark_noise_e"]["configured"] == pytest.approx(math.sqrt(3.0**2 + 25.0))
    assert data["saturation_e"]["configured"] == sensor.full_well_e
    assert (data["dsnu_e"]["configured"], data["prnu_percent"]["configured"]) == (2.0, 1.0)
    for key, tolerance in {"K_dn_per_e": 0.02, "dark_noise_e": 0.02, "qe": 0.02, "dsnu_e": 0.05,
                           "prnu_percent": 0.05}.items():
        assert _rel(data[key]) <= tolerance, (key, data[key])
        assert data[key]["relative_error"] == pytest.approx(data[key]["recovered"] / data[key]["configured"] - 1)
    # EMVA's saturation: the variance peak, a few % below the clip (full well minus the 25 dark electrons)
    assert 0.9 * predicted_saturation_e(sensor) < data["saturation_e"]["recovered"] < predicted_saturation_e(sensor)
    report = (out / "report.md").read_text()
    assert "emva-12bit" in report and "| System gain K" in report and "✗" not in report
    for png in ("photon_transfer.png", "snr.png", "nonuniformity.png"):
        assert (out / png).stat().st_size > 10_000
        assert f"]({png})" in report
    assert not list(out.glob(".*partial"))


def test_small_run_recovers_the_configuration():
    result = run("emva-12bit", SMALL)
    rows = result.comparison()
    assert _rel(rows["K_dn_per_e"]) < 0.03 and _rel(rows["qe"]) < 0.03
    assert _rel(rows["dark_noise_e"]) < 0.05
    assert _rel(rows["dsnu_e"]) < 0.10 and _rel(rows["prnu_percent"]) < 0.10
    # the realised maps are what the standard measures
    assert result.measurement.realised_dsnu_e == pytest.approx(2.0, rel=0.03)
    assert result.measurement.realised_prnu_percent == pytest.approx(1.0, rel=0.03)
    # the temporal statistics of camsim's model, quantised, exactly: mean (with the −½ DN) and variance in the dark
    mean, var = model_dark_temporal_dn(result.measurement.sensor)
    assert result.details["u_ydark_dn"] == pytest.approx(mean, abs=0.05)
    assert result.details["s2_ydark_dn2"] == pytest.approx(var, rel=0.06)


def test_same_seed_same_result_and_another_seed_differs():
    a, b = run("emva-12bit", SMALL), run("emva-12bit", SMALL)
    assert a.comparison() == b.comparison()
    c = run("emva-12bit", EmvaSetup(size=64, steps=30, low_steps=5, stack_frames=16, seed=2))
    assert c.comparison()["K_dn_per_e"]["recovered"] != a.comparison()["K_dn_per_e"]["recovered"]
    # one sensor: the fixed pattern does not depend on the frames' seed
    assert c.measurement.realised_dsnu_e == a.measurement.realised_dsnu_e


def test_eight_bit_dark_noise_is_quantisation_limited_as_the_model_predicts():
    result = run("paper-table1", SMALL)
    rows = result.comparison()
    assert _rel(rows["K_dn_per_e"]) < 0.03 and _rel(rows["qe"]) < 0.03
    # σ_d is about 5 % low: the standard subtracts 1/12 DN², while the exact quantised dark variance is smaller
    sensor = result.measurement.sensor
    _, var = model_dark_temporal_dn(sensor)
    expected = math.sqrt(var - 1 / 12) / sensor.dn_per_electron
    assert expected < 0.97 * rows["dark_noise_e"]["configured"]
    assert rows["dark_noise_e"]["recovered"] == pytest.approx(expected, rel=0.03)
    assert rows["dsnu_e"]["relative_error"] is None and rows["prnu_percent"]["relative_error"] is None
    assert result.within_target("dsnu_e") is None


def test_numpy_is_as_before_after_the_analysis_and_its_plots(tmp_path, monkeypatch):
    from camsim.emva import write_outputs

    for name in ("int", "asfarray"):  # NumPy as NumPy 2 has it (NumPy 1 has both names)
        monkeypatch.delattr(np, name, raising=False)
    result = run("emva-12bit", EmvaSetup(size=16, steps=10, low_steps=0, stack_frames=2))
    write_outputs(result, tmp_path / "emva")  # the reference plots call emva1288's routines too
    assert (tmp_path / "emva" / "snr.png").is_file()
    assert not hasattr(np, "int") and not hasattr(np, "asfarray")


def test_the_numpy_shims_add_only_what_is_missing_and_remove_only_that(monkeypatch):
    from camsim.emva.simulate import emva1288_numpy_shims

    monkeypatch.delattr(np, "asfarray", raising=False)
    mine = object()
    monkeypatch.setattr(np, "int", mine, raising=False)
    with emva1288_numpy_shims():
        assert np.int is mine  # present before: left alone
        assert np.asfarray([1, 2]).dtype == np.float64
    assert np.int is mine and not hasattr(np, "asfarray")
    with pytest.raises(RuntimeError), emva1288_numpy_shims():
        raise RuntimeError("an error inside the block")
    assert np.int is mine and not hasattr(np, "asfarray")


def test_running_reduction_is_the_reference_one():
    from camsim.emva.simulate import IntStack, emva1288_process

    emva1288_process()
    from emva1288.process import routines

    rng = np.random.default_rng(0)
    images = [rng.integers(0, 4096, (5, 7), dtype=np.uint16) for _ in range(4)]
    stack = IntStack()
    for image in images:
        stack.add(image)
    mine, reference = stack.result(), routines.get_int_imgs(images)
    assert mine["L"] == reference["L"] and mine["dmean"] == pytest.approx(reference["dmean"])
    np.testing.assert_array_equal(mine["sum"], reference["sum"])
    np.testing.assert_array_equal(mine["pvar"], reference["pvar"])


def test_bayer_sensor_is_measured_on_its_green_sites():
    result = run(sensor=preset("emva-12bit", cfa="GRBG"), setup=EmvaSetup(size=96, steps=30, stack_frames=16))
    assert result.measurement.data["width"] == 48
    assert _rel(result.comparison()["K_dn_per_e"]) < 0.03


@pytest.mark.parametrize("args, message", [
    (["--size", "8"], "region of interest"),
    (["--preset", "ideal"], "quantisation off"),
    (["--preset", "nope"], "unknown preset 'nope'"),
    (["--iso", "800"], "has no ISO axis"),
    (["--preset", "sony-a7s2", "--iso", "10"], "outside preset sony-a7s2's range"),
    (["--seed", "-1"], "must be ≥ 0"),
    (["--dsnu-exposure-factor", "1"], "dsnu_exposure_factor (the DSNU's second exposure time over the first) must be"),
    (["--sensor", "dsnu_dark_current_percent=100"], "must be ≥ 0 and < 100 %"),
])
def test_bad_input_is_one_line_and_exit_2(tmp_path, capsys, args, message):
    assert main(["emva", *args, "--out", str(tmp_path / "o"), "-q"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("camsim: error: ") and message in err and err.count("\n") == 1
    assert not (tmp_path / "o").exists()


def test_dsnu_split_through_two_exposure_times_is_exact_for_the_two_kinds():
    from camsim.emva.simulate import dsnu_split

    offset, rate = 2.0, 2.5  # DSNU²(T) = σ_o² + (c T)²
    dsnu = [math.hypot(offset, rate * t) for t in (1.0, 4.0)]
    assert dsnu_split(dsnu[0], 1.0, dsnu[1], 4.0) == pytest.approx((offset, rate), rel=1e-12)
    assert dsnu_split(2.0, 1.0, 2.0, 4.0) == pytest.approx((2.0, 0.0), abs=1e-12)  # an offset alone: constant
    assert dsnu_split(2.5, 1.0, 10.0, 4.0) == pytest.approx((0.0, 2.5), abs=1e-7)  # a dark current alone: ∝ T
    assert dsnu_split(2.0, 1.0, 1.9, 4.0) == (pytest.approx(math.sqrt((16 * 4 - 1.9**2) / 15)), None)  # below noise
    assert dsnu_split(None, 1.0, 2.0, 4.0) == (None, None)


SPLIT = EmvaSetup(size=128, steps=30, low_steps=5, stack_frames=16, seed=1, dsnu_exposure_factor=4.0)


@pytest.mark.parametrize("dsnu_e, p", [(2.0, 0.0), (0.0, 10.0), (2.0, 10.0)])
def test_emva_dsnu_at_two_exposure_times_splits_the_two_kinds(dsnu_e, p):
    """The offset DSNU is the same at T and 4 T, the dark-current DSNU grows ∝ T: on 128 × 128 pixels with
    L = 16 the DSNU's estimators scatter by about 1 % (their noise, the temporal variance left after averaging,
    is below 1 % of the spatial variance, and K's 0.5 %), so the split σ_o and c are asserted within 5 % of the
    maps actually drawn (sensor seed 0), and the ratio DSNU(4 T) / DSNU(T) within 5 % of √(σ_o² + (4 c T)²) /
    √(σ_o² + (c T)²): 1 for the offset alone, 4 for the dark current alone."""
    result = run(sensor=preset("emva-12bit", dsnu_e=dsnu_e, dsnu_dark_current_percent=p), setup=SPLIT)
    m, rows, d = result.measurement, result.comparison(), result.details
    assert list(rows) == KEYS + ["dsnu_offset_e", "dsnu_dark_current_e_per_s"]
    assert d["dsnu_exposures_s"] == (1.0, 4.0) and m.dsnu_exposure_s == 4.0
    offset = m.realised_dsnu_e or 0.0
    rate = m.realised_dark_dsnu_e_per_s or 0.0
    assert (m.realised_dark_dsnu_e_per_s is None) == (p == 0)
    expected_ratio = math.hypot(offset, 4 * rate) / math.hypot(offset, rate)
    assert d["dsnu_long_e"] / rows["dsnu_e"]["recovered"] == pytest.approx(expected_ratio, rel=0.05)
    for key, realised in (("dsnu_offset_e", offset), ("dsnu_dark_current_e_per_s", rate)):
        recovered = rows[key]["recovered"]
        if realised:
            assert recovered == pytest.approx(realised, rel=0.05), key
        else:  # the part is off: what is left is the estimators' noise, well below the other part
            assert recovered is None or recovered < 0.15 * max(offset, rate), key
    # configured: the offset dsnu_e, the rate p/100 · σ²_dark, and the DSNU at T the two added in variance
    assert rows["dsnu_offset_e"]["configured"] == dsnu_e
    assert rows["dsnu_dark_current_e_per_s"]["configured"] == pytest.approx(p / 100 * 25.0)
    assert rows["dsnu_e"]["configured"] == pytest.approx(math.hypot(dsnu_e, p / 100 * 25.0))
    assert rows["dsnu_e"]["recovered"] == pytest.approx(math.hypot(offset, rate), rel=0.05)
    # the model's dark temporal statistics hold with the dark-current map too
    mean, var = model_dark_temporal_dn(m.sensor)
    assert d["u_ydark_dn"] == pytest.approx(mean, abs=0.05)
    assert d["s2_ydark_dn2"] == pytest.approx(var, rel=0.06)


def test_the_dark_spatial_variance_is_the_reference_ones():
    """The second exposure's DSNU uses the standard's formula; on the first exposure's stack it gives the reference
    implementation's own s²_y.dark."""
    from camsim.emva.report import markdown
    from camsim.emva.simulate import dark_spatial_variance_dn2, emva1288_numpy_shims

    result = run(sensor=preset("emva-12bit", dsnu_dark_current_percent=10.0), setup=SMALL)
    assert result.measurement.dark_stack_long is not None  # taken by default for a dark-current DSNU
    assert result.measurement.dsnu_exposure_s == 4.0
    stack = next(iter(result.measurement.data["spatial"].values()))[0.0]
    with emva1288_numpy_shims():
        reference = float(result.results.s_2_y_dark)
    assert dark_spatial_variance_dn2(stack) == pytest.approx(reference, rel=1e-12)
    report = markdown(result, {"photon_transfer": "a.png", "snr": "b.png", "nonuniformity": "c.png"})
    assert "## DSNU at two exposure times" in report
    assert sum(line.startswith("| 4 s |") for line in report.splitlines()) == 1  # the second exposure's row


def test_no_second_stack_unless_asked_or_needed():
    result = run("emva-12bit", SMALL)
    assert result.measurement.dark_stack_long is None and list(result.comparison()) == KEYS


@pytest.mark.parametrize("factor, preset_name, message", [
    (1.0, "emva-12bit", "must be > 1 and ≤ 100"),
    (40.0, "paper-table1", "saturates this sensor at the DSNU's second exposure time"),
])
def test_a_bad_second_exposure_is_refused(factor, preset_name, message):
    from camsim.core.errors import CamsimError

    with pytest.raises(CamsimError, match=message):
        run(preset_name, EmvaSetup(size=16, steps=10, low_steps=0, stack_frames=2, dsnu_exposure_factor=factor))


@pytest.mark.slow
def test_cli_measures_a_dark_current_dsnu_at_two_exposure_times(tmp_path):
    out = tmp_path / "emva"
    assert main(["emva", "--size", "32", "--sensor", "dsnu_dark_current_percent=10", "--out", str(out), "-q"]) == 0
    data = json.loads((out / "emva.json").read_text())
    assert list(data) == KEYS + ["dsnu_offset_e", "dsnu_dark_current_e_per_s"]
    assert data["dsnu_dark_current_e_per_s"]["configured"] == pytest.approx(2.5)
    report = (out / "report.md").read_text()
    assert "preset `emva-12bit with dsnu_dark_current_percent=10.0`" in report
    assert "## DSNU at two exposure times" in report and "| 4 s |" in report
