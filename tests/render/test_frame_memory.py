"""A frame that does not fit in the memory free is refused from its header, before a pixel is decoded
(camsim.render.frame_memory, with the measured figures of camsim.core.memory_limit): a 14 000 × 14 000 PNG under a
6 GB address-space limit is one line naming the memory it needs, the memory free and ``--max-megapixels``, where it
used to decode for half a minute and run out of memory."""

import os
import resource
import sys
import time

import numpy as np
import pytest

from camsim.cli import main
from camsim.core import memory_limit
from camsim.core.memory_limit import (
    COLOUR_BYTES,
    CUBE_BYTES_PER_PIXEL,
    FRAME_BYTES_PER_PIXEL,
    OPTICS_BYTES_PER_PIXEL,
    RESIZE_BYTES_PER_SOURCE_PIXEL,
    FreeMemory,
)
from camsim.render.frame_memory import frame_need
from camsim.scene.scene_file import load_scene
from tests.core.test_pixel_limit import write_constant_png
from tests.support import clock
from tests.support.helpers import ROOT
from tests.support.hostile_files import one_error_line

#: The big valid image: 196 megapixels, under camsim's 200-megapixel cap, 24 kB on disk. Unit: pixels.
SIDE = 14_000
#: The address space of the subprocess that is handed it: 6 GB, less than its render needs (about 9 GB). Unit: bytes.
ADDRESS_SPACE = 6_000_000_000


@pytest.fixture(scope="module")
def big_png(tmp_path_factory):
    path = tmp_path_factory.mktemp("big") / "big.png"
    write_constant_png(path, SIDE, SIDE)
    return path


def _scene(tmp_path, body: str):
    path = tmp_path / "scene.toml"
    path.write_text('name = "s"\n' + body)
    return path


def test_a_big_image_under_an_address_space_limit_is_refused_from_its_header(big_png, tmp_path):
    """In a subprocess under RLIMIT_AS = 6 GB (never gigabytes here): one line, exit 2, in seconds of CPU time;
    before the memory check the render decoded for 35 s and then ran out of memory."""
    scene = _scene(tmp_path, f'[image]\npath = "{big_png.as_posix()}"\n')

    def limited():
        resource.setrlimit(resource.RLIMIT_AS, (ADDRESS_SPACE, ADDRESS_SPACE))

    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    done = clock.run([sys.executable, "-m", "camsim", "render", str(scene), "--out", str(tmp_path / "out"), "-q"],
                     cpu_s=30, env=env, capture_output=True, text=True, preexec_fn=limited)
    assert done.returncode == 2, done.stderr
    line = one_error_line(done.stderr)
    assert line.startswith(f"camsim: error: image {big_png} is {SIDE} × {SIDE} pixels (196 MP); rendering it needs "
                           "about 8.82 GB of memory, over the "), line
    assert line.endswith(" GB free under this process's address-space limit (ulimit -v) (--max-megapixels 196 "
                         "allows it)"), line
    assert not (tmp_path / "out").exists()


def test_a_big_image_over_max_megapixels_is_refused_at_once(big_png, tmp_path, capsys):
    scene = _scene(tmp_path, f'[image]\npath = "{big_png.as_posix()}"\n')
    start = time.process_time()
    assert main(["render", str(scene), "--max-megapixels", "1", "--out", str(tmp_path / "out"), "-q"]) == 2
    assert time.process_time() - start < 3.0  # decoding it takes tens of seconds
    line = one_error_line(capsys.readouterr().err)
    assert line == (f"camsim: error: image {big_png} is {SIDE} × {SIDE} pixels (196 MP), over --max-megapixels 1 "
                    "(--max-megapixels 196 allows it)")
    assert not (tmp_path / "out").exists()


