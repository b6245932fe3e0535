"""Hyperspectral cube files (:mod:`camsim.io.cube_files`): ``.npy``, ENVI and MATLAB cubes written here with numpy
and scipy.io read back to the same array; resampling against colour-science's own interpolation; bad files give one
clear error, exit 2, and write nothing."""

import numpy as np
import pytest
import scipy.io

from camsim.cli import main
from camsim.core.errors import CamsimError
from camsim.io import cube_files
from camsim.io.cube_files import cube_size, read_cube
from camsim.light.spectra import WavelengthGrid, import_colour

GRID = WavelengthGrid()  # 380–780 nm every 4 nm, N = 101
H, W = 30, 40
SCALE = 1024.0  # the integer cubes hold REF × 1024; every REF value is exact in float32 and float64
COUNTS = np.random.default_rng(12).integers(50, 950, size=(H, W, GRID.size))
REF = COUNTS / SCALE
WL31 = np.arange(400.0, 701.0, 10.0)
REF31 = np.random.default_rng(31).uniform(0.05, 0.9, size=(H, W, WL31.size))
GRID31 = WavelengthGrid(400.0, 700.0, 4.0)  # inside the 31-band cube's 400–700 nm


def write_envi(path, cube, *, interleave="bsq", dtype="<f4", offset=0, binary=None, extra=""):
    """Write an H × W × B cube as an ENVI header ``path`` and a binary beside it (``.img`` unless ``path``'s stem
    names it), independently of camsim: numpy transposes to the interleave and writes the bytes."""
    dtype = np.dtype(dtype)
    codes = {"u1": 1, "i2": 2, "i4": 3, "f4": 4, "f8": 5, "u2": 12, "u4": 13, "i8": 14, "u8": 15}
    axes = {"bsq": (2, 0, 1), "bil": (0, 2, 1), "bip": (0, 1, 2)}[interleave]
    body = np.ascontiguousarray(np.transpose(cube, axes)).astype(dtype).tobytes()
    binary = path.with_suffix(".img") if binary is None else binary
    binary.write_bytes(b"\xab" * offset + body)
    order = 1 if dtype.byteorder == ">" else 0
    path.write_text(
        f"ENVI\ndescription = {{written by a test,\n  for camsim}}\nsamples = {cube.shape[1]}\n"
        f"lines   = {cube.shape[0]}\nbands = {cube.shape[2]}\nheader offset = {offset}\nfile type = ENVI Standard\n"
        f"data type = {codes[dtype.str[1:]]}\ninterleave = {interleave}\nbyte order = {order}\n{extra}"
    )
    return path


def wavelength_lines(wavelengths, units="Nanometers"):
    values = ",\n ".join(f"{v:g}" for v in wavelengths)
    return f"wavelength units = {units}\nwavelength = {{\n {values}}}\n"


def memory_mapped(array):
    """Whether ``array`` is a view of an ``np.memmap``."""
    while array is not None:
        if isinstance(array, np.memmap):
            return True
        array = array.base
    return False


# --- round trips ------------------------------------------------------------------------------------------------

def test_npy_is_memory_mapped_and_round_trips(tmp_path):
    np.save(tmp_path / "c.npy", REF)
    cube = read_cube(tmp_path / "c.npy", GRID)
    assert memory_mapped(cube.stored) and cube.mapped is not None and cube.resample is None
    assert cube.shape == (H, W, GRID.size)
    np.testing.assert_array_equal(cube.to_array(), REF)
    np.testing.assert_array_equal(cube.rows(7, 9), REF[7:9])
    np.testing.assert_array_equal(cube.wavelengths_nm, GRID.wavelengths_nm)


@pytest.mark.parametrize("interleave", ["bsq", "bil", "bip"])
@pytest.mark.parametrize("order", ["<", ">"])
def test_envi_interleaves_and_byte_orders(tmp_path, interleave, order):
    header = write_envi(tmp_path / "c.hdr", REF, interleave=interleave, dtype=order + "f4",
                        extra=wavelength_lines(GRID.wavelengths_nm))
    cube = read_cube(header, GRID)
    assert memory_mapped(cube.stored) and cube.stored.shape == (H, W, GRID.size)
    np.testing.assert_array_equal(cube.to_array(), REF)


