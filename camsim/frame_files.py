"""The frame format, both ways: writing a rendered frame and reading one back — never from the renderer's memory.

A frame is ``STEM.dng`` (the quantised digital numbers; none without quantisation), ``STEM.exr`` (float DN before
quantisation plus the ``clean`` layer; its header carries the whole sidecar under ``camsim:metadata``) and
``STEM.json``, the sidecar (:func:`sidecar`). A DNG is read with its sidecar beside it, an EXR on its own, so
frames that were moved or renamed (with their sidecar) still read.

No wall-clock time goes into any file, so that the same seed gives byte-identical files. Every file is written
under a temporary name and renamed when complete.

A frame is committed by its sidecar: :func:`write_frame` writes the pixel files first and renames the sidecar
into place last, so a frame whose sidecar is there is complete, and the files no sidecar claims belong to a frame
that was never finished (readers skip them). A frame being re-written loses its old sidecar first; a write that
fails removes the files it had written.
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass
from functools import partial
from pathlib import Path

import numpy as np

import camsim
from camsim.io.atomic import undo_on_failure, write_json_atomic
from camsim.errors import CamsimError, output_error
from camsim.io.dng import read_dng, write_dng, write_dng_cfa
from camsim.io.exr import read_exr, write_exr
from camsim.io.output_folder import make_folder
from camsim.rawcolour import CALIBRATION_ILLUMINANT_D65
from camsim.methods import get_method
from camsim.render import Frame


#: The sidecar file's suffix, beside the DNG and EXR of the same stem.
SIDECAR_SUFFIX = ".json"
#: The EXR header attribute holding the whole sidecar as JSON.
EXR_METADATA_KEY = "camsim:metadata"


@dataclass(frozen=True)
class FrameInfo:
    """What a sidecar says about a frame besides the frame's own arrays."""

    scene: str
    illuminant: str
    intensity_factor: float
    seed: int
    photon_statistics: str
    method: str
    camera: str
    sensitivity_basis: str
    reflectances: str
    wavelengths_nm: np.ndarray
    luminance_cd_m2: float
    normalisation: str
    scale: dict
    patch_names: list
    patch_rects: list
    color_matrix1: np.ndarray
    as_shot_neutral: np.ndarray
    patch_xyz: np.ndarray | None = None


def frame_stem(scene: str, illuminant: str, intensity_factor: float) -> str:
    """File stem of a frame, e.g. ``macbeth_26_D65_F0.1``; safe on every file system."""
    slug = re.sub(r"[^A-Za-z0-9.+-]+", "-", illuminant).strip("-")
    return f"{scene}_{slug}_F{intensity_factor:g}"


