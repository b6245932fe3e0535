"""Float EXR frames: bit-exact pixels and exact string metadata through OpenEXR and OpenImageIO."""

import json
import re
import time

import numpy as np
import OpenEXR
import pytest

from camsim.core.errors import CamsimError, OutputError
from camsim.io import exr as exr_mod
from camsim.io.exr import (
    DEFAULT_EXR_COMPRESSION,
    EXR_COMPRESSIONS,
    check_exr_compression,
    exr_compressions,
    read_exr,
    read_exr_header,
    read_exr_oiio,
    write_exr,
)
from tests.support.helpers import FullDiskExrFile
from tests.support.hostile_files import HUGE_SIZES, no_hang, not_regular, one_error_line, with_exr_window

H, W = 48, 64
READERS = [read_exr, read_exr_oiio]


def read_noisy(path):
    """read_exr without the clean layer (OpenEXR's channel-selecting reader)."""
    return read_exr(path, clean=False)


def read_header(path):
    """read_exr_header, shaped like the readers' returns: the pixels are not read."""
    header, shape = read_exr_header(path)
    return shape, None, header


ERROR_READERS = [*READERS, read_noisy]  # each refuses every broken file with a CamsimError naming it
HEADER = {
    "camsim:version": "0.1.0",
    "camsim:gain_e_per_dn": "0.12345678901234567890123456789",  # longer than any float carries
    "camsim:exposure_s": "1e-300",
    "camsim:read_noise_e": "-0.000000000000000000000000000001",
    "camsim:scene": "ColorChecker® – Macbeth, 24 patches; \"quoted\" and\ttabbed",
    "camsim:spectra_sha256": "9f86d081884c7d659a2feaa0c55ad015a3bf4f1b2b0b822cd15d6c15b0f00a08" * 8,
    "Z last key": "x",
}


def frames(seed, h=H, w=W):
    rng = np.random.default_rng(seed)
    noisy = rng.normal(0.0, 100.0, size=(3, h, w)).astype(np.float32)  # about half negative
    clean = (rng.random(size=(3, h, w), dtype=np.float32) - 0.25) * np.float32(1e-3)
    f32 = np.finfo(np.float32)
    specials = np.array([0.0, -0.0, f32.max, -f32.max, f32.tiny, -f32.tiny, f32.smallest_subnormal, np.inf, -np.inf,
                         np.nan, 1.0, -1.0], dtype=np.float32)
    noisy.reshape(-1)[: specials.size] = specials
    noisy.view(np.uint32).reshape(-1)[specials.size] = 0x7FC12345  # NaN with a payload
    return noisy, clean


def bits(a):
    return a.view(np.uint32)


@pytest.mark.parametrize("reader", READERS)
@pytest.mark.parametrize(("seed", "h", "w"), [(0, H, W), (1, 1, 1), (2, 17, 3)])
def test_pixels_and_header_round_trip_bit_exact(tmp_path, reader, seed, h, w):
    noisy, clean = frames(seed, h, w) if h * w >= 16 else (
        np.array([-1.5, 0.0, 2.0], np.float32).reshape(3, 1, 1), np.array([3, 4, 5], np.float32).reshape(3, 1, 1))
    path = tmp_path / "f.exr"
    write_exr(path, noisy, clean, HEADER)
    n2, c2, hdr = reader(path)
    assert n2.dtype == np.float32 and n2.shape == (3, h, w) and c2.dtype == np.float32 and c2.shape == (3, h, w)
    np.testing.assert_array_equal(bits(n2), bits(noisy))  # bitwise: also -0.0, subnormals, inf, NaN payloads
    np.testing.assert_array_equal(bits(c2), bits(clean))
    assert hdr == HEADER