@pytest.mark.parametrize("dtype, values, scale", [
    ("<f8", REF, None), (">f8", REF, None), ("<u2", COUNTS, SCALE), (">i2", COUNTS, SCALE),
    ("<i4", COUNTS, SCALE), ("<u4", COUNTS, SCALE), (">i8", COUNTS, SCALE), ("<u8", COUNTS, SCALE),
])
def test_envi_data_types_and_scale_factor(tmp_path, dtype, values, scale):
    extra = "" if scale is None else f"reflectance scale factor = {scale:g}\n"
    header = write_envi(tmp_path / "c.hdr", values, interleave="bip", dtype=dtype, offset=0, extra=extra)
    np.testing.assert_array_equal(read_cube(header, GRID).to_array(), REF)


def test_envi_uint8_and_header_offset(tmp_path):
    small = COUNTS % 256
    header = write_envi(tmp_path / "c.hdr", small, interleave="bil", dtype="u1", offset=1234,
                        extra="reflectance scale factor = 255\n")
    np.testing.assert_array_equal(read_cube(header, GRID).to_array(), small / 255.0)


def test_envi_named_by_its_binary(tmp_path):
    # cube.img.hdr beside cube.img, and a binary with no extension beside its .hdr
    write_envi(tmp_path / "cube.img.hdr", REF, binary=tmp_path / "cube.img")
    np.testing.assert_array_equal(read_cube(tmp_path / "cube.img", GRID).to_array(), REF)
    write_envi(tmp_path / "raw.hdr", REF, binary=tmp_path / "raw")
    np.testing.assert_array_equal(read_cube(tmp_path / "raw.hdr", GRID).to_array(), REF)
    np.testing.assert_array_equal(read_cube(tmp_path / "raw", GRID).to_array(), REF)


@pytest.mark.parametrize("compress", [False, True])
def test_mat_round_trips(tmp_path, compress):
    scipy.io.savemat(tmp_path / "c.mat", {"rad": REF, "wavelengths": GRID.wavelengths_nm}, do_compression=compress)
    cube = read_cube(tmp_path / "c.mat", GRID)
    np.testing.assert_array_equal(cube.to_array(), REF)
    np.testing.assert_array_equal(cube.wavelengths_nm, GRID.wavelengths_nm)
    scipy.io.savemat(tmp_path / "bare.mat", {"cube": REF.astype(np.float32)})  # no wavelengths: the grid's
    np.testing.assert_array_equal(read_cube(tmp_path / "bare.mat", GRID).to_array(), REF)


def test_mat_with_several_cubes_needs_a_variable(tmp_path):
    scipy.io.savemat(tmp_path / "two.mat", {"a": REF, "b": REF * 0.5})
    with pytest.raises(CamsimError, match="several 3-D variables"):
        read_cube(tmp_path / "two.mat", GRID)
    np.testing.assert_array_equal(read_cube(tmp_path / "two.mat", GRID, variable="b").to_array(), REF * 0.5)


def test_size_from_the_header_alone(tmp_path):
    np.save(tmp_path / "c.npy", REF)
    write_envi(tmp_path / "c.hdr", REF)
    scipy.io.savemat(tmp_path / "c.mat", {"cube": REF})
    for name in ("c.npy", "c.hdr", "c.img", "c.mat"):
        assert cube_size(tmp_path / name) == (W, H)


def test_blocks_cover_the_cube(tmp_path, monkeypatch):
    # blocks of 7 rows of W × N float64; the last one short (30 = 4 × 7 + 2)
    monkeypatch.setattr(cube_files, "BLOCK_BYTES", 7 * W * GRID.size * 8)
    header = write_envi(tmp_path / "c.hdr", REF, interleave="bsq", dtype=">f4")
    cube = read_cube(header, GRID)
    assert cube.block_rows == 7
    starts = [start for start, _ in cube.blocks()]
    assert starts == [0, 7, 14, 21, 28]
    np.testing.assert_array_equal(cube.to_array(), REF)
    bad = REF.copy()
    bad[23, 5, 60] = np.nan  # in the fourth block
    header = write_envi(tmp_path / "c.hdr", bad, interleave="bsq", dtype=">f4")
    with pytest.raises(CamsimError, match="NaN or infinite values .first in row 23"):
        read_cube(header, GRID)


# --- wavelengths and resampling ------------------------------------------------------------------------------------

