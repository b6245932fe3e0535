"""``camsim denoise-eval``: denoisers scored against the clean layer, user targets, outputs and the report."""

import argparse
import csv
import json
import math
import re
import sys
import textwrap

import numpy as np
import pytest

from camsim.cli.commands.denoise_eval import add_parser, run
from camsim.core.errors import CamsimError
from camsim.denoise.denoisers import (
    DENOISERS,
    bm3d_available,
    estimate_noise_sigma,
    model_noise_sigma,
    resolve_denoiser,
)
from camsim.denoise.evaluate import EvalSettings, evaluate
from camsim.denoise.summary import Criterion, verdict
from camsim.render.run import render_scene
from camsim.scene.scene_file import load_scene
from tests.support.helpers import ROOT

FACTORS = (1.0, 0.1, 0.01)
SIZE = (192, 128)

# A command denoiser: copies R, G, B from {input} to {output} with camsim's EXR functions (argv[1], argv[2]).
COPY_CODE = ("import sys; from camsim.io.exr import read_exr, write_exr; "
             "noisy, _, _ = read_exr(sys.argv[1]); write_exr(sys.argv[2], noisy, None, None)")


def _scene(**changes):
    scene = load_scene(ROOT / "scenes" / "macbeth_26.toml")
    return scene.replace(**{"width": SIZE[0], "height": SIZE[1], "illuminants": ("D65",), "intensity_factors": FACTORS,
                            **changes})


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    out = tmp_path_factory.mktemp("dataset")
    render_scene(_scene(), out / "three_chip", progress=False)
    return out


@pytest.fixture(scope="module")
def dataset_with_bayer(tmp_path_factory, dataset):
    """The three-chip frames plus one Bayer frame in a sub-folder (copied, so the module's dataset stays clean)."""
    import shutil

    out = tmp_path_factory.mktemp("mixed")
    shutil.copytree(dataset / "three_chip", out / "three_chip")
    render_scene(_scene(intensity_factors=(0.1,)).with_sensor(cfa="RGGB"), out / "bayer", progress=False)
    return out


@pytest.fixture(scope="module")
def evaluation(dataset):
    denoisers = [resolve_denoiser(name) for name in ("identity", "nl-means", "tv")]
    return evaluate([dataset], denoisers, EvalSettings(), progress=False)


def _rows(rows, denoiser, factor=None):
    return [r for r in rows if r["denoiser"] == denoiser and (factor is None or r["intensity_factor"] == factor)]


def _summary(ev, denoiser, factor):
    (row,) = _rows(ev.summary_rows, denoiser, factor)
    return row


def test_identity_scores_equal_the_noisy_baseline_exactly(evaluation):
    frames = _rows(evaluation.frame_rows, "identity")
    assert len(frames) == len(FACTORS)
    for r in frames:
        assert r["psnr_denoised_db"] == r["psnr_noisy_db"] and r["ssim_denoised"] == r["ssim_noisy"]
        assert r["psnr_gain_db"] == 0.0 and r["ssim_gain"] == 0.0
    patches = _rows(evaluation.patch_rows, "identity")
    assert len(patches) == 24 * len(FACTORS)
    for p in patches:
        assert p["ellipse_size_ratio"] == 1.0
        assert p["ellipse_size_denoised"] == p["ellipse_size_noisy"]
        assert p["bias_denoised_xy"] == p["bias_noisy_xy"] and p["delta_e_denoised"] == p["delta_e_noisy"]
    for f in FACTORS:
        assert _summary(evaluation, "identity", f)["ellipse_size_ratio"] == 1.0


@pytest.mark.parametrize("name", ["nl-means", "tv"])
def test_denoisers_improve_psnr_and_shrink_the_ellipses_at_f_0_1(evaluation, name):
    row = _summary(evaluation, name, 0.1)
    assert row["psnr_gain_db"] > 5.0 and row["ssim_gain"] > 0.1
    assert row["ellipse_size_ratio"] < 0.5
    assert row["delta_e_denoised"] < row["delta_e_noisy"]
    patches = _rows(evaluation.patch_rows, name, 0.1)
    assert all(p["ellipse_size_ratio"] < 1.0 for p in patches)


