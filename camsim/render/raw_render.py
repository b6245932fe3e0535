"""Frames of a raw scene: a real camera's raw file made darker (or brighter), with the scene sensor's noise.

::

    raw file ──(crop, black, K_source at its ISO)──▶ source electrons e_src (H, W)       (source_electrons)
    e_src ──(fraction F·T / T_source, photon law, the sensor's stages, seed)──▶ RawDraw  (camsim.render.raw_frame)
    RawDraw + the source's metadata ──▶ .dng / .exr / .json                              (write_raw_frame)

The source's electrons at each site are (DN − black) / K_source, K_source the source camera's gain at the file's
ISO (:meth:`camsim.scene.sources.raw.RawSource.source_preset`). Sites at or above the file's white level are
saturated: their electrons are only a lower bound, so they are *masked* — counted in the sidecar
(``raw_source.masked_px``) and marked in ``STEM_mask.png`` (255 = masked) — and drawn from that lower bound.

The output DNG keeps the source's CFA pattern, colour matrices, calibration illuminants, as-shot neutral,
Make/Model and orientation, with the scene sensor's levels, ISO, exposure and noise profile; so raw developers
develop it as that camera's raw. The EXR's clean layer is the expectation of each site (``clean`` of its own colour;
the other two colours there are the bilinear interpolation of their neighbours' expectations, as the source has
no value of them). Frames are named ``SCENE_as-shot_F<F>`` and seeded as other frames
(:func:`camsim.core.seeding.frame_seed_sequence` with the label ``as-shot``).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

import camsim
from camsim.core.errors import CamsimError
from camsim.core.seeding import frame_seed_sequence
from camsim.io.atomic import undo_on_failure, write_json_atomic
from camsim.io.dng import MAX_EXPOSURE_S, MIN_SIZE, write_dng_cfa
from camsim.io.exr import DEFAULT_EXR_COMPRESSION, check_exr_compression, write_exr
from camsim.io.output_folder import make_folder, output_folder
from camsim.render.frame_files import (
    SIDECAR_SUFFIX,
    camera_view,
    effects_record,
    exr_header,
    frame_stem,
    uncommit_frame,
)
from camsim.render.frame_manifest import MANIFEST_NAME, FrameManifest, manifest_entry
from camsim.render.raw_frame import RawDraw, render_raw_frame
from camsim.scene.sources.raw import source_gain_dn_per_e
from camsim.sensor.noise_profile import dng_noise_profile
from camsim.sensor.params import SensorParams
from camsim.sensor.raw_laws import PHOTON_LAW_FORMULAS, check_thin_exposure

#: The illuminant a raw scene's frames are under: the source's own light, as shot.
RAW_ILLUMINANT = "as-shot"
#: The XYZ → linear sRGB matrix (IEC 61966-2-1, D65), the colour matrix of a source that records none.
_SRGB_XYZ_TO_RGB = np.array([[3.2404542, -1.5371385, -0.4985314],
                             [-0.9692660, 1.8760108, 0.0415560],
                             [0.0556434, -0.2040259, 1.0572252]])


@dataclass(frozen=True)
class LoadedRaw:
    """A raw scene's source, read once for all its frames.

    Attributes
    ----------
    capture : camsim.io.raw_capture.RawCapture
        The file's (cropped) mosaic and metadata.
    electrons_e : numpy.ndarray, shape (H, W), float32
        (DN − black) / K_source at each site (negative where the source's read noise took it below black). Unit: e⁻.
    masked : numpy.ndarray, shape (H, W), bool
        Saturated sites (DN ≥ the file's white level): their electrons are a lower bound.
    preset : str
        The source camera's preset; ``k_dn_per_e`` its gain at ``iso``. Unit: DN/e⁻.
    iso, exposure_s : float
        The source's ISO and exposure time (s).
    """

    capture: object
    electrons_e: np.ndarray
    masked: np.ndarray
    preset: str
    k_dn_per_e: float
    iso: float
    exposure_s: float

    def record(self, photon_law: str, fraction: float) -> dict:
        """The sidecar's ``raw_source``: where the frame's electrons came from."""
        cap = self.capture
        masked = int(np.count_nonzero(self.masked))
        return {
            "file": Path(cap.path).name,
            "crop_xywh": None if cap.crop is None else [int(v) for v in cap.crop],
            "full_size_wh": [int(v) for v in cap.full_size],
            "cfa_pattern": cap.cfa,
            "black_dn": np.asarray(cap.black_dn, dtype=np.float64).tolist(),
            "white_dn": float(cap.white_dn),
            "iso": self.iso,
            "exposure_s": self.exposure_s,
            "make": cap.make,
            "model": cap.model,
            "unique_camera_model": cap.unique_camera_model,
            "preset": self.preset,
            "k_dn_per_e": self.k_dn_per_e,
            "photon_law": photon_law,
            "photon_law_formula": PHOTON_LAW_FORMULAS[photon_law],
            "fraction": fraction,
            "masked_px": masked,
            "masked_fraction": masked / self.masked.size,
        }


def source_electrons(capture, k_dn_per_e: float) -> tuple[np.ndarray, np.ndarray]:
    """The source's electrons (DN − black) / K at each site, float32 (H, W) (unit: e⁻), and its saturated sites
    (DN ≥ white level), bool (H, W)."""
    mosaic = capture.mosaic
    electrons = np.empty(mosaic.shape, dtype=np.float32)
    black = np.asarray(capture.black_dn, dtype=np.float64)
    scale = np.float32(1.0 / k_dn_per_e)
    for dy in (0, 1):
        for dx in (0, 1):
            site = (slice(dy, None, 2), slice(dx, None, 2))
            np.subtract(mosaic[site], np.float32(black[dy, dx]), out=electrons[site], dtype=np.float32)
            electrons[site] *= scale
    return electrons, mosaic >= capture.white_dn


def read_source(scene) -> LoadedRaw:
    """The raw scene's source: its capture, the source camera's gain at its ISO, its electrons and mask."""
    src = scene.source
    preset = src.source_preset(scene.preset_name)
    iso, exposure = src.source_iso, src.source_exposure_s
    k = source_gain_dn_per_e(preset, iso, src.base_dir)
    capture = src.capture()
    electrons, masked = source_electrons(capture, k)
    if masked.all():
        raise CamsimError(f"{src.path}: every pixel is saturated (at or above the white level {capture.white_dn:g} "
                          "DN): nothing to draw from")
    return LoadedRaw(capture, electrons, masked, preset, k, iso, exposure)


def frame_fraction(sensor: SensorParams, source: LoadedRaw, intensity_factor: float) -> float:
    """F · T / T_source (T the frame's sensor's exposure): the share of the source's electrons a frame expects."""
    return float(intensity_factor) * float(sensor.exposure_s) / source.exposure_s


def check_raw_scene(scene) -> None:
    """Refuse, before any work, a raw scene whose frames cannot be drawn or written: names, sizes, the photon law
    (``thin`` cannot brighten), the sensor's pattern (the file's)."""
    from camsim.scene.scene_file import RAW_SCENE_ILLUMINANTS

    if tuple(scene.illuminants) != RAW_SCENE_ILLUMINANTS:
        raise CamsimError(f"a raw scene is lit by its own light ({RAW_ILLUMINANT}): illuminants do not apply, "
                          f"got {', '.join(scene.illuminants)}")
    if scene.regions:
        raise CamsimError("[[region]] does not apply to raw scenes yet")
    if scene.exposure != "fixed":
        raise CamsimError("auto exposure meters a perfect white, which a raw scene has not: give the exposure time "
                          "(--exposure SECONDS, [sensor] exposure_s; default the source's)")
    if scene.statistics != "pixel" or scene.method != "poisson":
        raise CamsimError(f"a raw scene's frames are drawn by its photon law ([raw] photon_law = "
                          f"{scene.source.photon_law!r}), per pixel: statistics {scene.statistics!r} and method "
                          f"{scene.method!r} do not apply (leave them at pixel and poisson)")
    for factor in scene.intensity_factors:
        frame_stem(scene.name, RAW_ILLUMINANT, factor)
    width, height = scene.source.own_size()
    if min(width, height) < MIN_SIZE:
        raise CamsimError(f"raw scene's frame {width}x{height} is smaller than {MIN_SIZE}x{MIN_SIZE} pixels, which "
                          "raw readers (LibRaw) refuse")
    sensor = scene.sensor
    pattern = scene.source.cfa
    if sensor.cfa != pattern:
        raise CamsimError(f"a raw scene's sensor has its file's colour filter array {pattern}, got cfa = "
                          f"{sensor.cfa}")
    if sensor.quantisation and sensor.exposure_s > MAX_EXPOSURE_S:
        raise CamsimError(f"exposure T = {sensor.exposure_s:g} s is longer than a DNG records ({MAX_EXPOSURE_S} s)")
    source_gain_dn_per_e(scene.source.source_preset(scene.preset_name), scene.source.source_iso,
                         scene.source.base_dir)  # a source camera with a gain at the raw's ISO
    if scene.source.photon_law == "thin":
        check_thin_exposure(max(scene.intensity_factors), sensor.exposure_s, scene.source.source_exposure_s)


def raw_frame_warnings(scene) -> list[str]:
    """:func:`camsim.render.pipeline.frame_warnings` of a raw scene's sensor (after :func:`check_raw_scene`); a
    ``[sequence]`` adds :func:`camsim.render.raw_sequence.raw_sequence_warnings`
    (:func:`camsim.render.run.scene_warnings` dispatches)."""
    from camsim.render.pipeline import frame_warnings

    check_raw_scene(scene)
    return frame_warnings(scene.sensor)


def raw_scene_frame(scene, intensity_factor: float, *, source: LoadedRaw | None = None, seed: int | None = None,
                    workers: int | None = None) -> tuple[RawDraw, dict]:
    """One frame of a raw scene at ``intensity_factor`` and its sidecar's ``raw_source`` record.

    ``source``: :func:`read_source` of the scene, when the caller keeps it between frames. The frame draws from
    ``frame_seed_sequence(seed, "as-shot", F)`` (``seed``: the run's, default the scene's)."""
    source = read_source(scene) if source is None else source
    seed = scene.seed if seed is None else seed
    sensor = scene.sensor
    fraction = frame_fraction(sensor, source, intensity_factor)
    draw = render_raw_frame(source.electrons_e, sensor, fraction, law=scene.source.photon_law,
                            rng=frame_seed_sequence(seed, RAW_ILLUMINANT, intensity_factor), workers=workers)
    return draw, source.record(scene.source.photon_law, fraction)


def clean_planes(clean_mosaic: np.ndarray, pattern: str) -> np.ndarray:
    """The clean layer (3, H, W) float32 of a raw frame's clean mosaic (H, W): each site's own colour exact, the
    other two the bilinear interpolation of their neighbours.

    The kernels of colour-demosaicing's ``demosaicing_CFA_Bayer_bilinear`` ([1 2 1]ᵀ[1 2 1] / 4 on R and B, the
    cross [0 1 0; 1 4 1; 0 1 0] / 4 on G), in float32 by shifted slices: 24 MP in 1.6 s against its 6.4 s in float64
    (2026-11-26, this machine). They agree inside the frame (``tests/render/test_raw_render.py``); at the edges the
    mosaic is mirrored about its outer sites here, which keeps each site's colour, where colour-demosaicing repeats the
    edge row and column."""
    from camsim.sensor.cfa import cfa_sites

    height, width = clean_mosaic.shape
    out = np.zeros((3, height + 2, width + 2), dtype=np.float32)  # each colour's sites, zero elsewhere, padded
    for dy, dx, c in cfa_sites(pattern):
        out[c, 1 + dy:1 + height:2, 1 + dx:1 + width:2] = clean_mosaic[dy::2, dx::2]
    for plane in out:  # mirror (no edge repeat) keeps each site's colour across the edge
        plane[0], plane[-1] = plane[2], plane[-3]
        plane[:, 0], plane[:, -1] = plane[:, 2], plane[:, -3]
    result = np.empty((3, height, width), dtype=np.float32)
    for c in (0, 2):  # R and B: separable [1 2 1] / 2 along rows, then along columns
        rows = out[c, :, :-2] + out[c, :, 2:]
        rows += 2 * out[c, :, 1:-1]
        result[c] = rows[:-2] + rows[2:]
        result[c] += 2 * rows[1:-1]
        result[c] *= np.float32(0.25)
    green = out[1]
    result[1] = green[:-2, 1:-1] + green[2:, 1:-1]
    result[1] += green[1:-1, :-2]
    result[1] += green[1:-1, 2:]
    result[1] *= np.float32(0.25)
    result[1] += green[1:-1, 1:-1]
    for dy, dx, c in cfa_sites(pattern):  # the sites' own values, exactly
        result[c, dy::2, dx::2] = clean_mosaic[dy::2, dx::2]
    return result


def raw_sidecar(scene, draw: RawDraw, record: dict, source: LoadedRaw, intensity_factor: float, seed: int,
                files: dict | None, exr_compression: str | None = None) -> dict:
    """The JSON sidecar of a raw scene's frame: the sensor's keys, the source's (``raw_source``), the colour of
    the source's camera."""
    sensor = scene.sensor
    cap = source.capture
    profile = dng_noise_profile(sensor, 1.0) if draw.digital_dn is not None else None
    matrix, matrix_from = colour_matrix(cap)
    height, width = draw.noisy_dn.shape[1:]
    return {
        "camsim_version": camsim.__version__,
        "scene": scene.name,
        "scene_source": "raw",
        "illuminant": RAW_ILLUMINANT,
        "intensity_factor": intensity_factor,
        "seed": seed,
        "photon_statistics": "pixel",
        "method": f"raw-{scene.source.photon_law}",
        "exposure": "fixed",
        "camera": record["unique_camera_model"] or " ".join(v for v in (cap.make, cap.model) if v) or source.preset,
        "width_px": width,
        "height_px": height,
        "channels": ["R", "G", "B"],
        **sensor.sidecar_record(),
        **effects_record(sensor, draw.maps, draw.black_level_error_dn),
        **scene_preset_record(scene),
        "noise_profile": None if profile is None else profile.tolist(),
        "color_matrix1_xyz_to_camera": matrix.tolist(),
        "color_matrix_source": matrix_from,
        "calibration_illuminant1": int(cap.calibration_illuminant1 or 21),
        "as_shot_neutral": as_shot_neutral(cap).tolist(),
        "patches": [],
        "surround": None,
        "raw_source": record,
        "units": {
            "raw_source": "the source file: black_dn per site of the top-left 2x2 cell (DN), white_dn (DN), "
                          "exposure_s (s), k_dn_per_e (DN/e-, the source camera's gain at its ISO, from preset); "
                          "fraction = F * T / T_source (the share of the source's electrons the frame expects); "
                          "masked_px: saturated source sites (DN >= white_dn), drawn from that lower bound and "
                          "marked in the mask file",
            "noise_profile": "per channel R, G, B: [S, O] of the DNG's NoiseProfile tag (unitless): the temporal "
                             "noise variance of x = (DN - B) / (W - B) is S x + O",
            "exr_channels": "noisy.CFA: noisy DN before quantisation; clean.R, clean.G, clean.B: the expected DN of "
                            "each site in its own colour, the other two colours bilinearly interpolated from the "
                            "neighbouring sites; R, G, B: the picture for viewers (camsim:view)",
        },
        **({"exr_compression": exr_compression} if exr_compression is not None else {}),
        "files": files,
    }


def scene_preset_record(scene) -> dict:
    """The sidecar's ``preset``, ``preset_title``, ``preset_source`` and ``iso`` of the scene's sensor (a camera
    preset's), or nothing."""
    from camsim.render.pipeline import preset_record

    return preset_record(scene) or {}


def colour_matrix(capture) -> tuple[np.ndarray, str]:
    """The source's ColorMatrix1 (XYZ → camera) and where it came from (``file``), or the XYZ → linear sRGB matrix
    (``srgb-stand-in``) for a file that records none."""
    if capture.color_matrix1 is not None and np.all(np.isfinite(capture.color_matrix1)) \
            and np.any(capture.color_matrix1 != 0):
        return np.asarray(capture.color_matrix1, dtype=np.float64).reshape(3, 3), "file"
    return _SRGB_XYZ_TO_RGB.copy(), "srgb-stand-in"


def as_shot_neutral(capture) -> np.ndarray:
    """The source's AsShotNeutral (camera R, G, B of white), or (1, 1, 1) where it records none usable."""
    neutral = None if capture.as_shot_neutral is None else np.asarray(capture.as_shot_neutral, dtype=np.float64)
    if neutral is None or neutral.shape != (3,) or not np.all(np.isfinite(neutral)) or not np.all(neutral > 0):
        return np.ones(3)
    return neutral


def write_raw_frame(out_dir: Path, stem: str, draw: RawDraw, meta: dict, source: LoadedRaw, sensor: SensorParams,
                    exr_compression: str = DEFAULT_EXR_COMPRESSION, *, clean: np.ndarray | None = None,
                    mask: np.ndarray | None = None) -> dict:
    """Write a raw scene's frame: ``stem.dng`` (if quantised, with the source's camera metadata), ``stem.exr``,
    ``stem_mask.png`` (where ``meta``'s ``raw_source.masked_px`` is not 0) and, last, ``stem.json`` (the commit
    record).

    ``meta`` is :func:`raw_sidecar`'s dict without its ``files`` (set here). ``clean``: the EXR's clean layer (3, H, W)
    DN (default: :func:`clean_planes` of the draw's clean mosaic); ``mask``: the mask file's values (H, W) uint8
    (default: 255 at the source's masked sites, 0 elsewhere; a moving sequence's: :mod:`camsim.render.raw_sequence`).
    Returns the files by kind."""
    check_exr_compression(exr_compression)
    files = {"dng": f"{stem}.dng" if draw.digital_dn is not None else None, "exr": f"{stem}.exr",
             "json": f"{stem}{SIDECAR_SUFFIX}"}
    if meta["raw_source"]["masked_px"]:
        files["mask"] = f"{stem}{MASK_SUFFIX}"
    meta = {**meta, "files": files, "exr_compression": exr_compression}
    cap = source.capture
    make_folder(out_dir)
    uncommit_frame(out_dir, stem)
    (out_dir / f"{stem}{MASK_SUFFIX}").unlink(missing_ok=True)
    with undo_on_failure():
        if draw.digital_dn is not None:
            write_dng_cfa(
                out_dir / files["dng"], draw.digital_dn[0], pattern=sensor.cfa,
                black_level_dn=sensor.black_level_tag_dn, white_level=sensor.max_dn,
                color_matrix1=meta["color_matrix1_xyz_to_camera"], as_shot_neutral=meta["as_shot_neutral"],
                calibration_illuminant1=meta["calibration_illuminant1"],
                color_matrix2=cap.color_matrix2 if meta["color_matrix_source"] == "file" else None,
                calibration_illuminant2=cap.calibration_illuminant2 if cap.color_matrix2 is not None else None,
                orientation=int(cap.orientation or 1),
                make=_ascii_or(cap.make, "camsim"), model=_ascii_or(cap.model, meta["camera"]),
                unique_camera_model=_ascii_or(cap.unique_camera_model, meta["camera"]),
                software=f"camsim {camsim.__version__}", noise_profile=meta["noise_profile"],
                iso=meta.get("iso"), exposure_s=float(sensor.exposure_s))
        header = exr_header(meta, sensor)
        view, view_header = camera_view(draw.noisy_dn, sensor)
        header.update(view_header)
        write_exr(out_dir / files["exr"], draw.noisy_dn,
                  clean_planes(draw.clean_dn, sensor.cfa) if clean is None else clean, header, exr_compression,
                  view=view)
        if "mask" in files:
            from camsim.render.preview import write_preview_png

            if mask is None:
                mask = np.where(source.masked, np.uint8(255), np.uint8(0))
            write_preview_png(out_dir / files["mask"], np.repeat(mask[..., None], 3, axis=2))
        write_json_atomic(out_dir / files["json"], meta)
    return files


#: The suffix of a raw frame's mask of saturated source sites (255 = masked), beside its other files.
MASK_SUFFIX = "_mask.png"


def _ascii_or(text, default: str) -> str:
    """``text`` as printable ASCII (others replaced by ``?``), or ``default`` where empty."""
    text = " ".join(str(text or "").encode("ascii", "replace").decode("ascii").split())
    return text or default


def render_raw_scene(scene, out_dir: str | Path, *, workers: int | None = None, progress: bool = True,
                     exr_compression: str = DEFAULT_EXR_COMPRESSION) -> dict:
    """Render every intensity factor of a raw scene into ``out_dir`` (:func:`camsim.render.run.render_scene`'s
    contract: the folder held, each frame committed by its sidecar, the manifest kept up to date)."""
    from tqdm import tqdm

    check_raw_scene(scene)
    check_exr_compression(exr_compression)
    with output_folder(out_dir) as out_dir:
        manifest = FrameManifest(out_dir, scene.name)
        if manifest.frames or (out_dir / MANIFEST_NAME).exists():
            manifest.write()
        source = read_source(scene)
        bar = tqdm(total=len(scene.intensity_factors), desc=f"rendering {scene.name}", unit="frame",
                   disable=not progress)
        with bar, manifest.kept_on_failure():
            for factor in scene.intensity_factors:
                draw, record = raw_scene_frame(scene, factor, source=source, workers=workers)
                stem = frame_stem(scene.name, RAW_ILLUMINANT, factor)
                manifest.withdraw(stem)
                meta = raw_sidecar(scene, draw, record, source, factor, scene.seed, None)
                files = write_raw_frame(out_dir, stem, draw, meta, source, scene.sensor, exr_compression)
                manifest.commit_entry(manifest_entry({**meta, "files": files}))
                bar.update()
    return manifest.as_dict()
