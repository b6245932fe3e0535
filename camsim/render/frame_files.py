"""The frame format, both ways: writing a rendered frame and reading one back — never from the renderer's memory.

A frame is ``STEM.dng`` (the quantised digital numbers; none without quantisation), ``STEM.exr`` (a picture for
image viewers in ``R, G, B`` (:func:`exr_view`), the float DN before quantisation in the ``noisy`` layer and their
expected values in the ``clean`` layer; its header carries the whole sidecar under ``camsim:metadata``) and
``STEM.json``, the sidecar (:func:`sidecar`). A DNG is read with its sidecar beside it, an EXR on its own, so
frames that were moved or renamed (with their sidecar) still read.

The sidecar is the commit record: it is written last and its ``files`` names the frame's files. A search of a
folder (:func:`search_frames`) takes only committed frames, whose sidecar claims the file, and passes over hidden
files (temporaries); a file named explicitly is read as it is, so a renamed frame is read by naming it.

No wall-clock time goes into any file, so that the same seed gives byte-identical files. Every file is written
under a temporary name and renamed when complete.

A frame is committed by its sidecar: :func:`write_frame` writes the pixel files first and renames the sidecar
into place last, so a frame whose sidecar is there is complete, and the files no sidecar claims belong to a frame
that was never finished (readers skip them). A frame being re-written loses its old sidecar first; a write that
fails removes the files it had written.
"""

from __future__ import annotations

import json
import os
import re
from dataclasses import dataclass
from functools import partial
from pathlib import Path

import numpy as np

import camsim
from camsim.colour.rawcolour import CALIBRATION_ILLUMINANT_D65
from camsim.core.errors import CamsimError, output_error
from camsim.core.input_files import check_input, read_input
from camsim.core.names import MAX_STEM_BYTES, safe_component
from camsim.io.atomic import undo_on_failure, write_json_atomic, write_text_atomic
from camsim.io.dng import DARKTABLE_XMP_SUFFIX, darktable_xmp, read_dng, write_dng, write_dng_cfa
from camsim.io.exr import DEFAULT_EXR_COMPRESSION, check_exr_compression, read_exr, read_exr_header, write_exr
from camsim.io.output_folder import make_folder
from camsim.methods import get_method
from camsim.render.frame import Frame
from camsim.render.sidecar_schema import MAX_SIDECAR_BYTES, check_sidecar, parse_sidecar
from camsim.scene.regions import weighted_rows
from camsim.sensor.noise_profile import frame_noise_profile

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
    exposure: dict | None = None  # how T was chosen: camsim.render.pipeline.exposure_record (None: a fixed T)
    surround: bool = True  # whether the spectrum after the patches is a chart's surround
    target: dict | None = None  # a synthetic target's geometry (camsim.scene.sources.target), the sidecar's "target"
    recovery: dict | None = None  # an image's RGB → spectrum recovery, out of gamut (camsim.scene.sources.image)
    # regions as patches (camsim.scene.regions): per patch (spectrum indices, pixel counts); None: patch i is spectrum i
    patch_weights: tuple | None = None
    white_signal_e_per_s: np.ndarray | None = None  # the perfect white's e⁻/s per channel at F = 1 (LitScene)
    preset: dict | None = None  # a camera preset's name (or file) and ISO: the sidecar's "preset" and "iso"
    # the device that drew the frame, where not the CPU (camsim.render.backends.device_record): the sidecar's "device",
    # "device_name", "device_library" and, where a device draws another method, "method_requested"
    device: dict | None = None
    # a sequence's frame (camsim.render.sequence): its keys frame_index, time_s, homography, sequence …, at the top
    sequence: dict | None = None
    # the scene's [optics] (camsim.render.optics): the table, channel_wavelength_weights, otf_model, negative_clipped_e
    # and _fraction: the sidecar's "optics"
    optics: dict | None = None


def frame_stem(scene: str, illuminant: str, intensity_factor: float) -> str:
    """File stem of a frame, e.g. ``macbeth_26_D65_F0.1``; safe on every file system (checked:
    :func:`camsim.core.names.safe_component`, a :class:`CamsimError` otherwise)."""
    slug = re.sub(r"[^A-Za-z0-9.+-]+", "-", illuminant).strip("-")
    return safe_component(f"{scene}_{slug}_F{intensity_factor:g}", "frame name", MAX_STEM_BYTES)