def test_reference_is_found_and_colour_is_judged(evaluation):
    assert all(p["delta_e_status"] == "ok" for p in evaluation.patch_rows)
    # The clean layer is its own truth: its ΔE against the clean F = 1 reference is ~0 with the black subtracted.
    assert all(abs(p["delta_e_clean"]) < 1e-3 for p in evaluation.patch_rows)
    nlm = evaluation.verdicts["nl-means"]
    assert nlm["by_factor"][1.0] == "yes" and nlm["by_factor"][0.01] == "no"
    assert nlm["status"] == "stops" and nlm["stops_at"] in FACTORS


def test_noise_estimate_is_blind_and_close_to_the_truth(evaluation):
    for r in _rows(evaluation.frame_rows, "identity", 0.01):  # read + dark noise dominate: nearly white Gaussian
        for c in "RGB":
            assert r[f"sigma_est_{c}_dn"] == pytest.approx(r[f"noise_std_{c}_dn"], rel=0.1)


def test_user_module_function(dataset, tmp_path, monkeypatch):
    (tmp_path / "my_filters.py").write_text(textwrap.dedent("""
        import numpy as np
        from scipy.ndimage import uniform_filter

        calls = []

        def box(image):
            assert image.shape[-1] == 3 and image.dtype == np.float32
            return uniform_filter(image, size=(3, 3, 1))

        def with_sigma(image, sigma_dn=None):
            calls.append(sigma_dn)
            return image.copy()

        def wrong_shape(image):
            return image[..., :2]

        def nan(image):
            return image * np.nan
        """))
    monkeypatch.syspath_prepend(str(tmp_path))
    box = resolve_denoiser("my_filters:box")
    assert box.kind == "function"
    ev = evaluate([dataset], [box], progress=False)
    row = _summary(ev, box.name, 0.1)  # averaging 9 pixels: the ellipses shrink to about 1/3
    assert row["ellipse_size_ratio"] < 0.5 and row["psnr_denoised_db"] != row["psnr_noisy_db"]

    sigma_fn = resolve_denoiser("my_filters:with_sigma")
    ev = evaluate([dataset / "three_chip" / "macbeth_26_D65_F0.1.exr"], [sigma_fn], progress=False)
    import my_filters

    assert len(my_filters.calls) == 1 and np.asarray(my_filters.calls[0]).shape == (3,)
    assert ev.frame_rows[0]["psnr_gain_db"] == 0.0

    for bad in ("wrong_shape", "nan"):
        with pytest.raises(CamsimError, match="my_filters:" + bad):
            evaluate([dataset], [resolve_denoiser(f"my_filters:{bad}")], progress=False)

    by_path = resolve_denoiser(f"{tmp_path / 'my_filters.py'}:box")  # a .py file works too
    image = np.ones((8, 8, 3), np.float32)
    assert np.array_equal(by_path(image), image)


def test_command_denoiser(dataset):
    target = f"cmd:{sys.executable} -c '{COPY_CODE}' {{input}} {{output}}"
    command = resolve_denoiser(target)
    assert command.kind == "command"
    ev = evaluate([dataset], [command, resolve_denoiser("identity")], progress=False)
    for a, b in zip(_rows(ev.frame_rows, command.name), _rows(ev.frame_rows, "identity")):
        assert a["psnr_denoised_db"] == b["psnr_denoised_db"] == a["psnr_noisy_db"]