def test_both_readers_agree_and_clean_is_optional(tmp_path):
    noisy, _ = frames(3)
    path = tmp_path / "noisy_only.exr"
    write_exr(path, noisy, None, {"camsim:k": "v"})
    results = [reader(path) for reader in READERS]
    for n2, c2, hdr in results:
        np.testing.assert_array_equal(bits(n2), bits(noisy))
        assert c2 is None and hdr == {"camsim:k": "v"}
    write_exr(tmp_path / "no_header.exr", noisy, None, {})
    assert all(reader(tmp_path / "no_header.exr")[2] == {} for reader in READERS)


def test_file_layout(tmp_path):
    noisy, clean = frames(4)
    path = tmp_path / "f.exr"
    write_exr(path, np.asfortranarray(noisy), clean[:, :, :].copy(order="F"), HEADER)  # non-C-contiguous input
    with OpenEXR.File(str(path), separate_channels=True) as f:
        header = dict(f.header())
        channels = {name: (ch.type(), ch.pixels.copy()) for name, ch in f.channels().items()}
        n_parts = len(f.parts)
    assert n_parts == 1
    assert header["compression"] == getattr(OpenEXR, EXR_COMPRESSIONS[DEFAULT_EXR_COMPRESSION][0])
    assert header["type"] == OpenEXR.scanlineimage
    assert sorted(channels) == ["B", "G", "R", "clean.B", "clean.G", "clean.R"]
    assert all(t == OpenEXR.FLOAT for t, _ in channels.values())
    for i, c in enumerate("RGB"):
        np.testing.assert_array_equal(bits(channels[c][1]), bits(noisy[i]))
        np.testing.assert_array_equal(bits(channels["clean." + c][1]), bits(clean[i]))


def test_same_input_gives_identical_bytes(tmp_path):
    noisy, clean = frames(5)
    write_exr(tmp_path / "a.exr", noisy, clean, HEADER)
    write_exr(tmp_path / "b.exr", noisy.copy(), clean.copy(), dict(reversed(list(HEADER.items()))))
    a, b = (tmp_path / "a.exr").read_bytes(), (tmp_path / "b.exr").read_bytes()
    assert a == b
    noisy[0, 5, 5] = np.nextafter(noisy[0, 5, 5], np.float32(np.inf))
    write_exr(tmp_path / "c.exr", noisy, clean, HEADER)
    assert (tmp_path / "c.exr").read_bytes() != a


@pytest.mark.parametrize(("noisy", "clean"), [
    (np.zeros((3, H, W), np.float64), None), (np.zeros((3, H, W), np.float16), None),
    (np.zeros((3, H, W), np.int32), None), (np.zeros((H, W, 3), np.float32), None),
    (np.zeros((4, H, W), np.float32), None), (np.zeros((H, W), np.float32), None),
    (np.zeros((3, 0, W), np.float32), None), ([[[0.0]]] * 3, None),
    (np.zeros((3, H, W), np.float32), np.zeros((3, H, W), np.float64)),
    (np.zeros((3, H, W), np.float32), np.zeros((3, H, W + 1), np.float32)),
])
def test_rejects_bad_arrays_without_writing(tmp_path, noisy, clean):
    path = tmp_path / "bad.exr"
    with pytest.raises(CamsimError, match=re.escape(str(path))):
        write_exr(path, noisy, clean, {})
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("header", [
    {"owner": "me"}, {"comments": "x"}, {"compression": "zip"}, {"oiio:ColorSpace": "lin"}, {"openexr:x": "1"},
    {"": "x"}, {"camsim:k": 1.5}, {"camsim:k": ""}, {"camsim:k": "a\x00b"}, {3: "x"}, [("camsim:k", "v")],
])
def test_rejects_bad_header_without_writing(tmp_path, header):
    path = tmp_path / "bad.exr"
    noisy, clean = frames(6)
    with pytest.raises(CamsimError, match=re.escape(str(path))):
        write_exr(path, noisy, clean, header)
    assert list(tmp_path.iterdir()) == []


