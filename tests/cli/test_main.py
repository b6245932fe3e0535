"""The command line, in-process through ``main([...])``: end to end, help, and one-line errors with exit 2."""

import json
import signal

import numpy as np
import pytest

import camsim
from camsim.cli import main
from tests.support.helpers import ROOT

SCENE = ROOT / "scenes" / "macbeth_26.toml"
SMALL = ["--size", "120x80", "-q"]


def test_render_end_to_end(tmp_path, capsys):
    out = tmp_path / "frames"
    code = main(["render", str(SCENE), "--illuminant", "D65", "A", "--intensity", "1", "0.1", "--seed", "3",
                 "--out", str(out), *SMALL])
    assert code == 0
    printed = capsys.readouterr().out
    assert str(out) in printed and "4 frames" in printed
    manifest = json.loads((out / "manifest.json").read_text())
    assert len(manifest["frames"]) == 4
    sidecar = json.loads((out / "macbeth_26_A_F0.1.json").read_text())
    assert sidecar["seed"] == 3 and sidecar["intensity_factor"] == 0.1 and sidecar["width_px"] == 120
    assert len(list(out.glob("*.dng"))) == 4 and len(list(out.glob("*.exr"))) == 4


def test_options_reach_the_frames(tmp_path):
    out = tmp_path / "o"
    code = main(["render", str(SCENE), "--illuminant", "D65", "--intensity", "0.5", "--statistics", "paper",
                 "--method", "spectral", "--preset", "paper-photon-dark", "--disable", "dark_current",
                 "--exposure", "0.5", "--out", str(out), *SMALL])
    assert code == 0
    sidecar = json.loads((out / "macbeth_26_D65_F0.5.json").read_text())
    assert sidecar["photon_statistics"] == "paper" and sidecar["method"] == "spectral"
    assert sidecar["stages"] == {"photon_noise": True, "dark_current": False, "saturation": False,
                                 "read_noise": False, "quantisation": False}
    assert sidecar["exposure_s"] == 0.5 and sidecar["black_level_dn"] == [0.0, 0.0, 0.0]
    assert sidecar["files"]["dng"] is None
    # 0.5 s at F = 0.5: the perfect white would give 8000 · 0.25 e⁻; the white patch reflects about 90 % of it
    assert 0.8 * 2000 < max(sidecar["patches"][18]["signal_e"]) < 2000


def test_csv_camera_from_the_command_line(tmp_path):
    wl = np.arange(380, 781, 10)
    curves = [np.exp(-0.5 * ((wl - peak) / 30.0) ** 2) for peak in (600, 540, 450)]
    csv = tmp_path / "my_camera.csv"
    csv.write_text("wavelength_nm,R,G,B\n" + "\n".join(
        f"{w},{r:.6f},{g:.6f},{b:.6f}" for w, r, g, b in zip(wl, *curves)) + "\n")
    out = tmp_path / "o"
    assert main(["render", str(SCENE), "--illuminant", "E", "--intensity", "1", "--camera", str(csv),
                 "--out", str(out), *SMALL]) == 0
    sidecar = json.loads((out / "macbeth_26_E_F1.json").read_text())
    assert sidecar["camera"] == "my_camera.csv"


