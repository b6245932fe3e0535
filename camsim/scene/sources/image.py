"""A picture as a scene: an RGB image file, its colours recovered as spectra (scene table ``[image]``).

A photograph of surfaces (``kind = "reflectance"``, the default): pixel value 1 is the perfect white, lit by the
scene's illuminants at the scene's luminance. Its distinct colours become the scene's spectra (a label map plus K
colours, as a chart is a label map plus its patches); with the ``Mallett 2019`` recovery each colour's reflectance
is a non-negative combination of three basis spectra, ρ(λ) = r B_r(λ) + g B_g(λ) + b B_b(λ) for its linear sRGB
(r, g, b), so the spectra stay factored (:class:`camsim.light.rates.FactoredSpectra`): the expected electrons of every
colour are one 3 × 3 matrix per camera and light applied to its linear RGB — never an H × W × N cube. The other
methods of :data:`camsim.colour.recovery.RECOVERY_METHODS` give one spectrum per distinct colour.

An emissive picture (``kind = "radiance"``), e.g. a display or a light box, has its own absolute scale and is not
lit by the scene's illuminants (as a ``[cube]`` of radiance: every illuminant of the scene gives the same frame).
The linear RGB (1, 1, 1) is the colourspace's whitepoint light — CIE D65's spectrum for sRGB (and Adobe RGB,
Display P3, BT.2020), D50's for ProPhoto RGB; a colourspace whose white has no CIE spectrum in colour-science
(ACES2065-1, DCI-P3) is refused — at the luminance ``luminance_cd_m2`` of the ``[image]`` table (cd/m²,
required for this kind: the scene's ``[light] luminance_cd_m2`` scales reflectances and does not apply). Every
colour's spectral radiance is its recovered reflectance-like spectrum times that white's spectral radiance
W(λ) (W / (m² sr nm), Y = 683 Σ W ȳ δ = ``luminance_cd_m2``): L_k(λ) = ρ_k(λ) W(λ). With Mallett the basis sums to
1, so (1, 1, 1) is exactly W and (0.5, 0.5, 0.5) exactly half of it; the radiance stays factored (the basis times
W). Otsu and Jakob do not make (1, 1, 1) exactly flat (see :mod:`camsim.colour.recovery`), so the white is then their
recovered white times W.

Paths. ``path`` is a file, relative to the scene file; or ``"skimage:NAME"``, one of the photographs shipped inside
the installed scikit-image package (``skimage:astronaut``, ``skimage:coffee``, ``skimage:chelsea``, … — the stems
of the image files in the ``skimage.data`` package folder; nothing is downloaded, and an unknown name is an error
that lists them).

Resampling. ``size = [width, height]`` resamples the picture (after ``crop``) in linear light with
``skimage.transform.resize`` (bilinear, order 1; Gaussian anti-aliasing, skimage's σ = (factor − 1) / 2, on each
axis that shrinks), so an edge between two colours becomes their linear-light mixture, as a camera's pixel would
average it. The resampled values are floats: the image then has many distinct colours (up to one per pixel,
e.g. about 10⁵ for a photograph) instead of its file's codes. That costs nothing with Mallett (three numbers a
colour); with Otsu (about 1 ms a colour) or Jakob (about 0.3 s a colour) it is slow — use ``size`` with them only
for synthetic pictures of few colours.

Reading: OpenImageIO, 8- and 16-bit files (PNG, TIFF, JPEG, …) have their colourspace's transfer function decoded
(colour-science's ``cctf_decoding``); float files (EXR, HDR) are taken as linear. One channel is grey (R = G = B);
a fourth (alpha) is ignored. Colours outside sRGB's gamut (from a wider ``colourspace``) have their negative linear
sRGB components set to 0: Mallett's basis cannot make them, and the rest of the colour is kept.

Out of gamut, recorded. Every frame's sidecar gets ``recovery`` (:func:`recovery_record`): the method, the
colourspace, the share of the scene's pixels whose colour the method could not reproduce (Mallett: outside sRGB;
Otsu and Jakob: flagged ``outside`` by :mod:`camsim.colour.recovery`), the largest linear sRGB component clipped
(Mallett) and the largest CIE 2000 ΔE of such a pixel's recovered spectrum to its colour (under D65);
``camsim render`` warns once per frame where the share is above 0.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from camsim.colour.recovery import (
    RECOVERY_METHODS,
    linear_srgb,
    mallett_basis,
    recovery_delta_e,
    rgb_to_distinct_spectra,
)
from camsim.core.errors import CamsimError
from camsim.light.photons import scale_to_luminance
from camsim.light.rates import FactoredSpectra
from camsim.light.spectra import WavelengthGrid, cmfs_on_grid, illuminant_spd, import_colour
from camsim.scene.sources.base import SceneSource, SourceSpectra, typed

IMAGE_KINDS = ("reflectance", "radiance")
#: The prefix of a ``path`` that names a photograph shipped with scikit-image (``"skimage:astronaut"``).
SKIMAGE_PREFIX = "skimage:"
#: The file types looked for among scikit-image's shipped data files.
_SKIMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".tif", ".tiff")


@dataclass(frozen=True)
class ImageSource(SceneSource):
    """An image scene (scene-file table ``[image]``).

    Attributes
    ----------
    path : pathlib.Path
        The image file (in a scene file: relative to the scene file, or ``"skimage:NAME"`` for a photograph shipped
        with scikit-image, resolved by :func:`skimage_data_file`).
    kind : {'reflectance', 'radiance'}
        ``reflectance``: a photograph of surfaces, 1 = the perfect white, lit by the scene's illuminants.
        ``radiance``: an emissive picture, (1, 1, 1) = the colourspace's whitepoint light at ``luminance_cd_m2``,
        not lit by the illuminants (module docstring).
    colourspace : str
        colour-science RGB colourspace name of the file's values (default ``"sRGB"``).
    recovery : str
        RGB → spectrum method, a name of :data:`camsim.colour.recovery.RECOVERY_METHODS`: ``"Mallett 2019"`` (default;
        factored, one 3 × 3 matrix per camera and light), ``"Otsu 2018"`` or ``"Jakob 2019"`` (one spectrum per
        distinct colour, cached: a photograph's tens of thousands of colours cost seconds with Otsu, hours with
        Jakob — for synthetic images with few colours).
    crop : tuple of int or None
        (x, y, width, height) in pixels of the file: the part that is the scene.
    size : tuple of int or None
        (width, height) in pixels: the (cropped) picture resampled to this size in linear light (module
        docstring); None keeps the file's pixels.
    luminance_cd_m2 : float or None
        ``radiance`` only (and required there): the luminance of the linear RGB (1, 1, 1). Unit: cd / m².
    """

    table = "image"
    keys = frozenset({"path", "kind", "colourspace", "recovery", "crop", "size", "luminance_cd_m2"})
    has_own_size = True

    path: Path
    kind: str = "reflectance"
    colourspace: str = "sRGB"
    recovery: str = "Mallett 2019"
    crop: tuple | None = None
    size: tuple | None = None
    luminance_cd_m2: float | None = None

    def __post_init__(self):
        if self.kind not in IMAGE_KINDS:
            raise CamsimError(f"[image] kind must be one of {IMAGE_KINDS}, got {self.kind!r}")
        if self.kind == "radiance":
            value = self.luminance_cd_m2
            if value is None:
                raise CamsimError("[image] kind 'radiance' needs luminance_cd_m2, the luminance of the linear RGB "
                                  "(1, 1, 1) in cd/m² (an emissive picture has its own scale)")
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not (np.isfinite(value)
                                                                                      and value > 0):
                raise CamsimError(f"[image] luminance_cd_m2 must be a positive number (cd/m²), got {value!r}")
            whitepoint_name(self.colourspace)  # the white must have a spectrum
        elif self.luminance_cd_m2 is not None:
            raise CamsimError("[image] luminance_cd_m2 applies to kind 'radiance'; a reflectance image's white is "
                              "set by [light] luminance_cd_m2")
        if self.size is not None and not (
                isinstance(self.size, tuple) and len(self.size) == 2
                and all(isinstance(v, int) and not isinstance(v, bool) and v >= 1 for v in self.size)):
            raise CamsimError(f"[image] size must be [width, height], two positive integers (pixels), "
                              f"got {list(self.size) if isinstance(self.size, tuple) else self.size!r}")
        if self.size is not None:
            from camsim.core.pixel_limit import check_pixel_count

            check_pixel_count(*self.size, "[image] size")

    @classmethod
    def from_table(cls, table: dict, base_dir, where: str) -> ImageSource:
        if "path" not in table:
            raise CamsimError(f"{where}: [image] needs a path to an image file (or skimage:NAME)")
        kind = typed(table, "kind", str, "reflectance", where)  # checked by the constructor
        recovery = typed(table, "recovery", str, "Mallett 2019", where)
        if recovery not in RECOVERY_METHODS:
            raise CamsimError(f"{where}: [image] recovery must be one of {', '.join(RECOVERY_METHODS)}, "
                              f"got {recovery!r}")
        colourspace = typed(table, "colourspace", str, "sRGB", where)
        if colourspace not in import_colour().RGB_COLOURSPACES:
            raise CamsimError(f"{where}: [image] colourspace {colourspace!r} is not a colour-science RGB colourspace")
        crop = typed(table, "crop", list, None, where)
        if crop is not None:
            if len(crop) != 4 or not all(isinstance(v, int) and not isinstance(v, bool) for v in crop) \
                    or crop[0] < 0 or crop[1] < 0 or crop[2] < 1 or crop[3] < 1:
                raise CamsimError(f"{where}: [image] crop must be [x, y, width, height] in pixels, got {crop!r}")
            crop = tuple(crop)
        size = typed(table, "size", list, None, where)
        size = None if size is None else tuple(size)  # checked by the constructor
        luminance = typed(table, "luminance_cd_m2", float, None, where)
        path = typed(table, "path", str, "", where)
        try:
            if path.startswith(SKIMAGE_PREFIX):
                path = skimage_data_file(path[len(SKIMAGE_PREFIX):])
            else:
                path = base_dir / path
            return cls(path=path, kind=kind, colourspace=colourspace, recovery=recovery, crop=crop, size=size,
                       luminance_cd_m2=luminance)
        except CamsimError as exc:
            raise CamsimError(f"{where}: {exc}") from None

    def _cropped_size(self) -> tuple[int, int]:
        """(W, H) of the file's pixels that are the scene: the crop's, or the file's (read from its header)."""
        width, height, _ = _image_header(str(self.path))
        if self.crop is None:
            return width, height
        x, y, w, h = self.crop
        if x + w > width or y + h > height:
            raise CamsimError(f"[image] crop {list(self.crop)} reaches beyond the {width} × {height} image {self.path}")
        return w, h

    def own_size(self) -> tuple[int, int]:
        """(W, H) of the scene: ``size`` if set, else the crop's, or the file's (read from its header)."""
        cropped = self._cropped_size()  # checks the crop against the file
        return cropped if self.size is None else self.size

    def white_radiance(self, grid: WavelengthGrid) -> np.ndarray:
        """``radiance`` kind: the spectral radiance W(λ) of the linear RGB (1, 1, 1), shape (N,).

        The colourspace's whitepoint illuminant (colour-science's spectrum) scaled to :attr:`luminance_cd_m2`
        with the CIE 1931 ȳ on ``grid``. Unit: W / (m² sr nm).
        """
        if self.kind != "radiance":
            raise CamsimError("[image] white_radiance is defined for kind 'radiance' only")
        spd = illuminant_spd(whitepoint_name(self.colourspace), grid)
        return scale_to_luminance(spd, cmfs_on_grid(grid)[1], grid.step_nm, float(self.luminance_cd_m2))

    def spectra(self, grid: WavelengthGrid, width: int, height: int) -> SourceSpectra:
        """Labels (H, W) of the distinct colours and their spectra, factored on Mallett's basis with that method.

        ``reflectance``: reflectance factors (unitless). ``radiance``: each reflectance-like spectrum times
        :meth:`white_radiance` (W / (m² sr nm)); still factored with Mallett (the basis times the white).
        """
        self.own_size()  # checks the crop against the file
        labels, rgb = distinct_linear_rgb(str(self.path), self.colourspace, self.crop, self.size)
        counts = np.bincount(labels.ravel(), minlength=rgb.shape[0])  # pixels of each distinct colour
        if self.recovery == "Mallett 2019":  # linear: the colours stay factored on the basis
            srgb, outside, clip = linear_srgb(rgb, self.colourspace, return_clip=True)
            basis = np.asarray(mallett_basis(grid))
            spectra = FactoredSpectra(srgb, basis)
            delta_e = np.zeros(rgb.shape[0])
            if outside.any():  # only the colours outside: the others are sRGB colours, reproduced by the basis
                delta_e[outside] = recovery_delta_e(rgb[outside], srgb[outside] @ basis, self.colourspace, grid)
        else:  # one spectrum per distinct colour
            recovered = rgb_to_distinct_spectra(rgb, self.recovery, self.colourspace, grid)
            outside, delta_e = recovered.outside[recovered.labels], recovered.delta_e[recovered.labels]
            clip = None
            spectra, labels = recovered.spectra, recovered.labels[labels].astype(np.uint32)
        record = recovery_record(self.recovery, self.colourspace, counts, outside, delta_e, clip)
        if self.kind == "radiance":  # emissive: ρ_k(λ) W(λ), the illuminants play no part
            spectra = spectra * self.white_radiance(grid)
        return SourceSpectra(labels, spectra, self.kind, [], [], self.path.name, recovery=record)


