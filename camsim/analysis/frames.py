"""Reading frames back from files — never from the renderer's memory.

A frame is a DNG plus its JSON sidecar (same stem), or an EXR, whose header carries the whole sidecar
(``camsim:metadata``); so frames that were moved or renamed (with their sidecar) still analyse.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from camsim.errors import CamsimError

SOURCES = ("dng", "exr")
_REQUIRED = ("illuminant", "intensity_factor", "photon_statistics", "dn_per_electron", "black_level_dn",
             "wavelengths_nm", "qe_e_m2_sr_per_photon", "patches", "stages", "bits", "white_level_dn")


@dataclass(frozen=True)
class LoadedFrame:
    """A frame read from disk.

    Attributes
    ----------
    path : Path
        The pixel file.
    source : {'dng', 'exr'}
        ``dng``: the digital numbers I (quantised); ``exr``: the signal before quantisation.
    pixels_dn : numpy.ndarray, shape (3, H, W), or (1, H, W) for a Bayer (CFA) frame
        uint8 / uint16 for a DNG, float32 for an EXR. Unit: DN.
    meta : dict
        The sidecar.
    """

    path: Path
    source: str
    pixels_dn: np.ndarray
    meta: dict

    @property
    def cfa_pattern(self) -> str | None:
        """The Bayer pattern of a colour-filter-array frame (one value per pixel), None for three-chip frames."""
        return self.meta.get("cfa_pattern")

    @property
    def quantised(self) -> bool:
        return self.source == "dng"

    def expected_black_dn(self) -> np.ndarray:
        """The expected dark level of this file's numbers, per channel. Unit: DN.

        The sidecar's mean dark level k · σ²_dark · T; for quantised numbers minus ½ DN, because Eq. 11 keeps the
        integer part, which lowers the numbers by ½ DN on average.
        """
        black = np.asarray(self.meta["black_level_dn"], dtype=np.float64)
        return black - 0.5 if self.quantised else black


def _read_sidecar(path: Path) -> dict:
    try:
        meta = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise CamsimError(f"sidecar not found: {path} (a DNG is analysed with its .json sidecar)") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise CamsimError(f"cannot read sidecar {path}: {exc}") from None
    return meta


def _check_meta(meta, path: Path, shape) -> dict:
    if not isinstance(meta, dict):
        raise CamsimError(f"{path}: metadata is not a JSON object")
    missing = [key for key in _REQUIRED if key not in meta]
    if missing:
        raise CamsimError(f"{path}: metadata lacks {', '.join(missing)} (not a camsim frame?)")
    height, width = shape[1:]
    if (meta.get("height_px"), meta.get("width_px")) != (height, width):
        raise CamsimError(f"{path}: the sidecar describes a {meta.get('width_px')}x{meta.get('height_px')} frame "
                          f"but the file holds {width}x{height}: wrong sidecar?")
    return meta


def load_frame(path: str | Path) -> LoadedFrame:
    """Load a ``.dng`` (with its ``.json`` sidecar beside it) or an ``.exr`` frame.

    Raises
    ------
    CamsimError
        Unreadable, truncated or foreign files, a missing or mismatched sidecar.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".dng":
        from camsim.io.dng import read_dng

        dn, _ = read_dng(path)
        meta = _check_meta(_read_sidecar(path.with_suffix(".json")), path, dn.shape)
        return LoadedFrame(path, "dng", dn, meta)
    if suffix == ".exr":
        from camsim.io.exr import read_exr

        noisy, _, header = read_exr(path)
        if "camsim:metadata" in header:
            try:
                meta = json.loads(header["camsim:metadata"])
            except json.JSONDecodeError as exc:
                raise CamsimError(f"{path}: header camsim:metadata is not valid JSON ({exc})") from None
        else:
            meta = _read_sidecar(path.with_suffix(".json"))
        return LoadedFrame(path, "exr", noisy, _check_meta(meta, path, noisy.shape))
    raise CamsimError(f"not a frame file (.dng or .exr): {path}")


def find_frames(paths, source: str = "dng") -> list[Path]:
    """The frame files named by ``paths`` (files, or folders searched recursively), one per frame.

    A frame present as both DNG and EXR is taken from ``source``; a frame with only the other kind is taken
    from that (e.g. no DNG is written when quantisation is off).
    """
    if source not in SOURCES:
        raise CamsimError(f"source must be one of {SOURCES}, got {source!r}")
    found: dict[Path, dict[str, Path]] = {}
    for entry in paths:
        entry = Path(entry)
        if entry.is_dir():
            candidates = [p for p in sorted(entry.rglob("*")) if p.suffix.lower() in (".dng", ".exr")]
        elif entry.is_file():
            candidates = [entry]
        else:
            raise CamsimError(f"no such file or folder: {entry}")
        for candidate in candidates:
            kind = candidate.suffix.lower().lstrip(".")
            if kind not in SOURCES:
                raise CamsimError(f"not a frame file (.dng or .exr): {candidate}")
            found.setdefault(candidate.with_suffix(""), {})[kind] = candidate
    if not found:
        raise CamsimError(f"no .dng or .exr frames in {', '.join(str(p) for p in paths)}")
    other = "exr" if source == "dng" else "dng"
    return [kinds.get(source, kinds.get(other)) for _, kinds in sorted(found.items())]
