"""The sensor's temperature in ``camsim emva`` and ``camsim optimise`` (issue 28): the measurement is taken at the
sensor's ``temperature_c`` (its dark current D_ref · 2^((T − T_ref)/T_d)), ``camsim emva --temperatures`` measures the
dark current against the temperature and its doubling temperature, and the exposure search scores the dark charge
at the temperature. Expected values are the closed forms, computed here."""

import json
import math

import numpy as np
import pytest

from camsim.core.errors import CamsimError
from camsim.emva import EmvaSetup, run
from camsim.emva.simulate import doubling_temperature_fit
from camsim.optimise.model import SensorAtIso
from camsim.sensor.params import preset
from camsim.sensor.presets import sensor_preset

SMALL = dict(size=64, steps=30, low_steps=5, stack_frames=16, seed=1)
D_REF, K, READ = 25.0, 0.4, 3.0  # emva-12bit: 25 e⁻/s at its reference temperature, 0.4 DN/e⁻, 3 e⁻ read noise


def dark_current(temperature, reference=25.0, doubling=6.0):
    """EMVA 1288's law, here: D_ref · 2^((T − T_ref)/T_d). Unit: e⁻/s."""
    return D_REF * 2.0 ** ((temperature - reference) / doubling)


def test_emva_measures_the_dark_signal_at_the_sensors_temperature():
    sensor = preset("emva-12bit", temperature_c=31.0)  # 6 °C above the reference: twice the dark current
    result = run(sensor=sensor, setup=EmvaSetup(**SMALL))
    rows = result.comparison()
    dark_e = dark_current(31.0) * sensor.exposure_s  # 50 e⁻
    assert rows["dark_noise_e"]["configured"] == pytest.approx(math.sqrt(READ**2 + dark_e))
    assert abs(rows["dark_noise_e"]["recovered"] / rows["dark_noise_e"]["configured"] - 1) < 0.05
    # the dark mean: K · D(T) · t less the quantiser's half step (no pedestal; the DSNU has mean 0). Its standard
    # error: √(σ²_read + D) K / √(2 · 64²) ≈ 0.03 DN over the two dark frames, the DSNU's mean 2 K / 64 ≈ 0.013 DN
    assert result.details["u_ydark_dn"] == pytest.approx(K * dark_e - 0.5, abs=0.15)
    # and at the reference temperature, half of it
    cold = run(sensor=preset("emva-12bit", temperature_c=25.0), setup=EmvaSetup(**SMALL))
    assert cold.details["u_ydark_dn"] == pytest.approx(K * D_REF - 0.5, abs=0.15)


@pytest.mark.parametrize("doubling, temperatures", [(6.0, (19.0, 25.0, 37.0)), (9.0, (10.0, 28.0))])
def test_emva_dark_current_against_temperature_follows_the_doubling_law(doubling, temperatures):
    sensor = preset("emva-12bit", dark_current_doubling_c=doubling)
    result = run(sensor=sensor, setup=EmvaSetup(**SMALL, temperatures=temperatures))
    table = result.details["dark_current_vs_temperature"]
    assert [r["temperature_c"] for r in table] == list(temperatures)
    slopes, errors = [], []
    for row in table:
        expected_dn_per_s = K * dark_current(row["temperature_c"], doubling=doubling)
        # the slope of the dark mean against the exposure time: K · D(T), within 4 of its standard errors (and the
        # quantiser's residual, well below 0.1 %: the read noise, 1.2 DN, dithers it)
        error = row["slope_standard_error_dn_per_s"]
        assert abs(row["slope_dn_per_s"] - expected_dn_per_s) < 4 * error + 1e-3 * expected_dn_per_s
        assert row["configured_e_per_s"] == pytest.approx(dark_current(row["temperature_c"], doubling=doubling))
        slopes.append(row["slope_dn_per_s"])
        errors.append(error)
    # the doubling temperature: within 4 standard errors of the configured one, σ(T_d) propagated from the slopes'
    # (two temperatures: T_d = ΔT / log₂(r₂ / r₁), so σ(T_d) = T_d² / ΔT · √Σ (σ_i / r_i)² / ln 2; more: the
    # least-squares line's, bounded by the same with the outermost pair)
    lo, hi = 0, len(temperatures) - 1
    span = temperatures[hi] - temperatures[lo]
    sigma = doubling**2 / span * math.hypot(errors[lo] / slopes[lo], errors[hi] / slopes[hi]) / math.log(2)
    recovered = result.comparison()["dark_current_doubling_c"]
    assert recovered["configured"] == doubling
    assert abs(recovered["recovered"] - doubling) < 4 * sigma + 1e-3 * doubling
    assert result.within_target("dark_current_doubling_c")


def test_the_doubling_fit_is_the_closed_form_for_two_points_and_refuses_no_growth():
    assert doubling_temperature_fit([20.0, 32.0], [3.0, 12.0]) == pytest.approx(12.0 / 2.0)
    # several points on one law: exact
    t = np.array([-10.0, 0.0, 7.0, 25.0])
    assert doubling_temperature_fit(t, 0.08 * 2 ** (t / 6.3), [0.01] * 4) == pytest.approx(6.3, rel=1e-12)
    assert doubling_temperature_fit([20.0, 30.0], [5.0, 5.0]) is None
    assert doubling_temperature_fit([20.0, 30.0], [5.0, 0.0]) is None


