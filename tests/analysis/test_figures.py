"""``camsim analyze`` explains what it writes and draws it: the figures of the user's own frames, every CSV column
and printed column explained, and the SNR it reports is the power ratio signal² / variance of the pixels.

One real run, as a user would make it: ``camsim render`` and ``camsim analyze`` through ``main``, what it prints
captured."""

import contextlib
import csv
import io
import json
import math

import numpy as np
import pytest

from camsim.cli import main

F_VALUES = ("1", "0.1", "0.01")


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """The frames of the issue's check (macbeth_26, D65, F = 1, 0.1, 0.01, 240 × 160) and their analysis, with what
    it printed."""
    frames = tmp_path_factory.mktemp("readable") / "frames"
    assert main(["render", "macbeth_26", "--illuminant", "D65", "--intensity", *F_VALUES, "--size", "240x160",
                 "--out", str(frames), "-q"]) == 0
    out = frames / "analysis"
    with contextlib.redirect_stdout(io.StringIO()) as printed, contextlib.redirect_stderr(io.StringIO()) as err:
        status = main(["analyze", str(frames), "--out", str(out)])
    assert status == 0, err.getvalue()
    return frames, out, printed.getvalue()


def _csv_header(path) -> list:
    with open(path, newline="", encoding="utf-8") as f:
        return next(csv.reader(f))


def _guide_sections(text: str) -> dict:
    """README.txt's sections: heading line → {name: explanation} of its indented ``name: explanation`` lines."""
    sections, current = {}, None
    for line in text.splitlines():
        if line and not line.startswith(" "):
            current = sections.setdefault(line, {})
        elif line.startswith("  ") and current is not None and ": " in line:
            name, text_ = line.strip().split(": ", 1)
            current[name] = text_
    return sections


@pytest.mark.slow
def test_the_figures_are_written_as_valid_pngs_of_sane_size(run):
    from PIL import Image

    _, out, stdout = run
    names = sorted(p.name for p in out.glob("*.png"))
    assert names == sorted(f"macbeth_26_D65_pixel_{key}.png" for key in ("xy", "delta_e", "snr"))
    for name in names:
        path = out / name
        assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        with Image.open(path) as image:
            image.verify()  # a whole, uncorrupted PNG
        with Image.open(path) as image:
            width, height = image.size
            pixels = np.asarray(image.convert("RGB")).astype(np.uint32)
        assert 500 <= width <= 4000 and 400 <= height <= 2000, (name, image.size)
        # drawn, not blank: many distinct colours (samples, ellipses, lines, text)
        colours = (pixels[..., 0] << 16) | (pixels[..., 1] << 8) | pixels[..., 2]  # one integer per RGB colour
        assert len(np.unique(colours)) > 200, name
        assert name in (out / "README.txt").read_text(encoding="utf-8")
    assert "3 figure(s)" in stdout


def test_every_csv_column_is_explained_in_the_companion_text(run):
    _, out, _ = run
    sections = _guide_sections((out / "README.txt").read_text(encoding="utf-8"))
    for file in ("analysis.csv", "frame_statistics.csv"):
        section = next((v for k, v in sections.items() if k.startswith(file)), None)
        assert section is not None, f"README.txt has no section for {file}"
        header = _csv_header(out / file)
        missing = [c for c in header if not section.get(c, "").strip()]
        assert not missing, f"{file} columns without an explanation in README.txt: {missing}"
        assert not set(section) - set(header), f"README.txt explains columns {file} does not have"


def test_the_printed_table_columns_and_the_units_are_explained(run):
    _, out, stdout = run
    lines = stdout.splitlines()
    header = next(line for line in lines if line.startswith("frame") and "flags" in line)
    sections = _guide_sections((out / "README.txt").read_text(encoding="utf-8"))
    printed = sections["The printed table"]
    rest = header
    for name in sorted(printed, key=len, reverse=True):
        assert name in rest, f"README.txt explains a printed column {name!r} the table does not have"
        rest = rest.replace(name, " ")
    assert not rest.strip(), f"printed columns without an explanation: {rest.split()}"
    # the printed legend: SNR's definition and unit, ΔE at low light, the flags
    legend = "\n".join(lines[lines.index(header):])
    assert "signal² / variance" in legend and "power ratio" in legend and "10 log10" in legend
    assert "ΔE" in legend and "nears 0" in legend
    assert "flags:" in legend and "ellipse" in legend and "X + Y + Z ≤ 0" in legend
    guide = (out / "README.txt").read_text(encoding="utf-8")
    assert "power ratio" in guide and "√SNR" in guide and "Y = 100" in guide


def _dng_pixels(path, width, height) -> np.ndarray:
    """The DNG's main image, (H, W, 3), read with tifffile (not camsim's reader)."""
    import tifffile

    with tifffile.TiffFile(path) as tif:
        pages = [p for p in tif.pages if p.subfiletype == 0 and p.shape[:2] == (height, width)]
        assert pages, f"no full-size image in {path}"
        return pages[0].asarray()


@pytest.mark.parametrize("factor, patch_name", [("0.1", "neutral 5 (.70 D)"), ("0.01", "white 9.5 (.05 D)")])
def test_the_snr_is_mean_squared_over_variance_of_the_pixels(run, factor, patch_name):
    """SNR in the CSV = (mean − black level)² / variance of the patch's own pixels, computed here from the DNG's
    values (tifffile), the sidecar's rectangle, the documented 3-pixel border and the sidecar's black level."""
    frames, out, _ = run
    meta = json.loads((frames / f"macbeth_26_D65_F{factor}.json").read_text())
    pixels = _dng_pixels(frames / meta["files"]["dng"], meta["width_px"], meta["height_px"]).astype(np.float64)
    patch = next(p for p in meta["patches"] if p["name"] == patch_name)
    x, y, w, h = patch["rect_xywh"]
    border = 3
    block = pixels[y + border: y + h - border, x + border: x + w - border]
    rows = [r for r in csv.DictReader(open(out / "analysis.csv", newline="", encoding="utf-8"))
            if r["patch_name"] == patch_name and float(r["intensity_factor"]) == float(factor)]
    assert [r["channel"] for r in rows] == ["R", "G", "B"]
    for c, row in enumerate(rows):
        values = block[:, :, c].ravel()
        signal = values.mean() - meta["black_level_dn"][c]
        variance = values.var(ddof=1)
        expected = signal**2 / variance
        assert int(row["n_pixels"]) == values.size
        assert float(row["snr_empirical"]) == pytest.approx(expected, rel=1e-9)
        assert float(row["snr_empirical_db"]) == pytest.approx(10 * math.log10(expected), rel=1e-9)
        # a power ratio, not an amplitude ratio: (signal / σ)² ≠ signal / σ at these levels
        assert abs(float(row["snr_empirical"]) - signal / math.sqrt(variance)) > 0.1