def colour_resampled(cube, wavelengths, grid):
    """Every pixel resampled to ``grid`` by colour-science's LinearInterpolator, one pixel at a time."""
    colour = import_colour()
    out = np.empty(cube.shape[:2] + (grid.size,))
    for i in range(cube.shape[0]):
        for j in range(cube.shape[1]):
            out[i, j] = colour.LinearInterpolator(wavelengths, cube[i, j])(grid.wavelengths_nm)
    return out


@pytest.fixture(scope="module")
def expected31():
    return colour_resampled(REF31, WL31, GRID31)


def test_31_band_cube_resampled_as_colour_science_does(tmp_path, expected31):
    header = write_envi(tmp_path / "c.hdr", REF31, dtype="<f8", extra=wavelength_lines(WL31))
    np.save(tmp_path / "c.npy", REF31)
    scipy.io.savemat(tmp_path / "c.mat", {"cube": REF31, "bands": WL31[None, :]})
    for cube in (read_cube(header, GRID31), read_cube(tmp_path / "c.npy", GRID31, wavelengths_nm=WL31),
                 read_cube(tmp_path / "c.mat", GRID31)):
        assert cube.resample is not None and cube.mapped is None
        np.testing.assert_array_equal(cube.wavelengths_nm, WL31)
        np.testing.assert_allclose(cube.to_array(), expected31, rtol=1e-12, atol=1e-15)


@pytest.mark.parametrize("units", ["Micrometers", "um", "µm", "micrometres"])
def test_micrometre_wavelengths(tmp_path, units, expected31):
    header = write_envi(tmp_path / "c.hdr", REF31, dtype="<f8", extra=wavelength_lines(WL31 / 1000.0, units))
    cube = read_cube(header, GRID31)
    np.testing.assert_allclose(cube.wavelengths_nm, WL31, rtol=1e-12)
    np.testing.assert_allclose(cube.to_array(), expected31, rtol=1e-9, atol=1e-12)


def test_micrometres_without_units_are_named(tmp_path):
    header = write_envi(tmp_path / "c.hdr", REF31, extra=f"wavelength = {{{', '.join(map(str, WL31 / 1000))}}}\n")
    with pytest.raises(CamsimError, match="micrometres"):
        read_cube(header, GRID31)


def test_cube_on_the_grid_is_not_resampled(tmp_path):
    header = write_envi(tmp_path / "c.hdr", REF, extra=wavelength_lines(GRID.wavelengths_nm / 1000, "um"))
    cube = read_cube(header, GRID)
    assert cube.resample is None and cube.mapped is not None
    np.testing.assert_array_equal(cube.to_array(), REF)


# --- through the command line ----------------------------------------------------------------------------------

def cube_scene(tmp_path, name, path, extra="", spectral=""):
    scene = tmp_path / f"{name}.toml"
    scene.write_text(f'name = "cube"\n{spectral}[cube]\npath = "{path}"\n{extra}\n[light]\nilluminants = ["D65"]\n')
    return str(scene)


def render_dng(tmp_path, name, path, extra="", spectral=""):
    out = tmp_path / f"out_{name}"
    assert main(["render", cube_scene(tmp_path, name, path, extra, spectral), "--seed", "5", "--out", str(out),
                 "-q"]) == 0
    (dng,) = out.glob("*.dng")
    return dng.read_bytes()


def test_every_format_renders_the_same_frame(tmp_path):
    np.save(tmp_path / "c.npy", REF)
    write_envi(tmp_path / "f4.hdr", REF, interleave="bsq", dtype=">f4")
    write_envi(tmp_path / "u2.hdr", COUNTS, interleave="bip", dtype="<u2", offset=64,
               extra=f"reflectance scale factor = {SCALE:g}\n" + wavelength_lines(GRID.wavelengths_nm / 1000, "um"))
    scipy.io.savemat(tmp_path / "c.mat", {"cube": REF, "wl": GRID.wavelengths_nm}, do_compression=True)
    frames = {path: render_dng(tmp_path, path.replace(".", "_"), path)
              for path in ("c.npy", "f4.hdr", "f4.img", "u2.hdr", "c.mat")}
    assert len(set(frames.values())) == 1
    np.save(tmp_path / "half.npy", REF * 0.5)  # and a different cube gives a different frame
    assert render_dng(tmp_path, "half", "half.npy") != frames["c.npy"]