def effects_record(sensor, maps, black_level_error_dn) -> dict:
    """A frame's records of issue 28's effects, each only where its effect is on (so that every other frame's
    sidecar stays byte for byte as it was): ``dark_current_effective_e_per_s`` (R, G, B, e⁻/s: the dark current at
    ``temperature_c``), ``defect_counts`` (``{"hot", "dead", "stuck"}``: the frame's pixels of each population) and
    ``black_level_error_drawn_dn`` (R, G, B, DN: the frame's drawn black-level error)."""
    out = {}
    if sensor.temperature_c is not None:
        out["dark_current_effective_e_per_s"] = [float(v) for v in sensor.dark_current_effective_e_per_s]
    if maps is not None and maps.defect_counts is not None:
        out["defect_counts"] = dict(maps.defect_counts)
    if black_level_error_dn is not None:
        out["black_level_error_drawn_dn"] = [float(v) for v in black_level_error_dn]
    return out


def sidecar(frame: Frame, info: FrameInfo, files: dict | None, exr_compression: str | None = None) -> dict:
    """The JSON sidecar of a frame: every parameter with its unit, and per patch the model's expectations.

    ``files`` names the frame's files by kind (None: the frame is not in files of its own, e.g. it is a frame of a
    Zarr store); ``exr_compression`` the compression of its EXR, recorded as ``exr_compression`` (None: no key).
    """
    sensor = frame.sensor
    ex = frame.expected
    k = sensor.dn_per_electron
    patches = []
    for index, (name, rect) in enumerate(zip(info.patch_names, info.patch_rects)):
        if info.patch_weights is None:  # a chart's patch: one spectrum
            per_patch = lambda rows: np.asarray(rows[index])  # noqa: E731
        else:  # a region: the pixel-weighted mean over the spectra inside it
            per_patch = partial(weighted_rows, indices=info.patch_weights[index][0],
                                counts=info.patch_weights[index][1])
        patches.append(
            {
                "name": name,
                "rect_xywh": [int(v) for v in rect],
                "signal_e": per_patch(ex.signal_e).tolist(),
                "dark_e": ex.dark_e.tolist(),
                "signal_var_e2": per_patch(ex.signal_var_e2).tolist(),
                "clean_dn": (per_patch(ex.clean_e) * k).tolist(),
                "xyz_cd_m2": None if info.patch_xyz is None else info.patch_xyz[index].tolist(),
            }
            | ({"sampling": frame.plan.names(index), "gaussian_ks": frame.plan.predicted_ks[index].tolist()}
               if get_method(info.method).records_sampling and info.patch_weights is None else {}),
        )
    height, width = frame.labels.shape
    profile = frame_noise_profile(frame, info.photon_statistics)
    return {
        "camsim_version": camsim.__version__,
        "scene": info.scene,
        "illuminant": info.illuminant,
        "intensity_factor": info.intensity_factor,
        "seed": info.seed,
        "photon_statistics": info.photon_statistics,
        "method": info.method,
        **(info.device or {}),
        "auto_tolerance_ks": None if frame.plan is None else frame.plan.tolerance,
        **(info.exposure if info.exposure is not None else {"exposure": "fixed"}),
        "camera": info.camera,
        "sensitivity_basis": info.sensitivity_basis,
        "reflectances": info.reflectances,
        "width_px": width,
        "height_px": height,
        "channels": ["R", "G", "B"],
        **sensor.sidecar_record(),
        **effects_record(sensor, frame.maps, frame.black_level_error_dn),
        **(info.preset or {}),
        # the DNG's NoiseProfile: per channel (S, O), the temporal variance of the normalised value is S x + O
        "noise_profile": None if profile is None else profile.tolist(),
        "luminance_cd_m2": info.luminance_cd_m2,
        "normalisation": info.normalisation,
        "scale": info.scale,
        "wavelengths_nm": info.wavelengths_nm.tolist(),
        "qe_e_m2_sr_per_photon": ex.qe.tolist(),
        "color_matrix1_xyz_to_camera": info.color_matrix1.tolist(),
        "calibration_illuminant1": CALIBRATION_ILLUMINANT_D65,
        "as_shot_neutral": info.as_shot_neutral.tolist(),
        "patches": patches,
        # a chart's last spectrum is its surround; a cube has no patches and no surround, nor has a target
        "surround": {"signal_e": ex.signal_e[len(patches)].tolist()} if patches and info.surround else None,
        **({"target": info.target} if info.target is not None else {}),
        **({"recovery": info.recovery} if info.recovery is not None else {}),
        **(info.sequence or {}),
        **({"optics": info.optics} if info.optics is not None else {}),
        # the perfect white (reflectance 1) under the frame's light at this F, in this exposure: the colour white
        **({"white_signal_e": (info.white_signal_e_per_s * info.intensity_factor * sensor.exposure_s).tolist()}
           if info.white_signal_e_per_s is not None else {}),
        "units": {
            "signal_e": "e- (mean signal electrons per pixel in the exposure; a region's: the mean over its pixels)",
            "dark_e": "e- (mean dark electrons per pixel in the exposure)",
            "white_signal_e": "e- (mean signal electrons of the perfect white under the frame's light at this F, "
                              "in the exposure; no saturation)",
            "signal_var_e2": "e-^2 (variance of the signal electrons under the photon statistics)",
            "clean_dn": "DN (expected value after saturation, before read noise and quantisation)",
            "xyz_cd_m2": "CIE 1931 XYZ of the patch's light at this F (Y = luminance, cd/m^2)",
            "sampling": "gaussian and auto methods: how each channel of the patch was drawn (poisson = exact, "
                        "under paper statistics the scaled-Poisson stand-in; spectral = Eq. 4's per-bin draws)",
            "gaussian_ks": "per channel, the KS distance a Gaussian draw has to the exact law of a pixel value "
                           "before quantisation (paper statistics: an upper bound; auto takes the Gaussian where "
                           "it is within auto_tolerance_ks)",
            "qe_e_m2_sr_per_photon": "e- m^2 sr / photon, rows R, G, B on wavelengths_nm",
            "rect_xywh": "pixels: x, y of the top-left corner, width, height",
            **({"recovery": "an image scene's RGB -> spectrum recovery: out_of_gamut_fraction = share of the "
                            "scene's pixels whose colour the method cannot reproduce (0 to 1); max_clip = largest "
                            "linear sRGB component set to 0 (Mallett 2019; 1 = the perfect white's); "
                            "max_delta_e00_outside = largest CIE 2000 dE of such a pixel's spectrum to its colour "
                            "under D65"} if info.recovery is not None else {}),
            "noise_profile": "per channel R, G, B: [S, O] of the DNG's NoiseProfile tag (unitless): the temporal "
                             "noise variance of x = (DN - B) / (W - B) is S x + O, B the DNG's BlackLevel "
                             "(black_level_tag_dn where given, else black_level_dn) and W white_level_dn (shot, "
                             "dark-shot, read and row noise and the quantiser's 1/12 DN^2; no DSNU or PRNU); null "
                             "where no DNG is written or without photon noise",
            "exr_channels": "noisy.R, noisy.G, noisy.B (or noisy.CFA, the Bayer mosaic): noisy DN before "
                            "quantisation; clean.R, clean.G, clean.B: expected DN of every channel at every pixel; "
                            "R, G, B: the picture for viewers (the header's camsim:view says what it is)",
        },
        **({"exr_compression": exr_compression} if exr_compression is not None else {}),
        "files": files,
    }