def recovery_record(method: str, colourspace: str, counts, outside, delta_e, clip=None) -> dict:
    """The sidecar's ``recovery``: how an image's colours became spectra and what fell outside the method's gamut.

    Parameters
    ----------
    method, colourspace : str
        The recovery method and the image's colourspace.
    counts : numpy.ndarray of int, shape (K,)
        Pixels of each distinct colour.
    outside : numpy.ndarray of bool, shape (K,)
        Colours the method could not reproduce (:mod:`camsim.colour.recovery`, per method).
    delta_e : numpy.ndarray, shape (K,)
        CIE 2000 ΔE of each colour's recovered spectrum to the colour (D65); read where ``outside`` only.
    clip : numpy.ndarray, shape (K,), optional
        Mallett 2019: the linear sRGB component clipped to 0 (:func:`camsim.colour.recovery.linear_srgb`).

    Returns
    -------
    dict
        ``method``; ``colour_space``; ``out_of_gamut_fraction``, the share of the pixels outside (0 to 1);
        ``out_of_gamut_colours``, their distinct colours; ``max_clip``, the largest linear sRGB component set to 0
        (Mallett; 1 = the perfect white's component; 0 when none, None for the other methods);
        ``max_delta_e00_outside``, the largest ΔE00 among the pixels outside (0 when none).
    """
    counts = np.asarray(counts, dtype=np.int64)
    outside = np.asarray(outside, dtype=bool) & (counts > 0)
    return {
        "method": method,
        "colour_space": colourspace,
        "out_of_gamut_fraction": float(counts[outside].sum() / counts.sum()) if counts.sum() else 0.0,
        "out_of_gamut_colours": int(np.count_nonzero(outside)),
        "max_clip": None if clip is None else float(np.max(np.asarray(clip)[outside], initial=0.0)),
        "max_delta_e00_outside": float(np.max(np.asarray(delta_e)[outside], initial=0.0)),
    }


