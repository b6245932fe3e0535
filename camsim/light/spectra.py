"""Spectral data: the wavelength grid and the named spectra camsim ships through colour-science.

Every spectrum in camsim lives on one :class:`WavelengthGrid` (the paper's default: 380–780 nm every 4 nm,
N = 101 bins). Data from colour-science (illuminants, ColorChecker reflectances, camera sensitivities, the
CIE 1931 colour-matching functions) or from CSV files is aligned to that grid with colour-science, by linear
interpolation (no overshoot, so non-negative data stays non-negative, which Poisson rates need).

Illuminants and reflectances must cover the grid: extrapolating a light source beyond its measured range would
invent radiance, so that is an error. Camera sensitivities outside their measured range are taken as zero.
"""

from __future__ import annotations

import contextlib
import csv
import io
import signal
import sys
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from camsim.core.errors import CamsimError
from camsim.core.input_files import check_input, read_input
from camsim.core.signals import handlers_installed

CMFS_NAME = "CIE 1931 2 Degree Standard Observer"


def import_colour():
    """Import colour-science lazily and quietly (its import is slow and warns about optional packages).

    The first import holds SIGINT and SIGTERM back until it is over (when called from the main thread, where
    Python acts on signals): colour-science imports OpenImageIO, whose nanobind extension aborts the whole process
    ("Critical nanobind error", SIGABRT) if Ctrl-C lands while it initialises. A signal that came meanwhile is
    re-sent as the import ends, and the run stops cleanly.
    """
    if "colour" in sys.modules:
        return sys.modules["colour"]
    with warnings.catch_warnings(), _signals_held():
        warnings.simplefilter("ignore")
        import colour
    return colour


@contextlib.contextmanager
def _signals_held():
    """Hold SIGINT and SIGTERM back in the block: they are noted, not acted on, and re-sent as the block ends."""
    received = []
    try:
        with handlers_installed({sig: lambda signum, frame: received.append(signum)
                                 for sig in (signal.SIGINT, signal.SIGTERM)}):
            yield
    finally:
        if received:
            signal.raise_signal(received[0])


#: The most bins a wavelength grid may have (380–780 nm at 4 nm is 101; at 0.01 nm, 40 001).
MAX_BINS = 100_000


@dataclass(frozen=True)
class WavelengthGrid:
    """A uniform wavelength grid.

    Attributes
    ----------
    start_nm, end_nm, step_nm : float
        First and last bin centre and bin width δ. Unit: nm.
    """

    start_nm: float = 380.0
    end_nm: float = 780.0
    step_nm: float = 4.0

    def __post_init__(self):
        values = (self.start_nm, self.end_nm, self.step_nm)
        if not all(np.isfinite(v) for v in values):
            raise CamsimError(f"wavelength grid has a non-finite value: {values}")
        if self.step_nm <= 0 or self.end_nm <= self.start_nm or self.start_nm <= 0:
            raise CamsimError(
                f"wavelength grid {self.start_nm}–{self.end_nm} nm step {self.step_nm} nm is not a valid grid "
                "(need 0 < start < end and step > 0)"
            )
        n = (self.end_nm - self.start_nm) / self.step_nm
        if not n < MAX_BINS:  # also a step so small, or a range so wide, that the count is infinite
            raise CamsimError(f"wavelength grid {self.start_nm:g}–{self.end_nm:g} nm step {self.step_nm:g} nm has "
                              f"{n + 1:.3g} bins, more than {MAX_BINS}")
        if abs(n - round(n)) > 1e-6:
            raise CamsimError(
                f"wavelength grid {self.start_nm}–{self.end_nm} nm is not a whole number of {self.step_nm} nm steps"
            )

    @property
    def wavelengths_nm(self) -> np.ndarray:
        """Bin centres, shape (N,). Unit: nm."""
        n = int(round((self.end_nm - self.start_nm) / self.step_nm)) + 1
        return self.start_nm + self.step_nm * np.arange(n, dtype=np.float64)

    @property
    def size(self) -> int:
        return self.wavelengths_nm.size

    def shape(self):
        """The grid as a ``colour.SpectralShape``."""
        return import_colour().SpectralShape(self.start_nm, self.end_nm, self.step_nm)


def _check_values(values: np.ndarray, what: str, *, allow_negative: bool = False) -> np.ndarray:
    values = np.asarray(values, dtype=np.float64)
    if not np.all(np.isfinite(values)):
        raise CamsimError(f"{what} contains NaN or infinite values")
    if not allow_negative and np.any(values < 0):
        raise CamsimError(f"{what} has negative values (min {values.min():.4g})")
    return values


