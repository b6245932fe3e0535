"""The analysis package on rendered frames, read back from files: SNR, undefined cases, ΔE, the CLI."""

import csv
import json
import shutil

import numpy as np
import pytest

from camsim.analysis.analyze import analyse_paths
from camsim.analysis.patches import AnalysisSettings, analyse_frame
from camsim.cli import main
from camsim.core.errors import CamsimError
from camsim.render.frame_files import load_frame
from camsim.render.run import render_scene
from tests.support.helpers import ROOT, small_scene

SCENE = ROOT / "scenes" / "macbeth_26.toml"


@pytest.fixture(scope="module")
def frames(tmp_path_factory):
    out = tmp_path_factory.mktemp("frames")
    render_scene(small_scene(intensity_factors=(1.0, 0.1, 0.01)), out, progress=False)
    return out


@pytest.fixture(scope="module")
def analysed(frames):
    """The frames' analysis with the default settings (from the DNGs), which several tests read."""
    return analyse_paths([frames], AnalysisSettings(), progress=False)


def _snr_se(samples_mean, samples_var, n):
    """Relative standard error of SNR = m² / v from n samples (mean and variance errors)."""
    return np.sqrt(4 * samples_var / (n * samples_mean**2) + 2 / (n - 1))


@pytest.mark.parametrize("source", ["dng", "exr"])
def test_model_snr_matches_the_pixels(frames, request, source):
    results = (request.getfixturevalue("analysed") if source == "dng"  # (not built for the EXR case)
               else analyse_paths([frames], AnalysisSettings(), source=source, progress=False))
    checked = 0
    for result in results:
        assert result["source"] == source
        for patch in result["patches"]:
            for ch in patch["channels"]:
                if ch["saturated_pixels"] or ch["snr_model"] is None or ch["snr_model"] < 1:
                    continue
                signal = np.sqrt(ch["snr_model"] * ch["var_dn2"])
                se = _snr_se(signal, ch["var_dn2"], ch["n_pixels"])
                assert abs(ch["snr_empirical"] / ch["snr_model"] - 1) < 5 * se, (result["frame_file"], patch["name"])
                checked += 1
    assert checked > 150


def test_model_snr_columns_under_paper_statistics(tmp_path):
    """``snr_model``: the statistics' own variance and the quantiser's 1/12 DN²; ``snr_model_eq13``: Eqs. 13–14 as
    printed, [k S]_nb² / (k² (S + D + σ²_read) + 1/3): computed here from the sidecar's numbers."""
    out = _render(tmp_path, small_scene(statistics="paper", method="poisson", intensity_factors=(0.01,),
                                        width=240, height=160))
    meta = json.loads(next(out.glob("test_*.json")).read_text())
    k, read = meta["dn_per_electron"], meta["read_noise_e"]
    (result,) = analyse_paths([out], AnalysisSettings(), progress=False)
    for patch, recorded in zip(result["patches"], meta["patches"]):
        for c, ch in enumerate(patch["channels"]):
            s, d, var = recorded["signal_e"][c], recorded["dark_e"][c], recorded["signal_var_e2"][c]
            assert var < 1e-6 * s  # paper statistics: Var S is tiny against S
            own = (k * s) ** 2 / (k**2 * (var + d + read**2) + 1 / 12)
            printed = np.floor(k * s) ** 2 / (k**2 * (s + d + read**2) + 1 / 3)
            assert ch["snr_model"] == pytest.approx(own, rel=1e-9)
            if printed == 0:
                assert ch["snr_model_eq13"] in (0.0, None)
            else:
                assert ch["snr_model_eq13"] == pytest.approx(printed, rel=1e-9)


def test_delta_e_is_small_at_f1_and_grows_as_light_falls(analysed):
    results = analysed
    by_f = {r["intensity_factor"]: np.mean([p["delta_e_ab_mean"] for p in r["patches"]]) for r in results}
    assert by_f[1.0] < by_f[0.1] < by_f[0.01]
    for r in results:
        assert all(p["delta_e_status"] == "ok" for p in r["patches"])


