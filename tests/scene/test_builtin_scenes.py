"""Built-in scenes: shipped as package data, addressable by name from any directory, and in the wheel."""

import hashlib
import importlib.metadata
import json
import os
import re
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest

from camsim.cli import main
from camsim.core.errors import CamsimError
from camsim.dataset import load_spec
from camsim.experiments.scenarios import DEFAULT_SCENE
from camsim.scene.builtin_scenes import SCENES_DIR, builtin_scene_names, builtin_scene_path, resolve_scene_file
from camsim.scene.scene_file import load_scene
from camsim.scene.sources import ImageSource
from tests.support.helpers import ROOT

BUILTIN = "astronaut, chelsea, coffee, dark, dead_leaves, flat, macbeth_26, slanted_edge, slanted_edge_lens"
PHOTOGRAPHS = ("astronaut", "chelsea", "coffee")
SCENE_ARGS = ["--illuminant", "D65", "--intensity", "1", "--size", "120x80", "-q"]


def _digests(folder):
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(folder.iterdir()) if p.is_file()}


def test_names_and_paths():
    # denoise_small.toml beside them is a dataset spec
    assert builtin_scene_names() == ("astronaut", "chelsea", "coffee", "dark", "dead_leaves", "flat", "macbeth_26",
                                     "slanted_edge", "slanted_edge_lens")
    path = builtin_scene_path("macbeth_26")
    assert path == SCENES_DIR / "macbeth_26.toml" and path.is_file()
    assert SCENES_DIR.parent == ROOT / "camsim"
    assert DEFAULT_SCENE == path  # the experiments' scene comes from the package
    # the checkout's scenes/ is the package folder itself (a link), not a copy
    assert (ROOT / "scenes").resolve() == SCENES_DIR.resolve()
    assert sorted(p.name for p in (ROOT / "scenes").glob("*.toml")) == [
        "astronaut.toml", "chelsea.toml", "coffee.toml", "dark.toml", "dead_leaves.toml", "denoise_small.toml",
        "flat.toml", "macbeth_26.toml", "slanted_edge.toml", "slanted_edge_lens.toml"]


def test_load_by_name_equals_load_by_path(tmp_path, monkeypatch):
    by_path = load_scene(ROOT / "scenes" / "macbeth_26.toml")
    monkeypatch.chdir(tmp_path)  # no scenes/ here: the name alone finds it
    by_name = load_scene("macbeth_26")
    assert by_name == by_path and by_name.name == "macbeth_26" and len(by_name.illuminants) == 26


def test_an_existing_file_wins_over_the_name(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "macbeth_26").write_text('name = "local"\n[chart]\n')
    assert load_scene("macbeth_26").name == "local"
    (tmp_path / "macbeth_26").unlink()
    (tmp_path / "macbeth_26").mkdir()  # e.g. an output folder of that name: not a scene file, the name still works
    assert load_scene("macbeth_26").name == "macbeth_26"


@pytest.mark.parametrize(("given", "message"), [
    ("macbeth", rf"no scene file 'macbeth' and no built-in scene of that name: the built-in scenes are {BUILTIN}"),
    ("denoise_small", rf"'denoise_small' is a built-in dataset spec .*not a scene: the built-in scenes are {BUILTIN}"),
    ("missing.toml", r"scene file not found: missing\.toml"),  # a path stays a path
    ("sub/macbeth_26", r"scene file not found: sub/macbeth_26"),
])
def test_unknown_names_and_missing_paths(tmp_path, monkeypatch, given, message):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(CamsimError, match=message):
        load_scene(given)


