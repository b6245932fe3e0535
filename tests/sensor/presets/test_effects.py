"""What the camera presets carry for the sensor effects of real low-light raws (issue 28): every built-in preset says,
per effect, what its source publishes; the figures it states are its source's (read independently from
``../shared/data/cameras``, skipped cleanly where absent), and an effect its source gives nothing for stays off.
"""

import csv
import re
from pathlib import Path

import numpy as np
import pytest

from camsim.sensor.presets import CAMERA_PRESETS, sensor_preset
from camsim.sensor.presets.model import EFFECTS, NOT_PUBLISHED

DATA = Path(__file__).resolve().parents[3].parent / "shared" / "data" / "cameras"
needs_data = pytest.mark.skipif(not DATA.is_dir(), reason="../shared/data/cameras is absent")

#: sensor_datasheets.csv's rows (sensor, the start of camera_or_model) → the preset built from each.
DATASHEET_PRESETS = {("Sony IMX363", "Google Pixel 4a"): "sony-imx363",
                     ("Sony IMX174", "machine-vision"): "sony-imx174",
                     ("Sony ICX625 (CCD)", "Basler"): "sony-icx625-basler",
                     ("Sony ICX625 (CCD)", "Point Grey"): "sony-icx625-pointgrey",
                     ("Kodak KAF-3200ME (CCD)", "QSI 532"): "kodak-kaf3200me"}
#: eld_noise_fits.csv's cameras → their presets (ELD's, and LED's A7M4).
FIT_PRESETS = {"Sony A7S2": "sony-a7s2-eld", "Nikon D850": "nikon-d850", "Canon EOS 5D Mark IV": "canon-eos-5d4",
               "Canon EOS 70D": "canon-eos-70d", "Canon EOS 700D": "canon-eos-700d", "Sony A7M4": "sony-a7m4"}
#: The sensor parameters of each effect that a preset without a published figure leaves at their off value.
OFF = {"defects": {"hot_pixel_fraction": 0.0, "dead_pixel_fraction": 0.0, "stuck_pixel_fraction": 0.0,
                   "hot_pixel_map": None},
       "black_level_error": {"black_level_error_dn": 0.0},
       "dark_shading": {"dark_shading_e": 0.0, "column_fpn_e": 0.0, "dark_shading_map": None}}


def _rows(name):
    with open(DATA / name, newline="") as handle:
        return list(csv.DictReader(handle))


def _not_published(camera, key):
    return camera.published_effects[key].startswith(NOT_PUBLISHED)


def test_every_preset_states_every_effect_in_its_notes_and_in_camsim_list(capsys):
    from camsim.cli import main

    assert main(["list"]) == 0
    listed = capsys.readouterr().out
    for camera in CAMERA_PRESETS.values():
        assert set(camera.published_effects) == set(EFFECTS), camera.name
        for key, text in camera.published_effects.items():
            assert f"{EFFECTS[key]}: {text}" in camera.notes  # the notes end with them
            # camsim list: a published effect in full, the others named on the "not published" line
            after = listed.split(f"\n  {camera.name}: ", 1)[1].split("\n")[1:]
            block = [line[4:] for line in after[:next(i for i, line in enumerate(after) if line[:4] != "    ")]]
            if text.startswith(NOT_PUBLISHED):
                assert EFFECTS[key] in block[-1].removeprefix(f"{NOT_PUBLISHED}: ").split("; ")
            else:
                assert f"{EFFECTS[key]}: {text}" in block


def test_an_effect_not_published_stays_off_in_the_rendered_sensor():
    for camera in CAMERA_PRESETS.values():
        sensor = sensor_preset(camera.name)
        for key, params in OFF.items():
            if _not_published(camera, key) or key == "dark_shading":  # no preset ships a map or a σ
                assert {p: getattr(sensor, p) for p in params} == params, (camera.name, key)
        assert sensor.temperature_c is None  # a preset states the temperature of its figures, not the sensor's
        if _not_published(camera, "dark_current"):
            assert not any(sensor.dark_current_e_per_s) and sensor.dsnu_e == 0, camera.name
        if _not_published(camera, "temperature"):
            assert camera.dark_current_reference_c is None, camera.name