def align_to_grid(wavelengths_nm, values, grid: WavelengthGrid, what: str, *, zero_outside: bool) -> np.ndarray:
    """Resample spectra to ``grid`` with colour-science (linear interpolation).

    Parameters
    ----------
    wavelengths_nm : array_like, shape (M,)
        Sample wavelengths, strictly increasing. Unit: nm.
    values : array_like, shape (M,) or (M, C)
        Spectral values (any unit; it is kept).
    grid : WavelengthGrid
        Target grid.
    what : str
        Name used in error messages.
    zero_outside : bool
        If True, values beyond the sampled range are zero; if False, a grid that reaches beyond the samples is
        an error.

    Returns
    -------
    numpy.ndarray, shape (N,) or (N, C)
    """
    colour = import_colour()
    wl = _check_values(wavelengths_nm, f"{what}: wavelengths")
    vals = _check_values(values, what)
    if wl.ndim != 1 or wl.size < 2 or np.any(np.diff(wl) <= 0):
        raise CamsimError(f"{what}: wavelengths must be a strictly increasing list of at least 2 values")
    if vals.shape[0] != wl.size:
        raise CamsimError(f"{what}: {vals.shape[0]} values for {wl.size} wavelengths")
    lo, hi = grid.start_nm, grid.end_nm
    tol = 1e-9
    if not zero_outside and (wl[0] > lo + tol or wl[-1] < hi - tol):
        raise CamsimError(
            f"{what} covers {wl[0]:g}–{wl[-1]:g} nm but the scene's wavelength grid needs {lo:g}–{hi:g} nm; "
            "narrow the grid ([spectral] start_nm / end_nm) or choose another spectrum"
        )
    target = grid.wavelengths_nm
    one_d = vals.ndim == 1
    cols = vals[:, None] if one_d else vals
    out = np.empty((target.size, cols.shape[1]))
    for j in range(cols.shape[1]):
        interpolator = colour.LinearInterpolator(wl, cols[:, j])
        inside = (target >= wl[0] - tol) & (target <= wl[-1] + tol)
        out[:, j] = 0.0
        out[inside, j] = interpolator(np.clip(target[inside], wl[0], wl[-1]))
    return out[:, 0] if one_d else out


def _sd_on_grid(sd, grid: WavelengthGrid, what: str, *, zero_outside: bool = False) -> np.ndarray:
    return align_to_grid(sd.wavelengths, sd.values, grid, what, zero_outside=zero_outside)


def illuminant_names() -> list[str]:
    """Names of the illuminants colour-science ships (``colour.SDS_ILLUMINANTS``)."""
    return sorted(import_colour().SDS_ILLUMINANTS.keys())


def illuminant_spd(name: str, grid: WavelengthGrid) -> np.ndarray:
    """Relative spectral power distribution of a colour-science illuminant on ``grid``, shape (N,)."""
    sds = import_colour().SDS_ILLUMINANTS
    if name not in sds:
        raise CamsimError(f"unknown illuminant {name!r}; known: {', '.join(sorted(sds))}")
    return _sd_on_grid(sds[name], grid, f"illuminant {name!r}")


def reflectance_set(name_or_csv: str, grid: WavelengthGrid, base_dir: Path | None = None):
    """Reflectance spectra of a colour-science ColorChecker set, or of a CSV file.

    The CSV has a header row ``wavelength_nm,<name>,<name>,...`` and one row per wavelength; values are
    reflectance factors in [0, 1].

    Returns
    -------
    names : list of str
        Patch names, in chart order (row-major, top left first).
    reflectances : numpy.ndarray, shape (K, N)
        Reflectance factor, unitless.
    """
    colour = import_colour()
    if name_or_csv in colour.SDS_COLOURCHECKERS:
        chart = colour.SDS_COLOURCHECKERS[name_or_csv]
        names = list(chart.keys())
        refl = np.stack([_sd_on_grid(chart[n], grid, f"reflectance {n!r} of {name_or_csv!r}") for n in names])
    elif name_or_csv.lower().endswith(".csv"):
        path = _resolve(name_or_csv, base_dir)
        names, wl, vals = read_spectra_csv(path)
        refl = align_to_grid(wl, vals, grid, f"reflectances in {path.name}", zero_outside=False).T
    else:
        known = ", ".join(sorted(colour.SDS_COLOURCHECKERS))
        raise CamsimError(f"unknown reflectance set {name_or_csv!r}; known: {known}, or a .csv file")
    if np.any(refl > 1.5):
        raise CamsimError(f"reflectance set {name_or_csv!r} has values above 1.5: these are not reflectance factors")
    return names, refl


def camera_names() -> list[str]:
    """Names of the camera sensitivity sets colour-science ships (``colour.MSDS_CAMERA_SENSITIVITIES``)."""
    return sorted(import_colour().MSDS_CAMERA_SENSITIVITIES.keys())


