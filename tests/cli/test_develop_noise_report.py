"""``camsim develop --noise-report``: the per-stage noise table and figure beside the developed picture, its raw
rows (noisy minus clean: mean zero within the standard error), and a DNG without its EXR refused on one line with
nothing written."""

import csv
import math

import pytest

from camsim.cli import main


@pytest.fixture(scope="module")
def flat(tmp_path_factory):
    """A flat field on the default three-chip sensor (the paper's Table I): one frame, DNG + EXR + sidecar."""
    out = tmp_path_factory.mktemp("noise_report")
    assert main(["render", "flat", "--size", "96x64", "-F", "0.05", "--out", str(out), "-q"]) == 0
    return out


def test_the_report_is_written_beside_the_picture_with_every_stage(flat, tmp_path):
    dng = next(flat.glob("*.dng"))
    out = tmp_path / "dev"
    assert main(["develop", str(dng), "--out", str(out), "--gain", "white", "--noise-report", "-q"]) == 0
    stem = dng.stem
    assert sorted(p.name for p in out.iterdir()) == sorted(
        [f"{stem}.png", f"{stem}.json", f"{stem}_noise_stages.csv", f"{stem}_noise_stages.png"])
    rows = list(csv.DictReader((out / f"{stem}_noise_stages.csv").open()))
    stages = {r["stage"] for r in rows}
    assert {"raw", "white_balanced", "srgb_linear", "toned"} <= stages
    # the raw stage's noise is the noisy EXR minus its clean layer: mean ≈ 0 within 5 standard errors
    for r in rows:
        if r["stage"] == "raw" and r["site"] == "all":
            std, n = float(r["std"]), int(r["pixels"])
            assert std > 0 and abs(float(r["mean"])) < 5 * std / math.sqrt(n), r


def test_the_report_needs_the_exr_and_writes_nothing_without_it(flat, tmp_path, capsys):
    frames = tmp_path / "frames"
    frames.mkdir()
    dng = next(flat.glob("*.dng"))
    for suffix in (".dng", ".json"):
        (frames / (dng.stem + suffix)).write_bytes(dng.with_suffix(suffix).read_bytes())
    out = tmp_path / "dev"
    status = main(["develop", str(frames / dng.name), "--out", str(out), "--noise-report", "-q"])
    err = capsys.readouterr().err.strip().splitlines()
    assert status == 2 and len(err) == 1 and err[0].startswith("camsim: error: ") and "EXR" in err[0], err
    assert not out.exists() or not any(out.iterdir())