def recovery_warning(record: dict, image: str) -> str | None:
    """The one line ``camsim render`` prints for a frame whose image had colours outside the method's gamut
    (None when it had none): the share of pixels, the method, the colourspace and the loss."""
    share = record.get("out_of_gamut_fraction") or 0.0
    if share <= 0:
        return None
    where = "outside sRGB, the gamut of" if record["method"] == "Mallett 2019" else "outside the reach of"
    clip = record.get("max_clip")
    clipped = f"negative linear sRGB components up to {clip:.3g} set to 0, " if clip else ""
    n = record["out_of_gamut_colours"]
    return (f"{100 * share:.4g} % of the pixels of {image} ({record['colour_space']}; {n} colour{'s' * (n != 1)}) "
            f"lie {where} {record['method']}: {clipped}"
            f"up to ΔE00 {record['max_delta_e00_outside']:.2f} from their colour (sidecar: recovery)")


def whitepoint_name(colourspace: str) -> str:
    """The colour-science illuminant name of ``colourspace``'s whitepoint (``"D65"`` for sRGB).

    Raises
    ------
    CamsimError
        If the colourspace is unknown, or its whitepoint has no spectrum in ``colour.SDS_ILLUMINANTS``.
    """
    colour = import_colour()
    if colourspace not in colour.RGB_COLOURSPACES:
        raise CamsimError(f"[image] colourspace {colourspace!r} is not a colour-science RGB colourspace")
    name = colour.RGB_COLOURSPACES[colourspace].whitepoint_name
    if name not in colour.SDS_ILLUMINANTS:
        raise CamsimError(f"[image] kind 'radiance' needs a colourspace whose white is a CIE illuminant with a "
                          f"spectrum (sRGB: D65, ProPhoto RGB: D50); the white of {colourspace!r} is {name!r}")
    return name


