"""Wrong successes (issue 24, point 6): inputs that used to be measured or accepted quietly are refused, or warned
about and recorded. A DNG header declaring a storage the reader does not decode (a JPEG Compression tag over
uncompressed data decoded as zeros and was measured), a denoiser that calls ``sys.exit(0)`` (denoise-eval exited 0
with no output), an unreadable EXR beside a DNG (dropped from the residual without a word), and a scene file's
``description = [1, 2, 3]``. Real files, through ``main(argv)`` in process."""

import json
import shutil
import textwrap

import pytest
import tifffile

from camsim.cli import main
from camsim.core.errors import CamsimError
from camsim.io.dng import read_dng
from camsim.render.run import render_scene
from tests.support.helpers import small_scene

STEM = "test_D65_F1"


@pytest.fixture(scope="module")
def rendered(tmp_path_factory):
    root = tmp_path_factory.mktemp("wrong_successes")
    render_scene(small_scene(width=64, height=48, intensity_factors=(1.0,)), root / "three_chip", progress=False)
    render_scene(small_scene(width=64, height=48, intensity_factors=(1.0,)).with_sensor(cfa="RGGB"), root / "bayer",
                 progress=False)
    return root


def _two_frames(rendered, folder, layout="three_chip"):
    """``folder`` with the rendered frame as it is (``test_D65_F1``) and a copy as ``b_bad`` (its sidecar claims
    its files, so its EXR's header no longer equals its sidecar: no residual for it, as for a renamed frame)."""
    folder.mkdir()
    for stem in (STEM, "b_bad"):
        for kind in (".dng", ".exr", ".json"):
            shutil.copy(rendered / layout / f"{STEM}{kind}", folder / f"{stem}{kind}")
    meta = json.loads((folder / "b_bad.json").read_text())
    meta["files"] = {"dng": "b_bad.dng", "exr": "b_bad.exr", "json": "b_bad.json"}
    (folder / "b_bad.json").write_text(json.dumps(meta))
    return folder


def _analyze(folder, out, capsys):
    status = main(["analyze", str(folder), "--out", str(out), "-q", "--no-figures"])
    captured = capsys.readouterr()
    assert "Traceback" not in captured.err + captured.out
    return status, [line for line in captured.err.splitlines() if line]


@pytest.mark.parametrize("layout, tag, value, reason", [
    ("three_chip", "Compression", 7, "Compression tag 7 (JPEG)"),
    ("bayer", "Compression", 7, "Compression tag 7 (JPEG)"),
    ("three_chip", "Compression", 8, "Compression tag 8 (ADOBE_DEFLATE)"),
    ("three_chip", "PlanarConfiguration", 2, "planar samples"),
    ("three_chip", "StripByteCounts", (4608,), "hold 4608 bytes"),  # half the pixels; the file is not short
    ("bayer", "RowsPerStrip", 10, "in 5 strip(s) takes 3072"),
    ("three_chip", "BitsPerSample", (8, 8, 16), "(8, 8, 16) bits"),
])
def test_a_dng_header_the_reader_does_not_decode_is_refused_before_decoding(rendered, tmp_path, capsys, layout, tag,
                                                                             value, reason):
    folder = _two_frames(rendered, tmp_path / "frames", layout)
    with tifffile.TiffFile(folder / "b_bad.dng", mode="r+b") as tif:
        tif.pages.first.tags[tag].overwrite(value)
    with pytest.raises(CamsimError, match="b_bad.dng") as refused:
        read_dng(folder / "b_bad.dng")
    assert reason in str(refused.value)
    status, err = _analyze(folder, tmp_path / "out", capsys)  # it used to be measured (as zeros), exit 0
    assert status == 0 and len(err) == 1, err  # nothing from tifffile's logger either
    assert err[0].startswith("camsim: warning: skipped ") and "b_bad.dng" in err[0] and reason in err[0]
    summary = json.loads((tmp_path / "out" / "analysis.json").read_text())
    assert [f["frame_file"].rsplit("/", 1)[-1] for f in summary["frames"]] == [f"{STEM}.dng"]


