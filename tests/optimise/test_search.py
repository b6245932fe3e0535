"""camsim optimise: the search moves as the physics says (dark current off, a large dark current, the A7S2's
dual-gain step), its moments against rendered frames, its outputs, and bad input."""

import dataclasses
import math

import numpy as np
import pytest

from camsim.cli import main
from camsim.optimise.model import CLIP_SIGMAS, SensorAtIso, snr_db
from camsim.optimise.search import exposure_axis, iso_axis, optimise, patch_rates
from camsim.optimise.verify import three_chip, verify_choice
from camsim.render.pipeline import light_scene
from camsim.scene.scene_file import load_scene
from camsim.sensor.presets import camera_preset, sensor_preset

FACTORS = [1.0, 0.1, 0.01, 0.001]


@pytest.fixture(scope="module")
def scene():
    return load_scene("macbeth_26").replace(width=240, height=160, illuminants=("D65",))


def _search(scene, preset="sony-a7s2", max_exposure=1.0, objective="snr", factors=FACTORS, **overrides):
    isos = iso_axis(camera_preset(preset), None)
    at = lambda iso: three_chip(sensor_preset(preset, iso, **overrides))  # noqa: E731
    sensors = [SensorAtIso.of(at(iso), iso) for iso in isos]
    rates = patch_rates(scene, "D65", at(isos[0]))
    return optimise(rates, sensors, exposure_axis(max_exposure), factors, objective, preset=preset), rates, sensors


def test_without_dark_current_the_longest_allowed_exposure_wins(scene):
    result, _, _ = _search(scene, max_exposure=0.5)
    assert [c.exposure_s for c in result.choices] == pytest.approx([0.5] * len(FACTORS))
    assert all(c.limited_by == "exposure limit" for c in result.choices)
    # and at each exposure the SNR grows with it (Eq. 14 is increasing in T while nothing clips)
    grid = result.snr_grid[0.01]
    finite = np.isfinite(grid[:, 0])
    assert np.all(np.diff(grid[finite, 0]) > 0)


def test_a_large_dark_current_caps_the_exposure_where_the_dark_charge_fills_the_range(scene):
    dark = 1e4  # e⁻/s: 13 s of it fill the A7S2's well
    result, rates, sensors = _search(scene, max_exposure=100.0, factors=[0.01, 0.001], dark_current_e_per_s=dark)
    for choice in result.choices:
        assert choice.exposure_s < 100.0 and choice.limited_by == "saturation" and choice.dominant_noise == "dark"
        # computed here: the longest exposure of the grid at which every patch's charge stays 4 σ below the well
        # and the ADC's top at the chosen ISO
        sensor = next(s for s in sensors if s.iso == choice.iso)
        limit = min(sensor.full_well_e, sensor.adc_range_e)
        fits = []
        for t in result.exposures_s:
            charge = choice.intensity_factor * rates.rates_e_per_s * t + dark * t
            sd = np.sqrt(charge + sensor.read_noise_e**2 + sensor.row_noise_e**2 + sensor.quantisation_var_e2)
            fits.append(np.all(charge + CLIP_SIGMAS * sd <= limit))
        assert choice.exposure_s == pytest.approx(result.exposures_s[np.flatnonzero(fits)[-1]])
    # without it the same light takes the longest exposure at a far higher ISO
    plain, _, _ = _search(scene, max_exposure=100.0, factors=[0.001])
    assert plain.choices[0].exposure_s == 100.0 and plain.choices[0].iso > result.choices[-1].iso


