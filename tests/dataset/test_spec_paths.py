"""Paths in a dataset spec (an ``[images]`` or ``[raws]`` folder, a map, a camera CSV, a preset file) with a NUL
byte, which no file name holds, or naming a FIFO: one ``camsim: error:`` line, exit 2, never ``ValueError:
embedded null byte`` nor a wait."""

import os

import imageio.v3 as iio
import numpy as np
import pytest

from camsim.cli import main
from tests.support.fifo_watchdog import fifo_watchdog
from tests.support.hostile_files import not_regular, one_error_line

CHART = 'name = "x"\nscene = "macbeth_26"\n[frame]\nwidth = 32\nheight = 32\n'


@pytest.mark.parametrize("text, said", [
    ('name = "x"\nscene = "macbeth_26"\n[images]\nfolder = "a\\u0000b"\ncrop = [32, 32]\n', "[images] folder path"),
    ('name = "x"\n[raws]\nfolder = "a\\u0000b"\ncrop = [32, 32]\n', "[raws] folder path"),
    (CHART + '[fixed]\ndark_shading_map = "a\\u0000b.npy"\n', "dark_shading_map path"),
    (CHART + '[fixed]\nhot_pixel_map = "a\\u0000b.npy"\n', "hot_pixel_map path"),
    (CHART + '[fixed]\ncamera = "a\\u0000b.csv"\n', "camera path"),
    (CHART + '[fixed]\npreset = "a\\u0000b.toml"\n', "camera preset file path"),
])
def test_a_path_with_a_nul_byte_in_a_spec_is_one_line(tmp_path, capsys, text, said):
    spec = tmp_path / "spec.toml"
    spec.write_text(text)
    assert main(["dataset", str(spec), "--out", str(tmp_path / "out"), "--dry-run"]) == 2
    line = one_error_line(capsys.readouterr().err)
    assert said in line and "holds a NUL byte, which no file name can" in line, line


@pytest.mark.parametrize("key", ["dark_shading_map", "preset"])
def test_a_file_a_spec_names_that_is_a_fifo_is_one_line(tmp_path, capsys, key):
    fifo = not_regular(tmp_path / ("f.npy" if key == "dark_shading_map" else "f.toml"), "fifo")
    spec = tmp_path / "spec.toml"
    spec.write_text(CHART + f'[fixed]\n{key} = "{fifo.name}"\n')
    with fifo_watchdog(fifo, what=f"camsim dataset of a spec whose {key} is a FIFO"):
        assert main(["dataset", str(spec), "--out", str(tmp_path / "out"), "--dry-run"]) == 2
    line = one_error_line(capsys.readouterr().err)
    assert f"{fifo}: it is a FIFO (named pipe), not a regular file" in line, line


def test_a_fifo_in_an_images_folder_is_not_an_image_and_is_not_read(tmp_path, capsys):
    """The folder's images are its regular files: a FIFO by an image's name is passed over, not hashed."""
    folder = tmp_path / "images"
    folder.mkdir()
    iio.imwrite(folder / "a.png", np.full((40, 40, 3), 90, np.uint8))
    os.mkfifo(folder / "b.png")
    spec = tmp_path / "spec.toml"
    spec.write_text('name = "x"\nscene = "macbeth_26"\n[images]\nfolder = "images"\ncrop = [32, 32]\n')
    with fifo_watchdog(folder / "b.png", what="camsim dataset of an images folder holding a FIFO"):
        assert main(["dataset", str(spec), "--out", str(tmp_path / "out"), "--dry-run"]) == 0
    assert capsys.readouterr().err == ""