def test_an_unreadable_exr_beside_a_dng_is_told_and_recorded(rendered, tmp_path, capsys):
    folder = _two_frames(rendered, tmp_path / "frames")
    exr = folder / "b_bad.exr"
    exr.write_bytes(exr.read_bytes()[: exr.stat().st_size // 2])  # truncated: the DNG is fine
    status, err = _analyze(folder, tmp_path / "out", capsys)
    assert status == 0 and len(err) == 1, err
    assert err[0].startswith("camsim: warning: measured ") and "b_bad.dng" in err[0] and "b_bad.exr" in err[0]
    summary = json.loads((tmp_path / "out" / "analysis.json").read_text())
    assert summary["totals"]["unreadable_exr"] == 1 and summary["totals"]["frames"] == 2
    by_name = {f["frame_file"].rsplit("/", 1)[-1]: f for f in summary["frames"]}
    good = by_name[f"{STEM}.dng"]
    assert "b_bad.exr" in by_name["b_bad.dng"]["unreadable_exr"] and good["unreadable_exr"] is None
    assert {ch["residual_status"] for ch in by_name["b_bad.dng"]["frame_statistics"]} == {"exr-unreadable"}
    assert {ch["residual_status"] for ch in good["frame_statistics"]} == {"ok"}
    assert "exr-unreadable" in (tmp_path / "out" / "frame_statistics.csv").read_text()
    # a frame whose EXR is simply not there stays as it was: no warning, no-clean-layer
    exr.unlink()
    status, err = _analyze(folder, tmp_path / "out2", capsys)
    assert status == 0 and err == []


EXITING = textwrap.dedent("""
    import sys

    def exit0(image):
        sys.exit(0)

    def exit3(image):
        raise SystemExit(3)

    def exit_text(image):
        sys.exit("giving up")

    def interrupt(image):
        raise KeyboardInterrupt
    """)


@pytest.mark.parametrize("function, shown", [("exit0", "sys.exit(0)"), ("exit3", "sys.exit(3)"),
                                             ("exit_text", "sys.exit('giving up')")])
def test_a_denoiser_that_exits_is_a_failing_denoiser(rendered, tmp_path, capsys, function, shown):
    (tmp_path / "exiting.py").write_text(EXITING)
    out = tmp_path / "eval"
    status = main(["denoise-eval", str(rendered / "three_chip"), "-d", f"{tmp_path / 'exiting.py'}:{function}",
                   "--out", str(out), "-q"])  # it used to exit 0 with no output
    err = [line for line in capsys.readouterr().err.splitlines() if line]
    assert status == 2 and len(err) == 1 and err[0].startswith("camsim: error: denoiser "), err
    assert shown in err[0] and function in err[0]
    assert not out.exists() or not any(out.iterdir())


def test_a_denoiser_module_that_exits_on_import_is_a_failing_denoiser(rendered, tmp_path, capsys):
    (tmp_path / "exits_on_import.py").write_text("import sys\nsys.exit(0)\n")
    status = main(["denoise-eval", str(rendered / "three_chip"), "-d", f"{tmp_path / 'exits_on_import.py'}:f",
                   "--out", str(tmp_path / "eval"), "-q"])
    err = [line for line in capsys.readouterr().err.splitlines() if line]
    assert status == 2 and len(err) == 1 and "sys.exit(0)" in err[0], err


def test_ctrl_c_in_a_denoiser_stays_an_interruption(rendered, tmp_path, capsys):
    (tmp_path / "exiting.py").write_text(EXITING)
    status = main(["denoise-eval", str(rendered / "three_chip"), "-d", f"{tmp_path / 'exiting.py'}:interrupt",
                   "--out", str(tmp_path / "eval"), "-q"])
    assert status == 130
    assert "camsim: interrupted" in capsys.readouterr().err


CHART = "[chart]\n[frame]\nwidth = 48\nheight = 32\n"


@pytest.mark.parametrize("value", ["[1, 2, 3]", "3", "{ a = 1 }", "true"])
def test_a_scene_description_must_be_text(tmp_path, capsys, value):
    scene = tmp_path / "scene.toml"
    scene.write_text(f'name = "d"\ndescription = {value}\n{CHART}')
    out = tmp_path / "out"
    assert main(["render", str(scene), "--out", str(out), "-q"]) == 2
    err = [line for line in capsys.readouterr().err.splitlines() if line]
    assert len(err) == 1 and "description must be of type str" in err[0], err
    assert not out.exists() or not any(out.iterdir())
    scene.write_text('name = "d"\ndescription = "a chart, for the record"\n' + CHART)
    assert main(["render", str(scene), "--out", str(out), "-q", "-F", "1"]) == 0


@pytest.mark.parametrize("layer", [0, 1])
def test_non_finite_values_in_an_exr_are_not_scored(rendered, tmp_path, capsys, layer):
    """A NaN in a frame's clean values (a damaged file) gave a traceback in denoise-eval's tables (found by
    tools/fuzz_cli.py); one in its noisy values reached the denoiser: the frame is skipped with its reason."""
    import numpy as np

    from camsim.io.exr import read_exr, write_exr

    folder = tmp_path / "frames"
    shutil.copytree(rendered / "three_chip", folder)
    noisy, clean, header = read_exr(folder / f"{STEM}.exr")
    (noisy, clean)[layer][1, 10, 10] = np.nan
    (folder / f"{STEM}.exr").unlink()
    write_exr(folder / f"{STEM}.exr", noisy, clean, header)  # R, G, B hold the values (a file without a view)
    out = tmp_path / "eval"
    status = main(["denoise-eval", str(folder), "-d", "identity", "--out", str(out), "-q"])
    captured = capsys.readouterr()
    err = [line for line in captured.err.splitlines() if line]
    assert "Traceback" not in captured.err + captured.out
    assert status == 2 and len(err) == 1, err
    assert "non-finite values (NaN or infinity) in its noisy or clean" in err[0], err