def test_max_megapixels_renders_what_the_memory_check_would_refuse(tmp_path, capsys, monkeypatch):
    """With almost no memory free a small image is refused by default, and rendered with --max-megapixels (the
    user's word); the limit reaches the check as an argument, not through any state."""
    import imageio.v3 as iio

    iio.imwrite(tmp_path / "small.png", np.full((24, 32, 3), 128, np.uint8))
    scene = _scene(tmp_path, '[image]\npath = "small.png"\n[light]\nilluminants = ["D65"]\nintensity_factors = [1]\n')
    monkeypatch.setattr(memory_limit, "free_memory", lambda: FreeMemory(1000, "this machine has free", None))
    assert main(["render", str(scene), "--out", str(tmp_path / "a"), "-q"]) == 2
    line = one_error_line(capsys.readouterr().err)
    assert "over the 1 kB this machine has free (--max-megapixels 0.1 allows it)" in line, line
    assert main(["render", str(scene), "--max-megapixels", "0.1", "--out", str(tmp_path / "b"), "-q"]) == 0
    assert (tmp_path / "b" / "s_D65_F1.json").exists()


# --- the estimate, scene by scene ------------------------------------------------------------------------------

def test_a_charts_need_is_its_pixels(tmp_path):
    need = frame_need(load_scene(_scene(tmp_path, "[chart]\n[frame]\nwidth = 300\nheight = 200\n")))
    assert (need.what, need.width, need.height, need.resident, need.mapped) == \
        ("frame", 300, 200, 300 * 200 * FRAME_BYTES_PER_PIXEL, 0)


def test_a_lens_costs_its_ffts():
    need = frame_need(load_scene(ROOT / "scenes" / "slanted_edge_lens.toml"))
    assert need.resident == need.width * need.height * OPTICS_BYTES_PER_PIXEL


def test_an_images_colours_are_bounded_by_its_codes(tmp_path):
    import imageio.v3 as iio

    iio.imwrite(tmp_path / "rgb.png", np.zeros((40, 50, 3), np.uint8))
    iio.imwrite(tmp_path / "grey.png", np.zeros((400, 500), np.uint8))
    rgb = frame_need(load_scene(_scene(tmp_path, '[image]\npath = "rgb.png"\n')))
    assert (rgb.what, rgb.width, rgb.height) == (f"image {tmp_path / 'rgb.png'}", 50, 40)
    assert rgb.resident == 2000 * (FRAME_BYTES_PER_PIXEL + COLOUR_BYTES)  # up to a colour per pixel
    grey = frame_need(load_scene(_scene(tmp_path, '[image]\npath = "grey.png"\n')))
    assert grey.resident == 200_000 * FRAME_BYTES_PER_PIXEL + 256 * COLOUR_BYTES  # 256 grey levels at most


def test_a_crop_and_a_resampling_count_the_rows_decoded(tmp_path):
    import imageio.v3 as iio

    iio.imwrite(tmp_path / "grey.png", np.zeros((400, 500), np.uint8))
    crop = frame_need(load_scene(_scene(tmp_path, '[image]\npath = "grey.png"\ncrop = [0, 0, 100, 50]\n')))
    assert crop.what == f"the frame of image {tmp_path / 'grey.png'} ([image] crop or size)"
    decoded_outside = 50 * 500 - 100 * 50  # whole rows are decoded: their columns outside the crop
    assert crop.resident == 5000 * FRAME_BYTES_PER_PIXEL + 256 * COLOUR_BYTES + decoded_outside * 3 * 2
    resized = frame_need(load_scene(_scene(tmp_path, '[image]\npath = "grey.png"\nsize = [50, 40]\n')))
    assert resized.resident == 2000 * (FRAME_BYTES_PER_PIXEL + COLOUR_BYTES) + \
        200_000 * RESIZE_BYTES_PER_SOURCE_PIXEL  # float colours, one per pixel at most


def test_a_cubes_data_is_mapped_or_loaded(tmp_path):
    import scipy.io

    cube = np.zeros((30, 40, 101), np.float32)
    np.save(tmp_path / "c.npy", cube)
    scipy.io.savemat(tmp_path / "c.mat", {"cube": cube})
    mapped = frame_need(load_scene(_scene(tmp_path, '[cube]\npath = "c.npy"\n')))
    assert (mapped.resident, mapped.mapped) == (1200 * CUBE_BYTES_PER_PIXEL, cube.nbytes)
    loaded = frame_need(load_scene(_scene(tmp_path, '[cube]\npath = "c.mat"\n')))
    assert (loaded.resident, loaded.mapped) == (1200 * CUBE_BYTES_PER_PIXEL + cube.nbytes, 0)