def skimage_data_files() -> dict[str, Path]:
    """``{name: file}`` of the images shipped inside the installed scikit-image (no download).

    The files of the ``skimage.data`` package folder (``astronaut.png``, ``coffee.png``, ``chelsea.png``, …), by
    stem. That folder is :data:`skimage.data.data_dir` unless ``pooch`` is installed, when ``data_dir`` names
    a download cache instead; the shipped files stay in the package.
    """
    try:
        from importlib.resources import files

        folder = Path(str(files("skimage.data")))
    except ModuleNotFoundError:
        raise CamsimError("[image] skimage: paths need scikit-image (pip install scikit-image)") from None
    return {p.stem: p for p in sorted(folder.iterdir()) if p.suffix.lower() in _SKIMAGE_SUFFIXES and p.is_file()}


def skimage_data_file(name: str) -> Path:
    """The file of the photograph ``name`` shipped with scikit-image (``"astronaut"`` → ``.../astronaut.png``).

    Raises
    ------
    CamsimError
        For a name that is not one of :func:`skimage_data_files`; the message lists them.
    """
    available = skimage_data_files()
    if name not in available:
        raise CamsimError(f"[image] no image {name!r} ships with scikit-image: skimage: names are "
                          f"{', '.join(available)}")
    return available[name]


