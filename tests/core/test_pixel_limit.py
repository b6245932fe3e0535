"""One limit on sizes (camsim.core.pixel_limit.MAX_PIXELS, 200 megapixels), checked from the header, before anything is
decoded or rendered: an image file, a cube file, a scene's [frame], --size and a dataset spec's [frame] each get one
``camsim: error:`` line and exit 2, at once and without decoding (issue 24, point 3)."""

import struct
import time
import zlib

import numpy as np
import pytest

from camsim.cli import main
from camsim.core.pixel_limit import MAX_PIXELS
from camsim.scene.sources.image import read_image_codes

#: A 27 KB PNG that decodes to 15 000 × 15 000 pixels (225 megapixels): before the check, camsim decoded it whole
#: (11.4 GB resident, 495 s, SIGTERM ignored until the decoding ended). The refusal takes milliseconds.
BOMB_SIDE = 15_000
#: Far less than decoding the bomb takes (minutes of CPU time); covers the CLI's own work. CPU time of this process
#: (:func:`time.process_time`), which a busy machine does not stretch. Unit: s.
REFUSAL_S = 3.0


def _chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)


def write_constant_png(path, width: int, height: int) -> None:
    """A valid 1-bit grey PNG of zeros, ``width`` × ``height``: a few tens of kilobytes on disk at any size (so
    that OpenImageIO's own header-versus-file-size check lets it through)."""
    row = b"\x00" * (1 + (width + 7) // 8)  # filter byte + packed bits
    compressor = zlib.compressobj(9)
    data = b"".join(compressor.compress(row) for _ in range(height)) + compressor.flush()
    header = struct.pack(">IIBBBBB", width, height, 1, 0, 0, 0, 0)
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + _chunk(b"IHDR", header) + _chunk(b"IDAT", data) + _chunk(b"IEND", b""))


def _refused(capsys, argv, *phrases):
    start = time.process_time()
    status = main(argv)
    seconds = time.process_time() - start
    err = capsys.readouterr().err
    assert status == 2, err
    assert len(err.splitlines()) == 1 and err.startswith("camsim: error: "), err
    for phrase in phrases:
        assert phrase in err, err
    return seconds


@pytest.fixture(scope="module")
def bomb(tmp_path_factory):
    path = tmp_path_factory.mktemp("bomb") / "bomb.png"
    write_constant_png(path, BOMB_SIDE, BOMB_SIDE)
    assert path.stat().st_size < 100_000 and BOMB_SIDE**2 > MAX_PIXELS
    return path


def test_an_image_bomb_is_refused_from_its_header(bomb, tmp_path, capsys):
    scene = tmp_path / "bomb.toml"
    scene.write_text(f'name = "bomb"\n[image]\npath = "{bomb.as_posix()}"\nsize = [40, 30]\n')
    seconds = _refused(capsys, ["render", str(scene), "--out", str(tmp_path / "out")],
                       f"{BOMB_SIDE} × {BOMB_SIDE} pixels", "over camsim's limit of 200 megapixels")
    assert seconds < REFUSAL_S
    assert not (tmp_path / "out").exists() or not any((tmp_path / "out").glob("*.dng"))


def test_the_reader_refuses_before_decoding(bomb):
    from camsim.core.errors import CamsimError

    start = time.process_time()
    with pytest.raises(CamsimError, match="over camsim's limit"):
        read_image_codes(str(bomb))
    assert time.process_time() - start < 1.0


