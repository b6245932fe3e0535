"""Every file a scene file names is opened as camsim opens input (camsim.core.input_files): an image, a cube (.npy,
.mat, an ENVI header or binary), a raw, a map (dark_shading_map, hot_pixel_map), a camera preset file, a camera's
spectra CSV. Where the name is a FIFO, a character device, a directory or holds a NUL byte (``"a\\u0000b"`` in the
TOML string), ``camsim render`` says so on one line and exits 2, at once, and writes nothing."""

import numpy as np
import pytest

from camsim.cli import main
from tests.support.fifo_watchdog import fifo_watchdog
from tests.support.hostile_files import not_regular, one_error_line

#: What names a file in a scene file: the reader's name in messages, the scene's text (``{}`` the path) and the
#: file's extension.
READERS = {
    "image": ("image file", "[image]\npath = \"{}\"\n", ".png"),
    "npy cube": ("cube file", "[cube]\npath = \"{}\"\n", ".npy"),
    "mat cube": ("cube file", "[cube]\npath = \"{}\"\n", ".mat"),
    "ENVI header": ("cube file", "[cube]\npath = \"{}\"\n", ".hdr"),
    "ENVI binary": ("cube file", "[cube]\npath = \"{}\"\n", ".img"),
    "raw": ("raw file", "[raw]\npath = \"{}\"\n", ".dng"),
    "dark_shading_map": ("dark_shading_map", "[chart]\n[frame]\nwidth = 24\nheight = 24\n[sensor]\n"
                                             "dark_shading_map = \"{}\"\n", ".npy"),
    "hot_pixel_map": ("hot_pixel_map", "[chart]\n[frame]\nwidth = 24\nheight = 24\n[sensor]\n"
                                       "hot_pixel_map = \"{}\"\n", ".npy"),
    "preset file": ("camera preset file", "[chart]\n[sensor]\npreset = \"{}\"\n", ".toml"),
    "camera CSV": ("spectra file", "[chart]\n[camera]\nname = \"{}\"\n", ".csv"),
}
#: What each kind of path is called in the message.
SAID = {"fifo": "it is a FIFO (named pipe), not a regular file", "device": "it is a character device, not a regular "
        "file", "directory": "it is a directory, not a regular file", "nul": "holds a NUL byte, which no file name can"}


@pytest.mark.parametrize("kind", list(SAID))
@pytest.mark.parametrize("reader", list(READERS))
def test_a_path_in_a_scene_file_that_names_no_regular_file_is_one_line(tmp_path, capsys, reader, kind):
    what, table, suffix = READERS[reader]
    if kind == "nul":
        name, fifos = f"a\\u0000b{suffix}", []
    else:
        path = not_regular(tmp_path / f"input{suffix}", kind)
        name, fifos = path.name, [path] if kind == "fifo" else []
    scene = tmp_path / "scene.toml"
    scene.write_text('name = "s"\n' + table.format(name))
    out = tmp_path / "out"
    with fifo_watchdog(*fifos, what=f"camsim render of a scene whose {reader} is a FIFO"):
        assert main(["render", str(scene), "--out", str(out), "-q"]) == 2
    line = one_error_line(capsys.readouterr().err)
    assert what in line and SAID[kind] in line, line
    assert not out.exists() or not any(out.iterdir())


def test_an_envi_binary_that_is_a_fifo_beside_a_header_is_not_waited_on(tmp_path, capsys):
    """The header names its binary by the file beside it: a FIFO there is no binary (not one to read)."""
    (tmp_path / "cube.hdr").write_text("ENVI\nsamples = 24\nlines = 24\nbands = 3\ndata type = 4\n"
                                       "interleave = bsq\nbyte order = 0\nwavelength = {400, 550, 700}\n")
    fifo = not_regular(tmp_path / "cube.img", "fifo")
    scene = tmp_path / "scene.toml"
    scene.write_text('name = "s"\n[cube]\npath = "cube.hdr"\n')
    with fifo_watchdog(fifo, what="camsim render of an ENVI cube whose binary is a FIFO"):
        assert main(["render", str(scene), "--out", str(tmp_path / "out"), "-q"]) == 2
    line = one_error_line(capsys.readouterr().err)
    assert "has no binary beside it" in line, line


def test_a_map_in_a_preset_files_iso_point_that_names_no_regular_file_is_one_line(tmp_path, capsys):
    from tests.support.helpers import preset_toml

    fifo = not_regular(tmp_path / "dark.npy", "fifo")
    (tmp_path / "p.toml").write_text(preset_toml() + 'dark_shading_map = "dark.npy"\n')
    scene = tmp_path / "scene.toml"
    scene.write_text('name = "s"\n[chart]\n[sensor]\npreset = "p.toml"\n')
    with fifo_watchdog(fifo, what="a preset file's map that is a FIFO"):
        assert main(["render", str(scene), "--out", str(tmp_path / "out"), "-q"]) == 2
    line = one_error_line(capsys.readouterr().err)
    assert f"cannot read dark_shading_map file {fifo}: it is a FIFO" in line, line
    (tmp_path / "p.toml").write_text(preset_toml() + 'dark_shading_map = "a\\u0000b.npy"\n')
    assert main(["render", str(scene), "--out", str(tmp_path / "out"), "-q"]) == 2
    assert "holds a NUL byte" in one_error_line(capsys.readouterr().err)


def test_a_map_whose_header_claims_too_many_values_is_refused_before_it_is_mapped(tmp_path, capsys):
    """A preset file's map checked from its .npy header (three planes of 200 megapixels at most), as a scene's is."""
    from numpy.lib import format as npy_format

    from tests.support.helpers import preset_toml

    with open(tmp_path / "dark.npy", "wb") as file:  # 10¹⁰ float64 claimed, 64 bytes held
        npy_format.write_array_header_1_0(file, {"descr": "<f8", "fortran_order": False, "shape": (100_000, 100_000)})
        file.write(bytes(64))
    (tmp_path / "p.toml").write_text(preset_toml() + 'dark_shading_map = "dark.npy"\n')
    scene = tmp_path / "scene.toml"
    scene.write_text('name = "s"\n[chart]\n[sensor]\npreset = "p.toml"\n')
    assert main(["render", str(scene), "--out", str(tmp_path / "out"), "-q"]) == 2
    line = one_error_line(capsys.readouterr().err)
    assert "holds 10000000000 values, more than a frame of 200000000 pixels" in line, line
    np.save(tmp_path / "dark.npy", np.zeros((24, 24)))  # a map that fits is read
    assert main(["render", str(scene), "--size", "24x24", "--out", str(tmp_path / "out"), "-q"]) == 0