def test_noisy_only_and_header_only_reads_agree_with_the_full_read(tmp_path):
    noisy, clean = frames(4)
    write_exr(tmp_path / "rgb.exr", noisy, clean, HEADER)
    write_exr(tmp_path / "cfa.exr", noisy[:1], None, HEADER)
    for name, planes in (("rgb.exr", 3), ("cfa.exr", 1)):
        full = read_exr(tmp_path / name)
        n2, c2, hdr = read_noisy(tmp_path / name)
        assert c2 is None and n2.dtype == np.float32 and n2.flags.c_contiguous and hdr == full[2] == HEADER
        np.testing.assert_array_equal(bits(n2), bits(full[0]))
        assert read_header(tmp_path / name) == ((planes, H, W), None, HEADER)


@pytest.mark.parametrize("reader", ERROR_READERS)
@pytest.mark.parametrize("keep", [0.999, 0.5, 0.01])
def test_truncated_file_is_a_user_error(tmp_path, reader, keep):
    noisy, clean = frames(7)
    write_exr(tmp_path / "good.exr", noisy, clean, HEADER)
    good = (tmp_path / "good.exr").read_bytes()
    bad = tmp_path / "truncated.exr"
    bad.write_bytes(good[: int(len(good) * keep)])
    with pytest.raises(CamsimError, match=re.escape(str(bad))):
        reader(bad)


@pytest.mark.parametrize("reader", ERROR_READERS)
def test_a_corrupt_chunk_is_one_error_and_no_library_line(tmp_path, capfd, reader):
    """OpenEXR prints its own "(EXR_ERR_…)" lines on descriptor 2 before it raises: they go into camsim's one
    error instead of the terminal."""
    noisy, clean = frames(7)
    write_exr(tmp_path / "good.exr", noisy, clean, HEADER, compression="zip")
    data = bytearray((tmp_path / "good.exr").read_bytes())
    at = data.index(b"compression\x00compression\x00\x01\x00\x00\x00") + 28  # the attribute's one byte
    assert data[at] == 3  # ZIP_COMPRESSION: the chunks are declared PIZ (4) instead, which they are not
    data[at] = 4
    bad = tmp_path / "corrupt.exr"
    bad.write_bytes(bytes(data))
    capfd.readouterr()
    with pytest.raises(CamsimError, match=re.escape(str(bad))):
        reader(bad)
    _, err = capfd.readouterr()
    assert "EXR_ERR" not in err and err == ""


@pytest.mark.parametrize("reader", [*ERROR_READERS, read_header])
def test_text_and_missing_files_are_user_errors(tmp_path, reader):
    text = tmp_path / "notes.exr"
    text.write_text("not an image\n")
    for path in (text, tmp_path / "missing.exr"):
        with pytest.raises(CamsimError, match=re.escape(str(path))):
            reader(path)