def write_frame(out_dir: Path, stem: str, frame: Frame, info: FrameInfo, preview: bool = False,
                exr_compression: str = DEFAULT_EXR_COMPRESSION) -> dict:
    """Write ``stem.dng`` (if quantised), ``stem.exr`` and ``stem.json`` into ``out_dir``.

    A three-chip DNG gets ``stem.dng.xmp`` beside it, ``files``' ``xmp``: darktable's sidecar with its black level
    (:func:`camsim.io.dng.darktable_xmp`), which darktable cannot read from such a DNG. With ``preview``, also
    ``stem.png``: an 8-bit sRGB picture of the frame (:func:`camsim.render.preview.preview_srgb`,
    default exposure), listed in the sidecar's ``files`` as ``png``. ``exr_compression``: a lossless name of
    :data:`camsim.io.exr.EXR_COMPRESSIONS`, recorded in the sidecar.

    Returns
    -------
    dict
        File names relative to ``out_dir`` by kind (``dng`` is None when quantisation is off: an integer raw
        file cannot hold unquantised values).
    """
    check_exr_compression(exr_compression)  # before any file is touched
    files = {"dng": f"{stem}.dng" if frame.digital_dn is not None else None, "exr": f"{stem}.exr",
             "json": f"{stem}{SIDECAR_SUFFIX}"}
    if frame.digital_dn is not None and frame.sensor.cfa is None:  # darktable reads no three-chip black level
        files["xmp"] = f"{stem}{DARKTABLE_XMP_SUFFIX}"
    if preview:
        files["png"] = f"{stem}.png"
    meta = sidecar(frame, info, files, exr_compression)
    make_folder(out_dir)
    uncommit_frame(out_dir, stem)
    with undo_on_failure():  # a failed or interrupted write leaves none of the frame's files
        _write_pixel_files(out_dir, files, frame, info, meta, exr_compression)
        write_json_atomic(out_dir / files["json"], meta)  # last: the commit record
    return files