def test_a7s2_iso_2000_beats_1600_at_low_light(scene):
    result, rates, sensors = _search(scene, factors=[0.01, 0.001])
    isos = result.isos
    for factor in (0.01, 0.001):
        grid = result.snr_grid[factor]
        low, high = grid[-1, isos.index(1600.0)], grid[-1, isos.index(2000.0)]
        assert high > low + 3.0, (factor, low, high)  # dB, at the longest exposure
    # by the closed form too: read noise 4.12 → 1.39 e⁻ across the step
    at = {iso: SensorAtIso.of(three_chip(sensor_preset("sony-a7s2", iso)), iso) for iso in (1600.0, 2000.0)}
    assert at[1600.0].read_noise_e > 2.5 * at[2000.0].read_noise_e
    signal = 0.001 * rates.rates_e_per_s
    assert np.mean(snr_db(signal, 0.0, at[2000.0])) > np.mean(snr_db(signal, 0.0, at[1600.0])) + 3.0


def test_the_model_agrees_with_rendered_frames_and_the_choice_is_not_beaten(scene):
    result, rates, _ = _search(scene, objective="both", factors=[1.0, 0.2])
    lit = light_scene(scene, "D65")
    sensor_at = lambda iso, t: three_chip(dataclasses.replace(sensor_preset("sony-a7s2", iso), exposure_s=t))  # noqa
    for k, choice in enumerate(result.choices):
        rows = verify_choice(choice, result, lit, rates, sensor_at, seed=k)
        assert len(rows) >= 3
        for row in rows:
            assert row["snr_agrees"] and row["delta_e_agrees"], row
            assert not row.get("beats_choice"), row


def test_the_search_is_fast_and_writes_its_outputs(scene, tmp_path, capsys):
    out = tmp_path / "o"
    assert main(["optimise", "macbeth_26", "--preset", "sony-a7s2", "--iso-range", "800", "3200", "-F", "0.5",
                 "0.05", "--max-exposure", "0.1", "--objective", "both", "--out", str(out), "-q"]) == 0
    for name in ("choices.csv", "verification.csv", "pareto.csv", "objective_maps.png", "report.md"):
        assert (out / name).stat().st_size > 0
    report = (out / "report.md").read_text()
    assert "dual-gain step: ISO 2000" in report and "What to take away" in report
    choices = (out / "choices.csv").read_text().splitlines()
    assert len(choices) == 1 + 4  # two light levels, two objectives each
    assert all(800 <= float(line.split(",")[3]) <= 3200 for line in choices[1:])


@pytest.mark.parametrize("argv, message", [
    (["--iso-range", "3200", "800"], "--iso-range needs 0 < A ≤ B"),
    (["--iso-range", "30000", "40000"], "holds none of sony-a7s2's ISO points"),
    (["--max-exposure", "-1"], "--max-exposure must be a positive number"),
    (["--preset", "paper-table1", "--iso-range", "100", "800"], "needs a camera preset with an ISO axis"),
    (["--preset", "sony-imx174", "--iso-range", "100", "800"], "needs a camera preset with an ISO axis"),
    (["--preset", "nope"], "unknown preset 'nope'"),
    (["--objective", "colour"], "invalid choice"),
])
def test_bad_input_is_one_line_and_exit_2(tmp_path, capsys, argv, message):
    argv = ["optimise", "macbeth_26", "--preset", "sony-a7s2", "--out", str(tmp_path / "o"), "-q", *argv]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("camsim: error:") and err.count("\n") == 1 and message in err, err
    assert not (tmp_path / "o").exists() or not any((tmp_path / "o").iterdir())


def test_a_scene_without_patches_is_refused(tmp_path, capsys):
    assert main(["optimise", "astronaut", "--preset", "sony-a7s2", "--out", str(tmp_path / "o"), "-q"]) == 2
    assert "needs a scene with patches" in capsys.readouterr().err


def test_exposure_axis_and_iso_axis():
    t = exposure_axis(0.5)
    assert t[-1] == pytest.approx(0.5) and t[0] == pytest.approx(0.5e-4) and np.all(np.diff(np.log10(t)) > 0)
    assert iso_axis(camera_preset("sony-a7s2"), (1000, 2000)) == [1000.0, 1250.0, 1600.0, 2000.0]
    assert iso_axis(None, None) == [None]
    assert math.isclose(iso_axis(camera_preset("nikon-d850"), None)[0], 100.0)