def _oiio():
    import OpenImageIO as oiio

    return oiio


#: What :func:`camsim.core.input_files.open_input` calls an image in its messages (``image file not found: …``).
_WHAT = "image file"


def _file_key(path: str) -> tuple:
    """(path, modification time, size): a cache key that changes when the file does, once the path is known to name
    a regular file (:func:`camsim.core.input_files.open_input`: not a FIFO, a device, a directory, a socket or a
    path with a NUL byte, which OpenImageIO would block on, read forever or fail on)."""
    import os

    from camsim.core.input_files import open_input

    with open_input(path, _WHAT) as handle:
        stat = os.fstat(handle.fileno())
    return path, stat.st_mtime_ns, stat.st_size


def _image_header(path: str) -> tuple[int, int, int]:
    """(width, height, channels) of an image file, without reading its pixels."""
    return _cached_header(*_file_key(path))[:3]


def image_file_size(path: str) -> tuple[int, int]:
    """(width, height) of an image file in pixels, from its header (checked against
    :data:`camsim.core.pixel_limit.MAX_PIXELS`; no pixel decoded)."""
    return _image_header(path)[:2]


def image_colour_limit(path: str) -> int | None:
    """The most distinct colours an image file can have, from its header: 2^(bits × channels) of its integer codes
    (one channel for grey, three for colour: 2²⁴ for 8-bit RGB, 256 for 8-bit grey), None for a file read as floats
    (half, float, and integer types other than 8- and 16-bit unsigned), whose colours are bounded by its pixels
    only. What an image's colours cost to render follows (:mod:`camsim.render.frame_memory`)."""
    _, _, channels, bits = _cached_header(*_file_key(path))
    return None if bits == 0 else 2 ** (bits * (1 if channels == 1 else 3))