def uncommit_frame(out_dir: Path, stem: str) -> None:
    """Remove frame ``stem``'s sidecar (if any), so that its files are no longer a committed frame, and then its
    pixel files (which also frees their space for the frame about to replace them)."""
    out_dir = Path(out_dir)
    for name in (f"{stem}{SIDECAR_SUFFIX}", *(f"{stem}.{kind}" for kind in (*PIXEL_FILE_KINDS, "png")),
                 f"{stem}{DARKTABLE_XMP_SUFFIX}"):
        try:
            (out_dir / name).unlink(missing_ok=True)
        except OSError as exc:
            raise output_error(out_dir / name, exc) from None


def _write_pixel_files(out_dir: Path, files: dict, frame: Frame, info: FrameInfo, meta: dict,
                       exr_compression: str = DEFAULT_EXR_COMPRESSION) -> None:
    """The frame's DNG (if quantised), EXR and preview PNG (if asked for), each written atomically."""
    sensor = frame.sensor
    if frame.digital_dn is not None:
        write = write_dng if sensor.cfa is None else partial(write_dng_cfa, pattern=sensor.cfa)
        write(
            out_dir / files["dng"],
            frame.digital_dn if sensor.cfa is None else frame.digital_dn[0],
            black_level_dn=sensor.black_level_tag_dn,  # below the white level, as readers need
            white_level=sensor.max_dn,
            color_matrix1=info.color_matrix1,
            as_shot_neutral=info.as_shot_neutral,
            calibration_illuminant1=CALIBRATION_ILLUMINANT_D65,
            software=f"camsim {camsim.__version__}",
            noise_profile=meta["noise_profile"],  # the sidecar's pairs, exactly
            iso=(info.preset or {}).get("iso"),  # a camera preset's ISO (None: no ISO, no tag)
            exposure_s=float(sensor.exposure_s),
            **camera_identity(info),
        )
        if "xmp" in files:  # darktable reads no BlackLevel of a three-chip DNG: its own sidecar holds it
            write_text_atomic(out_dir / files["xmp"], darktable_xmp(sensor.black_level_tag_dn, sensor.max_dn))
    header = exr_header(meta, sensor)
    view, view_header = exr_view(frame, info)
    header.update(view_header)
    write_exr(out_dir / files["exr"], frame.noisy_dn, frame.clean_dn(), header, exr_compression, view=view)
    if "png" in files:
        from camsim.render.preview import preview_srgb, write_preview_png

        write_preview_png(out_dir / files["png"], preview_srgb(frame, info))


def exr_header(meta: dict, sensor) -> dict:
    """The EXR header attributes of a frame with sidecar ``meta`` and sensor ``sensor`` (besides its view's): the
    keys that tell frames apart, the levels, and the whole sidecar under :data:`EXR_METADATA_KEY`."""
    return {
        "camsim:scene": meta["scene"],
        "camsim:illuminant": meta["illuminant"],
        "camsim:intensity_factor": repr(meta["intensity_factor"]),
        "camsim:seed": str(meta["seed"]),
        "camsim:photon_statistics": meta["photon_statistics"],
        "camsim:method": meta["method"],
        "camsim:camera": meta["camera"],
        "camsim:dn_per_electron": repr(sensor.dn_per_electron),
        "camsim:black_level_dn": json.dumps(sensor.black_level_dn.tolist()),
        "camsim:dark_level_dn": json.dumps(sensor.dark_level_dn.tolist()),  # the mean of these values in the dark
        "camsim:white_level_dn": str(sensor.max_dn),
        "camsim:units": "DN (layers noisy and clean; R, G, B: see camsim:view)",
        EXR_METADATA_KEY: json.dumps(meta, ensure_ascii=False),
    }


