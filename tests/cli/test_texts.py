"""What the command line says (issue 23, point 11): help texts that are true for every preset, the summary line of
``camsim render`` naming the files it wrote, ``-q`` silencing colour-science's warnings, and the DNG's 22 × 22
minimum refused on one line before any work."""

import os
import re
import subprocess
import sys
import tomllib

import pytest

import camsim.render.pipeline
from camsim.cli import main
from camsim.io.dng import MIN_SIZE
from camsim.scene.builtin_scenes import SCENES_DIR
from camsim.sensor.params import PRESETS, preset
from camsim.sensor.presets import CAMERA_PRESETS
from tests.support import clock
from tests.support.helpers import ROOT

SMALL = ["--illuminant", "D65", "-F", "1", "--size", "32x24", "-q"]


def _help(capsys, *command) -> str:
    with pytest.raises(SystemExit) as exit_:
        main([*command, "--help"])
    assert exit_.value.code == 0
    return " ".join(capsys.readouterr().out.split())  # argparse's line breaks undone


def test_render_help_states_the_bit_depths_the_presets_have(capsys):
    text = _help(capsys, "render")
    assert "auto exposure: auto exposure" not in text and text.count("auto exposure:") == 2
    assert "8-bit raw" not in text
    assert ("the raw digital numbers at the sensor's bit depth: 8-bit for paper-table1 and paper-photon-dark, 12 for "
            "emva-12bit, 10 to 16 for the camera presets (camsim list), or --sensor bits=N; no DNG when quantisation "
            "is off, e.g. --preset ideal") in text
    # what it says is so
    assert preset("paper-table1").bits == preset("paper-photon-dark").bits == 8 and preset("emva-12bit").bits == 12
    assert not preset("ideal").quantisation and set(PRESETS) == {"paper-table1", "paper-photon-dark", "ideal",
                                                                 "emva-12bit"}
    bits = {c.bits for c in CAMERA_PRESETS.values()}
    assert min(bits) == 10 and max(bits) == 16


def test_denoise_eval_help_does_not_ask_to_install_a_dependency(capsys):
    text = _help(capsys, "denoise-eval")
    assert "pip install bm3d" not in text and "installed with camsim" in text
    dependencies = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["dependencies"]
    assert any(d.startswith("bm3d") for d in dependencies)


@pytest.mark.parametrize(("extra", "line", "kinds"), [
    ([], "wrote 1 frame (DNG, darktable XMP, EXR, JSON) to", {".dng", ".xmp", ".exr", ".json"}),
    (["--cfa", "RGGB"], "wrote 1 frame (DNG, EXR, JSON) to", {".dng", ".exr", ".json"}),  # darktable reads a CFA's
    (["--preset", "ideal"], "wrote 1 frame (EXR, JSON; no DNG: quantisation is off) to", {".exr", ".json"}),
    (["--preview", "--illuminant", "A"], "wrote 2 frames (DNG, darktable XMP, EXR, JSON, PNG) to",
     {".dng", ".xmp", ".exr", ".json", ".png"}),
])
def test_render_says_which_files_it_wrote(tmp_path, capsys, extra, line, kinds):
    out = tmp_path / "out"
    assert main(["render", "macbeth_26", *SMALL, *extra, "--out", str(out)]) == 0
    said = capsys.readouterr().out.strip().splitlines()[-1]
    assert said == f"{line} {out}/ — index: {out / 'manifest.json'}"
    assert {p.suffix for p in out.iterdir() if p.name != "manifest.json"} == kinds
    frames = len({p.stem for p in out.glob("*.json") if p.name != "manifest.json"})
    assert frames == int(line.split()[1])


def test_render_counts_the_frames_of_earlier_runs(tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["render", "macbeth_26", *SMALL, "--illuminant", "A", "--out", str(out)]) == 0
    assert main(["render", "macbeth_26", *SMALL, "--out", str(out)]) == 0
    said = capsys.readouterr().out.strip().splitlines()[-1]
    assert (said.startswith("wrote 1 frame (DNG, darktable XMP, EXR, JSON) to")
            and said.endswith("(with 1 frame of earlier runs)"))


def _render(args, tmp_path):
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), *filter(None, [os.environ.get("PYTHONPATH")])])}
    env.pop("PYTHONWARNINGS", None)
    return clock.run([sys.executable, "-m", "camsim", "render", *args], cpu_s=120, cwd=tmp_path, env=env,
                     capture_output=True, text=True)