def _render(tmp_path, scene, name="f"):
    render_scene(scene, tmp_path / name, progress=False)
    return tmp_path / name


@pytest.mark.slow
def test_undefined_cases_are_counted_not_nan(tmp_path):
    # 1. black-subtracted, almost no light: X+Y+Z ≤ 0 and Y ≤ 0 samples
    dark = _render(tmp_path, small_scene(intensity_factors=(1.0, 1e-3)), "dark")
    results = analyse_paths([dark], AnalysisSettings(black="sidecar"), source="exr", progress=False)
    low = next(r for r in results if r["intensity_factor"] == 1e-3)
    assert sum(p["n_xy_undefined"] for p in low["patches"]) > 1000
    assert sum(p["n_y_nonpositive"] for p in low["patches"]) > 1000
    # 2. a patch that is one value after quantisation: no noise at all
    still = small_scene(intensity_factors=(0.5,)).with_sensor(photon_noise=False, dark_current=False,
                                                              read_noise=False)
    constant = analyse_paths([_render(tmp_path, still, "still")], AnalysisSettings(), progress=False)[0]
    assert all(p["ellipse_status"] == "constant" for p in constant["patches"])
    assert all(ch["constant"] and ch["snr_status"] == "constant" for p in constant["patches"]
               for ch in p["channels"])
    # 3. only one channel noisy: the xy samples lie on a line (a projective image of a segment)
    line = small_scene(intensity_factors=(0.5,)).with_sensor(photon_noise=False, read_noise=False,
                                                             quantisation=False, dark_current_e_per_s=(0, 0, 218.0))
    rank1 = analyse_paths([_render(tmp_path, line, "line")], AnalysisSettings(), progress=False)[0]
    assert all(p["ellipse_status"] == "rank-1" for p in rank1["patches"])
    # 4. saturation
    bright = analyse_paths([_render(tmp_path, small_scene(intensity_factors=(3.0,)), "bright")],
                           AnalysisSettings(), progress=False)[0]
    assert bright["patches"][18]["channels"][1]["saturated_pixels"] == bright["patches"][18]["channels"][1]["n_pixels"]
    # 5. a border that leaves no pixel: the analysis refuses it; measured anyway, every patch is empty, not NaN
    with pytest.raises(CamsimError, match=r"border of 200 px .* leaves patch 0 'dark skin' \(\d+x\d+ px\)"):
        analyse_paths([tmp_path / "bright"], AnalysisSettings(border_px=200), progress=False)
    frame = load_frame(next((tmp_path / "bright").glob("*.dng")))
    empty, _ = analyse_frame(frame, AnalysisSettings(border_px=200), np.zeros(3), np.eye(3))
    assert all(p["ellipse_status"] == "too-few-samples" and p["channels"][0]["mean_dn"] is None for p in empty)
    # the CLI writes all of it without NaN (JSON is written with allow_nan=False)
    for folder in ("dark", "still", "line", "bright"):
        assert main(["analyze", str(tmp_path / folder), "--subtract-black", "--out", str(tmp_path / f"a-{folder}"),
                     "-q"]) == 0
        with open(tmp_path / f"a-{folder}" / "analysis.csv") as handle:
            cells = [cell.lower() for row in csv.reader(handle) for cell in row]
        assert not {"nan", "inf", "-inf", "infinity"} & set(cells)
        summary = json.loads((tmp_path / f"a-{folder}" / "analysis.json").read_text())
        assert summary["totals"]["patches"] == 24 * summary["totals"]["frames"]
    totals = json.loads((tmp_path / "a-dark" / "analysis.json").read_text())["totals"]
    assert totals["xy_undefined_samples"] > 0 and totals["y_nonpositive_samples"] > 0