@needs_data
def test_datasheet_presets_carry_the_published_dark_current_dsnu_and_temperature():
    seen = set()
    for row in _rows("sensor_datasheets.csv"):
        name = next(p for (s, c), p in DATASHEET_PRESETS.items()
                    if row["sensor"] == s and row["camera_or_model"].startswith(c))
        seen.add(name)
        camera, sensor = CAMERA_PRESETS[name], sensor_preset(name)
        # the temperature of the dark current, where the source states one ("dark current at 0 C")
        stated = re.search(r"dark current at (-?[0-9.]+) C", row["notes"])
        if row["dark_current_e_per_s"]:
            rate = float(row["dark_current_e_per_s"])
            assert camera.dark_current_e_per_s == rate
            assert np.all(np.asarray(sensor.dark_current_e_per_s) == rate)
            assert f"{rate:g} e⁻/s" in camera.published_effects["dark_current"]
        else:
            assert camera.dark_current_e_per_s == 0 and not any(sensor.dark_current_e_per_s)
            assert NOT_PUBLISHED in camera.published_effects["dark_current"]
        if stated:
            reference = float(stated.group(1))
            assert camera.dark_current_reference_c == reference == sensor.dark_current_reference_c
            assert not _not_published(camera, "temperature")
        else:
            assert camera.dark_current_reference_c is None and _not_published(camera, "temperature")
        if row["dsnu_e"]:
            assert sensor.dsnu_e == float(row["dsnu_e"])
            assert f"DSNU {float(row['dsnu_e']):g} e⁻" in camera.published_effects["dark_current"]
        else:
            assert sensor.dsnu_e == 0 and "DSNU" in camera.published_effects["dark_current"] \
                and NOT_PUBLISHED in camera.published_effects["dark_current"]
    assert seen == set(DATASHEET_PRESETS.values())


@needs_data
def test_eld_and_led_presets_say_their_colour_bias_is_not_in_camsims_sources():
    readme = (DATA / "README.md").read_text()
    assert "colour-bias" in readme and "not included" in readme  # what the shared data say of ELD's tables
    for camera in {row["camera"] for row in _rows("eld_noise_fits.csv")}:
        preset = CAMERA_PRESETS[FIT_PRESETS[camera]]
        statement = preset.published_effects["black_level_error"]
        assert _not_published(preset, "black_level_error") and "bias" in statement.lower()
        assert sensor_preset(preset.name).black_level_error_dn == 0


def test_the_pmn_a7s2_says_its_dark_shading_is_published_as_files_not_numbers():
    camera = CAMERA_PRESETS["sony-a7s2"]
    text = camera.published_effects["dark_shading"]
    assert not text.startswith(NOT_PUBLISHED) and "files, not as numbers" in text and "darkshading" in text
    sensor = sensor_preset("sony-a7s2", 3200)
    assert sensor.dark_shading_e == 0 and sensor.dark_shading_map is None  # camsim ships no map


@pytest.mark.parametrize("temperature", [-20.0, 0.0, 6.0, 25.0])
def test_the_kaf3200me_dark_current_follows_the_temperature_from_its_published_0_c(temperature):
    # 0.080 e⁻/s measured at 0 °C: at T, 0.080 · 2^(T / T_d) e⁻/s (EMVA 1288's doubling law), T_d the sensor's
    sensor = sensor_preset("kodak-kaf3200me", temperature_c=temperature, exposure_s=30.0)
    expected = 0.080 * 2.0 ** (temperature / sensor.dark_current_doubling_c) * 30.0
    assert sensor.dark_mean_e == pytest.approx(np.full(3, expected), rel=1e-12)
    # without a temperature the published figure holds as given
    assert sensor_preset("kodak-kaf3200me", exposure_s=30.0).dark_mean_e == pytest.approx(np.full(3, 2.4))
