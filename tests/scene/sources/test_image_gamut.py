"""Image scenes: colours outside the recovery method's gamut are recorded in the sidecar and warned about, once per
frame, with the share of pixels outside (issue 23, point 12). ``camsim render`` through ``main``, its stderr as a
user sees it."""

import json
import re

import imageio.v3 as iio
import numpy as np
import pytest

from camsim.cli import main

WIDTH, HEIGHT = 160, 120
GREEN_COLUMNS = 37  # P3 green (outside sRGB): 37 / 160 of the pixels
BLUE_COLUMNS = 20  # P3 blue, which is sRGB's blue primary: on sRGB's border, not outside
SHARE = GREEN_COLUMNS / WIDTH


def _picture() -> np.ndarray:
    picture = np.full((HEIGHT, WIDTH, 3), 128, dtype=np.uint8)
    picture[:, :GREEN_COLUMNS] = (0, 255, 0)
    picture[:, GREEN_COLUMNS : GREEN_COLUMNS + BLUE_COLUMNS] = (0, 0, 255)
    return picture


def _render(tmp_path, capsys, colourspace, *extra):
    iio.imwrite(tmp_path / "picture.png", _picture())
    scene = tmp_path / f"{colourspace.replace(' ', '_')}.toml"
    scene.write_text(f'name = "pic"\n[image]\npath = "picture.png"\ncolourspace = "{colourspace}"\n'
                     '[light]\nilluminants = ["D65"]\n', encoding="utf-8")
    out = tmp_path / f"out-{colourspace.replace(' ', '_')}{''.join(extra)}"
    capsys.readouterr()
    status = main(["render", str(scene), "--intensity", "1", "0.5", "--out", str(out), *extra])
    stderr = capsys.readouterr().err
    assert status == 0, stderr
    warnings = [line for line in stderr.replace("\r", "\n").splitlines() if line.startswith("camsim: warning")]
    return out, warnings


def _independent_loss_de00(colour) -> tuple[float, float]:
    """P3 green (linear (0, 1, 0)) through Mallett 2019, with colour-science alone: the clip of its linear sRGB
    components and the CIE 2000 ΔE of the clipped colour's Mallett spectrum (1 nm, CIE 1931 2°, D65) to it."""
    p3, srgb = colour.RGB_COLOURSPACES["Display P3"], colour.RGB_COLOURSPACES["sRGB"]
    d65 = colour.CCS_ILLUMINANTS["CIE 1931 2 Degree Standard Observer"]["D65"]
    green = np.array([0.0, 1.0, 0.0])
    in_srgb = colour.RGB_to_RGB(green, p3, srgb)
    clip = float(-in_srgb.min())
    sd = colour.recovery.RGB_to_sd_Mallett2019(np.maximum(in_srgb, 0.0),
                                               colour.recovery.MSDS_BASIS_FUNCTIONS_sRGB_MALLETT2019)
    xyz = colour.sd_to_XYZ(sd, colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"],
                           colour.SDS_ILLUMINANTS["D65"]) / 100
    wanted = colour.XYZ_to_Lab(colour.RGB_to_XYZ(green, p3, illuminant=d65), d65)
    return clip, float(colour.delta_E(wanted, colour.XYZ_to_Lab(xyz, d65), method="CIE 2000"))


def test_a_p3_image_outside_srgb_is_recorded_and_warned_once_per_frame(tmp_path, capsys):
    import colour

    out, warnings = _render(tmp_path, capsys, "Display P3")
    assert len(warnings) == 2  # one per frame (F = 1 and 0.5)
    for factor, line in zip(("1", "0.5"), warnings):
        assert line.startswith(f"camsim: warning: pic_D65_F{factor}: ")
        share = float(re.search(r"([\d.]+) % of the pixels of picture\.png", line).group(1))
        assert share == pytest.approx(100 * SHARE, abs=0.01)
        assert "Display P3" in line and "Mallett 2019" in line and "outside sRGB" in line
        record = json.loads((out / f"pic_D65_F{factor}.json").read_text())["recovery"]
        assert record["method"] == "Mallett 2019" and record["colour_space"] == "Display P3"
        assert record["out_of_gamut_fraction"] == pytest.approx(SHARE, rel=1e-12)  # the blue is not counted
        assert record["out_of_gamut_colours"] == 1
        clip, loss = _independent_loss_de00(colour)
        assert record["max_clip"] == pytest.approx(clip, rel=1e-9)
        assert clip > 0.2
        # camsim integrates on its 4 nm grid, colour-science here at 1 nm: the same loss to 0.1 ΔE00
        assert record["max_delta_e00_outside"] == pytest.approx(loss, abs=0.1)
        assert loss > 5
    # the EXR's header carries the same record
    from camsim.render.frame_files import read_frame_meta

    assert read_frame_meta(out / "pic_D65_F1.exr")["recovery"]["out_of_gamut_fraction"] == pytest.approx(SHARE)


def test_quiet_keeps_the_warning_and_the_record(tmp_path, capsys):
    """-q silences the progress bar and colour-science, not camsim's own warnings."""
    out, warnings = _render(tmp_path, capsys, "Display P3", "-q")
    assert len(warnings) == 2 and all("23.12 %" in w for w in warnings)
    record = json.loads((out / "pic_D65_F1.json").read_text())["recovery"]
    assert record["out_of_gamut_fraction"] == pytest.approx(SHARE, rel=1e-12)


def test_an_srgb_image_is_inside_no_warning_and_fraction_zero(tmp_path, capsys):
    out, warnings = _render(tmp_path, capsys, "sRGB")
    assert warnings == []
    for factor in ("1", "0.5"):
        record = json.loads((out / f"pic_D65_F{factor}.json").read_text())["recovery"]
        assert record == {"method": "Mallett 2019", "colour_space": "sRGB", "out_of_gamut_fraction": 0.0,
                          "out_of_gamut_colours": 0, "max_clip": 0.0, "max_delta_e00_outside": 0.0}