#: What the EXR's ``R, G, B`` hold, by the matrix that made them (the header's ``camsim:view``).
VIEW_DESCRIPTIONS = {
    "least-squares": "linear sRGB (IEC 61966-2-1 primaries, D65 white), 1 = the perfect white at F = 1: "
                     "camsim:view_matrix @ (noisy DN - camsim:dark_level_dn), a Bayer mosaic demosaiced "
                     "(bilinear) first; the matrix fitted on the chart, white-balanced to D65",
    "paper": "linear sRGB (IEC 61966-2-1 primaries, D65 white), 1 = the perfect white at F = 1: "
             "camsim:view_matrix @ (noisy DN - camsim:dark_level_dn), a Bayer mosaic demosaiced (bilinear) first; "
             "the matrix of Eq. 15 (no chart to fit on), white-balanced to D65",
    "camera": "camera R, G, B (noisy DN - camsim:view_black_dn) / (camsim:white_level_dn - camsim:view_black_dn): "
              "0 = the dark level, 1 = the white level; a Bayer mosaic as grey (R = G = B)",
}


def exr_view(frame: Frame, info: FrameInfo) -> tuple[np.ndarray, dict[str, str]]:
    """The picture a frame's EXR holds in ``R, G, B`` for image viewers, and the header attributes saying what it is.

    Linear sRGB, 1 = the perfect white at F = 1, from the values before quantisation
    (:func:`camsim.render.preview.linear_srgb`: the ``--preview`` PNG's picture before its clip and transfer function),
    so that a viewer shows the scene in its colours, at its light level (a frame at F is F times darker), with black at
    0. The camera → XYZ matrix is fitted on the chart's patches; where that fit cannot be made (a frame without
    patches, or patches that do not span the colours, such as a dark or a flat frame) Eq. 15's matrix is taken; where
    that cannot white-balance either, the camera's own R, G, B scaled so that the dark level is 0 and the white level
    1 (a Bayer mosaic as grey).

    Returns
    -------
    view : numpy.ndarray, shape (3, H, W), float32
        Linear R, G, B. Unit: 1 = the perfect white at F = 1 (``camera``: 1 = the white level).
    header : dict of str to str
        ``camsim:view`` (what the picture is: :data:`VIEW_DESCRIPTIONS`), ``camsim:view_matrix`` (the 3 × 3 matrix
        from black-subtracted camera DN to linear sRGB, rows R, G, B, as JSON) or, for ``camera``,
        ``camsim:view_black_dn`` (per channel, DN, as JSON).
    """
    from camsim.render.preview import linear_srgb, preview_transform

    fit = info.patch_xyz is not None and len(info.patch_xyz) >= 3  # else preview_transform takes Eq. 15's
    for matrix in ("least-squares", "paper") if fit else ("paper",):
        try:
            transform = preview_transform(frame, info, matrix=matrix)
        except (CamsimError, ValueError):  # no white balance, or a singular fit
            continue
        if np.all(np.isfinite(transform)):
            return (linear_srgb(frame, info, matrix=matrix, transform=transform),
                    {"camsim:view": VIEW_DESCRIPTIONS[matrix], "camsim:view_matrix": json.dumps(transform.tolist())})
    return camera_view(frame.noisy_dn, frame.sensor)


def camera_view(noisy_dn: np.ndarray, sensor) -> tuple[np.ndarray, dict[str, str]]:
    """The ``camera`` picture of :func:`exr_view` (:data:`VIEW_DESCRIPTIONS`) of values ``noisy_dn`` (3, H, W) or a
    mosaic (1, H, W), and its header attributes: (DN − dark level) / (white level − dark level), a mosaic as grey."""
    black = np.minimum(sensor.dark_level_dn, sensor.max_dn - 1.0)  # below the white level: a positive scale
    view = np.empty((3, *noisy_dn.shape[1:]), dtype=np.float32)
    if sensor.cfa is None:
        for c in range(3):
            view[c] = (noisy_dn[c].astype(np.float64) - black[c]) / (sensor.max_dn - black[c])
    else:
        from camsim.sensor.cfa import cfa_sites

        for dy, dx, c in cfa_sites(sensor.cfa):
            view[0, dy::2, dx::2] = ((noisy_dn[0, dy::2, dx::2].astype(np.float64) - black[c])
                                     / (sensor.max_dn - black[c]))
        view[1:] = view[0]
    return view, {"camsim:view": VIEW_DESCRIPTIONS["camera"], "camsim:view_black_dn": json.dumps(black.tolist())}