@pytest.mark.parametrize(("reader", "names", "message"), [
    *((reader, names, "lacks channel") for reader in (*READERS, read_noisy, read_header) for names in (["R", "G"],
                                                                                                        ["Y"])),
    *((reader, ["R", "G", "B", "clean.R"], "only some clean") for reader in READERS),  # the others skip clean.*
])
def test_missing_channels_are_user_errors(tmp_path, reader, names, message):
    path = tmp_path / "foreign.exr"
    plane = np.ones((H, W), np.float32)
    with OpenEXR.File({"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage},
                      {n: plane for n in names}) as f:
        f.write(str(path))
    with pytest.raises(CamsimError, match=re.escape(str(path)) + ".*" + message):
        reader(path)


def test_exception_mid_write_leaves_no_file(tmp_path, monkeypatch):
    noisy, clean = frames(8)
    final = tmp_path / "f.exr"
    write_exr(final, noisy, clean, HEADER)
    before = final.read_bytes()

    monkeypatch.setattr(exr_mod.OpenEXR, "File", FullDiskExrFile)
    with pytest.raises(OutputError, match=f"cannot write {re.escape(str(final))}: No space left on device"):
        write_exr(final, -noisy, clean, HEADER)
    with pytest.raises(OutputError, match="No space left on device"):
        write_exr(tmp_path / "new.exr", noisy, clean, HEADER)
    monkeypatch.undo()
    assert final.read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == ["f.exr"]



@pytest.mark.parametrize("reader", READERS)
@pytest.mark.parametrize("planes", [3, 1])
def test_with_a_view_the_picture_takes_rgb_and_the_values_the_noisy_layer(tmp_path, reader, planes):
    noisy, clean = frames(13)
    noisy = noisy[:planes].copy()  # 1: a colour filter array's mosaic
    view = np.random.default_rng(13).random((3, H, W), dtype=np.float32)
    path = tmp_path / "f.exr"
    write_exr(path, noisy, clean, HEADER, view=view)
    with OpenEXR.File(str(path), separate_channels=True) as f:  # the layout, as OpenEXR reads it
        channels = {name: ch.pixels.copy() for name, ch in f.channels().items()}
    layer = ["noisy.R", "noisy.G", "noisy.B"] if planes == 3 else ["noisy.CFA"]
    assert sorted(channels) == sorted(["R", "G", "B", *layer, "clean.R", "clean.G", "clean.B"])
    for i, c in enumerate("RGB"):
        np.testing.assert_array_equal(bits(channels[c]), bits(view[i]))
    for i, c in enumerate(layer):
        np.testing.assert_array_equal(bits(channels[c]), bits(noisy[i]))
    n2, c2, hdr = reader(path)  # the values, not the picture
    np.testing.assert_array_equal(bits(n2), bits(noisy))
    np.testing.assert_array_equal(bits(c2), bits(clean))
    assert hdr == HEADER
    n3, c3, _ = read_noisy(path)
    np.testing.assert_array_equal(bits(n3), bits(noisy))
    assert c3 is None and read_header(path) == ((planes, H, W), None, HEADER)


@pytest.mark.parametrize("view", [np.zeros((3, H, W), np.float64), np.zeros((3, H, W + 1), np.float32),
                                  np.zeros((1, H, W), np.float32)])
def test_rejects_a_bad_view_without_writing(tmp_path, view):
    noisy, clean = frames(14)
    path = tmp_path / "bad.exr"
    with pytest.raises(CamsimError, match=re.escape(str(path)) + ".*view"):
        write_exr(path, noisy, clean, HEADER, view=view)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("reader", [*READERS, read_noisy, read_header])
def test_a_partial_noisy_layer_is_a_user_error(tmp_path, reader):
    path = tmp_path / "foreign.exr"
    plane = np.ones((H, W), np.float32)
    with OpenEXR.File({"compression": OpenEXR.NO_COMPRESSION, "type": OpenEXR.scanlineimage},
                      {n: plane for n in ("R", "G", "B", "noisy.R", "noisy.G")}) as f:
        f.write(str(path))
    with pytest.raises(CamsimError, match=re.escape(str(path)) + ".*lacks channel.*noisy.B"):
        reader(path)

# --- compressions ----------------------------------------------------------------------------------------------

LOSSLESS = exr_compressions()  # the lossless ones the installed OpenEXR offers
REFUSED = [name for name, (_, lossless, _) in EXR_COMPRESSIONS.items() if not lossless]


def written_compression(path) -> int:
    with OpenEXR.File(str(path), header_only=True) as f:
        return f.header()["compression"]


def test_every_compression_of_the_bindings_is_classified():
    """A newer OpenEXR's new compression must be measured and classified before camsim offers it."""
    offered = {n for n in dir(OpenEXR) if n.endswith("_COMPRESSION") and not n.startswith("NUM_")}
    assert offered <= {constant for constant, _, _ in EXR_COMPRESSIONS.values()}
    assert {"none", "zip", "piz"} <= set(LOSSLESS) and DEFAULT_EXR_COMPRESSION in LOSSLESS


@pytest.mark.parametrize("reader", READERS)
@pytest.mark.parametrize("name", LOSSLESS)
def test_every_lossless_compression_round_trips_bit_exact(tmp_path, reader, name):
    noisy, clean = frames(9, 37, 53)  # odd sizes: partial blocks of every method
    path = tmp_path / f"{name}.exr"
    write_exr(path, noisy, clean, HEADER, compression=name)
    assert written_compression(path) == getattr(OpenEXR, EXR_COMPRESSIONS[name][0])
    n2, c2, hdr = reader(path)
    np.testing.assert_array_equal(bits(n2), bits(noisy))  # every bit: -0.0, subnormals, inf, NaN payloads
    np.testing.assert_array_equal(bits(c2), bits(clean))
    assert hdr == HEADER
    mosaic = noisy[:1].copy()  # a colour filter array's one channel
    write_exr(path, mosaic, clean, HEADER, compression=name)
    np.testing.assert_array_equal(bits(read_exr(path)[0]), bits(mosaic))


@pytest.mark.parametrize("name", LOSSLESS)
def test_every_lossless_compression_is_deterministic_whatever_the_threads(tmp_path, name):
    noisy, clean = frames(10, 70, 90)
    previous = OpenEXR.global_thread_count()
    try:
        contents = []
        for threads in (1, 4):
            OpenEXR.set_global_thread_count(threads)
            write_exr(tmp_path / "f.exr", noisy, clean, HEADER, compression=name)
            contents.append((tmp_path / "f.exr").read_bytes())
    finally:
        OpenEXR.set_global_thread_count(previous)
    assert contents[0] == contents[1]


@pytest.mark.parametrize("name", REFUSED)
def test_lossy_compressions_are_refused_and_are_what_the_table_says(tmp_path, name):
    noisy, clean = frames(11)
    path = tmp_path / "f.exr"
    with pytest.raises(CamsimError, match=f"cannot write EXR .*{name}.* is refused: .*keep every float32 bit"):
        write_exr(path, noisy, clean, HEADER, compression=name)
    assert list(tmp_path.iterdir()) == []
    constant = EXR_COMPRESSIONS[name][0]
    if not hasattr(OpenEXR, constant):
        pytest.skip(f"this OpenEXR has no {constant}")
    # written by OpenEXR directly: the label is right
    channels = {c: np.ascontiguousarray(noisy[i]) for i, c in enumerate("RGB")}
    with OpenEXR.File({"compression": getattr(OpenEXR, constant), "type": OpenEXR.scanlineimage},
                      dict(channels)) as f:
        f.write(str(path))
    back, _, _ = read_exr(path)
    exact = np.array_equal(bits(back), bits(noisy))
    if name in ("b44", "b44a"):  # HALF channels only: float32 is stored as it is, uncompressed
        assert exact and path.stat().st_size > noisy.nbytes
    else:
        assert not exact


@pytest.mark.parametrize(("name", "message"), [("zap", "unknown EXR compression 'zap'"), (None, "unknown"),
                                               ("ZIP", "unknown")])
def test_unknown_compressions_are_refused(tmp_path, name, message):
    noisy, clean = frames(12)
    with pytest.raises(CamsimError, match=message):
        write_exr(tmp_path / "f.exr", noisy, clean, HEADER, compression=name)
    assert list(tmp_path.iterdir()) == []


def test_a_compression_newer_than_the_bindings_is_refused(monkeypatch):
    monkeypatch.delattr(OpenEXR, "ZSTD_COMPRESSION", raising=False)
    with pytest.raises(CamsimError, match="'zstd' needs a newer OpenEXR"):
        check_exr_compression("zstd")
    assert "zstd" not in exr_compressions()


def test_render_writes_the_chosen_compression_and_records_it(tmp_path, capsys):
    from camsim.cli import main

    argv = ["render", "macbeth_26", "--size", "64x48", "--illuminant", "D65", "--intensity", "0.5", "-q"]
    assert main([*argv, "--out", str(tmp_path / "default")]) == 0
    assert main([*argv, "--out", str(tmp_path / "zip"), "--exr-compression", "zip"]) == 0
    frames_written = {}
    for name, expected in (("default", DEFAULT_EXR_COMPRESSION), ("zip", "zip")):
        exr = tmp_path / name / "macbeth_26_D65_F0.5.exr"
        assert written_compression(exr) == getattr(OpenEXR, EXR_COMPRESSIONS[expected][0])
        sidecar = json.loads(exr.with_suffix(".json").read_text())
        assert sidecar["exr_compression"] == expected
        noisy, clean, header = read_exr(exr)
        assert json.loads(header["camsim:metadata"])["exr_compression"] == expected
        frames_written[name] = (noisy, clean)
    for a, b in zip(frames_written["default"], frames_written["zip"]):  # the same pixels, however compressed
        np.testing.assert_array_equal(bits(a), bits(b))
    capsys.readouterr()
    assert main([*argv, "--out", str(tmp_path / "lossy"), "--exr-compression", "dwab"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("camsim: error: EXR compression 'dwab' is refused: lossy")
    assert not (tmp_path / "lossy").exists()  # refused before the folder is made


# --- hostile headers and paths -------------------------------------------------------------------------------

def read_clean(path):
    """read_exr_clean, shaped like the readers' returns."""
    clean, header = exr_mod.read_exr_clean(path)
    return None, clean, header


ALL_READERS = [*ERROR_READERS, read_header, read_clean]


@pytest.mark.parametrize("reader", ALL_READERS)
@pytest.mark.parametrize("size", HUGE_SIZES)
def test_a_data_window_over_the_pixel_limit_is_refused_from_the_header(tmp_path, capfd, reader, size):
    """A header that declares 2 × 10⁸ + 10⁴ to 10¹⁰ pixels (a few bytes changed in a real frame) is refused on one
    line before a pixel is allocated or read, and OpenEXR says nothing on the terminal. OpenImageIO refuses such a
    header itself when it opens the file, in its own (several-line) words: one line here too."""
    noisy, clean = frames(7)
    write_exr(tmp_path / "good.exr", noisy, clean, HEADER)
    bad = tmp_path / "huge.exr"
    bad.write_bytes(with_exr_window((tmp_path / "good.exr").read_bytes(), *size))
    capfd.readouterr()
    start = time.process_time()
    with pytest.raises(CamsimError) as exc:
        reader(bad)
    message = str(exc.value)
    assert "\n" not in message and str(bad) in message, message
    if reader is not read_exr_oiio:
        assert f"{size[0]} × {size[1]} pixels, over camsim's limit" in message
    assert time.process_time() - start < 5
    assert capfd.readouterr() == ("", "")


@pytest.mark.parametrize("reader", ALL_READERS)
@pytest.mark.parametrize("kind", ["fifo", "device", "directory"])
def test_a_path_that_is_no_regular_file_is_refused_not_waited_on(tmp_path, reader, kind):
    """OpenEXR and OpenImageIO open a FIFO by name and wait for a writer that never comes; /dev/zero never ends."""
    path = not_regular(tmp_path / "frame.exr", kind)
    with no_hang(f"{reader.__name__} of a {kind}"), pytest.raises(CamsimError) as exc:
        reader(path)
    assert f"cannot read EXR {path}: it is a" in str(exc.value) and "not a regular file" in str(exc.value)


@pytest.mark.parametrize("size", HUGE_SIZES)
def test_develop_refuses_a_huge_exr_header_on_one_line(tmp_path, capfd, size):
    from camsim.cli import main

    noisy, clean = frames(7)
    write_exr(tmp_path / "good.exr", noisy, clean, HEADER)
    bad = tmp_path / "huge.exr"
    bad.write_bytes(with_exr_window((tmp_path / "good.exr").read_bytes(), *size))
    capfd.readouterr()
    assert main(["develop", str(bad), "--out", str(tmp_path / "out"), "-q"]) == 2
    out, err = capfd.readouterr()
    assert "over camsim's limit" in one_error_line(err) and out == ""
    assert not (tmp_path / "out").exists() or not any((tmp_path / "out").iterdir())