def test_failing_command_reports_its_stderr(dataset):
    code = "import sys; sys.stderr.write('model weights missing'); sys.exit(3)"
    command = resolve_denoiser(f"cmd:{sys.executable} -c \"{code}\" {{input}} {{output}}")
    with pytest.raises(CamsimError, match="exit status 3.*model weights missing"):
        evaluate([dataset], [command], progress=False)
    silent = resolve_denoiser(f"cmd:{sys.executable} -c 'pass' {{input}} {{output}}")
    with pytest.raises(CamsimError, match="wrote no"):
        evaluate([dataset], [silent], progress=False)


@pytest.mark.parametrize("target, message", [
    ("no-such-denoiser", "unknown denoiser"),
    ("camsim_no_such_module_xyz:denoise", "no module named"),
    ("os.path:no_such_function", "has no attribute"),
    ("os:sep", "not a function"),
    ("cmd:", "empty command"),
    ("cmd:cp {input}", r"\{output\}"),
    ("cmd:camsim-no-such-program-xyz {input} {output}", "not found"),
    ("cmd:cp 'unbalanced {input} {output}", "cannot split"),
])
def test_bad_targets_are_user_errors(target, message):
    with pytest.raises(CamsimError, match=message):
        resolve_denoiser(target)


def test_no_frames_is_a_user_error(tmp_path):
    with pytest.raises(CamsimError, match="no scorable frames"):
        evaluate([tmp_path], [resolve_denoiser("identity")], progress=False)
    with pytest.raises(CamsimError, match="no such file"):
        evaluate([tmp_path / "missing"], [resolve_denoiser("identity")], progress=False)


def test_missing_reference_leaves_delta_e_undefined_and_counted(dataset):
    frame = dataset / "three_chip" / "macbeth_26_D65_F0.1.exr"
    ev = evaluate([frame], [resolve_denoiser("identity")], progress=False)
    assert all(p["delta_e_denoised"] is None and p["delta_e_status"] == "no-reference" for p in ev.patch_rows)
    assert ev.counts["identity"]["delta_e_no_reference"] == 24
    assert ev.verdicts["identity"]["status"] == "undetermined"


def _cli(argv):
    parser = argparse.ArgumentParser(prog="camsim")
    add_parser(parser.add_subparsers(dest="command"))
    return run(parser.parse_args(argv))


def _assert_no_nan(path):
    text = path.read_text(encoding="utf-8")
    assert not re.search(r"\b(nan|inf|NaN|Infinity)\b", text), path  # Python's and JSON's spellings
    if path.suffix == ".csv":
        for row in csv.DictReader(text.splitlines()):
            for value in row.values():
                try:
                    assert math.isfinite(float(value)), (path, row)
                except ValueError:
                    pass  # text or empty (undefined, counted)


@pytest.mark.slow
def test_cli_outputs_report_and_comparison(dataset_with_bayer, tmp_path, capsys):
    out = tmp_path / "eval"
    assert _cli(["denoise-eval", str(dataset_with_bayer), "--denoiser", "identity", "-d", "nl-means",
                 "--out", str(out), "-q"]) == 0
    for name in ("frames.csv", "patches.csv", "summary.csv", "report.md", "summary.json", "psnr_ssim.png",
                 "chromaticity_bias.png", "delta_e.png", "ellipse_size.png", "examples.png"):
        assert (out / name).is_file(), name
    for name in ("frames.csv", "patches.csv", "summary.csv", "report.md", "summary.json"):
        _assert_no_nan(out / name)
    summary = list(csv.DictReader((out / "summary.csv").read_text().splitlines()))
    assert len(summary) == 2 * len(FACTORS)
    assert len((out / "patches.csv").read_text().splitlines()) == 1 + 2 * 24 * len(FACTORS)
    report = (out / "report.md").read_text()
    assert "## Chart colour" in report and "≤ 3" in report and "≤ 0.005" in report
    assert "≥ 0.8" in report and "≤ 5" in report  # the chart-free criteria (SSIM, ΔE00), stated
    assert re.search(r"\*\*nl-means\*\* preserves detail down to F = [0-9.]+", report)
    assert (out / "bands.csv").is_file() and (out / "crops_by_band.png").is_file()
    assert re.search(r"\*\*nl-means\*\* preserves colour down to F = [0-9.]+ and stops at F = [0-9.]+", report)
    assert "Comparison per light level" in report  # two denoisers: one comparison table
    assert "## Bayer frames: raw and after the ISP" in report  # the CFA frame is scored (issue 26), in its section
    data = json.loads((out / "summary.json").read_text())
    assert data["skipped"] == [] and data["frames_scored"] == len(FACTORS) + 1 and data["frames_scored_bayer"] == 1
    assert {d["name"] for d in data["denoisers"]} == {"identity", "nl-means"}
    printed = capsys.readouterr().out
    assert "nl-means preserves colour down to F =" in printed and "skipped" not in printed