def camera_identity(info: FrameInfo) -> dict:
    """The DNG's ``make``, ``model`` and ``unique_camera_model`` (ASCII) for a frame.

    With a camera preset at one of its ISO settings (the sidecar's ``iso``; a gain set on top of the preset, as
    a virtual camera's, is no setting of that camera), the camera's, from the preset's title
    (:func:`camsim.sensor.presets.model.camera_identity_of_title`: ``"Sony A7S2 (ILCE-7SM2)"`` → Sony, ILCE-7SM2,
    ``"Sony ILCE-7SM2"``). Otherwise camsim's own: Make ``camsim``,
    Model the spectral curves' name, UniqueCameraModel ``"camsim " + curves``. A calibration of the files names
    its preset after the UniqueCameraModel (``camsim calibrate``).
    """
    title = (info.preset or {}).get("preset_title")
    if not title or (info.preset or {}).get("iso") is None:
        return {"make": "camsim", "model": info.camera, "unique_camera_model": f"camsim {info.camera}"}
    from camsim.sensor.presets.model import camera_identity_of_title

    return camera_identity_of_title(title)


# --- reading ----------------------------------------------------------------------------------------------

#: The pixel files a frame may be read from (not to be confused with scene sources, camsim.scene.sources).
PIXEL_FILE_KINDS = ("dng", "exr")


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

        The sidecar's ``black_level_dn`` (the exact mean digital number of an unlit pixel) for a DNG's quantised
        numbers, its ``dark_level_dn`` (the mean before the ADC) for an EXR's. A sidecar of an older camsim, without
        ``dark_level_dn``, held the level before the ADC as ``black_level_dn``: ½ DN less is its quantised mean.
        """
        black = np.asarray(self.meta["black_level_dn"], dtype=np.float64)
        if "dark_level_dn" not in self.meta:
            return black - 0.5 if self.quantised else black
        return black if self.quantised else np.asarray(self.meta["dark_level_dn"], dtype=np.float64)


def _read_sidecar(path: Path) -> dict:
    if not os.path.lexists(path):
        raise CamsimError(f"sidecar not found: {path} (a DNG is analysed with its .json sidecar)")
    data = read_input(path, "sidecar", MAX_SIDECAR_BYTES)  # a regular file, refused before parsing when too large
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise CamsimError(f"cannot read sidecar {path}: {exc}") from None
    return parse_sidecar(text, path)


def _check_meta(meta, path: Path, shape=None) -> dict:
    """``meta`` if it is a camsim frame's metadata (:func:`camsim.render.sidecar_schema.check_sidecar`: every key the
    readers use of the right type, shape and range, and finite) that fits pixels of ``shape`` (planes, H, W);
    else CamsimError.

    ``shape`` None checks the metadata only (the pixels are not read yet).
    """
    check_sidecar(meta, path)
    if shape is None:
        return meta
    planes, height, width = shape
    if (meta.get("height_px"), meta.get("width_px")) != (height, width):
        raise CamsimError(f"{path}: the sidecar describes a {meta.get('width_px')}x{meta.get('height_px')} frame "
                          f"but the file holds {width}x{height}: wrong sidecar?")
    if (planes == 1) != bool(meta.get("cfa_pattern")):
        held = "a Bayer mosaic" if planes == 1 else "R, G and B at every pixel"
        raise CamsimError(f"{path}: the sidecar describes a {meta.get('cfa_pattern') or 'three-chip'} frame but "
                          f"the file holds {held}: wrong sidecar?")
    return meta


def _exr_meta(path: Path, header: dict) -> dict:
    """The metadata of an EXR: its header's copy of the sidecar, or else the sidecar beside it."""
    if EXR_METADATA_KEY not in header:
        return _read_sidecar(path.with_suffix(SIDECAR_SUFFIX))
    return parse_sidecar(header[EXR_METADATA_KEY], f"{path} (header {EXR_METADATA_KEY})")


