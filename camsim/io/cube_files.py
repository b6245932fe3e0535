"""Hyperspectral cube files: ``.npy``, ENVI (``.hdr`` + binary) and MATLAB ``.mat``, read onto the scene grid.

:func:`read_cube` reads a cube file of any supported format (chosen by its extension, :data:`CUBE_READERS`) into a
:class:`CubeData`: the cube as stored (H × W × B, memory-mapped for ``.npy`` and ENVI), its B source wavelengths,
and the linear map that resamples it to the scene's N-bin grid. Values come out block by block
(:meth:`CubeData.rows`, :meth:`CubeData.blocks`): each block is converted to float64, divided by the file's scale
factor and resampled, so reading a cube needs memory for a few blocks (:data:`BLOCK_BYTES` each), not the cube.

Formats
-------
``.npy``
    ``np.load(mmap_mode="r")``: never copied whole. Its wavelengths are the scene grid's, unless the scene's
    ``[cube]`` table gives ``wavelengths_nm``.
ENVI (``.hdr``, or the binary — ``.img``, ``.dat``, ``.raw``, ``.bin``, ``.bsq``, ``.bil``, ``.bip`` — with a
``.hdr`` beside it)
    The header's ``samples``, ``lines``, ``bands``, ``data type`` (1, 2, 3, 4, 5, 12, 13, 14, 15), ``interleave``
    (bsq, bil, bip), ``byte order``, ``header offset``, ``wavelength`` and ``wavelength units`` (nanometres,
    micrometres, or none: nanometres), ``reflectance scale factor`` (values are divided by it) and
    ``data ignore value``. The binary is a ``np.memmap`` of the file's dtype and byte order, transposed to
    H × W × B as a view (no copy). A file whose size is not the header offset plus the data is refused (truncated,
    or a header that does not describe it). A pixel equal to the ``data ignore value`` is refused, not masked: a
    masked pixel would have to be given some spectrum, which the file does not have.
``.mat`` (MATLAB v4, v5, v7, through ``scipy.io.loadmat``)
    The cube is the file's 3-D array (H × W × B, bands last; with several, the ``[cube]`` table's ``variable``
    names it); the wavelengths are ``wavelengths_nm`` from the table, else a vector of length B named
    ``wavelengths``, ``wavelength``, ``wavelengths_nm``, ``bands``, ``wl`` or ``lambda`` (any case), else the scene
    grid's. The cube variable is loaded whole (a compressed MAT file cannot be mapped). MATLAB v7.3 files are HDF5,
    which camsim does not read: save with ``-v7``, or convert the cube to ``.npy``.

Wavelengths and resampling
--------------------------
A cube whose wavelengths are the scene grid's is used as it is. Any other cube is resampled to the grid by linear
interpolation with colour-science's ``LinearInterpolator`` (as every spectrum in camsim is,
:func:`camsim.light.spectra.align_to_grid`): being linear in the values, the interpolation of every pixel is one
B → N matrix, built once from colour-science's interpolation of the B unit vectors and applied to each block. The
cube must cover the grid: camsim does not extrapolate (:mod:`camsim.light.spectra`).

Values must be finite and non-negative (checked block by block when the cube is read).

Every file is checked to be a regular file before a library opens it (:mod:`camsim.core.input_files`: a FIFO, a
device, a directory or a path with a NUL byte is one line), and every header's size — ``.npy`` shape, ENVI
``samples``, ``lines`` and ``bands``, the MAT file's directory — against
:data:`camsim.core.pixel_limit.MAX_PIXELS` and :data:`MAX_BANDS` before any data is mapped or loaded.
"""

from __future__ import annotations

import mmap
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from camsim.core.errors import CamsimError
from camsim.core.input_files import check_input, open_input, read_input
from camsim.light.spectra import WavelengthGrid, align_to_grid

#: Bytes of float64 values in one block (its B source bands or N grid bins, whichever is more): 32 MiB.
BLOCK_BYTES = 32 * 2**20