def camera_sensitivities(name_or_csv: str, grid: WavelengthGrid, base_dir: Path | None = None):
    """Relative R, G, B spectral sensitivities on ``grid``, as published (peak-normalised later).

    Returns
    -------
    label : str
        The colour-science dataset name, or the CSV file name.
    sensitivities : numpy.ndarray, shape (3, N)
        Relative sensitivity, unitless; zero outside the measured range.
    """
    colour = import_colour()
    if name_or_csv in colour.MSDS_CAMERA_SENSITIVITIES:
        msds = colour.MSDS_CAMERA_SENSITIVITIES[name_or_csv]
        sens = align_to_grid(msds.wavelengths, msds.values, grid, f"camera {name_or_csv!r}", zero_outside=True)
        label = name_or_csv
    elif name_or_csv.lower().endswith(".csv"):
        path = _resolve(name_or_csv, base_dir)
        names, wl, vals = read_spectra_csv(path)
        if len(names) != 3:
            raise CamsimError(f"camera file {path}: expected columns wavelength, R, G, B; found {len(names) + 1}")
        sens = align_to_grid(wl, vals, grid, f"camera file {path.name}", zero_outside=True)
        label = path.name
    else:
        known = ", ".join(sorted(colour.MSDS_CAMERA_SENSITIVITIES))
        raise CamsimError(f"unknown camera {name_or_csv!r}; known: {known}, or a .csv file (wavelength, R, G, B)")
    sens = sens.T
    if np.any(sens.max(axis=1) <= 0):
        raise CamsimError(f"camera {label!r} has a channel with no sensitivity on the scene's wavelength grid")
    return label, sens


def cmfs_on_grid(grid: WavelengthGrid) -> np.ndarray:
    """CIE 1931 2° colour-matching functions x̄, ȳ, z̄ on ``grid``, shape (3, N)."""
    return cmfs_at(grid.wavelengths_nm)


def cmfs_at(wavelengths_nm) -> np.ndarray:
    """CIE 1931 2° colour-matching functions at any wavelengths (nm), shape (3, N); zero outside 360–830 nm.

    Linear interpolation with ``colour.LinearInterpolator``.
    """
    colour = import_colour()
    cmfs = colour.MSDS_CMFS[CMFS_NAME]
    wl = np.asarray(wavelengths_nm, dtype=np.float64)
    out = np.zeros((3, wl.size))
    inside = (wl >= cmfs.wavelengths[0]) & (wl <= cmfs.wavelengths[-1])
    for j in range(3):
        out[j, inside] = colour.LinearInterpolator(cmfs.wavelengths, cmfs.values[:, j])(wl[inside])
    return out


#: The largest spectra CSV read: a camera's or a set of spectra at 0.1 nm steps is well under a megabyte. Unit: bytes.
MAX_SPECTRA_CSV_BYTES = 16_000_000


def _resolve(path_text: str, base_dir: Path | None) -> Path:
    path = Path(path_text).expanduser()
    if not path.is_absolute() and base_dir is not None:
        path = base_dir / path
    return check_input(path, "spectra file", MAX_SPECTRA_CSV_BYTES)  # a regular file: not a FIFO, no NUL byte


def read_spectra_csv(path: Path):
    """Read a CSV of spectra: a header ``wavelength_nm,name1,name2,...`` then one row per wavelength.

    Returns
    -------
    names : list of str, wavelengths : numpy.ndarray (M,) in nm, values : numpy.ndarray (M, C)
    """
    data = read_input(path, "spectra file", MAX_SPECTRA_CSV_BYTES)
    try:
        text = io.StringIO(data.decode("utf-8"), newline="")
        rows = [row for row in csv.reader(text) if row and not row[0].lstrip().startswith("#")]
    except (csv.Error, UnicodeDecodeError) as exc:
        raise CamsimError(f"cannot read spectra file {path}: {exc}") from None
    if len(rows) < 3:
        raise CamsimError(f"spectra file {path}: needs a header row and at least 2 data rows")
    header, body = rows[0], rows[1:]
    if len(header) < 2:
        raise CamsimError(f"spectra file {path}: needs a wavelength column and at least one spectrum column")
    try:
        data = np.array([[float(cell) for cell in row] for row in body])
    except ValueError as exc:
        raise CamsimError(f"spectra file {path}: non-numeric value ({exc})") from None
    if data.ndim != 2 or data.shape[1] != len(header):
        raise CamsimError(f"spectra file {path}: every row must have {len(header)} columns")
    names = [h.strip() for h in header[1:]]
    return names, data[:, 0], data[:, 1:]


def reflectance_set_names() -> list[str]:
    """Names of the ColorChecker reflectance sets colour-science ships (``colour.SDS_COLOURCHECKERS``)."""
    return sorted(import_colour().SDS_COLOURCHECKERS.keys())