@pytest.mark.parametrize("temperatures", [(20.0,), (20.0, 20.0), (20.0, float("nan")), (20.0, -300.0), 20.0])
def test_a_bad_temperature_list_is_refused(temperatures):
    with pytest.raises(CamsimError, match="two distinct temperatures"):
        EmvaSetup(temperatures=temperatures)


def test_cli_writes_the_doubling_temperature(tmp_path):
    from camsim.cli import main

    out = tmp_path / "emva"
    assert main(["emva", "--size", "32", "--temperatures", "20", "30", "--out", str(out), "-q"]) == 0
    data = json.loads((out / "emva.json").read_text())
    assert list(data)[-1] == "dark_current_doubling_c" and data["dark_current_doubling_c"]["configured"] == 6.0
    assert "## Dark current against the temperature" in (out / "report.md").read_text()


@pytest.mark.parametrize("temperature", [None, -5.0, 25.0, 40.0])
def test_optimise_scores_the_dark_current_at_the_sensors_temperature(temperature):
    sensor = sensor_preset("kodak-kaf3200me", temperature_c=temperature)  # 0.080 e⁻/s published at 0 °C
    rate = 0.080 if temperature is None else 0.080 * 2.0 ** (temperature / sensor.dark_current_doubling_c)
    assert SensorAtIso.of(sensor, None).dark_current_e_per_s == pytest.approx(np.full(3, rate), rel=1e-12)


def test_optimise_caps_the_exposure_sooner_when_the_sensor_is_warmer():
    from camsim.optimise.search import PatchRates, exposure_axis, optimise

    # one grey patch, 100 e⁻/s at F = 1; the well fills with dark charge faster at 40 °C than at 25 °C
    rates = PatchRates(["grey"], np.full((1, 3), 100.0), np.eye(3), np.array([0.3127, 0.3290]),
                       np.zeros((1, 3)))
    chosen = {}
    for temperature in (25.0, 40.0):
        sensor = preset("emva-12bit", temperature_c=temperature, dark_current_e_per_s=(200.0,) * 3)
        result = optimise(rates, [SensorAtIso.of(sensor, None)], exposure_axis(100.0), [1.0])
        chosen[temperature] = result.choices[0]
        # the longest exposure of the grid keeping charge + 4 σ below the well, computed here
        dark = 200.0 * 2.0 ** ((temperature - 25.0) / 6.0)
        charge = (100.0 + dark) * result.exposures_s
        sd = np.sqrt(charge + READ**2 + 1 / (12 * K**2))
        limit = min(10000.0, (4095 - 0.0) / K)
        assert chosen[temperature].exposure_s == pytest.approx(result.exposures_s[np.flatnonzero(
            charge + 4 * sd <= limit)[-1]])
    assert chosen[40.0].exposure_s < chosen[25.0].exposure_s


def test_the_clip_at_0_dn_biases_a_cold_slope_as_the_exact_model_says():
    # 10 °C without a pedestal: 3.9 e⁻/s, 1.6 DN in the 1 s dark against 1.2 DN of read noise: pixels clip at 0
    cold = run(sensor=preset("emva-12bit"), setup=EmvaSetup(**SMALL, temperatures=(10.0, 25.0)))
    row = cold.details["dark_current_vs_temperature"][0]
    measured = row["slope_dn_per_s"] / (K * dark_current(10.0)) - 1
    assert row["clip_bias"] < -0.01  # the model's bias is large here
    assert abs(measured - row["clip_bias"]) < 4 * row["slope_standard_error_dn_per_s"] / (K * dark_current(10.0))
    # with a pedestal the dark level is clear of 0 and the slope is K · D(T)
    clear = run(sensor=preset("emva-12bit", pedestal_dn=64), setup=EmvaSetup(**SMALL, temperatures=(10.0, 25.0)))
    row = clear.details["dark_current_vs_temperature"][0]
    assert abs(row["clip_bias"]) < 1e-4
    assert abs(row["slope_dn_per_s"] - K * dark_current(10.0)) < 4 * row["slope_standard_error_dn_per_s"]


def test_a_temperature_whose_dark_signal_saturates_is_refused():
    # emva-12bit at 4 s (25 e⁻/s · 4 s = 100 e⁻ at 25 °C): its 10 000 e⁻ well fills with dark charge above
    # 25 + 6 log2(10000 / 100) ≈ 65 °C
    with pytest.raises(CamsimError, match="saturates this sensor at 70 °C"):
        run("emva-12bit", EmvaSetup(size=16, steps=10, low_steps=0, stack_frames=2, temperatures=(20.0, 70.0)))
    with pytest.raises(CamsimError, match="dark-current stage on"):
        run(sensor=preset("emva-12bit", dark_current=False),
            setup=EmvaSetup(size=16, steps=10, low_steps=0, stack_frames=2, temperatures=(20.0, 30.0)))
