"""Writing one rendered frame: the ``.dng`` raw, the ``.exr`` float frame and the ``.json`` sidecar.

No wall-clock time goes into any file, so that the same seed gives byte-identical files. Every file is written
under a temporary name and renamed when complete.
"""

from __future__ import annotations

import json
import re
from functools import partial
from dataclasses import dataclass
from pathlib import Path

import numpy as np

import camsim
from camsim.io.atomic import write_json_atomic
from camsim.io.dng import write_dng, write_dng_cfa
from camsim.io.exr import write_exr
from camsim.rawcolour import CALIBRATION_ILLUMINANT_D65
from camsim.methods import get_method
from camsim.render import Frame


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
    out_dir.mkdir(parents=True, exist_ok=True)
    sensor = frame.sensor
    files = {"dng": f"{stem}.dng" if frame.digital_dn is not None else None, "exr": f"{stem}.exr",
             "json": f"{stem}.json"}
    if preview:
        files["png"] = f"{stem}.png"
    meta = sidecar(frame, info, files)
    if frame.digital_dn is not None:
        write = write_dng if sensor.cfa is None else partial(write_dng_cfa, pattern=sensor.cfa)
        write(
            out_dir / files["dng"],
            frame.digital_dn if sensor.cfa is None else frame.digital_dn[0],
            black_level_dn=sensor.black_level_dn,
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
        "camsim:metadata": json.dumps(meta, ensure_ascii=False),
    }
    write_exr(out_dir / files["exr"], frame.noisy_dn, frame.clean_dn(), header)
    if preview:
        from camsim.preview import preview_srgb, write_preview_png

        write_preview_png(out_dir / files["png"], preview_srgb(frame, info))
    write_json_atomic(out_dir / files["json"], meta)
    return files