@lru_cache(maxsize=8)
def _cached_header(path: str, _mtime_ns: int, _size: int) -> tuple[int, int, int, int]:
    image = _open_image(path, checked=True)
    try:
        spec = image.spec()
        oiio = _oiio()
        bits = {oiio.UINT8: 8, oiio.UINT16: 16}.get(spec.format.basetype, 0)
        return int(spec.width), int(spec.height), int(spec.nchannels), bits
    finally:
        image.close()


#: Rows of an image decoded per call (:func:`read_image_codes`): about 16 MB of 8-bit RGB at 5 000 pixels a row,
#: so that Ctrl-C and SIGTERM are handled between blocks, not after the whole image.
ROWS_PER_READ = 1024


def _open_image(path: str, checked: bool = False):
    """OpenImageIO's ``ImageInput`` for ``path``, its header read and its size checked against
    :data:`camsim.core.pixel_limit.MAX_PIXELS`, before any pixel is decoded; the library's own messages on standard
    error (``libpng error: ...``) become the reason of the one-line error.

    The path is first checked to name a regular file (:func:`camsim.core.input_files.check_input`), unless
    ``checked`` says the caller has just done so. A volume image (a header's depth above 1: a 3-D texture, whose
    slices OpenImageIO would read whole) is refused: an image scene is a picture.
    """
    from camsim.core.input_files import check_input
    from camsim.core.pixel_limit import check_pixel_count
    from camsim.io.library_stderr import library_stderr

    if not checked:
        check_input(path, _WHAT)
    oiio = _oiio()
    with library_stderr() as chatter:
        image = oiio.ImageInput.open(path)
        error = oiio.geterror() if image is None else ""
    if image is None:
        raise CamsimError(f"cannot read image {path}: "
                          f"{error or chatter.reason() or 'not an image OpenImageIO reads'}")
    spec = image.spec()
    try:
        check_pixel_count(int(spec.width), int(spec.height), f"image {path}")
        if int(spec.depth) != 1:
            raise CamsimError(f"image {path} is a volume of {int(spec.depth)} slices: an image scene reads a 2-D "
                              "picture")
    except CamsimError:
        image.close()
        raise
    return image