def sidecar(frame: Frame, info: FrameInfo, files: dict) -> dict:
    """The JSON sidecar of a frame: every parameter with its unit, and per patch the model's expectations."""
    sensor = frame.sensor
    ex = frame.expected
    k = sensor.dn_per_electron
    patches = []
    for index, (name, rect) in enumerate(zip(info.patch_names, info.patch_rects)):
        patches.append(
            {
                "name": name,
                "rect_xywh": [int(v) for v in rect],
                "signal_e": ex.signal_e[index].tolist(),
                "dark_e": ex.dark_e.tolist(),
                "signal_var_e2": ex.signal_var_e2[index].tolist(),
                "clean_dn": (ex.clean_e[index] * k).tolist(),
                "xyz_cd_m2": None if info.patch_xyz is None else info.patch_xyz[index].tolist(),
            }
            | ({"sampling": frame.plan.names(index), "gaussian_ks": frame.plan.predicted_ks[index].tolist()}
               if get_method(info.method).records_sampling else {}),
        )
    height, width = frame.labels.shape
    return {
        "camsim_version": camsim.__version__,
        "scene": info.scene,
        "illuminant": info.illuminant,
        "intensity_factor": info.intensity_factor,
        "seed": info.seed,
        "photon_statistics": info.photon_statistics,
        "method": info.method,
        "auto_tolerance_ks": None if frame.plan is None else frame.plan.tolerance,
        "camera": info.camera,
        "sensitivity_basis": info.sensitivity_basis,
        "reflectances": info.reflectances,
        "width_px": width,
        "height_px": height,
        "channels": ["R", "G", "B"],
        **sensor.sidecar_record(),
        "luminance_cd_m2": info.luminance_cd_m2,
        "normalisation": info.normalisation,
        "scale": info.scale,
        "wavelengths_nm": info.wavelengths_nm.tolist(),
        "qe_e_m2_sr_per_photon": ex.qe.tolist(),
        "color_matrix1_xyz_to_camera": info.color_matrix1.tolist(),
        "calibration_illuminant1": CALIBRATION_ILLUMINANT_D65,
        "as_shot_neutral": info.as_shot_neutral.tolist(),
        "patches": patches,
        # a chart's last spectrum is its surround; a cube has no patches and no surround
        "surround": {"signal_e": ex.signal_e[len(patches)].tolist()} if patches else None,
        "units": {
            "signal_e": "e- (mean signal electrons per pixel in the exposure)",
            "dark_e": "e- (mean dark electrons per pixel in the exposure)",
            "signal_var_e2": "e-^2 (variance of the signal electrons under the photon statistics)",
            "clean_dn": "DN (expected value after saturation, before read noise and quantisation)",
            "xyz_cd_m2": "CIE 1931 XYZ of the patch's light at this F (Y = luminance, cd/m^2)",
            "sampling": "gaussian and auto methods: how each channel of the patch was drawn (poisson = exact)",
            "gaussian_ks": "per channel, the KS distance a Gaussian draw has to the exact law (auto takes the "
                           "Gaussian where it is within auto_tolerance_ks)",
            "qe_e_m2_sr_per_photon": "e- m^2 sr / photon, rows R, G, B on wavelengths_nm",
            "rect_xywh": "pixels: x, y of the top-left corner, width, height",
            "exr_channels": "R, G, B (or CFA, the Bayer mosaic): noisy DN before quantisation; clean.R, clean.G, "
                            "clean.B: expected DN of every channel at every pixel",
        },
        "files": files,
    }


def write_frame(out_dir: Path, stem: str, frame: Frame, info: FrameInfo, preview: bool = False) -> dict:
    """Write ``stem.dng`` (if quantised), ``stem.exr`` and ``stem.json`` into ``out_dir``.

    With ``preview``, also ``stem.png``: an 8-bit sRGB picture of the frame (:func:`camsim.preview.preview_srgb`,
    default exposure), listed in the sidecar's ``files`` as ``png``.

    Returns
    -------
    dict
        File names relative to ``out_dir`` by kind (``dng`` is None when quantisation is off: an integer raw
        file cannot hold unquantised values).
    """
    files = {"dng": f"{stem}.dng" if frame.digital_dn is not None else None, "exr": f"{stem}.exr",
             "json": f"{stem}{SIDECAR_SUFFIX}"}
    if preview:
        files["png"] = f"{stem}.png"
    meta = sidecar(frame, info, files)
    make_folder(out_dir)
    uncommit_frame(out_dir, stem)
    with undo_on_failure():  # a failed or interrupted write leaves none of the frame's files
        _write_pixel_files(out_dir, files, frame, info, meta)
        write_json_atomic(out_dir / files["json"], meta)  # last: the commit record
    return files


def uncommit_frame(out_dir: Path, stem: str) -> None:
    """Remove frame ``stem``'s sidecar (if any), so that its files are no longer a committed frame, and then its
    pixel files (which also frees their space for the frame about to replace them)."""
    out_dir = Path(out_dir)
    for name in (f"{stem}{SIDECAR_SUFFIX}", *(f"{stem}.{kind}" for kind in (*PIXEL_FILE_KINDS, "png"))):
        try:
            (out_dir / name).unlink(missing_ok=True)
        except OSError as exc:
            raise output_error(out_dir / name, exc) from None


