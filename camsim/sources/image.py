"""A picture as a scene: an RGB image file, its colours recovered as reflectance spectra (scene table ``[image]``).

A photograph of surfaces (``kind = "reflectance"``): pixel value 1 is the perfect white, lit by the scene's
illuminants at the scene's luminance. Its distinct colours become the scene's spectra (a label map plus K colours,
as a chart is a label map plus its patches); with the ``Mallett 2019`` recovery each colour's reflectance is a
non-negative combination of three basis spectra, ρ(λ) = r B_r(λ) + g B_g(λ) + b B_b(λ) for its linear sRGB (r, g, b),
so the spectra stay factored (:class:`camsim.rates.FactoredSpectra`): the expected electrons of every colour are one
3 × 3 matrix per camera and light applied to its linear RGB — never an H × W × N cube. The other methods of
:data:`camsim.recovery.RECOVERY_METHODS` give one spectrum per distinct colour.

Reading: OpenImageIO, 8- and 16-bit files (PNG, TIFF, JPEG, …) have their colourspace's transfer function decoded
(colour-science's ``cctf_decoding``); float files (EXR, HDR) are taken as linear. One channel is grey (R = G = B);
a fourth (alpha) is ignored. Colours outside sRGB's gamut (from a wider ``colourspace``) have their negative linear
sRGB components set to 0: Mallett's basis cannot make them, and the rest of the colour is kept.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from camsim.errors import CamsimError
from camsim.rates import FactoredSpectra
from camsim.sources.base import SceneSource, SourceSpectra, typed
from camsim.recovery import RECOVERY_METHODS, linear_srgb, mallett_basis, rgb_to_distinct_spectra
from camsim.spectra import WavelengthGrid, import_colour

IMAGE_KINDS = ("reflectance",)


@dataclass(frozen=True)
class ImageSource(SceneSource):
    """An image scene (scene-file table ``[image]``).

    Attributes
    ----------
    path : pathlib.Path
        The image file (relative paths are relative to the scene file).
    kind : {'reflectance'}
        A photograph of surfaces: 1 = the perfect white.
    colourspace : str
        colour-science RGB colourspace name of the file's values (default ``"sRGB"``).
    recovery : str
        RGB → spectrum method, a name of :data:`camsim.recovery.RECOVERY_METHODS`: ``"Mallett 2019"`` (default;
        factored, one 3 × 3 matrix per camera and light), ``"Otsu 2018"`` or ``"Jakob 2019"`` (one spectrum per
        distinct colour, cached: a photograph's tens of thousands of colours cost seconds with Otsu, hours with
        Jakob — for synthetic images with few colours).
    crop : tuple of int or None
        (x, y, width, height) in pixels of the file: the part that is the scene.
    """

    table = "image"
    keys = frozenset({"path", "kind", "colourspace", "recovery", "crop"})
    has_own_size = True

    path: Path
    kind: str = "reflectance"
    colourspace: str = "sRGB"
    recovery: str = "Mallett 2019"
    crop: tuple | None = None

    @classmethod
    def from_table(cls, table: dict, base_dir, where: str) -> ImageSource:
        if "path" not in table:
            raise CamsimError(f"{where}: [image] needs a path to an image file")
        kind = typed(table, "kind", str, "reflectance", where)
        if kind not in IMAGE_KINDS:
            raise CamsimError(f"{where}: [image] kind must be one of {IMAGE_KINDS}, got {kind!r} (emissive image "
                              "scenes are not available yet: use a [cube] of radiance)")
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
        return cls(path=base_dir / typed(table, "path", str, "", where), kind=kind, colourspace=colourspace,
                   recovery=recovery, crop=crop)

    def own_size(self) -> tuple[int, int]:
        """(W, H) of the scene: the crop's, or the file's (read from its header)."""
        width, height, _ = _image_header(str(self.path))
        if self.crop is None:
            return width, height
        x, y, w, h = self.crop
        if x + w > width or y + h > height:
            raise CamsimError(f"[image] crop {list(self.crop)} reaches beyond the {width} × {height} image {self.path}")
        return w, h

    def spectra(self, grid: WavelengthGrid, width: int, height: int) -> SourceSpectra:
        """Labels (H, W) of the distinct colours and their reflectances, factored on Mallett's basis."""
        self.own_size()  # checks the crop against the file
        labels, rgb = distinct_linear_rgb(str(self.path), self.colourspace, self.crop)
        if self.recovery == "Mallett 2019":  # linear: the colours stay factored on the basis
            srgb, _ = linear_srgb(rgb, self.colourspace)
            spectra = FactoredSpectra(srgb, np.asarray(mallett_basis(grid)))
        else:  # one spectrum per distinct colour
            recovered = rgb_to_distinct_spectra(rgb, self.recovery, self.colourspace, grid)
            spectra, labels = recovered.spectra, recovered.labels[labels].astype(np.uint32)
        return SourceSpectra(labels, spectra, self.kind, [], [], self.path.name)