def read_image_codes(path: str, rows: tuple[int, int] | None = None) -> tuple[np.ndarray, bool, int]:
    """The pixels of an image file as stored, shape (H, W, 3), and whether they are integer codes (and their bits).

    Integer files keep their codes (uint8 / uint16); float files (half, float) come as float32. One channel is
    replicated to three; channels beyond three (alpha) are dropped. The size in the file's header is checked
    (:func:`camsim.core.pixel_limit.check_pixel_count`) before any pixel is decoded; the pixels are decoded
    :data:`ROWS_PER_READ` rows at a time (a tiled file's in whole rows of tiles), so that a signal stops the read
    between blocks and a crop decodes its own rows only.

    Parameters
    ----------
    path : str
        The image file.
    rows : tuple of int, optional
        (first, stop): decode only these rows (a crop's); default all.
    """
    from camsim.io.library_stderr import library_stderr

    oiio = _oiio()
    image = _open_image(path)
    reason = ""
    try:
        spec = image.spec()
        channels = int(spec.nchannels)
        if channels == 2 or channels < 1:
            raise CamsimError(f"image {path} has {channels} channels: camsim reads grey, RGB and RGBA images")
        read_channels = min(channels, 3)  # grey is repeated to three; alpha and beyond are not read
        base = spec.format.basetype
        integer = {oiio.UINT8: (oiio.UINT8, 8), oiio.UINT16: (oiio.UINT16, 16)}.get(base)
        kind = integer[0] if integer else oiio.FLOAT
        first, stop = (0, spec.height) if rows is None else rows
        dtype = {8: np.uint8, 16: np.uint16}[integer[1]] if integer else np.float32
        pixels = np.empty((stop - first, spec.width, 3), dtype)  # filled block by block: no second copy
        tile = int(spec.tile_height) if spec.tile_width else 0
        if tile:  # a tiled file: whole rows of tiles, from the one that holds the first row wanted
            band = tile * max(1, ROWS_PER_READ // tile)
            steps = [(y, min(y + band, spec.height)) for y in range(first - first % tile, stop, band)]
        else:
            steps = [(y, min(y + ROWS_PER_READ, stop)) for y in range(first, stop, ROWS_PER_READ)]
        for start, end in steps:
            with library_stderr() as chatter:
                if tile:
                    block = image.read_tiles(0, 0, spec.x, spec.x + spec.width, spec.y + start, spec.y + end,
                                             spec.z, spec.z + 1, 0, read_channels, kind)
                else:
                    block = image.read_scanlines(0, 0, spec.y + start, spec.y + end, 0, 0, read_channels, kind)
                error = (image.geterror() or oiio.geterror()) if block is None else ""
            if block is None:
                reason = error or chatter.reason() or "the decoder gave no reason"
                break
            block = np.asarray(block).reshape(-1, spec.width, read_channels)
            if tile:  # the rows of the band that are wanted
                block = block[max(first, start) - start:min(stop, end) - start]
                start, end = max(first, start), min(stop, end)
            pixels[start - first:end - first] = block  # one channel broadcasts to three
    finally:
        image.close()
    if reason:
        raise CamsimError(f"cannot read the pixels of image {path}: {reason}")
    return pixels, integer is not None, integer[1] if integer else 0


def distinct_linear_rgb(path: str, colourspace: str = "sRGB", crop: tuple | None = None, size: tuple | None = None):
    """The distinct colours of an image file as linear RGB in ``colourspace``, and each pixel's colour index.

    Parameters
    ----------
    path : str
        The image file.
    colourspace : str
        colour-science name of the file's RGB colourspace (its transfer function decodes integer codes).
    crop : tuple of int or None
        (x, y, width, height) in pixels: the part of the file read.
    size : tuple of int or None
        (width, height) in pixels: the cropped pixels resampled to this size in linear light
        (``skimage.transform.resize``, bilinear, anti-aliased when shrinking); None or the cropped size keeps them.

    Returns
    -------
    labels : numpy.ndarray, shape (H, W), uint32
        Index of each pixel's colour.
    rgb : numpy.ndarray, shape (K, 3), float64
        Linear RGB of each distinct colour, ≥ 0 (the file's transfer function decoded for integer files). Cached
        per file version: do not modify.
    """
    return _cached_distinct(*_file_key(path), colourspace, crop, size)


def _resized_linear(codes: np.ndarray, integer: bool, bits: int, colourspace: str, size: tuple) -> np.ndarray:
    """The pixels as linear RGB (float64), resampled to ``size`` = (width, height) in linear light."""
    from skimage.transform import resize

    if integer:  # decode every code once, then look each pixel's up
        space = import_colour().RGB_COLOURSPACES[colourspace]
        table = np.asarray(space.cctf_decoding(np.arange(2**bits) / (2**bits - 1)), dtype=np.float64)
        linear = table[codes]
    else:
        linear = codes.astype(np.float64)
    height, width = linear.shape[:2]
    shrinks = size[0] < width or size[1] < height
    resized = resize(linear, (size[1], size[0], 3), order=1, mode="reflect", anti_aliasing=shrinks,
                     preserve_range=True)
    return np.maximum(resized, 0.0) + 0.0  # bilinear and Gaussian weights are ≥ 0: a guard, and −0 → 0


@lru_cache(maxsize=4)
def _cached_distinct(path: str, _mtime_ns: int, _size: int, colourspace: str, crop: tuple | None,
                     size: tuple | None = None):
    codes, integer, bits = read_image_codes(path, None if crop is None else (crop[1], crop[1] + crop[3]))
    if crop is not None:
        x, _, w, _ = crop
        codes = codes[:, x : x + w]
    height, width = codes.shape[:2]
    if not integer:
        _check_float_pixels(codes, path)
    if size is not None and tuple(size) != (width, height):
        linear = _resized_linear(codes, integer, bits, colourspace, tuple(size))
        values, inverse = np.unique(linear.reshape(-1, 3).view(np.dtype((np.void, 24))).ravel(), return_inverse=True)
        distinct = values.view(np.float64).reshape(-1, 3).copy()
        return inverse.reshape(size[1], size[0]).astype(np.uint32), distinct
    flat = codes.reshape(-1, 3)
    if integer and bits == 8:  # 24-bit codes: a presence table and its running count, O(pixels), no sort
        packed = (flat[:, 0].astype(np.uint32) << 16) | (flat[:, 1].astype(np.uint32) << 8) | flat[:, 2]
        present = np.zeros(1 << 24, dtype=bool)
        present[packed] = True
        values = np.flatnonzero(present).astype(np.uint32)
        index_of = np.cumsum(present, dtype=np.int32)
        index_of -= 1
        del present
        inverse = index_of[packed]
        del index_of, packed
        distinct = np.stack([(values >> 16) & 0xFF, (values >> 8) & 0xFF, values & 0xFF], axis=1)
    elif integer:  # pack the three codes into one integer: np.unique on a 1-D array is fast
        packed = (flat[:, 0].astype(np.uint64) << 32) | (flat[:, 1].astype(np.uint64) << 16) | flat[:, 2]
        values, inverse = np.unique(packed, return_inverse=True)
        distinct = np.stack([(values >> 32) & 0xFFFF, (values >> 16) & 0xFFFF, values & 0xFFFF], axis=1)
    if integer:  # decode the distinct codes only
        encoded = distinct.astype(np.float64) / (2**bits - 1)
        space = import_colour().RGB_COLOURSPACES[colourspace]
        linear = np.asarray(space.cctf_decoding(encoded), dtype=np.float64)
    else:
        values, inverse = np.unique(flat.view(np.dtype((np.void, 12))).ravel(), return_inverse=True)
        linear = values.view(np.float32).reshape(-1, 3).astype(np.float64)
    labels = inverse.reshape(height, width)
    labels = labels.view(np.uint32) if labels.dtype == np.int32 else labels.astype(np.uint32)  # indices are ≥ 0
    return labels, linear


def _check_float_pixels(pixels: np.ndarray, path: str) -> None:
    """A float image's values must be finite and ≥ 0 (reflectance-like, or relative radiance)."""
    if not np.all(np.isfinite(pixels)):
        raise CamsimError(f"image {path} has NaN or infinite values")
    if np.any(pixels < 0):
        raise CamsimError(f"image {path} has negative values: an image scene needs values ≥ 0")