def _frame_kind(path: Path) -> str:
    kind = path.suffix.lower().lstrip(".")
    if kind not in PIXEL_FILE_KINDS:
        raise CamsimError(f"not a frame file (.dng or .exr): {path}")
    return kind


def read_frame_meta(path: str | Path) -> dict:
    """The metadata of a frame file without reading its pixels: a DNG's sidecar, an EXR's header.

    What :func:`load_frame` would give as ``meta``, at the cost of a small JSON file or an EXR header, for
    sorting frames before they are loaded one at a time. The pixel dimensions are checked against the metadata
    for an EXR only (a DNG's when it is loaded).

    Raises
    ------
    CamsimError
        Unreadable or foreign files, a missing or mismatched sidecar.
    """
    path = Path(path)
    if _frame_kind(path) == "dng":
        return _check_meta(_read_sidecar(path.with_suffix(SIDECAR_SUFFIX)), path)
    header, shape = read_exr_header(path)
    return _check_meta(_exr_meta(path, header), path, shape)


def load_frame(path: str | Path) -> LoadedFrame:
    """Load a ``.dng`` (with its ``.json`` sidecar beside it) or an ``.exr`` frame.

    An EXR's clean layer is not read (:class:`LoadedFrame` holds the noisy values only).

    Raises
    ------
    CamsimError
        Unreadable, truncated or foreign files, a missing or mismatched sidecar.
    """
    path = Path(path)
    if _frame_kind(path) == "dng":
        dn, _ = read_dng(path)
        meta = _check_meta(_read_sidecar(path.with_suffix(SIDECAR_SUFFIX)), path, dn.shape)
        return LoadedFrame(path, "dng", dn, meta)
    noisy, _, header = read_exr(path, clean=False)
    return LoadedFrame(path, "exr", noisy, _check_meta(_exr_meta(path, header), path, noisy.shape))


@dataclass(frozen=True)
class FrameSearch:
    """What a search for frame files found.

    Attributes
    ----------
    files : list of Path
        One pixel file per frame, in the order of their paths less the suffix: the files named, and the
        committed frames in the folders searched.
    bad : list of tuple (Path, str)
        Files that are no frame, with the reason: a path that does not exist, a file named that is not a
        ``.dng`` or ``.exr``, a sidecar in a folder that cannot be read.
    uncommitted : list of Path
        Frame files (``.dng``, ``.exr``) in the folders searched that no sidecar claims: frames being written,
        or left by an interrupted writer.
    """

    files: list
    bad: list
    uncommitted: list


def _claims(sidecar: Path) -> dict | str | None:
    """The ``files`` record of ``sidecar``: None when there is no such file, the reason when it is unreadable."""
    if not os.path.lexists(sidecar):
        return None
    try:  # a FIFO or device named STEM.json is refused, not read; a sidecar over the limit is not parsed
        meta = parse_sidecar(read_input(sidecar, "sidecar", MAX_SIDECAR_BYTES).decode("utf-8"), sidecar)
    except CamsimError as exc:
        return f"unreadable sidecar ({str(exc).removeprefix(f'cannot read sidecar {sidecar}: ')[:200]})"
    except UnicodeDecodeError as exc:
        return f"unreadable sidecar ({type(exc).__name__}: {str(exc).splitlines()[0][:200]})"
    files = meta.get("files") if isinstance(meta, dict) else None
    return files if isinstance(files, dict) else "not a camsim sidecar (no 'files' record)"


def _search_folder(folder: Path, found: dict, bad: list, uncommitted: list) -> None:
    """Add the committed frame files under ``folder`` to ``found`` (stem → kind → path), and the rest to the lists.

    A frame file is committed when the sidecar of its stem exists and names it in ``files`` (the sidecar is
    written last, as the commit record). Hidden files and folders (names starting with '.': temporaries such as
    ``.x.dng.1234.partial``) are passed over.
    """
    claims_of: dict[Path, dict | str | None] = {}  # sidecar → its claims, read once for the DNG and the EXR
    for path in sorted(folder.rglob("*")):
        if any(part.startswith(".") for part in path.relative_to(folder).parts):
            continue
        kind = path.suffix.lower().lstrip(".")
        if kind not in PIXEL_FILE_KINDS or not path.is_file():
            continue
        sidecar = path.with_suffix(SIDECAR_SUFFIX)
        seen = sidecar in claims_of
        claims = claims_of[sidecar] if seen else claims_of.setdefault(sidecar, _claims(sidecar))
        if isinstance(claims, str):
            if not seen:  # one report per sidecar, not per frame file
                bad.append((sidecar, claims))
        elif claims is not None and claims.get(kind) == path.name:
            found.setdefault(path.with_suffix(""), {})[kind] = path
        else:
            uncommitted.append(path)