#: The most bands a cube may have. Hyperspectral imagers record a few hundred (AVIRIS 224, HySpex 400 to 500); a
#: cube off the scene's grid is resampled through a B × B identity (:func:`read_cube`), so a header claiming a
#: million bands would ask for terabytes before a value is read. Unit: bands.
MAX_BANDS = 4096
#: The largest ENVI header read (the text before the binary; a wavelength list of :data:`MAX_BANDS` values is tens
#: of kilobytes). Unit: bytes.
MAX_ENVI_HEADER_BYTES = 16_000_000

#: ENVI ``data type`` codes camsim reads, as numpy dtypes (byte order set by the header).
ENVI_DATA_TYPES = {1: "u1", 2: "i2", 3: "i4", 4: "f4", 5: "f8", 12: "u2", 13: "u4", 14: "i8", 15: "u8"}

#: Extensions of ENVI binaries read with the ``.hdr`` beside them.
ENVI_BINARY_EXTENSIONS = (".img", ".dat", ".raw", ".bin", ".bsq", ".bil", ".bip")

#: Names under which a MAT file's wavelength vector is looked for (compared case-insensitively).
MAT_WAVELENGTH_NAMES = ("wavelengths", "wavelength", "wavelengths_nm", "bands", "wl", "lambda")

_NM_UNITS = {"nm", "nanometer", "nanometers", "nanometre", "nanometres"}
_UM_UNITS = {"um", "µm", "μm", "micrometer", "micrometers", "micrometre", "micrometres", "micron", "microns"}
_NO_UNITS = {"", "unknown", "none"}