def test_the_refusal_does_not_grow_memory(bomb):
    """In a fresh process: the peak resident memory stays far below the 675 MB the bomb's pixels take."""
    import os
    import sys

    from tests.support import clock
    from tests.support.helpers import ROOT

    # VmHWM, the peak of this process's own memory map: ru_maxrss would also count the test process's resident
    # memory, which Linux carries into a child through fork and exec (406 MB after the image tests had run)
    code = ("import re, sys\nfrom camsim.core.errors import CamsimError\n"
            "from camsim.scene.sources.image import read_image_codes\n"
            "try:\n    read_image_codes(sys.argv[1])\nexcept CamsimError:\n    pass\nelse:\n    sys.exit(1)\n"
            "print(re.search(r'VmHWM:\\s*(\\d+) kB', open('/proc/self/status').read()).group(1))")
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    done = clock.run([sys.executable, "-c", code, str(bomb)], cpu_s=60, env=env, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert int(done.stdout) * 1024 < 400e6  # kB (KiB)


def test_an_allowed_image_is_read_in_blocks_and_crops_read_their_rows(tmp_path):
    path = tmp_path / "small.png"
    write_constant_png(path, 300, 2500)  # more rows than one block
    codes, integer, bits = read_image_codes(str(path))
    assert codes.shape == (2500, 300, 3) and integer and bits == 8 and not codes.any()
    part, _, _ = read_image_codes(str(path), (1000, 2100))
    assert part.shape == (1100, 300, 3)


@pytest.mark.parametrize("width, height", [(2**40, 2**40), (20_000, 10_001), (1, MAX_PIXELS + 1)])
def test_a_scene_frame_over_the_limit_is_refused(tmp_path, capsys, width, height):
    scene = tmp_path / "big.toml"
    scene.write_text(f'name = "big"\n[chart]\n[frame]\nwidth = {width}\nheight = {height}\n')
    assert _refused(capsys, ["render", str(scene), "--out", str(tmp_path / "out")],
                    f"{width} × {height} pixels", "[frame]") < REFUSAL_S


def test_the_size_option_and_a_dataset_frame_share_the_limit(tmp_path, capsys):
    from tests.support.helpers import ROOT

    _refused(capsys, ["render", str(ROOT / "scenes" / "macbeth_26.toml"), "--size", "20000x10001",
                      "--out", str(tmp_path / "out")], "20000 × 10001 pixels", "200 megapixels")
    spec = tmp_path / "spec.toml"
    spec.write_text(f'name = "big"\nscene = "{(ROOT / "scenes" / "macbeth_26.toml").as_posix()}"\n'
                    "[frame]\nwidth = 20000\nheight = 10001\n")
    _refused(capsys, ["dataset", str(spec), "--out", str(tmp_path / "ds")], "20000 × 10001 pixels", "[frame]")


def test_a_cube_whose_header_is_over_the_limit_is_refused(tmp_path, capsys):
    from numpy.lib import format as npy_format

    cube = tmp_path / "cube.npy"
    with open(cube, "wb") as file:  # a header claiming 30 000 × 30 000 × 31 float32 (112 GB), and 64 bytes
        npy_format.write_array_header_1_0(file, {"descr": "<f4", "fortran_order": False,
                                                 "shape": (30_000, 30_000, 31)})
        file.write(bytes(64))
    scene = tmp_path / "cube.toml"
    scene.write_text(f'name = "cube"\n[cube]\npath = "{cube.as_posix()}"\n')
    assert _refused(capsys, ["render", str(scene), "--out", str(tmp_path / "out")],
                    "30000 × 30000 pixels", "cube") < REFUSAL_S
    np.save(tmp_path / "ok.npy", np.zeros((4, 5, 3)))  # an allowed header still reads
    from camsim.io.cube_files import cube_size

    assert cube_size(tmp_path / "ok.npy") == (5, 4)


@pytest.mark.parametrize("shape", [(22, 24, -1), (0, 24, 31), (-5, 24, 31)])
def test_a_cube_header_with_a_dimension_below_one_is_refused(tmp_path, capsys, shape):
    """A negative length reached numpy's memory map (OverflowError: a traceback, found by tools/fuzz_cli.py)."""
    from numpy.lib import format as npy_format

    cube = tmp_path / "cube.npy"
    with open(cube, "wb") as file:
        npy_format.write_array_header_1_0(file, {"descr": "<f8", "fortran_order": False, "shape": shape})
        file.write(bytes(4096))
    scene = tmp_path / "cube.toml"
    scene.write_text(f'name = "cube"\n[cube]\npath = "{cube.as_posix()}"\n')
    _refused(capsys, ["render", str(scene), "--out", str(tmp_path / "out")], "dimension below 1")


def test_a_dng_whose_header_is_over_the_limit_is_refused(tmp_path, capsys):
    """ImageLength 2^31 in a small CFA DNG: refused from the header (before: decoded for 10 s and 1.5 GB)."""
    import tifffile

    from camsim.render.frame_files import load_frame

    out = tmp_path / "frames"
    assert main(["render", "macbeth_26", "--illuminant", "D65", "-F", "1", "--size", "48x32", "--cfa", "RGGB",
                 "--out", str(out), "-q"]) == 0
    capsys.readouterr()
    dng = out / "macbeth_26_D65_F1.dng"
    with tifffile.TiffFile(dng, mode="r+b") as tif:
        tif.pages.first.tags["ImageLength"].overwrite(2**31)
    from camsim.core.errors import CamsimError

    start = time.process_time()
    with pytest.raises(CamsimError, match="over camsim's limit of 200 megapixels"):
        load_frame(dng)
    assert time.process_time() - start < REFUSAL_S


@pytest.mark.parametrize("header, phrase", [
    ({"descr": "|u1", "fortran_order": False, "shape": (24, 22, 2**40)}, "1099511627776 bands, over camsim's limit"),
    ({"descr": "|u1", "fortran_order": False, "shape": (24, 22, 4000)}, "needs 2112000 bytes"),
    ({"descr": "<f8", "fortran_order": False, "shape": (24, 22, 31)}, "the file holds 64"),
])
def test_a_cube_header_claiming_more_data_than_the_file_holds_is_refused(tmp_path, capsys, header, phrase):
    """Bands × pixels × item size beyond the file (an int64 overflow in numpy's memory map: a traceback, found by
    tools/fuzz_cli.py); a malformed header is one line too."""
    from numpy.lib import format as npy_format

    cube = tmp_path / "cube.npy"
    with open(cube, "wb") as file:
        npy_format.write_array_header_1_0(file, header)
        file.write(bytes(64))
    scene = tmp_path / "cube.toml"
    scene.write_text(f'name = "cube"\n[cube]\npath = "{cube.as_posix()}"\n')
    _refused(capsys, ["render", str(scene), "--out", str(tmp_path / "out")], phrase)
    data = bytearray(cube.read_bytes())
    data[10:40] = bytes(30)  # zeros in the header's text
    cube.write_bytes(bytes(data))
    _refused(capsys, ["render", str(scene), "--out", str(tmp_path / "out")], "header is malformed")