def _not_a_file(path: Path) -> str:
    """Why ``path``, neither a folder nor a regular file, is no frame: it does not exist, or what it is (a FIFO, a
    device, a socket; :func:`camsim.core.input_files.check_input` says, without waiting on it)."""
    if not os.path.exists(path):
        return "no such file or folder"
    try:
        check_input(path, "frame file")
    except CamsimError as exc:
        return str(exc).removeprefix(f"cannot read frame file {path}: ")
    return "not a regular file"  # it has become one since it was looked at: judged as it was then


def search_frames(paths, source: str = "dng") -> FrameSearch:
    """The frame files named by ``paths``: files, or folders searched recursively for committed frames.

    A frame present as both DNG and EXR is taken from ``source``; a frame with only the other kind is taken
    from that (e.g. no DNG is written when quantisation is off). A file named is taken as it is (an EXR carries
    its own metadata); in a folder only the frames whose sidecar claims the file are (see :class:`FrameSearch`).
    Nothing raises for a bad path: it is reported in the result.
    """
    if source not in PIXEL_FILE_KINDS:
        raise CamsimError(f"source must be one of {PIXEL_FILE_KINDS}, got {source!r}")
    found: dict[Path, dict[str, Path]] = {}
    bad: list = []
    uncommitted: list = []
    for entry in map(Path, paths):
        if entry.is_dir():
            _search_folder(entry, found, bad, uncommitted)
        elif not entry.is_file():
            bad.append((entry, _not_a_file(entry)))
        elif entry.suffix.lower().lstrip(".") not in PIXEL_FILE_KINDS:
            bad.append((entry, "not a frame file (.dng or .exr)"))
        else:
            found.setdefault(entry.with_suffix(""), {})[entry.suffix.lower().lstrip(".")] = entry
    other = "exr" if source == "dng" else "dng"
    files = [kinds.get(source, kinds.get(other)) for _, kinds in sorted(found.items())]
    return FrameSearch(files, bad, uncommitted)


def uncommitted_lines(files, shown: int = 5) -> list[str]:
    """One warning line per folder about the uncommitted frame files in it, naming at most ``shown`` of them."""
    by_folder: dict[Path, list[str]] = {}
    for path in files:
        by_folder.setdefault(Path(path).parent, []).append(Path(path).name)
    lines = []
    for folder, names in by_folder.items():
        listed = ", ".join(names[:shown]) + (f" … (+{len(names) - shown})" if len(names) > shown else "")
        lines.append(f"ignored {len(names)} uncommitted frame file(s) in {folder} (no sidecar claims them): "
                     f"{listed}")
    return lines


def find_frames(paths, source: str = "dng") -> list[Path]:
    """The frame files named by ``paths`` (files, or folders searched recursively), one per frame.

    :func:`search_frames`, strictly: a bad path raises, and so does finding no frame at all. Uncommitted frame
    files in folders are left out.

    Raises
    ------
    CamsimError
        A path that does not exist, a file named that is no frame file, an unreadable sidecar in a folder, or
        no frame found.
    """
    search = search_frames(paths, source)
    if search.bad:
        path, reason = search.bad[0]
        raise CamsimError(f"{path}: {reason}")
    if not search.files:
        raise CamsimError(no_frames_message(paths, search.uncommitted))
    return search.files


def no_frames_message(paths, uncommitted) -> str:
    """Why ``paths`` gave no frame: none there, or only uncommitted ones."""
    where = ", ".join(str(p) for p in paths)
    if not uncommitted:
        return f"no .dng or .exr frames in {where}"
    names = ", ".join(Path(p).name for p in uncommitted[:5]) + (" …" if len(uncommitted) > 5 else "")
    return (f"no committed frames in {where}: {len(uncommitted)} frame file(s) that no sidecar claims ({names}), "
            "i.e. frames being written or left by an interrupted writer; name a file to read it anyway")
