"""``camsim analyze`` on imperfect folders: bad files skipped (or fatal with --strict), committed frames only,
nonsense settings refused, one frame in memory at a time. Real frames, damaged on disk."""

import dataclasses
import json
import shutil
import weakref

import numpy as np
import pytest

import camsim.analysis.analyze as analyze_module
from camsim.analysis.analyze import analyse
from camsim.analysis.dark import channel_means, lit_reason
from camsim.analysis.patches import AnalysisSettings, demosaiced_samples
from camsim.cli import main
from camsim.core.errors import CamsimError
from camsim.denoise.frames import UNCOMMITTED, find_dataset
from camsim.io.dng import read_dng
from camsim.render.frame_files import LoadedFrame, find_frames, load_frame, search_frames, uncommitted_lines
from camsim.render.run import render_scene
from tests.support.helpers import small_scene

SIZE = {"width": 64, "height": 48}  # 24 patches of 9 x 10 pixels
STEM = "test_D65_F"  # render_scene's file stems: test_D65_F1, test_D65_F0.1


@pytest.fixture(scope="module")
def rendered(tmp_path_factory):
    """Frames at F = 1 and 0.1, a dark frame, a larger dark frame and Bayer frames (with a Bayer dark frame)."""
    root = tmp_path_factory.mktemp("robust")
    render_scene(small_scene(**SIZE, intensity_factors=(1.0, 0.1)), root / "good", progress=False)
    render_scene(small_scene(**SIZE, intensity_factors=(1e-7,)), root / "dark", progress=False)
    render_scene(small_scene(width=96, height=64, intensity_factors=(1e-7,)), root / "dark96", progress=False)
    bayer = small_scene(**SIZE, intensity_factors=(1.0, 1e-7)).with_sensor(cfa="RGGB")
    render_scene(bayer, root / "bayer", progress=False)
    return root


def _copy_frame(src, stem, dest, new_stem, kinds=(".dng", ".exr", ".json")):
    """Copy a frame's files under a new stem; its sidecar then claims the new names (a committed frame)."""
    dest.mkdir(parents=True, exist_ok=True)
    for kind in kinds:
        shutil.copy(src / f"{stem}{kind}", dest / f"{new_stem}{kind}")
    if ".json" in kinds:
        sidecar = dest / f"{new_stem}.json"
        meta = json.loads(sidecar.read_text())
        meta["files"] = {k: (f"{new_stem}.{k}" if v else None) for k, v in meta["files"].items()}
        sidecar.write_text(json.dumps(meta))


