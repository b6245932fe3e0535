"""The frame pipeline: the one place where a frame is made.

::

    scene source ──(illuminant)──▶ SceneRadiance ──(camera, scale)──▶ LitScene   (per illuminant: K spectra)
    LitScene ──(sensor, F, statistics)──▶ ExpectedSignal ──(method, seed)──▶ Frame   (make_frame)
    Frame + FrameInfo ──▶ .dng / .exr / .json                                    (camsim.frame_files)

:func:`make_frame` draws every frame camsim makes: ``camsim render`` and ``camsim dataset`` (through
:func:`scene_frame`), the paper's experiments (their data points as a :class:`LitScene`), ``camsim emva`` (a
uniform monochromatic field), the benchmarks, the contact sheet and the tests. Seeds come from
:mod:`camsim.seeding`.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from camsim.camera import Camera, absolute_qe, load_camera
from camsim.expected import ExpectedSignal, expected_signal
from camsim.frame_files import FrameInfo
from camsim.photons import KM_LM_PER_W, photon_radiance
from camsim.radiance import SceneRadiance, scene_radiance
from camsim.rawcolour import as_shot_neutral, color_matrix_xyz_to_camera
from camsim.render import Frame, render_frame
from camsim.scene import Scene
from camsim.seeding import frame_seed_sequence
from camsim.sensor import SensorParams
from camsim.spectra import WavelengthGrid, cmfs_on_grid


@dataclass(frozen=True)
class LitScene:
    """A scene under one light, seen by one camera, at F = 1: everything a frame needs before the sensor.

    Attributes
    ----------
    labels : numpy.ndarray, shape (H, W), unsigned integer
        Spectrum index of each pixel.
    photon_rate : numpy.ndarray, shape (K, N)
        g(λi) of each distinct spectrum at F = 1. Unit: photons / (s m² sr) per bin.
    qe : numpy.ndarray, shape (3, N)
        The camera's absolute Qe_κ(λi). Unit: e⁻ · m² · sr / photon.
    grid : WavelengthGrid
    radiance : SceneRadiance or None
        The spectral radiance it came from (patch names and rectangles for the sidecar), if any.
    illuminant : str or None
        The light's colour-science name (the white balance of the frame's files), if any.
    """

    labels: np.ndarray
    photon_rate: np.ndarray
    qe: np.ndarray
    grid: WavelengthGrid
    radiance: SceneRadiance | None = None
    illuminant: str | None = None

    @cached_property
    def color_matrix1(self) -> np.ndarray:
        """DNG ColorMatrix1 (XYZ → camera), fitted on the ColorChecker under D65, shape (3, 3)."""
        return color_matrix_xyz_to_camera(self.qe, self.grid)

    @cached_property
    def as_shot_neutral(self) -> np.ndarray:
        """DNG AsShotNeutral: the camera's response to the perfect white under the illuminant, shape (3,)."""
        return as_shot_neutral(self.illuminant, self.qe, self.grid)

    @cached_property
    def patch_xyz(self) -> np.ndarray:
        """CIE 1931 XYZ of each patch's light at F = 1, shape (patches, 3); Y is the luminance in cd/m²."""
        return patch_xyz(self.radiance, self.grid)

    def expected(self, sensor: SensorParams, intensity_factor: float, statistics: str) -> ExpectedSignal:
        """The per-spectrum expected signal of a frame at ``intensity_factor`` (Eqs. 3–6)."""
        return expected_signal(self.photon_rate, self.qe, sensor, intensity_factor, statistics)


def lit_scene(radiance: SceneRadiance, camera: Camera, scale, grid: WavelengthGrid,
              illuminant: str | None = None) -> LitScene:
    """A :class:`LitScene` from spectral radiance, with Qe anchored on the radiance's perfect white."""
    g = photon_radiance(radiance.radiance, grid.wavelengths_nm, grid.step_nm)
    g_white = photon_radiance(radiance.white_radiance, grid.wavelengths_nm, grid.step_nm)
    return LitScene(radiance.labels, g, absolute_qe(camera, scale, g_white), grid, radiance, illuminant)


def light_scene(scene: Scene, illuminant: str, camera: Camera | None = None) -> LitScene:
    """``scene`` under ``illuminant`` through its camera (loaded if not given)."""
    if camera is None:
        camera = load_camera(scene.camera, scene.grid, scene.sensitivity_basis, scene.base_dir)
    return lit_scene(scene_radiance(scene, illuminant), camera, scene.scale, scene.grid, illuminant)