def test_31_band_cube_renders_the_same_from_mat_and_npy(tmp_path):
    # the .mat file's 'lambda' vector and the [cube] table's wavelengths_nm for a .npy file lead to the same frame
    scipy.io.savemat(tmp_path / "c31.mat", {"cube": REF31, "lambda": WL31})
    np.save(tmp_path / "c31.npy", REF31)
    spectral = "[spectral]\nstart_nm = 400\nend_nm = 700\nstep_nm = 4\n"
    a = render_dng(tmp_path, "mat", "c31.mat", spectral=spectral)
    b = render_dng(tmp_path, "npy", "c31.npy", spectral=spectral, extra=f"wavelengths_nm = {WL31.tolist()}")
    assert a == b


def _mat_v73(path):
    """A MATLAB v7.3 file's start, as MATLAB writes it: the 128-byte MAT header (version 0x0200), then HDF5."""
    text = b"MATLAB 7.3 MAT-file, Platform: GLNXA64, Created on: Mon Jan  1 00:00:00 2024 HDF5 schema 1.00 ."
    head = text.ljust(116, b" ") + b"\x00" * 8 + b"\x00\x02" + b"IM"
    path.write_bytes(head.ljust(512, b"\x00") + b"\x89HDF\r\n\x1a\n" + b"\x00" * 512)


def _bad_cases(tmp_path):
    write_envi(tmp_path / "trunc.hdr", REF)
    data = (tmp_path / "trunc.img").read_bytes()
    (tmp_path / "trunc.img").write_bytes(data[:-100])
    write_envi(tmp_path / "complex.hdr", REF)
    text = (tmp_path / "complex.hdr").read_text().replace("data type = 4", "data type = 6")
    (tmp_path / "complex.hdr").write_text(text)
    _mat_v73(tmp_path / "v73.mat")
    write_envi(tmp_path / "c31.hdr", REF31, extra=wavelength_lines(WL31))
    nan = REF.copy()
    nan[4, 4, 4] = np.inf
    write_envi(tmp_path / "nan.hdr", nan)
    np.save(tmp_path / "neg.npy", REF - 0.5)
    scipy.io.savemat(tmp_path / "two.mat", {"a": REF, "b": REF})
    write_envi(tmp_path / "ignore.hdr", REF, extra=f"data ignore value = {REF[3, 2, 1]!r}\n")
    return {
        "missing.hdr": "cube file not found",
        "missing.npy": "cube file not found",
        "missing.mat": "cube file not found",
        "trunc.hdr": "is truncated",
        "complex.hdr": "data type 6 is not supported",
        "v73.mat": "MATLAB v7.3 (HDF5)",
        "c31.hdr": "covers 400–700 nm but the scene's wavelength grid needs 380–780 nm",
        "nan.hdr": "NaN or infinite",
        "neg.npy": "negative values",
        "two.mat": "several 3-D variables (a, b)",
        "ignore.hdr": "data ignore value",
        "cube.tif": "unknown format '.tif'",
    }


def test_bad_cubes_give_one_line_exit_2_and_no_output(tmp_path, capsys):
    cases = _bad_cases(tmp_path)
    (tmp_path / "cube.tif").write_bytes(b"II*\x00")
    for path, message in cases.items():
        out = tmp_path / f"out_{path.replace('.', '_')}"
        assert main(["render", cube_scene(tmp_path, "bad", path), "--out", str(out)]) == 2, path
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and err.startswith("camsim: error: ") and message in err, (path, err)
        assert not out.exists() or not any(out.iterdir()), path


def test_bad_cubes_are_errors(tmp_path):
    cases = _bad_cases(tmp_path)
    for path, message in cases.items():
        if path == "cube.tif":
            continue
        with pytest.raises(CamsimError) as info:
            read_cube(tmp_path / path, GRID)
        assert message in str(info.value), path


def test_scene_file_keys(tmp_path, capsys):
    np.save(tmp_path / "c31.npy", REF31)
    out = tmp_path / "o"
    scene = cube_scene(tmp_path, "k", "c31.npy", extra='wavelengths_nm = "400-700"')
    assert main(["render", scene, "--out", str(out)]) == 2
    assert "wavelengths_nm must be of type list" in capsys.readouterr().err
    scene = cube_scene(tmp_path, "k", "c31.npy", extra='variable = "cube"')
    assert main(["render", scene, "--out", str(out)]) == 2
    assert "variable applies to .mat cubes only" in capsys.readouterr().err
    assert not out.exists()


# --- the cube as factored spectra: each pixel its own spectrum, read block by block ------------------------------