def _damaged_folder(rendered, tmp_path):
    """Two good frames, then bad ones: a truncated DNG, a corrupt sidecar, a sidecar of another frame size."""
    folder = tmp_path / "frames"
    good = rendered / "good"
    _copy_frame(good, f"{STEM}1", folder, "a_F1")
    _copy_frame(good, f"{STEM}0.1", folder, "b_F0.1")
    _copy_frame(good, f"{STEM}0.1", folder, "c_truncated")
    for kind in (".dng", ".exr"):
        data = (folder / f"c_truncated{kind}").read_bytes()
        (folder / f"c_truncated{kind}").write_bytes(data[: len(data) // 2])
    _copy_frame(good, f"{STEM}0.1", folder, "d_corrupt_sidecar")
    (folder / "d_corrupt_sidecar.json").write_text('{"files": {"dng": "d_corrupt_sidecar.dng"')  # cut short
    _copy_frame(good, f"{STEM}0.1", folder, "e_wrong_size", kinds=(".dng",))
    _copy_frame(rendered / "dark96", f"{STEM}1e-07", folder, "e_wrong_size", kinds=(".json",))
    return folder


def _err_lines(capsys):
    captured = capsys.readouterr()
    return captured.out, [line for line in captured.err.splitlines() if line]


@pytest.mark.slow
@pytest.mark.parametrize("source", ["dng", "exr"])
def test_bad_files_are_skipped_each_on_one_line_and_the_rest_analysed(rendered, tmp_path, capfd, source):
    folder = _damaged_folder(rendered, tmp_path)
    foreign = tmp_path / "notes.txt"
    foreign.write_text("not a frame")
    orphan = tmp_path / "orphan.dng"  # named explicitly, without a sidecar
    shutil.copy(rendered / "good" / f"{STEM}1.dng", orphan)
    out = tmp_path / "out"
    assert main(["analyze", str(folder), str(foreign), str(orphan), str(tmp_path / "missing.dng"), "--out",
                 str(out), "--source", source, "-q"]) == 0
    printed, err = _err_lines(capfd)  # at the file descriptor: nothing from LibRaw or OpenEXR either
    assert all(line.startswith("camsim: warning: skipped ") for line in err), err
    reasons = {name: next(line for line in err if f"{name}:" in line) for name in
               (f"c_truncated.{source}", "d_corrupt_sidecar.json", "e_wrong_size.dng", "notes.txt", "orphan.dng",
                "missing.dng")}
    assert len(err) == len(reasons)
    assert "truncated" in reasons[f"c_truncated.{source}"]
    assert "unreadable sidecar" in reasons["d_corrupt_sidecar.json"]
    assert "wrong sidecar?" in reasons["e_wrong_size.dng"]
    assert "not a frame file" in reasons["notes.txt"]
    assert "sidecar not found" in reasons["orphan.dng"]
    assert "no such file or folder" in reasons["missing.dng"]
    assert "analysed 2 frames, skipped 6 bad file(s)" in printed and "Traceback" not in printed
    summary = json.loads((out / "analysis.json").read_text())
    assert summary["totals"]["frames"] == 2 and summary["uncommitted"] == []
    assert sorted(s["file"].rsplit("/", 1)[-1] for s in summary["skipped"]) == sorted(reasons)
    assert all(s["reason"] for s in summary["skipped"])
    by_name = {f["frame_file"].rsplit("/", 1)[-1]: f for f in summary["frames"]}
    assert all(p["delta_e_status"] == "ok" for p in by_name[f"b_F0.1.{source}"]["patches"])  # reference found
    assert len((out / "analysis.csv").read_text().splitlines()) == 1 + 2 * 24 * 3


def test_strict_makes_the_first_bad_file_fatal(rendered, tmp_path, capsys):
    folder = _damaged_folder(rendered, tmp_path)
    assert main(["analyze", str(folder), "--strict", "--out", str(tmp_path / "out"), "-q"]) == 2
    _, err = _err_lines(capsys)
    assert len(err) == 1 and err[0].startswith("camsim: error: ") and "d_corrupt_sidecar.json" in err[0]
    assert not (tmp_path / "out").exists()
    shutil.rmtree(folder)
    _copy_frame(rendered / "good", f"{STEM}1", folder, "a_F1")
    # --strict has no say in the figures, and test_folders_give_committed_frames_only draws this same frame's
    assert main(["analyze", str(folder), "--strict", "--out", str(tmp_path / "out"), "-q", "--no-figures"]) == 0


def test_nothing_analysable_is_one_error_line(rendered, tmp_path, capsys):
    folder = _damaged_folder(rendered, tmp_path)
    for stem in ("a_F1", "b_F0.1"):
        for path in folder.glob(f"{stem}.*"):
            path.unlink()
    assert main(["analyze", str(folder), "--out", str(tmp_path / "out"), "-q"]) == 2
    _, err = _err_lines(capsys)
    assert len(err) == 1 and err[0].startswith("camsim: error: nothing analysed: skipped 3 bad files, e.g. ")
    assert not (tmp_path / "out").exists()


@pytest.mark.slow
def test_folders_give_committed_frames_only(rendered, tmp_path, capsys):
    folder = tmp_path / "frames"
    good = rendered / "good"
    _copy_frame(good, f"{STEM}1", folder, "a_F1")
    _copy_frame(good, f"{STEM}0.1", folder, "b_F0.1")
    (folder / "b_F0.1.json").unlink()  # data files written, sidecar not yet: uncommitted
    shutil.copy(good / f"{STEM}0.1.dng", folder / "c_stale.dng")  # a sidecar that names another file
    shutil.copy(good / f"{STEM}0.1.json", folder / "c_stale.json")
    shutil.copy(good / f"{STEM}0.1.dng", folder / f".a_F1.dng.{1234}.partial")  # a writer's temporary
    shutil.copy(good / f"{STEM}0.1.dng", folder / ".hidden.dng")
    out = tmp_path / "out"
    assert main(["analyze", str(folder), "--out", str(out), "-q"]) == 0
    printed, err = _err_lines(capsys)
    assert err == [f"camsim: warning: ignored 3 uncommitted frame file(s) in {folder} (no sidecar claims them): "
                   "b_F0.1.dng, b_F0.1.exr, c_stale.dng"]
    assert "analysed 1 frames, skipped 0 bad file(s), ignored 3 uncommitted file(s)" in printed
    summary = json.loads((out / "analysis.json").read_text())
    assert [f["frame_file"] for f in summary["frames"]] == [str(folder / "a_F1.dng")]
    assert summary["uncommitted"] == [str(folder / n) for n in ("b_F0.1.dng", "b_F0.1.exr", "c_stale.dng")]
    # named explicitly, a file is read as before: the stale sidecar's frame reads, the EXR carries its metadata
    assert main(["analyze", str(folder / "c_stale.dng"), str(folder / "b_F0.1.exr"), "--out", str(out), "-q"]) == 0
    printed, err = _err_lines(capsys)
    assert err == [] and "analysed 2 frames, skipped 0 bad file(s):" in printed
    # the compatible finder: committed frames only, an error when none is committed
    assert find_frames([folder]) == [folder / "a_F1.dng"]
    assert search_frames([folder], "exr").files == [folder / "a_F1.exr"]
    (folder / "a_F1.json").unlink()
    with pytest.raises(CamsimError, match=r"no committed frames .* 5 frame file\(s\) that no sidecar claims"):
        find_frames([folder])


def test_the_uncommitted_warning_is_one_line_per_folder_with_a_capped_list(tmp_path):
    files = [tmp_path / f"f{i}.dng" for i in range(8)] + [tmp_path / "sub" / "g.exr"]
    lines = uncommitted_lines(files)
    assert lines == [f"ignored 8 uncommitted frame file(s) in {tmp_path} (no sidecar claims them): "
                     "f0.dng, f1.dng, f2.dng, f3.dng, f4.dng … (+3)",
                     f"ignored 1 uncommitted frame file(s) in {tmp_path / 'sub'} (no sidecar claims them): g.exr"]


def test_denoise_eval_takes_committed_frames_only(rendered, tmp_path):
    folder = tmp_path / "frames"
    _copy_frame(rendered / "good", f"{STEM}1", folder, "a_F1")
    _copy_frame(rendered / "good", f"{STEM}0.1", folder, "b_F0.1", kinds=(".exr",))  # no sidecar yet
    shutil.copy(rendered / "good" / f"{STEM}0.1.exr", folder / ".b_F0.1.exr.99.partial")
    dataset = find_dataset([folder])
    assert [f.name for f in dataset.frames] == ["a_F1.exr"]
    assert dataset.skipped == [{"file": "b_F0.1.exr", "reason": UNCOMMITTED}]


def test_a_border_that_empties_a_patch_is_refused(rendered, tmp_path, capsys):
    good = rendered / "good"
    w, h = json.loads((good / f"{STEM}1.json").read_text())["patches"][0]["rect_xywh"][2:]
    largest = (min(w, h) - 1) // 2
    assert main(["analyze", str(good), "--border", str(largest), "--out", str(tmp_path / "ok"), "-q"]) == 0
    capsys.readouterr()
    assert main(["analyze", str(good), "--border", str(largest + 1), "--out", str(tmp_path / "no"), "-q"]) == 2
    _, err = _err_lines(capsys)
    assert len(err) == 1 and err[0].startswith(f"camsim: error: a border of {largest + 1} px (--border) leaves "
                                               f"patch 0 'dark skin' ({w}x{h} px) of ")
    assert err[0].endswith(f"empty: it allows at most {largest} px")
    # a Bayer patch needs a whole 2 x 2 cell
    bayer = rendered / "bayer"
    assert main(["analyze", str(bayer), "--border", str((min(w, h) - 2) // 2 + 1), "--out", str(tmp_path / "b"),
                 "-q"]) == 2


@pytest.mark.parametrize("case", ["other size", "other CFA layout", "lit"])
def test_unfit_dark_frames_are_refused(rendered, tmp_path, capsys, case):
    dark = {"other size": rendered / "dark96" / f"{STEM}1e-07.dng",
            "other CFA layout": rendered / "bayer" / f"{STEM}1e-07.dng",
            "lit": rendered / "good" / f"{STEM}0.1.dng"}[case]
    assert main(["analyze", str(rendered / "good"), "--dark", str(dark), "--out", str(tmp_path / "o"), "-q"]) == 2
    _, err = _err_lines(capsys)
    assert len(err) == 1 and err[0].startswith(f"camsim: error: --dark {dark} ")
    expected = {"other size": "is 96x64 three-chip but", "other CFA layout": "is 64x48 RGGB but",
                "lit": "is not a dark frame: its sidecar expects up to"}[case]
    assert expected in err[0]
    assert not (tmp_path / "o").exists()


def test_a_dark_frame_gives_its_per_channel_mean(rendered):
    dark = rendered / "dark" / f"{STEM}1e-07.dng"
    (result,) = analyse([rendered / "good" / f"{STEM}1.dng"], AnalysisSettings(black="dark-frame"),
                        dark_frame=dark, progress=False).results
    dn, _ = read_dng(dark)
    assert result["black_dn"] == dn.reshape(3, -1).mean(axis=1).tolist()
    # a Bayer dark frame: the mean of each colour's sites (not of thirds of the mosaic)
    bayer_dark = rendered / "bayer" / f"{STEM}1e-07.dng"
    (result,) = analyse([rendered / "bayer" / f"{STEM}1.dng"], AnalysisSettings(black="dark-frame"),
                        dark_frame=bayer_dark, progress=False).results
    mosaic = read_dng(bayer_dark)[0][0].astype(np.float64)  # RGGB
    sites = [mosaic[0::2, 0::2], np.concatenate([mosaic[0::2, 1::2].ravel(), mosaic[1::2, 0::2].ravel()]),
             mosaic[1::2, 1::2]]
    assert result["black_dn"] == pytest.approx([s.mean() for s in sites], rel=1e-12)


def test_without_a_chart_the_pixels_tell_a_lit_frame(rendered):
    """Frames whose sidecar has no patch signals (a radiance cube's) are judged from the pixels."""
    def chartless(path):
        frame = load_frame(path)
        return dataclasses.replace(frame, meta=frame.meta | {"patches": [], "surround": None})

    dark = chartless(rendered / "dark" / f"{STEM}1e-07.dng")
    assert lit_reason(dark, channel_means(dark)) is None
    lit = chartless(rendered / "good" / f"{STEM}0.1.dng")
    assert "mean" in lit_reason(lit, channel_means(lit)) and "exceeds the expected black level" in \
        lit_reason(lit, channel_means(lit))


def test_frames_are_loaded_one_at_a_time(rendered, tmp_path, monkeypatch):
    """Pass 1 reads metadata only; pass 2 holds one frame's pixels at a time (no earlier frame is alive)."""
    folder = tmp_path / "frames"
    for i, f in enumerate(("0.1", "1", "0.1", "1")):
        _copy_frame(rendered / "good", f"{STEM}{f}", folder, f"{i}_F{f}")
    alive: list = []
    most = []

    def load(path):
        most.append(sum(ref() is not None for ref in alive))
        frame = load_frame(path)
        alive.append(weakref.ref(frame))
        return frame

    monkeypatch.setattr(analyze_module, "load_frame", load)
    for source in ("dng", "exr"):
        alive.clear()
        most.clear()
        results = analyse([folder], source=source, progress=False).results
        assert len(most) == 4 and max(most) == 0
        assert [r["intensity_factor"] for r in results] == [1.0, 1.0, 0.1, 0.1]  # F = 1 first: the reference
        assert all(p["delta_e_status"] == "ok" for r in results for p in r["patches"])


@pytest.mark.parametrize("pattern", ["RGGB", "BGGR", "GRBG", "GBRG"])
def test_demosaicing_a_window_gives_the_whole_frames_values(pattern):
    from colour_demosaicing import demosaicing_CFA_Bayer_bilinear

    rng = np.random.default_rng(3)
    mosaic = rng.integers(0, 256, size=(1, 40, 50), dtype=np.uint8)
    frame = LoadedFrame(path=None, source="dng", pixels_dn=mosaic, meta={"cfa_pattern": pattern})
    whole = np.asarray(demosaicing_CFA_Bayer_bilinear(mosaic[0].astype(np.float64), pattern))
    for rect, border in [((0, 0, 10, 12), 0), ((3, 5, 11, 9), 1), ((40, 31, 10, 9), 0), ((13, 7, 20, 21), 3),
                         ((1, 1, 48, 38), 0)]:
        x, y, w, h = rect
        expected = whole[y + border : y + h - border, x + border : x + w - border].reshape(-1, 3)
        assert np.array_equal(demosaiced_samples(frame, rect, border), expected), (rect, border)