@pytest.mark.slow
def test_quiet_silences_colour_science_warnings(tmp_path):
    """An image scene recovered by Otsu 2018 makes colour-science warn (it interpolates its CMFs); -q keeps stderr
    clear of it, and the same run without -q shows it."""
    text = (SCENES_DIR / "chelsea.toml").read_text()
    text = text.replace("# crop = [x, y, width, height]", "crop = [0, 0, 48, 32]")
    text = "\n".join('recovery = "Otsu 2018"' if line.startswith("recovery =") else line for line in text.splitlines())
    assert 'recovery = "Otsu 2018"' in text and "crop = [0, 0, 48, 32]" in text
    (tmp_path / "otsu.toml").write_text(text)
    loud = _render(["otsu.toml", "-F", "1", "--out", "loud"], tmp_path)
    assert loud.returncode == 0, loud.stderr
    assert "ColourRuntimeWarning" in loud.stderr
    quiet = _render(["otsu.toml", "-F", "1", "--out", "quiet", "-q"], tmp_path)
    assert quiet.returncode == 0, quiet.stderr
    assert quiet.stderr == ""
    assert quiet.stdout.startswith("wrote 1 frame (DNG, darktable XMP, EXR, JSON)")


def test_a_frame_too_small_for_a_dng_is_refused_before_any_work(tmp_path, capsys, monkeypatch):
    """A chart at --size 21x40, an image scene cropped to 20 x 20 (its own size), an experiment at --size 20x30: one
    line, exit 2, no folder, and the frames were never checked or drawn (check_frames is not reached)."""
    def never(*args, **kwargs):
        raise AssertionError("work started before the size was checked")

    monkeypatch.setattr(camsim.render.pipeline, "check_frames", never)
    image = tmp_path / "tiny.toml"
    image.write_text((SCENES_DIR / "astronaut.toml").read_text().replace("# crop = [x, y, width, height]",
                                                                         "crop = [0, 0, 20, 20]"))
    cases = [
        (["render", "macbeth_26", "--size", "21x40", "-q"],
         f"frame 21x40 is smaller than {MIN_SIZE}x{MIN_SIZE} pixels, which raw readers (LibRaw) refuse"),
        (["render", str(image), "-q"],
         f"image scene's frame 20x20 is smaller than {MIN_SIZE}x{MIN_SIZE} pixels, which raw readers (LibRaw) refuse"),
        (["experiment", "scenario1", "--size", "20x30", "-q"],
         f"--size 20x30 is smaller than {MIN_SIZE}x{MIN_SIZE} pixels, which raw readers (LibRaw) refuse"),
    ]
    for i, (argv, message) in enumerate(cases):
        out = tmp_path / f"out{i}"
        assert main([*argv, "--out", str(out)]) == 2
        captured = capsys.readouterr()
        assert captured.err == f"camsim: error: {message}\n" and captured.out == ""
        assert not out.exists()
    # without quantisation no DNG is written, and the size is no reason to refuse
    monkeypatch.undo()
    assert main(["render", str(image), "-q", "--preset", "ideal", "--out", str(tmp_path / "ideal")]) == 0
    assert {p.suffix for p in (tmp_path / "ideal").iterdir()} == {".exr", ".json"}  # 2 frames and the manifest


def _tracked_text_files():
    done = subprocess.run(["git", "ls-files"], cwd=ROOT, capture_output=True, text=True)
    if done.returncode != 0:
        pytest.skip("not a git checkout")
    for name in done.stdout.splitlines():
        path = ROOT / name
        if path.suffix in (".py", ".md", ".toml", ".txt", ".cfg") and path.is_file():
            yield path


def test_install_commands_name_what_exists():
    """No text tells a user to pip install camsim by its distribution name (it is on no package index), and every
    extra the README names is one pyproject.toml defines, with the packages the README says it brings."""
    offenders = [str(p.relative_to(ROOT)) for p in _tracked_text_files()
                 if "pip install 'camsim-lowlight" in p.read_text(encoding="utf-8", errors="replace")
                 and p.name != "test_texts.py"]
    assert offenders == []
    extras = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["optional-dependencies"]
    # the README and the docs' install page, which has the extras' table
    readme = "\n".join((ROOT / name).read_text(encoding="utf-8") for name in ("README.md", "docs/getting-started.md"))
    named = {extra for group in re.findall(r"pip install '[^']*\[([a-z,]+)\]'", readme)
             for extra in group.split(",")}
    assert named and named <= set(extras), named - set(extras)
    assert extras["xarray"] == ["xarray>=2024.1"] and "xarray" in named  # the Zarr example's reader
    assert extras["torch"] == ["torch"] and extras["gpu"] == ["cupy-cuda12x"]
    assert "--index-url https://download.pytorch.org/whl/cpu" in readme