def _oiio():
    import OpenImageIO as oiio

    return oiio


def _file_key(path: str) -> tuple:
    """(path, modification time, size): a cache key that changes when the file does."""
    try:
        stat = Path(path).stat()
    except FileNotFoundError:
        raise CamsimError(f"image file not found: {path}") from None
    except OSError as exc:
        raise CamsimError(f"cannot read image {path}: {exc.strerror or exc}") from None
    return path, stat.st_mtime_ns, stat.st_size


def _image_header(path: str) -> tuple[int, int, int]:
    """(width, height, channels) of an image file, without reading its pixels."""
    return _cached_header(*_file_key(path))


@lru_cache(maxsize=8)
def _cached_header(path: str, _mtime_ns: int, _size: int) -> tuple[int, int, int]:
    oiio = _oiio()
    if not Path(path).is_file():
        raise CamsimError(f"image file not found: {path}")
    image = oiio.ImageInput.open(path)
    if image is None:
        raise CamsimError(f"cannot read image {path}: {oiio.geterror() or 'not an image OpenImageIO reads'}")
    try:
        spec = image.spec()
        return int(spec.width), int(spec.height), int(spec.nchannels)
    finally:
        image.close()


def read_image_codes(path: str) -> tuple[np.ndarray, bool, int]:
    """The pixels of an image file as stored, shape (H, W, 3), and whether they are integer codes (and their bits).

    Integer files keep their codes (uint8 / uint16); float files (half, float) come as float32. One channel is
    replicated to three; channels beyond three (alpha) are dropped.
    """
    oiio = _oiio()
    image = oiio.ImageInput.open(path)
    if image is None:
        raise CamsimError(f"cannot read image {path}: {oiio.geterror() or 'not an image OpenImageIO reads'}")
    try:
        spec = image.spec()
        base = spec.format.basetype
        integer = {oiio.UINT8: (oiio.UINT8, 8), oiio.UINT16: (oiio.UINT16, 16)}.get(base)
        pixels = image.read_image(integer[0] if integer else oiio.FLOAT)
    finally:
        image.close()
    if pixels is None:
        raise CamsimError(f"cannot read the pixels of image {path}: {oiio.geterror()}")
    pixels = np.asarray(pixels)
    if pixels.ndim == 2:
        pixels = pixels[:, :, None]
    if pixels.shape[2] == 1:
        pixels = np.repeat(pixels, 3, axis=2)
    elif pixels.shape[2] == 2 or pixels.shape[2] < 1:
        raise CamsimError(f"image {path} has {pixels.shape[2]} channels: camsim reads grey, RGB and RGBA images")
    return np.ascontiguousarray(pixels[:, :, :3]), integer is not None, integer[1] if integer else 0


def distinct_linear_rgb(path: str, colourspace: str = "sRGB", crop: tuple | None = None):
    """The distinct colours of an image file as linear RGB in ``colourspace``, and each pixel's colour index.

    Returns
    -------
    labels : numpy.ndarray, shape (H, W), uint32
        Index of each pixel's colour.
    rgb : numpy.ndarray, shape (K, 3), float64
        Linear RGB of each distinct colour, ≥ 0 (the file's transfer function decoded for integer files). Cached
        per file version: do not modify.
    """
    return _cached_distinct(*_file_key(path), colourspace, crop)


@lru_cache(maxsize=4)
def _cached_distinct(path: str, _mtime_ns: int, _size: int, colourspace: str, crop: tuple | None):
    codes, integer, bits = read_image_codes(path)
    if crop is not None:
        x, y, w, h = crop
        codes = codes[y : y + h, x : x + w]
    height, width = codes.shape[:2]
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
        if not np.all(np.isfinite(flat)):
            raise CamsimError(f"image {path} has NaN or infinite values")
        if np.any(flat < 0):
            raise CamsimError(f"image {path} has negative values: a reflectance image needs values ≥ 0")
        values, inverse = np.unique(flat.view(np.dtype((np.void, 12))).ravel(), return_inverse=True)
        linear = values.view(np.float32).reshape(-1, 3).astype(np.float64)
    labels = inverse.reshape(height, width)
    labels = labels.view(np.uint32) if labels.dtype == np.int32 else labels.astype(np.uint32)  # indices are ≥ 0
    return labels, linear