def make_frame(lit: LitScene, sensor: SensorParams, intensity_factor: float, *, statistics: str = "pixel",
               method: str = "poisson", rng=None, tolerance: float | None = None,
               workers: int | None = None) -> Frame:
    """Draw one frame: the expected signal of ``lit`` at F, then per-pixel noise by ``method``.

    Parameters
    ----------
    lit : LitScene
    sensor : SensorParams
    intensity_factor : float
        F: the light is F × the scene radiance.
    statistics : {'pixel', 'paper'}
    method : str
        A name of :data:`camsim.methods.METHODS`.
    rng : numpy.random.Generator, numpy.random.SeedSequence or int
        The frame's seed (see :mod:`camsim.seeding`); the output does not depend on ``workers``.
    tolerance : float, optional
        ``auto``'s KS tolerance.
    workers : int, optional
        Threads (default: every core).

    Returns
    -------
    Frame
    """
    expected = lit.expected(sensor, intensity_factor, statistics)
    return render_frame(lit.labels, expected, sensor, statistics=statistics, method=method, rng=rng,
                        workers=workers, tolerance=tolerance)


def patch_xyz(radiance: SceneRadiance, grid: WavelengthGrid) -> np.ndarray:
    """CIE 1931 XYZ of each patch's light at F = 1, shape (patches, 3); Y is the luminance in cd/m²."""
    n = len(radiance.patch_names)
    return KM_LM_PER_W * grid.step_nm * (radiance.radiance[:n] @ cmfs_on_grid(grid).T)


def scene_frame_info(scene: Scene, lit: LitScene, camera_name: str, intensity_factor: float,
                     seed: int) -> FrameInfo:
    """The :class:`FrameInfo` of one frame of ``scene`` under ``lit``: what its files say besides its pixels."""
    radiance, grid = lit.radiance, scene.grid
    return FrameInfo(
        scene=scene.name,
        illuminant=lit.illuminant,
        intensity_factor=intensity_factor,
        seed=seed,
        photon_statistics=scene.statistics,
        method=scene.method,
        camera=camera_name,
        sensitivity_basis=scene.sensitivity_basis,
        reflectances=radiance.reflectance_set,
        wavelengths_nm=grid.wavelengths_nm,
        luminance_cd_m2=scene.luminance_cd_m2,
        normalisation=scene.normalisation,
        scale={"kind": scene.scale.kind, **dataclasses.asdict(scene.scale)},
        patch_names=radiance.patch_names,
        patch_rects=radiance.patch_rects,
        color_matrix1=lit.color_matrix1,
        as_shot_neutral=lit.as_shot_neutral,
        patch_xyz=intensity_factor * lit.patch_xyz,
    )


def scene_frame(scene: Scene, illuminant: str, intensity_factor: float, *, seed: int | None = None,
                lit: LitScene | None = None, camera: Camera | None = None,
                workers: int | None = None) -> tuple[Frame, FrameInfo]:
    """One frame of ``scene`` (its sensor, statistics, method and tolerance) and its :class:`FrameInfo`.

    Parameters
    ----------
    seed : int, optional
        The run seed (default the scene's); the frame draws from
        ``camsim.seeding.frame_seed_sequence(seed, illuminant, intensity_factor)``, so a frame is the same
        whether it is rendered alone or in a longer run.
    lit, camera : optional
        ``light_scene(scene, illuminant)`` and the scene's camera, when the caller keeps them between frames.
    """
    seed = scene.seed if seed is None else seed
    if camera is None:
        camera = load_camera(scene.camera, scene.grid, scene.sensitivity_basis, scene.base_dir)
    lit = light_scene(scene, illuminant, camera) if lit is None else lit
    if lit.illuminant != illuminant:
        raise ValueError(f"scene_frame under {illuminant!r} was given a scene lit by {lit.illuminant!r}")
    frame = make_frame(lit, scene.sensor, intensity_factor, statistics=scene.statistics, method=scene.method,
                       rng=frame_seed_sequence(seed, illuminant, intensity_factor), tolerance=scene.tolerance,
                       workers=workers)
    return frame, scene_frame_info(scene, lit, camera.name, intensity_factor, seed)