@dataclass(frozen=True)
class CubeData:
    """A hyperspectral cube read from a file, on its way to the scene's wavelength grid.

    Attributes
    ----------
    path : pathlib.Path
        The file read.
    stored : numpy.ndarray, shape (H, W, B)
        The cube as stored, in the file's dtype and byte order: a view of a memory map for ``.npy`` and ENVI files
        (nothing is read until it is indexed), an array in memory for ``.mat`` files.
    wavelengths_nm : numpy.ndarray, shape (B,)
        The cube's own wavelengths. Unit: nm.
    grid : WavelengthGrid
        The scene's grid (N bins).
    scale : float
        The stored values are divided by it (an ENVI ``reflectance scale factor``; else 1).
    resample : numpy.ndarray or None, shape (N, B)
        The linear interpolation from the cube's wavelengths to the grid; None when they are the grid's.
    """

    path: Path
    stored: np.ndarray
    wavelengths_nm: np.ndarray
    grid: WavelengthGrid
    scale: float = 1.0
    resample: np.ndarray | None = None
    _mapping: mmap.mmap | None = field(default=None, repr=False, compare=False)

    @property
    def shape(self) -> tuple[int, int, int]:
        """(H, W, N): the cube on the scene grid."""
        return self.stored.shape[0], self.stored.shape[1], self.grid.size

    @property
    def mapped(self) -> np.ndarray | None:
        """The H × W × N cube as the memory-mapped file itself (float, on the grid, unscaled), else None."""
        if (self._mapping is not None and self.resample is None and self.scale == 1.0
                and self.stored.dtype.kind == "f"):
            return self.stored
        return None

    @property
    def block_rows(self) -> int:
        """Rows per block: as many as keep a block's float64 values within :data:`BLOCK_BYTES` (at least 1)."""
        height, width, bands = self.stored.shape
        return max(1, BLOCK_BYTES // (8 * max(1, width) * max(bands, self.grid.size)))

    def rows(self, start: int, stop: int) -> np.ndarray:
        """Rows ``start:stop`` on the scene grid.

        Returns
        -------
        numpy.ndarray, shape (stop − start, W, N), float64
            Reflectance (unitless) or radiance (the file's unit), a new array.
        """
        block = np.array(self.stored[start:stop], dtype=np.float64)  # a copy: converted, byte-swapped
        self._release()
        if self.scale != 1.0:
            block /= self.scale
        if self.resample is not None:
            block = block @ self.resample.T
        return block

    def blocks(self):
        """Yield ``(start, rows)`` over the whole cube, ``rows`` as from :meth:`rows`, :attr:`block_rows` at a time."""
        step = self.block_rows
        for start in range(0, self.stored.shape[0], step):
            yield start, self.rows(start, min(start + step, self.stored.shape[0]))

    def to_array(self) -> np.ndarray:
        """The whole cube on the scene grid, shape (H, W, N), float64 (materialised: H · W · N · 8 bytes)."""
        out = np.empty(self.shape)
        for start, block in self.blocks():
            out[start:start + block.shape[0]] = block
        return out

    def check(self, ignore_value=None) -> None:
        """Check every stored value, block by block: finite, non-negative, and none equal to ``ignore_value``.

        Raises
        ------
        CamsimError
            Naming the file and the first offending row.
        """
        step = self.block_rows
        for start in range(0, self.stored.shape[0], step):
            self._check_block(start, self.stored[start:start + step], ignore_value)
            self._release()

    def _check_block(self, start: int, block: np.ndarray, ignore_value) -> None:
        """Check one block of stored values (rows ``start:``) as :meth:`check` does."""
        if block.dtype.kind == "f" and not np.all(np.isfinite(block)):
            row = start + int(np.argwhere(~np.isfinite(block))[0][0])
            raise CamsimError(f"cube {self.path} contains NaN or infinite values (first in row {row})")
        if block.dtype.kind in "fi" and np.any(block < 0):
            row = start + int(np.argwhere(block < 0)[0][0])
            raise CamsimError(f"cube {self.path} has negative values (first in row {row}, min {block.min():.4g})")
        if ignore_value is not None and np.any(block == ignore_value):
            row = start + int(np.argwhere(block == ignore_value)[0][0])
            raise CamsimError(
                f"cube {self.path} has pixels equal to its data ignore value {ignore_value:g} (first in row "
                f"{row}): camsim does not invent spectra for them; fill them in or crop them out"
            )

    def _release(self) -> None:
        """Drop the mapped pages from this process (the page cache keeps them), so reading the cube block by block
        does not leave it all resident."""
        if self._mapping is not None and hasattr(mmap, "MADV_DONTNEED"):
            self._mapping.madvise(mmap.MADV_DONTNEED)


@dataclass(frozen=True, eq=False)
class CubeRows:
    """A cube's pixels as the K = H · W coefficient rows of :class:`camsim.light.rates.FactoredSpectra` (the
    :class:`camsim.light.rates.CoefficientRows` protocol): row p is pixel
    (p // W, p % W), its B stored values as float64 (unscaled: the scale and the resampling to the grid are the
    factored spectra's basis, :meth:`basis`). Read block by block from the file, the mapped pages dropped after
    each block: the cube is never copied whole.
    """

    cube: CubeData

    @property
    def shape(self) -> tuple[int, int]:
        height, width, bands = self.cube.stored.shape
        return height * width, bands

    def basis(self) -> np.ndarray:
        """(B, N): band b's contribution to each grid bin, the resampling divided by the file's scale factor."""
        cube = self.cube
        resample = np.eye(cube.grid.size) if cube.resample is None else cube.resample.T
        return resample / cube.scale

    def blocks(self):
        stored, width = self.cube.stored, self.cube.stored.shape[1]
        step = self.cube.block_rows
        for start in range(0, stored.shape[0], step):
            block = np.array(stored[start:start + step], dtype=np.float64)
            self.cube._release()
            yield start * width, block.reshape(-1, block.shape[2])

    def rows(self, index) -> np.ndarray:
        height, width, bands = self.cube.stored.shape
        if isinstance(index, slice):
            index = np.arange(height * width)[index]
        flat = np.asarray(index)
        if flat.size and (flat.min() < -height * width or flat.max() >= height * width):
            raise IndexError(f"pixel index out of range for a {width} × {height} cube")
        y, x = np.divmod(flat % (height * width), width)
        rows = np.array(self.cube.stored[y, x], dtype=np.float64)
        self.cube._release()
        return rows

    def all_finite(self) -> bool:
        """True: :func:`read_cube` checked every value (finite, non-negative) when it read the file."""
        return True


@dataclass(frozen=True)
class _Stored:
    """What a format reader found: the H × W × B array as stored, and what the file says about it."""

    array: np.ndarray
    wavelengths_nm: np.ndarray | None = None
    scale: float = 1.0
    ignore_value: float | None = None
    mapping: mmap.mmap | None = None


# --- .npy -----------------------------------------------------------------------------------------------------------

def read_npy(path: Path, *, variable: str | None = None) -> _Stored:
    """A ``.npy`` cube, H × W × B, memory-mapped (``np.load(mmap_mode="r")``); it carries no wavelengths."""
    _no_variable(path, variable)
    _check_npy_header(path)
    try:
        array = np.load(path, mmap_mode="r", allow_pickle=False)
    except (OSError, ValueError, EOFError) as exc:
        raise CamsimError(f"cannot read cube file {path}: {exc}") from None
    return _Stored(_check_array(array, path), mapping=getattr(array, "_mmap", None))


def _check_npy_header(path: Path) -> None:
    """Check the (H, W) of a ``.npy`` file's header against :data:`camsim.core.pixel_limit.MAX_PIXELS` and its bands
    against :data:`MAX_BANDS` before the file is mapped (a header may claim any shape:
    :func:`camsim.core.npy_header.npy_header`, which also refuses a path that is not a regular file); other problems
    are left to ``np.load``, which reports them."""
    from camsim.core.npy_header import npy_header

    npy_header(path, "cube file",
               check_shape=lambda shape: _check_size(shape[1], shape[0], path, shape[2]) if len(shape) == 3 else None)


def _check_size(width, height, path: Path, bands=None) -> None:
    """Refuse a cube whose header claims more than :data:`camsim.core.pixel_limit.MAX_PIXELS` pixels or more than
    :data:`MAX_BANDS` bands, before its data is read."""
    from camsim.core.pixel_limit import check_pixel_count

    check_pixel_count(int(width), int(height), f"cube {path}")
    if bands is not None and int(bands) > MAX_BANDS:
        raise CamsimError(f"cube {path} has {int(bands)} bands, over camsim's limit of {MAX_BANDS} (hyperspectral "
                          "cameras record a few hundred)")


# --- ENVI -----------------------------------------------------------------------------------------------------------

def read_envi(path: Path, *, variable: str | None = None) -> _Stored:
    """An ENVI cube: the header (``path`` itself or the ``.hdr`` beside it) and its binary, memory-mapped."""
    _no_variable(path, variable)
    header_path, binary_path = envi_files(path)
    header = parse_envi_header(header_path)
    where = f"ENVI header {header_path}"

    def integer(key, default=None, minimum=0):
        if key not in header:
            if default is None:
                raise CamsimError(f"{where} has no '{key}'")
            return default
        try:
            value = int(header[key])
        except (TypeError, ValueError):
            raise CamsimError(f"{where}: '{key}' must be an integer, got {header[key]!r}") from None
        if value < minimum:
            raise CamsimError(f"{where}: '{key}' must be at least {minimum}, got {value}")
        return value

    samples, lines, bands = integer("samples", minimum=1), integer("lines", minimum=1), integer("bands", minimum=1)
    _check_size(samples, lines, path, bands)
    code = integer("data type")
    if code not in ENVI_DATA_TYPES:
        raise CamsimError(f"{where}: data type {code} is not supported (camsim reads "
                          f"{', '.join(map(str, ENVI_DATA_TYPES))}: integers and real floats, not complex)")
    order = integer("byte order", default=0)
    if order not in (0, 1):
        raise CamsimError(f"{where}: byte order must be 0 (little-endian) or 1 (big-endian), got {order}")
    dtype = np.dtype(("<" if order == 0 else ">") + ENVI_DATA_TYPES[code])
    offset = integer("header offset", default=0)
    interleave = str(header.get("interleave", "")).strip().lower()
    stored_shapes = {"bsq": (bands, lines, samples), "bil": (lines, bands, samples), "bip": (lines, samples, bands)}
    if interleave not in stored_shapes:
        raise CamsimError(f"{where}: interleave must be bsq, bil or bip, got {interleave or 'nothing'!r}")
    for key in ("data gain values", "data offset values"):
        values = _numbers(header, key, where)
        trivial = 1.0 if key == "data gain values" else 0.0
        if values is not None and np.any(values != trivial):
            raise CamsimError(f"{where}: '{key}' is not supported (camsim reads the values as stored); "
                              "apply them and write the calibrated cube")

    expected = offset + samples * lines * bands * dtype.itemsize
    with open_input(binary_path, "cube file") as handle:  # a regular file: a FIFO or a device cannot be mapped
        size = os.fstat(handle.fileno()).st_size
    if size != expected:
        what = "is truncated" if size < expected else "is longer than its header describes"
        raise CamsimError(
            f"ENVI binary {binary_path} {what}: {size} bytes, but {samples} samples × {lines} lines × {bands} bands "
            f"of {dtype.itemsize}-byte values after a {offset}-byte offset need {expected}"
        )
    try:
        memory = np.memmap(binary_path, dtype=dtype, mode="r", offset=offset, shape=stored_shapes[interleave])
    except (OSError, ValueError) as exc:
        raise CamsimError(f"cannot read cube file {binary_path}: {exc}") from None
    array = {"bsq": memory.transpose(1, 2, 0), "bil": memory.transpose(0, 2, 1), "bip": memory}[interleave]

    wavelengths = _numbers(header, "wavelength", where)
    if wavelengths is not None:
        if wavelengths.size != bands:
            raise CamsimError(f"{where}: {wavelengths.size} wavelengths for {bands} bands")
        units = str(header.get("wavelength units", "")).strip().lower()
        if units in _UM_UNITS:
            wavelengths = wavelengths * 1000.0
        elif units not in _NM_UNITS | _NO_UNITS:
            raise CamsimError(f"{where}: wavelength units {header['wavelength units']!r} are not a length camsim "
                              "reads (nanometers or micrometers)")
    scale = _numbers(header, "reflectance scale factor", where)
    if scale is not None and (scale.size != 1 or not np.isfinite(scale[0]) or scale[0] <= 0):
        raise CamsimError(f"{where}: reflectance scale factor must be one positive number, got {scale.tolist()}")
    ignore = _numbers(header, "data ignore value", where)
    if ignore is not None and ignore.size != 1:
        raise CamsimError(f"{where}: data ignore value must be one number, got {ignore.tolist()}")
    return _Stored(array, wavelengths, 1.0 if scale is None else float(scale[0]),
                   None if ignore is None else float(ignore[0]), memory._mmap)


def envi_files(path: Path) -> tuple[Path, Path]:
    """(header, binary) of an ENVI cube named by either file.

    The header of ``cube.img`` is ``cube.hdr`` or ``cube.img.hdr``; the binary of ``cube.hdr`` is ``cube`` or
    ``cube`` with one of :data:`ENVI_BINARY_EXTENSIONS` (either case).
    """
    if path.suffix.lower() == ".hdr":
        stem = path.with_suffix("")
        candidates = [stem] + [stem.with_name(stem.name + ext) for ext in ENVI_BINARY_EXTENSIONS]
        candidates += [stem.with_name(stem.name + ext.upper()) for ext in ENVI_BINARY_EXTENSIONS]
        check_input(path, "cube file")
        for candidate in candidates:
            if candidate.is_file():
                return path, candidate
        raise CamsimError(f"ENVI header {path} has no binary beside it (looked for {stem.name} and {stem.name}"
                          f"{{{','.join(ENVI_BINARY_EXTENSIONS)}}})")
    check_input(path, "cube file")
    for header in (path.with_suffix(".hdr"), path.with_name(path.name + ".hdr")):
        if header.is_file():
            return header, path
    raise CamsimError(f"ENVI binary {path} has no header beside it ({path.with_suffix('.hdr').name} or "
                      f"{path.name}.hdr)")


def parse_envi_header(path: Path) -> dict:
    """The fields of an ENVI header: lower-case names to their text (a ``{…}`` list as a list of strings).

    Raises
    ------
    CamsimError
        If the file is missing or not a regular file of at most :data:`MAX_ENVI_HEADER_BYTES`
        (:func:`camsim.core.input_files.read_input`), does not start with ``ENVI``, or has an unclosed ``{``.
    """
    raw = read_input(path, "header of an ENVI cube", MAX_ENVI_HEADER_BYTES)
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError:
        text = raw.decode("latin-1")
    lines = text.splitlines()
    if not lines or lines[0].strip() != "ENVI":
        raise CamsimError(f"{path} is not an ENVI header (its first line is not 'ENVI')")
    fields, i = {}, 1
    while i < len(lines):
        line = lines[i]
        i += 1
        if "=" not in line:
            continue
        key, value = line.split("=", 1)
        key, value = key.strip().lower(), value.strip()
        if value.startswith("{"):
            while "}" not in value and i < len(lines):
                value += " " + lines[i].strip()
                i += 1
            if "}" not in value:
                raise CamsimError(f"ENVI header {path}: the value of '{key}' has no closing '}}'")
            inner = value[1:value.index("}")]
            value = [item.strip() for item in inner.split(",")] if key != "description" else inner.strip()
        fields[key] = value
    return fields


def _numbers(header: dict, key: str, where: str) -> np.ndarray | None:
    """The header's ``key`` as an array of floats (one number or a ``{…}`` list), None when absent."""
    if key not in header:
        return None
    items = header[key] if isinstance(header[key], list) else [header[key]]
    try:
        return np.array([float(item) for item in items if item != ""], dtype=np.float64)
    except ValueError:
        raise CamsimError(f"{where}: '{key}' must be numbers, got {header[key]!r}") from None


# --- MATLAB -----------------------------------------------------------------------------------------------------------

def read_mat(path: Path, *, variable: str | None = None) -> _Stored:
    """A MATLAB v4 – v7 cube through ``scipy.io.loadmat``: the 3-D variable (``variable`` if given), loaded whole,
    and the wavelength vector beside it, if any."""
    import scipy.io

    cube_name, wavelength_name, _ = _mat_variables(path, variable)
    names = [cube_name] + ([wavelength_name] if wavelength_name else [])
    try:
        contents = scipy.io.loadmat(path, variable_names=names)
    except (OSError, ValueError, TypeError, NotImplementedError) as exc:
        raise CamsimError(f"cannot read cube file {path}: {exc}") from None
    array = _check_array(np.asarray(contents[cube_name]), path, f"variable {cube_name!r}")
    wavelengths = None
    if wavelength_name:
        wavelengths = np.asarray(contents[wavelength_name], dtype=np.float64).ravel()
    return _Stored(array, wavelengths)


def _mat_variables(path: Path, variable: str | None):
    """(cube variable, wavelength vector name or None, cube shape) of a MAT file, from its directory only."""
    import scipy.io
    from scipy.io.matlab import matfile_version

    check_input(path, "cube file")  # a regular file: scipy would block on a FIFO and read a device forever
    try:
        major, _ = matfile_version(str(path))
    except Exception as exc:  # noqa: BLE001 — scipy raises several types for a file that is not a MAT file
        raise CamsimError(f"cannot read cube file {path}: not a MATLAB file ({exc})") from None
    if major == 2:
        raise CamsimError(f"cube file {path} is a MATLAB v7.3 (HDF5) file, which camsim does not read: save it "
                          "with save(..., '-v7'), or install h5py and convert the cube to .npy")
    try:
        directory = scipy.io.whosmat(path)
    except (OSError, ValueError, TypeError, NotImplementedError) as exc:
        raise CamsimError(f"cannot read cube file {path}: {exc}") from None
    shapes = {name: tuple(shape) for name, shape, _ in directory}
    cubes = [name for name, shape in shapes.items() if len(shape) == 3]
    if variable is not None:
        if variable not in shapes:
            raise CamsimError(f"cube file {path} has no variable {variable!r} (it has {', '.join(shapes) or 'none'})")
        if len(shapes[variable]) != 3:
            raise CamsimError(f"variable {variable!r} of {path} is not H × W × N: its shape is {shapes[variable]}")
        cube = variable
    elif len(cubes) == 1:
        cube = cubes[0]
    elif not cubes:
        raise CamsimError(f"cube file {path} has no 3-D variable (H × W × N): it has "
                          + (", ".join(f"{n} {s}" for n, s in shapes.items()) or "no variables"))
    else:
        raise CamsimError(f"cube file {path} has several 3-D variables ({', '.join(cubes)}): name one with "
                          "variable = \"…\" in [cube]")
    _check_size(shapes[cube][1], shapes[cube][0], path, shapes[cube][2])
    bands = shapes[cube][2]
    wavelength = None
    wanted = {name.lower() for name in MAT_WAVELENGTH_NAMES}
    for name, shape in shapes.items():
        if name.lower() in wanted and name != cube and int(np.prod(shape)) == bands and max(shape) == bands:
            wavelength = name
            break
    return cube, wavelength, shapes[cube]


def mat_cube_shape(path: Path, *, variable: str | None = None) -> tuple[int, int, int]:
    """(H, W, B) of a MAT file's cube, from the file's directory without loading the data."""
    return _mat_variables(path, variable)[2]


# --- the registry and read_cube ----------------------------------------------------------------------------------

#: Cube readers by file extension (lower case).
CUBE_READERS = {".npy": read_npy, ".mat": read_mat, ".hdr": read_envi,
                **{ext: read_envi for ext in ENVI_BINARY_EXTENSIONS}}


def _reader(path: Path):
    reader = CUBE_READERS.get(path.suffix.lower())
    if reader is None and (path.with_suffix(".hdr").is_file() or path.with_name(path.name + ".hdr").is_file()):
        reader = read_envi  # an ENVI binary with another extension (or none), its header beside it
    if reader is None:
        raise CamsimError(f"cube file {path}: unknown format {path.suffix or '(no extension)'!r}; camsim reads "
                          f"{', '.join(sorted(CUBE_READERS))} (ENVI: a .hdr beside the binary)")
    return reader


@dataclass(frozen=True)
class CubeHeader:
    """What a cube file's header says about its data, before any is read.

    Attributes
    ----------
    width, height, bands : int
        The cube's size: pixels, and bands per pixel.
    itemsize : int
        Bytes of one stored value. Unit: bytes.
    mapped : bool
        Whether the data is memory-mapped from the file (``.npy``, ENVI: it takes address space, not memory) or
        loaded whole (``.mat``).
    """

    width: int
    height: int
    bands: int
    itemsize: int
    mapped: bool

    @property
    def data_bytes(self) -> int:
        """Bytes of the stored values: width × height × bands × itemsize. Unit: bytes."""
        return self.width * self.height * self.bands * self.itemsize


#: Bytes of a value of each MATLAB class, as ``scipy.io.whosmat`` names them (a v4 file's are all ``double``).
_MAT_ITEMSIZES = {"double": 8, "single": 4, "int8": 1, "uint8": 1, "int16": 2, "uint16": 2, "int32": 4,
                  "uint32": 4, "int64": 8, "uint64": 8, "logical": 1}


def cube_header(path, *, variable: str | None = None) -> CubeHeader:
    """The size, value size and storage of a cube file, from its header alone (no data read), checked as
    :func:`read_cube` checks it (:data:`camsim.core.pixel_limit.MAX_PIXELS`, :data:`MAX_BANDS`).

    Raises
    ------
    CamsimError
        For a missing, unreadable or malformed file.
    """
    import scipy.io

    path = Path(path)
    reader = _reader(path)
    if reader is read_mat:
        cube, _, (height, width, bands) = _mat_variables(path, variable)
        kind = {name: mat_class for name, _, mat_class in scipy.io.whosmat(path)}.get(cube, "double")
        return CubeHeader(int(width), int(height), int(bands), _MAT_ITEMSIZES.get(kind, 8), mapped=False)
    check_input(path, "cube file")
    array = reader(path, variable=variable).array
    height, width, bands = array.shape
    return CubeHeader(int(width), int(height), int(bands), int(array.dtype.itemsize), mapped=True)


def cube_size(path, *, variable: str | None = None) -> tuple[int, int]:
    """(W, H) of a cube file, from its header alone (no data read: :func:`cube_header`).

    Raises
    ------
    CamsimError
        For a missing, unreadable or malformed file.
    """
    header = cube_header(path, variable=variable)
    return header.width, header.height


def read_cube(path, grid: WavelengthGrid, *, wavelengths_nm=None, variable: str | None = None,
              check: bool = True) -> CubeData:
    """Read a hyperspectral cube file onto the scene's wavelength grid.

    Parameters
    ----------
    path : str or pathlib.Path
        A ``.npy``, ENVI (``.hdr`` or its binary) or ``.mat`` file; the format is chosen by the extension
        (:data:`CUBE_READERS`).
    grid : WavelengthGrid
        The scene's grid, N bins.
    wavelengths_nm : array_like, shape (B,), optional
        The cube's wavelengths in nm, overriding the file's. Without it and without wavelengths in the file, the
        cube must have N bands and is taken to be on the grid.
    variable : str, optional
        The cube's variable in a ``.mat`` file with several 3-D arrays (an error for other formats).
    check : bool
        Check every value (finite, non-negative, not the ENVI data ignore value) in one pass over the file, block
        by block. Default True.

    Returns
    -------
    CubeData
        The stored cube (a memory map for ``.npy`` and ENVI), its wavelengths and the resampling to ``grid``.

    Raises
    ------
    CamsimError
        For a missing, unreadable, truncated or malformed file, wavelengths that do not cover the grid (named with
        both ranges), or a bad value.
    """
    path = Path(path)
    reader = _reader(path)
    if reader is not read_mat:  # read_mat checks its file itself
        check_input(path, "cube file")
    stored = reader(path, variable=variable)
    bands = stored.array.shape[2]
    wavelengths = stored.wavelengths_nm
    if wavelengths_nm is not None:
        wavelengths = np.asarray(wavelengths_nm, dtype=np.float64).ravel()
        if wavelengths.size != bands:
            raise CamsimError(f"cube {path} has {bands} bands but wavelengths_nm lists {wavelengths.size}")
    target = grid.wavelengths_nm
    if wavelengths is None:
        if bands != grid.size:
            raise CamsimError(
                f"cube {path} has {bands} wavelength bins but the scene's grid has {grid.size}: set [spectral] to "
                "the cube's grid, or give the cube's wavelengths (wavelengths_nm in [cube])"
            )
        wavelengths = target.copy()
    if wavelengths.size == target.size and np.allclose(wavelengths, target, rtol=0, atol=1e-6):
        resample = None
    else:
        if np.all(np.isfinite(wavelengths)) and wavelengths.max() < 100:
            raise CamsimError(
                f"cube {path} covers {wavelengths.min():g}–{wavelengths.max():g} nm but the scene's wavelength grid "
                f"needs {grid.start_nm:g}–{grid.end_nm:g} nm; are its wavelengths in micrometres? (ENVI: "
                "wavelength units = Micrometers)"
            )
        # the interpolation of the B unit vectors: column b is how band b spreads over the grid
        resample = align_to_grid(wavelengths, np.eye(bands), grid, f"cube {path}", zero_outside=False)
    cube = CubeData(path, stored.array, wavelengths, grid, stored.scale, resample, stored.mapping)
    if check:
        cube.check(stored.ignore_value)
    return cube


def _check_array(array: np.ndarray, path: Path, what: str = "") -> np.ndarray:
    what = f" {what}" if what else ""
    if array.ndim != 3:
        raise CamsimError(f"cube {path}{what} must be H × W × N, got shape {array.shape}")
    if array.dtype.kind not in "uif":
        raise CamsimError(f"cube {path}{what} has {array.dtype} values; camsim reads integers and real floats")
    if 0 in array.shape:
        raise CamsimError(f"cube {path}{what} is empty: shape {array.shape}")
    _check_size(array.shape[1], array.shape[0], path)
    return array


def _no_variable(path: Path, variable) -> None:
    if variable is not None:
        raise CamsimError(f"cube {path}: variable applies to .mat cubes only")


__all__ = ["BLOCK_BYTES", "CUBE_READERS", "CubeData", "CubeHeader", "MAX_BANDS", "MAX_ENVI_HEADER_BYTES", "cube_header",
           "cube_size", "envi_files", "parse_envi_header", "read_cube",
           "read_envi", "read_mat", "read_npy"]
