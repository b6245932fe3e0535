"""Names that become part of a path (issue 24, point 1): every one is a safe file name (camsim.core.names), refused
where it is read — one line ``camsim: error: …``, exit 2, nothing written anywhere (not in --out, not in the folders
above it) — and, behind that, no write of a run leaves its output folder (camsim.io.atomic.confined_to)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from camsim.cli import main
from camsim.core.errors import CamsimError, OutputError
from camsim.core.names import (
    FORBIDDEN_CHARACTERS,
    MAX_NAME_BYTES,
    name_problem,
    safe_component,
)
from camsim.io.atomic import write_text_atomic
from camsim.io.output_folder import make_folder, output_folder
from camsim.render.frame_files import frame_stem
from tests.support.helpers import flat_scene_toml, preset_toml, write_text_file
from tests.support.profiles import examples

#: The issue's names (as TOML string literals), and a few more of the kinds the rule refuses.
BAD_NAMES = {
    "parent": '"../../escaped"',
    "absolute": '"/abs/path/victim"',
    "newline": '"a\\nb"',
    "dot-dot": '".."',
    "dot": '"."',
    "hidden": '".hidden"',
    "backslash": '"a\\\\b"',
    "nul": '"a\\u0000b"',
    "empty": '""',
    "colon": '"a:b"',
    "too long": '"' + "x" * (MAX_NAME_BYTES + 1) + '"',
}


SPEC = """
name = {name}
scene = "scene.toml"
[frame]
width = 32
height = 24
"""



def tree(root: Path) -> set:
    """Every path under ``root`` (files and folders)."""
    return {p.relative_to(root).as_posix() for p in root.rglob("*")}


def refused(capsys, argv, root: Path, before: set) -> str:
    """Run ``argv``; assert exit 2, one stderr line ``camsim: error: …``, nothing new under ``root``; return it."""
    status = main(argv)
    err = capsys.readouterr().err
    assert status == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("camsim: error: "), err
    assert "Traceback" not in err
    assert tree(root) == before  # nothing written: not in --out, not above it
    assert not Path("/abs/path/victim_D65_F0.5.json").exists()
    return lines[0]


@pytest.fixture
def deep(tmp_path, monkeypatch) -> Path:
    """``tmp/a/b``, the working directory: a run that escaped two folders up would write into ``tmp``."""
    folder = tmp_path / "a" / "b"
    folder.mkdir(parents=True)
    monkeypatch.chdir(folder)
    return folder


@pytest.mark.parametrize("name", BAD_NAMES.values(), ids=BAD_NAMES.keys())
def test_render_refuses_an_unsafe_scene_name(deep, tmp_path, capsys, name):
    write_text_file(deep, "scene.toml", flat_scene_toml(name, '"emva-12bit"'))
    before = tree(tmp_path)
    for out in (["--out", str(deep / "out")], []):  # also the default output folder, outputs/NAME
        line = refused(capsys, ["render", "scene.toml", "-q", *out], tmp_path, before)
        assert "name" in line and "is not a safe file name" in line


@pytest.mark.parametrize("name", BAD_NAMES.values(), ids=BAD_NAMES.keys())
def test_dataset_refuses_an_unsafe_spec_name(deep, tmp_path, capsys, name):
    write_text_file(deep, "scene.toml", flat_scene_toml('"ok"', '"emva-12bit"'))
    write_text_file(deep, "spec.toml", SPEC.format(name=name))
    before = tree(tmp_path)
    for argv in (["--dry-run"], ["--workers", "1", "-q", "--out", str(deep / "out")], ["--workers", "1", "-q"]):
        line = refused(capsys, ["dataset", "spec.toml", *argv], tmp_path, before)
        assert "spec.toml: name" in line


@pytest.mark.parametrize("name", ['"../../escaped"', '"/abs/path/victim"', '"a\\nb"', '".."'])
def test_dataset_refuses_a_scene_with_an_unsafe_name(deep, tmp_path, capsys, name):
    write_text_file(deep, "scene.toml", flat_scene_toml(name, '"emva-12bit"'))
    write_text_file(deep, "spec.toml", SPEC.format(name='"fine"'))
    before = tree(tmp_path)
    for argv in (["--dry-run"], ["--workers", "1", "-q", "--out", str(deep / "out")]):
        assert "scene.toml: name" in refused(capsys, ["dataset", "spec.toml", *argv], tmp_path, before)


@pytest.mark.parametrize("name", ["../../escaped", "/abs/path/victim", "a\nb", "..", ".hidden", ""])
def test_calibrate_refuses_an_unsafe_name_before_reading_anything(deep, tmp_path, capsys, name):
    before = tree(tmp_path)
    argv = ["calibrate", "--dark", "d1.dng", "d2.dng", "--flat", "f1.dng", "f2.dng", "--name", name,
            "--out", str(deep / "out")]
    assert "argument --name: NAME" in refused(capsys, argv, tmp_path, before)


@pytest.mark.parametrize("name", ['"../../escaped"', '"/abs/path/victim"', '"a\\nb"', '".."'])
def test_a_camera_preset_file_with_an_unsafe_name_is_refused(deep, tmp_path, capsys, name):
    write_text_file(deep, "preset.toml", preset_toml(name))
    write_text_file(deep, "scene.toml", flat_scene_toml('"ok"', '"preset.toml"'))
    before = tree(tmp_path)
    line = refused(capsys, ["render", "scene.toml", "-q", "--out", str(deep / "out")], tmp_path, before)
    assert "preset.toml: name" in line


@pytest.mark.parametrize("illuminant", ["../../escaped", "/abs/path/victim", "a\nb", ".."])
def test_an_unsafe_illuminant_name_is_refused(deep, tmp_path, capsys, illuminant):
    write_text_file(deep, "scene.toml", flat_scene_toml('"ok"', '"emva-12bit"'))
    before = tree(tmp_path)
    argv = ["render", "scene.toml", "-q", "--illuminant", illuminant, "--out", str(deep / "out")]
    assert "illuminant" in refused(capsys, argv, tmp_path, before)


def test_safe_names_are_written_as_they_are(deep, capsys):
    """Inner spaces and letters of any script are safe: the frames carry the name unchanged."""
    write_text_file(deep, "scene.toml", flat_scene_toml('"Błękit 青 chart"', '"emva-12bit"'))
    assert main(["render", "scene.toml", "-q", "--out", "out"]) == 0
    assert (deep / "out" / "Błękit 青 chart_D65_F0.5.json").is_file()


def test_a_frame_stem_is_checked_too():
    assert frame_stem("macbeth_26", "D65", 0.1) == "macbeth_26_D65_F0.1"
    assert frame_stem("x", "../../etc", 1) == "x_..-..-etc_F1"  # the illuminant slug has no separator
    with pytest.raises(CamsimError, match="frame name"):
        frame_stem("x" * 200, "D65", 1)


@pytest.mark.parametrize("name", ["../x", "/x", "a\nb", "..", ".", ".x", "", "a\x00b", "a\u202eb", " a", "a ", "a|b",
                                  "x" * 129, "é" * 65, 7, None])
def test_the_rule_refuses(name):
    assert name_problem(name) is not None
    with pytest.raises(CamsimError, match="is not a safe file name"):
        safe_component(name, "name")


@pytest.mark.parametrize("name", ["macbeth_26", "a b", "Błękit", "青", "x" * 128, "é" * 64, "a.b", "a..b", "F1e+308"])
def test_the_rule_accepts(name):
    assert safe_component(name, "name") == name


@settings(max_examples=examples(300), deadline=None)
@given(st.text(min_size=0, max_size=140) | st.sampled_from(["..", ".", "../x", "a/..", "/", "\\", "a\\..\\b"]))
def test_an_accepted_name_joined_to_a_folder_stays_in_it(name):
    folder = Path("/some/output/folder")
    if name_problem(name) is not None:
        return
    joined = folder / name
    assert joined.parent == folder and joined.name == name  # one component, this one
    assert os.path.normpath(joined) == str(joined)  # nothing that normalises away (., .., //)
    assert not name.startswith(".") and name.isprintable()
    assert not set(name) & set(FORBIDDEN_CHARACTERS)
    assert len(name.encode("utf-8")) <= MAX_NAME_BYTES


def test_no_write_leaves_the_output_folder(tmp_path):
    """The last line of defence: in a run's folder, a write whose path leads out is refused before it is made."""
    out = tmp_path / "out"
    (tmp_path / "elsewhere").mkdir()
    with output_folder(out):
        (out / "link").symlink_to(tmp_path / "elsewhere", target_is_directory=True)
        write_text_atomic(out / "inside.txt", "ok")
        make_folder(out / "sub" / "deeper")
        write_text_atomic(out / "sub" / "deeper" / "x.txt", "ok")
        for target in (tmp_path / "escaped.txt", out / ".." / "escaped.txt", Path("/abs/path/victim.json"),
                       out / "link" / "escaped.txt"):
            with pytest.raises(OutputError, match="outside the output folder"):
                write_text_atomic(target, "no")
        with pytest.raises(OutputError, match="outside the output folder"):
            make_folder(tmp_path / "made")
    assert sorted(tree(tmp_path)) == ["elsewhere", "out", "out/inside.txt", "out/link", "out/sub", "out/sub/deeper",
                                      "out/sub/deeper/x.txt"]
    write_text_atomic(tmp_path / "after.txt", "ok")  # outside a run, writes go where they are sent