@pytest.mark.slow
def test_cli_criterion_options_and_default_out(dataset, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert _cli(["denoise-eval", str(dataset), "-d", "identity", "--max-delta-e", "1e9", "--max-bias", "1", "-q"]) == 0
    out = tmp_path / "outputs" / "denoise-eval" / "identity"
    data = json.loads((out / "summary.json").read_text())
    assert data["criterion"]["max_delta_e"] == 1e9
    assert data["denoisers"][0]["verdict"]["status"] == "all-preserved"
    assert "below the tested range" in (out / "report.md").read_text()
    with pytest.raises(CamsimError, match="more than once"):
        _cli(["denoise-eval", str(dataset), "-d", "identity", "-d", "identity", "-q"])


def test_keep_black_measures_as_the_paper(dataset):
    ev = evaluate([dataset], [resolve_denoiser("identity")], EvalSettings(subtract_black=False), progress=False)
    # Without black subtraction the dark current drags the clean colours at low light: ΔE floor > 0.
    assert _summary(ev, "identity", 0.01)["delta_e_clean"] > 1.0


def test_verdict_rules():
    def rows(marks):
        return [{"intensity_factor": f, "ok": m} for f, m in zip((1.0, 0.3, 0.1, 0.03), marks)]

    v = verdict(rows(["yes", "yes", "no", "no"]), "ok")
    assert (v["status"], v["preserved_down_to"], v["stops_at"]) == ("stops", 0.3, 0.1)
    v = verdict(rows(["yes"] * 4), "ok")
    assert (v["status"], v["preserved_down_to"], v["stops_at"]) == ("all-preserved", 0.03, None)
    v = verdict(rows(["no", "yes", "no", "no"]), "ok")
    assert (v["status"], v["stops_at"], v["recovers_below"]) == ("never-preserved", 1.0, [0.3])
    assert verdict(rows(["undetermined"] * 4), "ok")["status"] == "undetermined"
    with pytest.raises(CamsimError):
        Criterion(max_delta_e=float("nan"))


def test_noise_estimator():
    rng = np.random.default_rng(0)
    noise = rng.normal(0.0, 2.0, size=(128, 160, 3))
    assert estimate_noise_sigma(noise) == pytest.approx([2.0, 2.0, 2.0], rel=0.05)


@pytest.mark.parametrize("sigma_dn", [None, 8.0])
def test_every_builtin_denoiser_resolves_keeps_the_mean_and_removes_noise(sigma_dn):
    """Each built-in name resolves and, on a piecewise-flat image (known truth) plus N(0, 8²) DN noise, keeps each
    channel's mean and (the identity control excepted, which returns its input unchanged) removes at least half
    of the noise's RMS error; blind (σ estimated from the image) and with σ given."""
    assert set(DENOISERS) == {"identity", "nl-means", "wavelet", "tv", "bm3d"}  # the names the docs and --help list
    rng = np.random.default_rng(2)
    clean = np.kron(rng.uniform(20, 200, size=(4, 6, 3)), np.ones((16, 16, 1))).astype(np.float32)
    noisy = (clean + rng.normal(0.0, 8.0, clean.shape)).astype(np.float32)
    sigma = None if sigma_dn is None else np.full(3, sigma_dn)
    for name in DENOISERS:
        if name == "bm3d" and not bm3d_available():
            continue  # its own test reports the skip
        out = resolve_denoiser(name)(noisy, sigma)
        assert out.shape == clean.shape and out.dtype == np.float32, name
        # the mean of 6144 pixels per channel: standard error 8 / √6144 ≈ 0.1 DN
        np.testing.assert_allclose(out.mean(axis=(0, 1)), clean.mean(axis=(0, 1)), atol=0.5, err_msg=name)
        rmse = float(np.sqrt(np.mean((out - clean) ** 2)))
        if name == "identity":
            np.testing.assert_array_equal(out, noisy)
            assert rmse == pytest.approx(8.0, rel=0.05)
        else:
            assert rmse < 0.5 * 8.0, (name, rmse)


def test_wavelet_denoiser_runs(dataset):
    ev = evaluate([dataset / "three_chip" / "macbeth_26_D65_F0.1.exr"], [resolve_denoiser("wavelet")],
                  progress=False)
    assert ev.frame_rows[0]["psnr_gain_db"] > 1.0


# ------------------------------------------------------------------------------------ chart-free colour fidelity

# A camera → XYZ matrix (any invertible one: the score goes through it both ways) and a white in its scale.
_M = np.array([[0.41, 0.36, 0.18], [0.21, 0.72, 0.07], [0.02, 0.12, 0.95]])
_WHITE_DN = np.array([800.0, 1000.0, 900.0])


def _dn_of_lab(lab, white_xyz):
    """Camera DN whose XYZ has the given Lab against ``white_xyz`` (colour-science's Lab_to_XYZ, the inverse way)."""
    import colour

    xy = white_xyz[:2] / white_xyz.sum()
    xyz = np.asarray(colour.Lab_to_XYZ(lab, illuminant=xy)) * white_xyz[1]
    return xyz @ np.linalg.inv(_M).T


def test_delta_e00_is_zero_for_clean_and_the_published_value_for_a_known_shift():
    from camsim.denoise.colour_fidelity import frame_white_xyz, lab_against_white, mean_delta_e00

    meta = {"white_signal_e": (_WHITE_DN / 0.4).tolist(), "dn_per_electron": 0.4}
    white, _ = frame_white_xyz(meta, _M)
    # The perfect white itself is L* = 100, a* = b* = 0.
    np.testing.assert_allclose(lab_against_white(_WHITE_DN @ _M.T, white), [100.0, 0.0, 0.0], atol=1e-9)
    rng = np.random.default_rng(5)
    clean = rng.uniform(10.0, 700.0, size=(12, 16, 3))
    assert mean_delta_e00(clean, clean, _M, white) == 0.0
    # Sharma, Wu & Dalal (2005), CIEDE2000 test data, pairs 1, 7 and 17: Lab pairs and their published ΔE00.
    pairs = [((50.0, 2.6772, -79.7751), (50.0, 0.0, -82.7485), 2.0425),
             ((50.0, 0.0, 0.0), (50.0, -1.0, 2.0), 2.3669),
             ((50.0, 2.5, 0.0), (73.0, 25.0, -18.0), 27.1492)]
    for lab_clean, lab_test, expected in pairs:
        clean_px = np.broadcast_to(_dn_of_lab(np.array(lab_clean), white), (4, 5, 3))
        test_px = np.broadcast_to(_dn_of_lab(np.array(lab_test), white), (4, 5, 3))
        assert mean_delta_e00(test_px, clean_px, _M, white) == pytest.approx(expected, abs=1e-4)
    # Half the pixels shifted by pair 1, half unchanged: the mean is half the pair's ΔE00.
    clean_px = np.broadcast_to(_dn_of_lab(np.array(pairs[0][0]), white), (4, 6, 3)).copy()
    test_px = clean_px.copy()
    test_px[:, :3] = _dn_of_lab(np.array(pairs[0][1]), white)
    assert mean_delta_e00(test_px, clean_px, _M, white) == pytest.approx(pairs[0][2] / 2, abs=1e-4)


def test_delta_e00_grows_with_noise_and_a_denoiser_lowers_it(evaluation):
    for name in ("nl-means", "tv"):
        noisy = [_summary(evaluation, name, f)["delta_e_noisy"] for f in FACTORS]  # chart ΔE, for comparison
        assert all(v is not None for v in noisy)
    rows = {f: _rows(evaluation.frame_rows, "nl-means", f)[0] for f in FACTORS}
    de_noisy = [rows[f]["delta_e00_noisy"] for f in FACTORS]
    assert de_noisy[0] < de_noisy[1] < de_noisy[2]  # less light, more visible noise
    assert all(rows[f]["delta_e00_denoised"] < rows[f]["delta_e00_noisy"] for f in FACTORS)
    for r in _rows(evaluation.frame_rows, "identity"):
        assert r["delta_e00_denoised"] == r["delta_e00_noisy"]
    assert all(r["white_source"].startswith("perfect white") for r in evaluation.frame_rows)


@pytest.fixture(scope="module")
def chartless(tmp_path_factory):
    """Dead-leaves frames (no chart) at F = 0.1 and 0.01: no F = 1 frame."""
    out = tmp_path_factory.mktemp("chartless")
    scene = load_scene(ROOT / "scenes" / "dead_leaves.toml")
    scene = scene.replace(width=128, height=96, intensity_factors=(0.1, 0.01))
    render_scene(scene, out / "dead_leaves", progress=False)
    return out


def test_chart_free_colour_judges_a_frame_with_no_chart_and_no_f1(chartless, tmp_path):
    ev = evaluate([chartless], [resolve_denoiser("identity"), resolve_denoiser("tv")], progress=False)
    assert not ev.patch_rows  # no chart in view
    for r in ev.frame_rows:
        assert r["delta_e00_noisy"] is not None and r["delta_e00_noisy"] > 0
    for name in ("identity", "tv", "noisy"):
        assert ev.band_verdicts[name]["colour"]["status"] != "undetermined"
        assert ev.band_verdicts[name]["detail"]["status"] != "undetermined"
    from camsim.denoise import write_outputs

    paths = write_outputs(ev, tmp_path / "eval")
    report = paths["report"].read_text(encoding="utf-8")
    table_lines = [line for line in report.splitlines() if line.startswith("|")]
    assert table_lines and not any("?" in line for line in table_lines)
    assert "cannot be judged" not in report and "No chart in view" in report
    assert re.search(r"\*\*tv\*\* (preserves|does not preserve) colour", report)
    assert (tmp_path / "eval" / "crops_by_band.png").is_file() and "crops_by_band.png" in report
    bands = list(csv.DictReader(paths["bands"].read_text().splitlines()))
    assert {b["band"] for b in bands} == {"0.1–0.316", "0.01–0.0316"}


# ------------------------------------------------------------------------------------------------------ BM3D

def test_bm3d_lowers_the_error_of_a_noisy_frame():
    if not bm3d_available():
        with pytest.raises(CamsimError, match="pip install bm3d"):
            resolve_denoiser("bm3d")
        pytest.skip("the bm3d package is not installed")
    bm3d = resolve_denoiser("bm3d")
    assert bm3d.sigma_source == "model"
    rng = np.random.default_rng(11)
    clean = np.kron(rng.uniform(50, 400, size=(3, 4, 3)), np.ones((24, 24, 1)))
    yy, xx = np.mgrid[0:72, 0:96]
    clean = (clean + 40.0 * np.sin(xx / 5.0)[..., None]).astype(np.float32)  # some texture too
    sigma = np.array([6.0, 8.0, 10.0])
    noisy = (clean + rng.normal(0.0, 1.0, clean.shape) * sigma).astype(np.float32)
    out = bm3d(noisy, sigma)
    rmse_noisy = float(np.sqrt(np.mean((noisy - clean) ** 2)))
    rmse_out = float(np.sqrt(np.mean((out - clean) ** 2)))
    assert rmse_out < 0.5 * rmse_noisy


def test_model_sigma_matches_the_true_noise(dataset):
    from camsim.io.exr import read_exr
    from camsim.render.frame_files import load_frame

    for f in FACTORS:
        path = dataset / "three_chip" / f"macbeth_26_D65_F{f:g}.exr"
        frame = load_frame(path)
        noisy = np.moveaxis(frame.pixels_dn, 0, -1).astype(np.float64)
        _, clean, _ = read_exr(path)
        true = (noisy - np.moveaxis(clean, 0, -1)).std(axis=(0, 1))
        model = model_noise_sigma(frame.meta, noisy, frame.expected_black_dn())
        np.testing.assert_allclose(model, true, rtol=0.05)


# ------------------------------------------------------------------------------------------- band verdicts

def test_band_verdicts_on_a_constructed_table():
    from camsim.denoise.summary import band_verdicts, f_band, summarise_bands

    assert f_band(1.0) == pytest.approx((1.0, 10 ** 0.5))
    assert f_band(0.1) == pytest.approx((0.1, 10 ** -0.5))
    assert f_band(0.05) == pytest.approx((10 ** -1.5, 0.1))
    table = [  # F, SSIM noisy, SSIM denoised, ΔE00 noisy, ΔE00 denoised
        (0.8, 0.95, 0.97, 2.0, 1.0), (0.5, 0.93, 0.96, 3.0, 1.5),  # band 0.316–1
        (0.2, 0.85, 0.93, 6.0, 3.0),  # band 0.1–0.316
        (0.05, 0.6, 0.85, 12.0, 6.0), (0.04, 0.5, 0.81, 14.0, 7.0),  # band 0.0316–0.1: mean SSIM 0.83, ΔE00 6.5
        (0.02, 0.4, 0.7, 25.0, 12.0),  # band 0.01–0.0316
        (0.005, 0.2, 0.9, 50.0, 2.0),  # band 0.00316–0.01: passes again (an odd denoiser), below the stops
    ]
    rows = [{"denoiser": "d", "intensity_factor": f, "ssim_noisy": sn, "ssim_denoised": sd, "ssim_gain": sd - sn,
             "psnr_gain_db": None, "delta_e00_noisy": en, "delta_e00_denoised": ed, "seconds": 0.1}
            for f, sn, sd, en, ed in table]
    crit = Criterion(min_ssim=0.8, max_delta_e00=5.0)
    bands = summarise_bands(rows, ["d"], crit)
    assert [b["n_frames"] for b in bands] == [2, 1, 2, 1, 1]
    assert bands[2]["ssim_denoised"] == pytest.approx(0.83) and bands[2]["delta_e00_denoised"] == pytest.approx(6.5)
    v = band_verdicts(bands, ["d"])
    detail, colour = v["d"]["detail"], v["d"]["colour"]
    assert (detail["status"], detail["preserved_down_to"], detail["stops_at"]) == ("stops", 0.04, 0.02)
    assert detail["recovers_below"] == [0.005]
    assert (colour["status"], colour["preserved_down_to"], colour["stops_at"]) == ("stops", 0.2, 0.04)
    noisy = v["noisy"]
    assert (noisy["detail"]["preserved_down_to"], noisy["detail"]["stops_at"]) == (0.2, 0.04)
    assert (noisy["colour"]["status"], noisy["colour"]["stops_at"]) == ("stops", 0.2)
    assert noisy["colour"]["preserved_down_to"] == 0.5
    with pytest.raises(CamsimError):
        Criterion(min_ssim=1.5)