def test_help_explains_options_with_units(capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(["render", "--help"])
    assert exit_info.value.code == 0
    text = capsys.readouterr().out
    for word in ("--intensity", "cd/m²", "--statistics", "--method", "--preset", "--seed", "--size", "pixels",
                 "--out", "--exposure", " s "):
        assert word in text
    with pytest.raises(SystemExit):
        main(["--help"])
    assert "render" in capsys.readouterr().out


def test_version(capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(["--version"])
    assert exit_info.value.code == 0
    assert capsys.readouterr().out == f"camsim {camsim.__version__}\n"


@pytest.mark.parametrize("argv, message", [
    (["render", str(SCENE), "--workers", "0"], "--workers: must be ≥ 1, got 0"),
    (["render", str(SCENE), "--workers", "two"], "--workers: not an integer"),
    (["analyze", ".", "--border", "-1"], "--border: must be ≥ 0, got -1"),
    (["emva", "--size", "4097"], "--size: the side of the EMVA region of interest in pixels must be 16 to 4096"),
])
def test_integer_options_are_checked_on_one_line(capsys, argv, message):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("camsim: error: ") and err.count("\n") == 1 and message in err, err


def _write(path, text):
    path.write_text(text)
    return str(path)


BAD_CASES = {
    "unknown illuminant": (["--illuminant", "D66"], "unknown illuminant 'D66'"),
    "illuminant off the grid": (["--illuminant", "ISO 7589 Photoflood"], "covers 350–690 nm"),
    "negative exposure": (["--exposure", "-1"], "--exposure"),
    "zero intensity": (["--intensity", "0"], "positive"),
    "bad size": (["--size", "12by8"], "WIDTHxHEIGHT"),
    "unknown preset": (["--preset", "nope"], "unknown preset 'nope'"),
    "ISO outside a camera's range": (["--preset", "sony-a7s2", "--iso", "30000"], "outside preset sony-a7s2's range"),
    "ISO on a preset without an ISO axis": (["--iso", "800"], "has no ISO axis"),
    "missing preset file": (["--preset", "nowhere.toml"], "camera preset file not found"),
    "unknown camera": (["--camera", "Canon 5D"], "unknown camera"),
    "missing camera file": (["--camera", "nowhere.csv"], "not found"),
}


@pytest.mark.parametrize("case", sorted(BAD_CASES))
def test_bad_options_give_one_line_and_exit_2(tmp_path, capsys, case):
    args, message = BAD_CASES[case]
    out = tmp_path / "o"
    code = main(["render", str(SCENE), "--out", str(out), *SMALL, *args])
    err = capsys.readouterr().err
    assert code == 2
    assert err.count("\n") == 1 and err.startswith("camsim: error:") and message in err, err
    assert "Traceback" not in err
    assert not out.exists() or not any(out.iterdir())


SCENE_TEXT = SCENE.read_text()
BAD_SCENES = {
    "malformed toml": ("name = [unclosed", "cannot read scene file"),
    "unknown key": (SCENE_TEXT.replace("[frame]", "[frame]\ncolour = 3"), "unknown key(s) in [frame]: colour"),
    "negative exposure": (SCENE_TEXT.replace('preset = "paper-table1"', 'preset = "paper-table1"\nexposure_s = -2'),
                          "exposure_s must be a positive number"),
    "wrong type": (SCENE_TEXT.replace("width = 600", 'width = "wide"'), "width must be of type int"),
    "bad grid": (SCENE_TEXT.replace("step_nm = 4", "step_nm = 7"), "not a whole number of 7.0 nm steps"),
    "unknown reflectances": (SCENE_TEXT.replace('"ColorChecker N Ohta"', '"Macbeth 1976"', 1),
                             "unknown reflectance set"),
}


@pytest.mark.parametrize("case", sorted(BAD_SCENES))
def test_bad_scene_files_give_one_line_and_exit_2(tmp_path, capsys, case):
    text, message = BAD_SCENES[case]
    scene = _write(tmp_path / "bad.toml", text)
    out = tmp_path / "o"
    code = main(["render", scene, "--out", str(out), *SMALL])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and message in err, err
    assert not out.exists() or not any(out.iterdir())


def test_missing_scene_file(tmp_path, capsys):
    assert main(["render", str(tmp_path / "none.toml")]) == 2
    assert "scene file not found" in capsys.readouterr().err


def test_nan_in_a_spectrum(tmp_path, capsys):
    csv = _write(tmp_path / "cam.csv", "wavelength_nm,R,G,B\n380,0.1,0.2,0.3\n580,nan,0.5,0.1\n780,0.2,0.1,0.0\n")
    assert main(["render", str(SCENE), "--camera", csv, "--out", str(tmp_path / "o"), *SMALL]) == 2
    assert "NaN" in capsys.readouterr().err


def _cube_scene(tmp_path, cube, extra=""):
    np.save(tmp_path / "cube.npy", cube)
    return _write(tmp_path / "cube.toml", f'name = "cube"\n[cube]\npath = "cube.npy"\n{extra}\n'
                                          '[light]\nilluminants = ["D65"]\n')


def test_cube_scene_renders(tmp_path):
    cube = np.random.default_rng(0).uniform(0.05, 0.9, size=(30, 40, 101))
    out = tmp_path / "o"
    assert main(["render", _cube_scene(tmp_path, cube), "--out", str(out), "-q"]) == 0
    sidecar = json.loads((out / "cube_D65_F1.json").read_text())
    assert sidecar["width_px"] == 40 and sidecar["height_px"] == 30 and sidecar["patches"] == []


def test_cube_on_the_wrong_grid(tmp_path, capsys):
    scene = _cube_scene(tmp_path, np.ones((30, 40, 81)))
    assert main(["render", scene, "--out", str(tmp_path / "o")]) == 2
    assert "81 wavelength bins but the scene's grid has 101" in capsys.readouterr().err


def test_truncated_cube(tmp_path, capsys):
    scene = _cube_scene(tmp_path, np.ones((30, 40, 101)))
    data = (tmp_path / "cube.npy").read_bytes()
    (tmp_path / "cube.npy").write_bytes(data[: len(data) // 2])
    assert main(["render", scene, "--out", str(tmp_path / "o")]) == 2
    assert "cannot read cube file" in capsys.readouterr().err


def test_an_error_message_with_line_breaks_is_printed_on_one_line(monkeypatch, capsys):
    """Whatever a message holds (a value's repr across lines, a library's text), the error is one line."""
    from camsim import cli
    from camsim.core.errors import CamsimError

    def fail(args):
        raise CamsimError("a value:\n   [1, 2,\n    3]\n")

    monkeypatch.setattr(cli.COMMANDS["list"], "run", fail)
    assert cli.main(["list"]) == 2
    assert capsys.readouterr().err == "camsim: error: a value: [1, 2, 3]\n"


@pytest.mark.parametrize("signum, status, line", [
    (signal.SIGINT, 130, "camsim: interrupted; "),
    (signal.SIGTERM, 143, "camsim: terminated (SIGTERM); "),
])
def test_a_stop_signal_whose_exception_a_library_turned_into_another_is_still_a_stop(monkeypatch, capsys, signum,
                                                                                     status, line):
    """A signal that lands inside a C library's call can come out as another exception: numpy's ``tofile`` (which
    tifffile writes DNGs with) turns the KeyboardInterrupt raised inside it into ``TypeError: expected str, bytes
    or os.PathLike object, not BufferedWriter``. The run was stopped all the same: one line and 130 or 143."""
    from camsim import cli

    def stopped_inside_a_library(args):
        try:
            signal.raise_signal(signum)  # the handler raises in this frame, as it would inside the library's call
        except BaseException:
            raise TypeError("expected str, bytes or os.PathLike object, not BufferedWriter") from None
        raise AssertionError("the signal's handler did not run")

    before = signal.getsignal(signal.SIGINT)
    monkeypatch.setattr(cli.COMMANDS["list"], "run", stopped_inside_a_library)
    assert cli.main(["list"]) == status
    err = capsys.readouterr().err
    assert err.startswith(line) and err.count("\n") == 1, err
    # the next run starts afresh: a genuine error is not taken for a stop
    monkeypatch.setattr(cli.COMMANDS["list"], "run", lambda args: 1 / 0)
    with pytest.raises(ZeroDivisionError):
        cli.main(["list"])
    assert signal.getsignal(signal.SIGINT) is before  # the handlers are put back


def test_an_error_with_control_characters_is_one_line_a_terminal_only_shows(tmp_path, capsys):
    """A path from input with a carriage return, an escape sequence and a DEL: the error names it escaped, on one
    line (a raw CR would overwrite the line, an ESC recolour the terminal)."""
    from camsim.cli import main

    scene = tmp_path / "s.toml"
    scene.write_text('name = "s"\n[cube]\npath = "c.npy\\r\\u001b[31m\\u007f"\n[light]\nilluminants = ["D65"]\n')
    assert main(["render", str(scene), "--out", str(tmp_path / "o"), "-q"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("camsim: error: "), repr(err)
    assert "\r" not in err and "\x1b" not in err and "\x7f" not in err
    assert "\\r\\x1b[31m\\x7f" in err, err


def test_a_nul_byte_in_an_argument_is_refused_as_exec_would(tmp_path, capsys):
    from camsim.cli import main

    assert main(["render", "macbeth_26", "--out", str(tmp_path / "o\x00x"), "-q"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "holds a NUL byte" in err and "\x00" not in err, repr(err)
    assert not (tmp_path / "o").exists()


def test_a_symbolic_link_loop_is_one_line(tmp_path, capsys):
    from camsim.cli import main

    (tmp_path / "loop.toml").symlink_to(tmp_path / "loop.toml")
    assert main(["render", "macbeth_26", "--preset", str(tmp_path / "loop.toml"), "--out", str(tmp_path / "o"),
                 "-q"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("camsim: error: ") and "loop" in err, err