@pytest.mark.slow
def test_analyze_cli_on_moved_and_renamed_frames(frames, tmp_path, capsys):
    moved = tmp_path / "elsewhere"
    moved.mkdir()
    for suffix in (".dng", ".json"):
        shutil.copy(frames / f"test_D65_F0.1{suffix}", moved / f"renamed{suffix}")
    shutil.copy(frames / "test_D65_F1.exr", moved / "reference.exr")  # the EXR carries its own metadata
    out = tmp_path / "analysis"
    assert main(["analyze", str(moved), "--out", str(out)]) == 2  # a folder gives its committed frames only
    assert "2 frame file(s) that no sidecar claims (reference.exr, renamed.dng)" in capsys.readouterr().err
    assert main(["analyze", str(moved / "renamed.dng"), str(moved / "reference.exr"), "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "renamed.dng" in printed and "reference.exr" in printed
    lines = (out / "analysis.csv").read_text().splitlines()
    header = lines[0].split(",")
    assert len(lines) == 1 + 2 * 24 * 3
    for column in ("mean_dn", "var_dn2", "mean_e", "std_e", "size_xy", "angle_deg", "delta_e_ab_mean",
                   "snr_empirical_db", "n_xy_undefined"):
        assert column in header
    summary = json.loads((out / "analysis.json").read_text())
    renamed = next(f for f in summary["frames"] if f["frame_file"].endswith("renamed.dng"))
    assert all(p["delta_e_status"] == "ok" for p in renamed["patches"])  # reference found by content, not name


@pytest.mark.parametrize("case", ["truncated", "no sidecar", "not a frame", "nothing"])
def test_analyze_bad_input(frames, tmp_path, capsys, case):
    target = tmp_path / "in"
    target.mkdir()
    if case == "truncated":
        data = (frames / "test_D65_F1.dng").read_bytes()
        (target / "x.dng").write_bytes(data[: len(data) // 3])
        meta = json.loads((frames / "test_D65_F1.json").read_text())
        meta["files"]["dng"] = "x.dng"  # a committed frame whose DNG is damaged
        (target / "x.json").write_text(json.dumps(meta))
    elif case == "no sidecar":
        shutil.copy(frames / "test_D65_F1.dng", target / "x.dng")
    elif case == "not a frame":
        (target / "x.exr").write_text("hello")
    assert main(["analyze", str(target), "--out", str(tmp_path / "o"), "-q"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("camsim: error:") and err.count("\n") == 1 and "Traceback" not in err
    assert not (tmp_path / "o").exists()


def test_distinct_values_with_counts_give_the_same_statistics(frames, monkeypatch):
    """Quantised patches are measured on their distinct values weighted by counts: exactly as on every pixel."""
    import camsim.analysis.patches as patches_module

    fast = analyse_paths([frames], AnalysisSettings(black="sidecar"), progress=False)
    monkeypatch.setattr(patches_module, "distinct_samples",
                        lambda raw: (raw.astype(np.float64), np.ones(raw.shape[0], dtype=np.int64)))
    slow = analyse_paths([frames], AnalysisSettings(black="sidecar"), progress=False)
    keys = ("center_x", "center_y", "semi_major_xy", "semi_minor_xy", "angle_deg", "frac_in_2sigma",
            "delta_e_ab_mean", "delta_e_ab_std", "n_xy_undefined", "n_y_nonpositive")
    for a, b in zip(fast, slow):
        for pa, pb in zip(a["patches"], b["patches"]):
            for key in keys:
                assert pa[key] == pytest.approx(pb[key], rel=1e-9, abs=1e-12), key
            for ca, cb in zip(pa["channels"], pb["channels"]):
                for key in ("mean_dn", "var_dn2", "saturated_pixels", "snr_empirical", "n_pixels"):
                    assert ca[key] == pytest.approx(cb[key], rel=1e-9), key