def _write_pixel_files(out_dir: Path, files: dict, frame: Frame, info: FrameInfo, meta: dict) -> None:
    """The frame's DNG (if quantised), EXR and preview PNG (if asked for), each written atomically."""
    sensor = frame.sensor
    if frame.digital_dn is not None:
        write = write_dng if sensor.cfa is None else partial(write_dng_cfa, pattern=sensor.cfa)
        write(
            out_dir / files["dng"],
            frame.digital_dn if sensor.cfa is None else frame.digital_dn[0],
            black_level_dn=sensor.black_level_tag_dn,  # below the white level, as readers need
            white_level=sensor.max_dn,
            unique_camera_model=f"camsim {info.camera}",
            color_matrix1=info.color_matrix1,
            as_shot_neutral=info.as_shot_neutral,
            calibration_illuminant1=CALIBRATION_ILLUMINANT_D65,
            model=info.camera,
            software=f"camsim {camsim.__version__}",
        )
    header = {
        "camsim:scene": info.scene,
        "camsim:illuminant": info.illuminant,
        "camsim:intensity_factor": repr(info.intensity_factor),
        "camsim:seed": str(info.seed),
        "camsim:photon_statistics": info.photon_statistics,
        "camsim:method": info.method,
        "camsim:camera": info.camera,
        "camsim:dn_per_electron": repr(sensor.dn_per_electron),
        "camsim:black_level_dn": json.dumps(sensor.black_level_dn.tolist()),
        "camsim:units": "DN",
        EXR_METADATA_KEY: json.dumps(meta, ensure_ascii=False),
    }
    write_exr(out_dir / files["exr"], frame.noisy_dn, frame.clean_dn(), header)
    if "png" in files:
        from camsim.preview import preview_srgb, write_preview_png

        write_preview_png(out_dir / files["png"], preview_srgb(frame, info))


# --- reading ----------------------------------------------------------------------------------------------

#: The pixel files a frame may be read from (not to be confused with scene sources, camsim.sources).
PIXEL_FILE_KINDS = ("dng", "exr")
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
        dn, _ = read_dng(path)
        meta = _check_meta(_read_sidecar(path.with_suffix(SIDECAR_SUFFIX)), path, dn.shape)
        return LoadedFrame(path, "dng", dn, meta)
    if suffix == ".exr":
        noisy, _, header = read_exr(path)
        if EXR_METADATA_KEY in header:
            try:
                meta = json.loads(header[EXR_METADATA_KEY])
            except json.JSONDecodeError as exc:
                raise CamsimError(f"{path}: header {EXR_METADATA_KEY} is not valid JSON ({exc})") from None
        else:
            meta = _read_sidecar(path.with_suffix(SIDECAR_SUFFIX))
        return LoadedFrame(path, "exr", noisy, _check_meta(meta, path, noisy.shape))
    raise CamsimError(f"not a frame file (.dng or .exr): {path}")


def find_frames(paths, source: str = "dng") -> list[Path]:
    """The frame files named by ``paths`` (files, or folders searched recursively), one per frame.

    A frame present as both DNG and EXR is taken from ``source``; a frame with only the other kind is taken
    from that (e.g. no DNG is written when quantisation is off).
    """
    if source not in PIXEL_FILE_KINDS:
        raise CamsimError(f"source must be one of {PIXEL_FILE_KINDS}, got {source!r}")
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
            if kind not in PIXEL_FILE_KINDS:
                raise CamsimError(f"not a frame file (.dng or .exr): {candidate}")
            found.setdefault(candidate.with_suffix(""), {})[kind] = candidate
    if not found:
        raise CamsimError(f"no .dng or .exr frames in {', '.join(str(p) for p in paths)}")
    other = "exr" if source == "dng" else "dng"
    return [kinds.get(source, kinds.get(other)) for _, kinds in sorted(found.items())]