def test_resolution_rules(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert resolve_scene_file("macbeth_26") == SCENES_DIR / "macbeth_26.toml"
    for path in ("macbeth_26.toml", "./macbeth_26", str(tmp_path / "macbeth_26"), Path("MACBETH_26.TOML")):
        assert resolve_scene_file(path) == Path(path)  # a path is never taken for a name
        with pytest.raises(CamsimError, match="scene file not found"):
            load_scene(path)


def test_cli_renders_a_builtin_scene_by_name_from_anywhere(tmp_path, monkeypatch, capsys):
    """The same frames, byte for byte, whether the scene is named or given by the checkout's path."""
    assert main(["render", str(ROOT / "scenes" / "macbeth_26.toml"), *SCENE_ARGS, "--out", str(tmp_path / "a")]) == 0
    monkeypatch.chdir(tmp_path)
    assert main(["render", "macbeth_26", *SCENE_ARGS, "--out", str(tmp_path / "b")]) == 0
    a, b = _digests(tmp_path / "a"), _digests(tmp_path / "b")
    assert set(a) >= {"macbeth_26_D65_F1.dng", "macbeth_26_D65_F1.exr", "macbeth_26_D65_F1.json", "manifest.json"}
    assert a == b
    assert main(["render", "macbeth", *SCENE_ARGS]) == 2
    assert f"built-in scenes are {BUILTIN}" in capsys.readouterr().err


def test_dataset_spec_finds_its_scene_beside_it():
    spec = load_spec(ROOT / "scenes" / "denoise_small.toml")  # scene = "macbeth_26.toml", relative to the spec
    assert len(spec.frames) == 96
    assert {Path(f.scene_path) for f in spec.frames} == {(SCENES_DIR / "macbeth_26.toml").resolve()}
    assert load_spec(SCENES_DIR / "denoise_small.toml").frames == spec.frames


SMALL_SPEC = """
name = "named"
scene = "SCENE"
[frame]
width = 32
height = 24
[fixed]
illuminant = "D65"
intensity_factor = 1.0
"""


def test_a_spec_names_a_builtin_scene(tmp_path, monkeypatch, capsys):
    """scene = "macbeth_26" in a spec is the built-in scene (issue 23, point 7): the same frames as the spec that
    gives the scene file's path; a file of that name beside the spec wins over the name."""
    (tmp_path / "by_name.toml").write_text(SMALL_SPEC.replace("SCENE", "macbeth_26"))
    (tmp_path / "by_path.toml").write_text(SMALL_SPEC.replace("SCENE", str(SCENES_DIR / "macbeth_26.toml")))
    spec = load_spec(tmp_path / "by_name.toml")
    assert [Path(f.scene_path) for f in spec.frames] == [(SCENES_DIR / "macbeth_26.toml").resolve()]
    monkeypatch.chdir(tmp_path)
    for name in ("by_name", "by_path"):
        assert main(["dataset", f"{name}.toml", "--workers", "1", "-q", "--out", name]) == 0
    # the same scene, light and sensor (the frame's id and seed hash the scene as the spec writes it, so the noise
    # differs): every sidecar entry but those
    (a,), (b,) = (sorted((tmp_path / n / "frames").glob("*.json")) for n in ("by_name", "by_path"))
    a, b = (json.loads(p.read_text()) for p in (a, b))
    assert a["patches"][18]["name"] == "white 9.5 (.05 D)" and a["patches"][18]["signal_e"][1] > 1000
    assert a["scene"] == b["scene"] == "macbeth_26"
    assert {k: v for k, v in a.items() if k not in ("seed", "files")} == \
        {k: v for k, v in b.items() if k not in ("seed", "files")}
    (tmp_path / "macbeth_26").write_text('name = "local"\n[chart]\n')  # a file beside the spec wins
    assert load_spec(tmp_path / "by_name.toml").frames[0].scene_path == str((tmp_path / "macbeth_26").resolve())


@pytest.mark.parametrize(("scene", "message"), [
    ("macbeth", r"spec\.toml: scene: no scene file 'macbeth' in .* and no built-in scene of that name: the built-in "
                rf"scenes are {BUILTIN}"),
    ("denoise_small", r"spec\.toml: scene: 'denoise_small' is a built-in dataset spec"),
    ("missing.toml", r"scene file not found: .*missing\.toml"),
])
def test_a_spec_with_an_unknown_scene_name_is_refused_on_one_line(tmp_path, capsys, scene, message):
    (tmp_path / "spec.toml").write_text(SMALL_SPEC.replace("SCENE", scene))
    assert main(["dataset", str(tmp_path / "spec.toml"), "--workers", "1", "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert re.fullmatch(rf"camsim: error: .*{message}.*\n", err) and err.count("\n") == 1
    assert not (tmp_path / "out").exists()


def test_dataset_takes_a_builtin_spec_by_name(tmp_path, monkeypatch, capsys):
    """camsim dataset denoise_small from a folder without the spec: the shipped spec, its scene and images."""
    monkeypatch.chdir(tmp_path)
    assert main(["dataset", "denoise_small", "--dry-run"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].startswith("dataset denoise_small: 96 frames of 256x192") and len(lines) == 97
    assert load_spec("denoise_small").frames == load_spec(SCENES_DIR / "denoise_small.toml").frames
    assert main(["dataset", "macbeth_26", "--dry-run"]) == 2
    assert capsys.readouterr().err == ("camsim: error: 'macbeth_26' is a built-in scene (camsim render macbeth_26), "
                                       "not a dataset spec: the built-in dataset specs are denoise_small\n")
    assert main(["dataset", "denoise", "--dry-run"]) == 2
    assert "no built-in dataset spec of that name: the built-in dataset specs are denoise_small" in \
        capsys.readouterr().err
    assert main(["dataset", "denoise.toml", "--dry-run"]) == 2  # a path stays a path
    assert capsys.readouterr().err == "camsim: error: dataset spec not found: denoise.toml\n"


def test_list_names_the_builtin_scenes_and_specs(capsys):
    assert main(["list"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0] == f"built-in scenes: {BUILTIN}"
    assert lines[1] == "built-in dataset specs (camsim dataset NAME): denoise_small"


def _can_build_wheels_offline() -> bool:
    """setuptools ≥ 70.1 builds wheels by itself; an older one needs the ``wheel`` package (the test extra has both)."""
    def version(name):
        try:
            return tuple(int(part) for part in importlib.metadata.version(name).split(".")[:2])
        except (importlib.metadata.PackageNotFoundError, ValueError):
            return None

    setuptools = version("setuptools")
    return setuptools is not None and (setuptools >= (70, 1) or version("wheel") is not None)


@pytest.mark.slow
@pytest.mark.skipif(not _can_build_wheels_offline(),
                    reason="building a wheel offline needs setuptools >= 70.1, or wheel: pip install -e '.[test]'")
def test_wheel_ships_the_scenes_and_resolves_them_without_a_checkout(tmp_path):
    """Build the wheel from a copy of the sources (no stale build/ folder), check the scene files and the extras are
    in it, then install it with pip into a folder of its own and, away from any checkout, import camsim from there,
    resolve names and run its console script with a built-in dataset spec."""
    src = tmp_path / "src"
    shutil.copytree(ROOT / "camsim", src / "camsim", ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
    for name in ("pyproject.toml", "README.md"):
        shutil.copy2(ROOT / name, src / name)
    subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "--no-index", "-q",
                    "-w", str(tmp_path / "dist"), str(src)], check=True, capture_output=True, cwd=tmp_path)
    (wheel,) = (tmp_path / "dist").glob("camsim_lowlight-*.whl")
    with zipfile.ZipFile(wheel) as archive:
        names = set(archive.namelist())
        for scene in ("macbeth_26.toml", "denoise_small.toml", "dead_leaves.toml", "slanted_edge.toml",
                      "slanted_edge_lens.toml", "astronaut.toml", "chelsea.toml", "coffee.toml", "dark.toml",
                      "flat.toml"):
            assert archive.read(f"camsim/scenes/{scene}") == (SCENES_DIR / scene).read_bytes()
        for image in ("astronaut.png", "chelsea.png", "coffee.png", "README.md"):  # denoise_small's [images]
            assert archive.read(f"camsim/scenes/images/{image}") == (SCENES_DIR / "images" / image).read_bytes()
        metadata = next(archive.read(n).decode() for n in names if n.endswith(".dist-info/METADATA"))
    assert "camsim/scene/builtin_scenes.py" in names and not any(n.startswith(("scenes/", "tests/")) for n in names)
    for extra, requirement in (("xarray", "xarray>=2024.1"), ("gpu", "cupy-cuda12x"), ("torch", "torch")):
        # pip install 'WHEEL[xarray]' (docs, 'Getting started'): the extra is in the wheel
        assert f"Provides-Extra: {extra}" in metadata
        assert f'Requires-Dist: {requirement}; extra == "{extra}"' in metadata
    # installed as pip installs it (into a folder of its own: the console script too), away from any checkout
    subprocess.run([sys.executable, "-m", "pip", "install", "--no-deps", "--no-index", "-q", "--target",
                    str(tmp_path / "site"), str(wheel)], check=True, capture_output=True, cwd=tmp_path)
    code = ("import camsim, camsim.scene.builtin_scenes as b, camsim.scene.scene_file as s, "
            "camsim.experiments.scenarios as e\n"
            "print(camsim.__file__); print(b.builtin_scene_names()); print(s.load_scene('macbeth_26').name)\n"
            "print(e.DEFAULT_SCENE.is_file(), e.DEFAULT_SCENE.relative_to(b.SCENES_DIR.parent.parent))\n"
            "from camsim.dataset import load_spec; print(len(load_spec(b.SCENES_DIR / 'denoise_small.toml')))\n")
    env = {**os.environ, "PYTHONPATH": str(tmp_path / "site")}
    env.pop("PYTHONSAFEPATH", None)
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=tmp_path, env=env)
    assert run.returncode == 0, run.stderr
    lines = run.stdout.splitlines()
    assert lines == [str(tmp_path / "site" / "camsim" / "__init__.py"),
                     f"{tuple(BUILTIN.split(', '))}", "macbeth_26",
                     "True camsim/scenes/macbeth_26.toml", "96"]
    # the installed command takes the built-in spec by name (issue 23, point 7), and a spec naming a built-in scene
    (tmp_path / "named.toml").write_text(SMALL_SPEC.replace("SCENE", "macbeth_26"))
    for args, first in ((["dataset", "denoise_small", "--dry-run"], "dataset denoise_small: 96 frames of 256x192"),
                        (["dataset", "named.toml", "--dry-run"], "dataset named: 1 frames of 32x24")):
        run = subprocess.run([str(tmp_path / "site" / "bin" / "camsim"), *args], capture_output=True, text=True,
                             cwd=tmp_path, env=env)
        assert run.returncode == 0, run.stderr
        assert run.stdout.startswith(first)


def _skimage_photograph(name):
    """The photograph as scikit-image itself loads it (skimage.data.<name>()), shape (H, W, 3) uint8."""
    import skimage.data

    return {"astronaut": skimage.data.astronaut, "chelsea": skimage.data.chelsea, "coffee": skimage.data.coffee}[name]()


def _srgb_luminance(codes):
    """Relative luminance of 8-bit sRGB codes (IEC 61966-2-1 decoding, Rec. 709 weights), written out here."""
    v = codes.astype(float) / 255
    linear = np.where(v <= 0.04045, v / 12.92, ((v + 0.055) / 1.055) ** 2.4)
    return linear @ np.array([0.2126, 0.7152, 0.0722])


@pytest.mark.parametrize("name", PHOTOGRAPHS)
def test_builtin_photographs_are_skimage_files_at_their_size(name):
    """Each photograph scene loads by name; its image is scikit-image's installed file (not a copy in camsim),
    and the frame has the photograph's size as scikit-image reads it."""
    import skimage

    scene = load_scene(name)
    source = scene.source
    assert isinstance(source, ImageSource) and source.kind == "reflectance" and source.recovery == "Mallett 2019"
    assert source.path.is_file() and source.path.name == f"{name}.png"
    assert Path(skimage.__file__).parent in source.path.resolve().parents
    assert (ROOT / "camsim").resolve() not in source.path.resolve().parents  # not a copy in the package (the
    # repository's own .venv, where scikit-image may be installed, is inside ROOT)
    height, width = _skimage_photograph(name).shape[:2]
    assert source.own_size() == (width, height)
    assert scene.illuminants == ("D65",) and scene.preset_name == "emva-12bit"
    # the licence and the source are cited in the scene file
    text = builtin_scene_path(name).read_text()
    assert ("public domain" if name == "astronaut" else "CC0") in text and f'path = "skimage:{name}"' in text


@pytest.mark.parametrize("name", PHOTOGRAPHS)
def test_a_crop_of_each_builtin_photograph_renders(tmp_path, name):
    """camsim render of the built-in scene with a crop added: frames at the crop's size, and the clean layer's green
    follows the photograph's own luminance there (sRGB decoded here) pixel by pixel."""
    from camsim.io.exr import read_exr

    x, y, w, h = 100, 60, 64, 48
    text = builtin_scene_path(name).read_text().replace("# crop = [x, y, width, height]",
                                                        f"crop = [{x}, {y}, {w}, {h}]")
    assert f"crop = [{x}" in text
    scene = tmp_path / f"{name}.toml"
    scene.write_text(text)
    out = tmp_path / "out"
    assert main(["render", str(scene), "--intensity", "1", "--out", str(out), "-q"]) == 0
    meta = json.loads((out / f"{name}_D65_F1.json").read_text())
    assert (meta["width_px"], meta["height_px"]) == (w, h) and meta["reflectances"] == f"{name}.png"
    noisy, clean, _ = read_exr(out / f"{name}_D65_F1.exr")
    assert noisy.shape[-2:] == (h, w) and np.all(np.isfinite(noisy))
    luminance = _srgb_luminance(_skimage_photograph(name)[y : y + h, x : x + w])
    assert np.corrcoef(clean[1].ravel(), luminance.ravel())[0, 1] > 0.95


@pytest.mark.slow
def test_cli_renders_the_astronaut_end_to_end(tmp_path):
    assert main(["render", "astronaut", "--intensity", "1", "0.1", "--illuminant", "D65", "--out", str(tmp_path),
                 "-q"]) == 0
    meta = json.loads((tmp_path / "astronaut_D65_F0.1.json").read_text())
    assert (meta["width_px"], meta["height_px"]) == (512, 512)
