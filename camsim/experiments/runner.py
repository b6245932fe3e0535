"""Render an experiment's frames to files, then analyse them from those files (never from memory)."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from tqdm import tqdm

from camsim.analysis.analyze import analyse_paths
from camsim.analysis.patches import AnalysisSettings
from camsim.core.seeding import frame_seed_sequence
from camsim.experiments.datapoints import data_points, points_radiance
from camsim.io.output_folder import make_folder
from camsim.light.photons import photon_radiance
from camsim.render.frame_files import FrameInfo, write_frame
from camsim.render.frame_manifest import FrameManifest
from camsim.render.pipeline import LitScene, make_frame
from camsim.scene.scene_file import load_scene
from camsim.sensor.camera import AnchorScale, absolute_qe, load_camera
from camsim.sensor.params import SensorParams

#: The photon statistics every experiment runs under, and the sampling method used for each: ``paper`` draws
#: per bin (Eq. 4 literally, with the channels' shared photon counts); ``pixel`` draws once per pixel (exact).
STATISTICS_METHODS = {"paper": "spectral", "pixel": "poisson"}


@dataclass(frozen=True)
class Setup:
    """What an experiment renders: the scene data, frame size, points and seed."""

    scene_file: Path
    width: int | None = None  # None: the experiment's default size
    height: int | None = None
    n_points: int = 20
    seed: int = 0
    camera: str | None = None


@dataclass(frozen=True)
class Prepared:
    grid: object
    points: list
    radiance: object
    camera: object
    name: str
    lit: LitScene  # the data points under their lights, Qe anchored once on D65

    @property
    def qe(self) -> np.ndarray:
        """The camera's absolute Qe, shape (3, N). Unit: e⁻ · m² · sr / photon."""
        return self.lit.qe

def prepare(setup: Setup) -> Prepared:
    """The data points' chart, the camera and its Qe (anchored on the D65 perfect white at 100 cd/m²)."""
    scene = load_scene(setup.scene_file)
    grid = scene.grid
    points, spectra = data_points(scene.source.reflectances, scene.illuminants, grid)
    points, spectra = points[: setup.n_points], spectra[: setup.n_points]
    radiance = points_radiance(points, spectra, grid, setup.width, setup.height)
    camera = load_camera(setup.camera or scene.camera, grid, scene.sensitivity_basis, scene.base_dir)
    qe = absolute_qe(camera, AnchorScale(reference_illuminant="D65"), grid)  # one camera for every data point
    g = photon_radiance(radiance.radiance, grid.wavelengths_nm, grid.step_nm)
    g_white = photon_radiance(radiance.white_radiance, grid.wavelengths_nm, grid.step_nm)
    return Prepared(grid, points, radiance, camera, scene.name,
                    LitScene(radiance.labels, g, qe, grid, radiance, "D65", g_white))


def render_series(prep: Prepared, sensor: SensorParams, factors, statistics: str, out_dir: Path, seed: int,
                  label: str, seed_label: str | None = None) -> Path:
    """Render one frame per F into ``out_dir`` (DNG/EXR/JSON + manifest); returns the folder."""
    method = STATISTICS_METHODS[statistics]
    lit = prep.lit
    make_folder(out_dir)
    manifest = FrameManifest(out_dir, f"experiment-{label}")
    with manifest.kept_on_failure():
        for factor in factors:
            frame = make_frame(lit, sensor, factor, statistics=statistics, method=method,
                               rng=frame_seed_sequence(seed, seed_label or label, factor))
            info = FrameInfo(
                scene=f"experiment-{label}", illuminant="per data point", intensity_factor=float(factor), seed=seed,
                photon_statistics=statistics, method=method, camera=prep.camera.name,
                sensitivity_basis=prep.camera.sensitivity_basis, reflectances=prep.radiance.reflectance_set,
                wavelengths_nm=prep.grid.wavelengths_nm, luminance_cd_m2=100.0, normalisation="per-spectrum",
                scale={"kind": "anchor", **dataclasses.asdict(AnchorScale(reference_illuminant="D65"))},
                patch_names=prep.radiance.patch_names, patch_rects=prep.radiance.patch_rects,
                color_matrix1=lit.color_matrix1, as_shot_neutral=lit.as_shot_neutral, patch_xyz=factor * lit.patch_xyz,
            )
            stem = f"{label}_F{factor:g}"
            manifest.withdraw(stem)
            files = write_frame(out_dir, stem, frame, info)
            manifest.commit(info, files)
    return out_dir


def analyse_series(folder: Path, black: str = "none", source: str = "dng") -> list[dict]:
    """Analyse a rendered series from its files: DNG where the sensor quantises, EXR otherwise.

    ``source="exr"`` reads the EXR even where there is a DNG: the same frame before the ADC (without quantisation).
    """
    return analyse_paths([folder], AnalysisSettings(black=black), source=source, progress=False)


def black_point_xy(prep: Prepared, sensor: SensorParams) -> tuple[float, float] | None:
    """Chromaticity of the camera black point, or None without dark current.

    The mean digital number of an unlit pixel (:attr:`camsim.sensor.params.SensorParams.black_level_dn`: after the ADC's
    floor where the sensor quantises, as in the DNGs the series is analysed from) through the paper's M: where the
    ellipse centres go as F falls.
    """
    from camsim.colour.colorimetry import camera_to_xyz_matrix

    if not sensor.dark_current:
        return None
    matrix = camera_to_xyz_matrix(prep.qe, prep.grid.wavelengths_nm, sensor.dn_per_electron, method="paper")
    xyz = matrix @ sensor.black_level_dn
    return float(xyz[0] / xyz.sum()), float(xyz[1] / xyz.sum())


def noise_free_xy(prep: Prepared, sensor: SensorParams, factor: float) -> np.ndarray:
    """Chromaticity of each point's expected camera signal (signal + dark, saturated) through M, shape (P, 2)."""
    from camsim.colour.colorimetry import camera_to_xyz_matrix

    expected = prep.lit.expected(sensor, factor, "pixel")
    dn = expected.clean_e[: len(prep.points)] * sensor.dn_per_electron
    matrix = camera_to_xyz_matrix(prep.qe, prep.grid.wavelengths_nm, sensor.dn_per_electron, method="paper")
    xyz = dn @ matrix.T
    return xyz[:, :2] / xyz.sum(axis=1, keepdims=True)


def run_conditions(prep: Prepared, conditions, out_dir: Path, seed: int, progress: bool = True) -> dict:
    """Render and analyse each ``(key, sensor, factors, statistics)``; returns {key: analysis results}.

    Frames are seeded by statistics and F only, so that variants of a sensor (e.g. read noise +10 %) draw the
    same random numbers where they can: their differences are then the parameters', not sampling noise.
    """
    results = {}
    for key, sensor, factors, statistics in tqdm(conditions, desc="experiment series", unit="series",
                                                  disable=not progress):
        folder = render_series(prep, sensor, factors, statistics, out_dir / "frames" / key, seed, key,
                               seed_label=statistics)
        results[key] = analyse_series(folder)
    return results