def test_cube_source_rows_are_each_pixels_resampled_spectrum(tmp_path, monkeypatch, expected31):
    """A [cube] scene's spectra are factored on the file (camsim.io.cube_files.CubeRows): rows, products and the
    expected electrons agree with colour-science's per-pixel resampling (``expected31``), computed independently,
    with blocks of 7 rows and an ENVI scale factor (integer codes)."""
    from camsim.scene.sources import CubeSource

    monkeypatch.setattr(cube_files, "BLOCK_BYTES", 7 * W * WL31.size * 8)
    codes = np.rint(REF31 * SCALE)
    header = write_envi(tmp_path / "c.hdr", codes, interleave="bil", dtype="<u2",
                        extra=wavelength_lines(WL31) + f"reflectance scale factor = {SCALE:g}\n")
    expected = colour_resampled(codes / SCALE, WL31, GRID31).reshape(-1, GRID31.size)
    source = CubeSource(path=header).spectra(GRID31, W, H)
    spectra = source.spectra
    assert spectra.shape == (H * W, GRID31.size)
    assert not isinstance(spectra.coefficients, np.ndarray)  # never materialised
    pixels = np.array([0, 1, W, 7 * W + 3, H * W - 1])
    np.testing.assert_allclose(spectra[pixels], expected[pixels], rtol=1e-12)
    np.testing.assert_allclose(spectra[3:5], expected[3:5], rtol=1e-12)
    weights = np.random.default_rng(3).uniform(0, 1, size=(GRID31.size, 3))
    np.testing.assert_allclose(spectra @ weights, expected @ weights, rtol=1e-12)
    y, x = 17, 23
    assert source.labels[y, x] == y * W + x


# --- headers: sizes and bands checked before the data; what the header says for the memory estimate ------------

@pytest.mark.parametrize("fmt", ["npy", "envi", "mat"])
def test_a_header_claiming_more_bands_than_the_limit_is_refused_before_the_data(tmp_path, capsys, fmt):
    """A cube of 1 × 2 pixels and MAX_BANDS + 1 bands (a few kilobytes): refused from the header or the MAT file's
    directory, for every format, before it is mapped or loaded (a cube off the grid is resampled through a B × B
    identity: a million bands would ask for terabytes)."""
    bands = cube_files.MAX_BANDS + 1
    cube = np.zeros((1, 2, bands), np.float32)
    path = {"npy": tmp_path / "c.npy", "envi": tmp_path / "c.hdr", "mat": tmp_path / "c.mat"}[fmt]
    if fmt == "npy":
        np.save(path, cube)
    elif fmt == "envi":
        write_envi(path, cube)
    else:
        scipy.io.savemat(path, {"cube": cube})
    with pytest.raises(CamsimError, match=f"has {bands} bands, over camsim's limit of {cube_files.MAX_BANDS}"):
        read_cube(path, GRID)
    assert main(["render", cube_scene(tmp_path, "bands", path.name), "--out", str(tmp_path / "out"), "-q"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("camsim: error: ") and "bands, over camsim's limit" in err, err


def test_an_envi_header_over_its_size_limit_is_refused_unread(tmp_path):
    path = tmp_path / "c.hdr"
    with open(path, "wb") as handle:  # sparse: no disk taken
        handle.write(b"ENVI\n")
        handle.truncate(cube_files.MAX_ENVI_HEADER_BYTES + 1)
    (tmp_path / "c.img").write_bytes(bytes(16))
    with pytest.raises(CamsimError, match="over the limit of 16 MB for a header of an ENVI cube"):
        read_cube(path, GRID)


def test_cube_header_says_size_value_size_and_storage(tmp_path):
    from camsim.io.cube_files import cube_header

    np.save(tmp_path / "c.npy", REF.astype(np.float32))
    write_envi(tmp_path / "e.hdr", REF, dtype="<u2")
    scipy.io.savemat(tmp_path / "m.mat", {"cube": REF.astype(np.float32), "wavelengths": np.arange(GRID.size)})
    npy, envi, mat = (cube_header(tmp_path / name) for name in ("c.npy", "e.hdr", "m.mat"))
    assert (npy.width, npy.height, npy.bands, npy.itemsize, npy.mapped) == (W, H, GRID.size, 4, True)
    assert (envi.itemsize, envi.mapped) == (2, True) and envi.data_bytes == W * H * GRID.size * 2
    assert (mat.width, mat.height, mat.bands, mat.itemsize, mat.mapped) == (W, H, GRID.size, 4, False)
