"""The frame pipeline: the one place where a frame is made.

::

    scene source ──(illuminant)──▶ SceneRadiance ──(camera, scale)──▶ LitScene   (per illuminant: K spectra)
    LitScene ──(sensor, F, exposure mode)──▶ the frame's sensor, its T                (frame_sensor)
    LitScene ──(sensor, F, statistics)──▶ ExpectedSignal ──(method, seed)──▶ Frame   (make_frame)
    Frame + FrameInfo ──▶ .dng / .exr / .json                                    (camsim.render.frame_files)

:func:`make_frame` draws every frame camsim makes: ``camsim render`` and ``camsim dataset`` (through
:func:`scene_frame`), the paper's experiments (their data points as a :class:`LitScene`), ``camsim emva`` (a
uniform monochromatic field), the benchmarks, the contact sheet and the tests. Seeds come from
:mod:`camsim.core.seeding`.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from camsim.colour.rawcolour import as_shot_neutral, color_matrix_xyz_to_camera
from camsim.core.errors import CamsimError
from camsim.core.seeding import frame_seed_sequence
from camsim.io.dng import MAX_EXPOSURE_S
from camsim.light.photons import KM_LM_PER_W, photon_radiance
from camsim.light.rates import FactoredSpectra, all_finite
from camsim.light.spectra import WavelengthGrid, cmfs_on_grid
from camsim.render.frame import Frame, check_frame_values, render_frame
from camsim.render.frame_files import FrameInfo
from camsim.scene.radiance import SceneRadiance, scene_radiance
from camsim.scene.regions import weighted_rows
from camsim.scene.scene_file import Scene
from camsim.sensor.camera import Camera, absolute_qe, load_camera
from camsim.sensor.expected import ExpectedSignal, expected_signal
from camsim.sensor.fixed_pattern import dark_gain_at
from camsim.sensor.params import SensorParams


@dataclass(frozen=True)
class LitScene:
    """A scene under one light, seen by one camera, at F = 1: everything a frame needs before the sensor.

    Attributes
    ----------
    labels : numpy.ndarray, shape (H, W), unsigned integer
        Spectrum index of each pixel.
    photon_rate : numpy.ndarray or camsim.light.rates.FactoredSpectra, shape (K, N)
        g(λi) of each distinct spectrum at F = 1. Unit: photons / (s m² sr) per bin. Factored for an image's
        colours (:mod:`camsim.light.rates`).
    qe : numpy.ndarray, shape (3, N)
        The camera's absolute Qe_κ(λi). Unit: e⁻ · m² · sr / photon.
    grid : WavelengthGrid
    radiance : SceneRadiance or None
        The spectral radiance it came from (patch names and rectangles for the sidecar), if any.
    illuminant : str or None
        The light's colour-science name (the white balance of the frame's files), if any.
    white_photon_rate : numpy.ndarray or None, shape (N,)
        g(λi) of the perfect white under this light at the scene's luminance, F = 1: what auto exposure meters
        (:func:`frame_sensor`). Unit: photons / (s m² sr) per bin.
    """

    labels: np.ndarray
    photon_rate: np.ndarray
    qe: np.ndarray
    grid: WavelengthGrid
    radiance: SceneRadiance | None = None
    illuminant: str | None = None
    white_photon_rate: np.ndarray | None = None

    @cached_property
    def white_signal_e_per_s(self) -> np.ndarray:
        """Signal electrons per second of the perfect white under this light at F = 1, per channel, shape (3,).

        Unit: e⁻ / s. Needs :attr:`white_photon_rate`.
        """
        if self.white_photon_rate is None:
            raise CamsimError("this lit scene has no perfect white: auto exposure cannot meter it")
        return self.qe @ self.white_photon_rate

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
    """A :class:`LitScene` from spectral radiance, seen by ``camera`` with its one absolute Qe (which does not depend
    on the light: :func:`camsim.sensor.camera.absolute_qe`)."""
    to_photons = lambda spectra: photon_radiance(spectra, grid.wavelengths_nm, grid.step_nm)  # noqa: E731
    with np.errstate(over="ignore", invalid="ignore"):  # refused below, with the reason
        g = radiance.radiance.map_basis(to_photons) if isinstance(radiance.radiance, FactoredSpectra) \
            else to_photons(radiance.radiance)
        g_white = photon_radiance(radiance.white_radiance, grid.wavelengths_nm, grid.step_nm)
    if not (all_finite(g) and np.all(np.isfinite(g_white))):
        raise CamsimError("the scene's photon rates are not finite under this light: the luminance is beyond "
                          "float64's range")
    return LitScene(radiance.labels, g, absolute_qe(camera, scale, grid), grid, radiance, illuminant, g_white)


def light_scene(scene: Scene, illuminant: str, camera: Camera | None = None) -> LitScene:
    """``scene`` under ``illuminant`` through its camera (loaded if not given)."""
    if camera is None:
        camera = load_camera(scene.camera, scene.grid, scene.sensitivity_basis, scene.base_dir)
    return lit_scene(scene_radiance(scene, illuminant), camera, scene.scale, scene.grid, illuminant)


def auto_exposure_s(lit: LitScene, intensity_factor: float, target_e: float,
                    max_exposure_s: float | None = None) -> float:
    """The exposure time at which the perfect white of ``lit`` at F reaches ``target_e`` signal electrons in its
    strongest channel: T = target / (F · max_κ Σ g_white Qe_κ), at most ``max_exposure_s``. Unit: s.

    The dark charge is not part of the target (a camera meters the light). Raises :class:`CamsimError` where T is
    not a finite positive number (F so small, or so large, that T leaves float64).
    """
    rate = intensity_factor * float(np.max(lit.white_signal_e_per_s))
    with np.errstate(divide="ignore", over="ignore"):
        exposure = float(target_e) / rate if rate > 0 else np.inf
    if max_exposure_s is not None:
        exposure = min(exposure, float(max_exposure_s))
    if not (np.isfinite(exposure) and exposure > 0):
        raise CamsimError(f"auto exposure at F = {intensity_factor:g} under {lit.illuminant}: the white's "
                          f"{rate:.3g} e⁻/s need T = {exposure:g} s to reach {target_e:g} e⁻; set exposure_max_s")
    return exposure


def frame_sensor(scene: Scene, lit: LitScene, intensity_factor: float,
                 sensor: SensorParams | None = None) -> SensorParams:
    """The sensor of one frame of ``scene``: its own (or ``sensor``, where given), or with ``exposure = "auto"``
    the same sensor at the frame's exposure time (:func:`auto_exposure_s`), so that dark current scales with T.
    Qe is never changed."""
    sensor = scene.sensor if sensor is None else sensor
    if scene.exposure == "fixed":
        return sensor
    exposure = auto_exposure_s(lit, intensity_factor, scene.exposure_target_e, scene.exposure_max_s)
    return dataclasses.replace(sensor, exposure_s=exposure)


def make_frame(lit: LitScene, sensor: SensorParams, intensity_factor: float, *, statistics: str = "pixel",
               method: str = "poisson", rng=None, tolerance: float | None = None,
               workers: int | None = None, device: str = "cpu") -> Frame:
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
        The frame's seed (see :mod:`camsim.core.seeding`); the output does not depend on ``workers``.
    tolerance : float, optional
        ``auto``'s KS tolerance.
    workers : int, optional
        Threads (default: every core).
    device : {'cpu', 'cuda', 'numpy'}
        ``cpu``: the block renderer (:func:`camsim.render.frame.render_frame`). ``cuda``: the array path on an NVIDIA
        GPU with CuPy; ``numpy``: the same code on the CPU (:mod:`camsim.render.backends`). On a device every method but
        ``spectral`` draws the exact per-pixel law, ``pixel`` statistics only; the frame's pixels are copied to
        the host (its ``plan`` is None). The same seed, device and library version give the same frame; the
        devices agree in distribution, not in bits.

    Returns
    -------
    Frame
    """
    expected = lit.expected(sensor, intensity_factor, statistics)
    if device != "cpu":
        from camsim.render.backends import array_module
        from camsim.render.backends.array_path import render_frame_xp

        drawn = render_frame_xp(array_module(device), lit.labels, expected, sensor, rng=rng, statistics=statistics,
                                method=method)
        return drawn.to_frame(lit.labels, expected, sensor)
    return render_frame(lit.labels, expected, sensor, statistics=statistics, method=method, rng=rng,
                        workers=workers, tolerance=tolerance)


def patch_xyz(radiance: SceneRadiance, grid: WavelengthGrid) -> np.ndarray:
    """CIE 1931 XYZ of each patch's light at F = 1, shape (patches, 3); Y is the luminance in cd/m².

    A chart's patch is one spectrum; a region (:mod:`camsim.scene.regions`) the mean of its pixels' spectra, weighted by
    pixel count (on a factored image's coefficients: no per-pixel spectra are made).
    """
    n = len(radiance.patch_names)
    if radiance.patch_weights is None:
        return KM_LM_PER_W * grid.step_nm * (radiance.radiance[:n] @ cmfs_on_grid(grid).T)
    means = np.array([weighted_rows(radiance.radiance, *w) for w in radiance.patch_weights]).reshape(n, -1)
    return KM_LM_PER_W * grid.step_nm * (means @ cmfs_on_grid(grid).T)


def scene_frame_info(scene: Scene, lit: LitScene, camera_name: str, intensity_factor: float,
                     seed: int, device: str = "cpu") -> FrameInfo:
    """The :class:`FrameInfo` of one frame of ``scene`` under ``lit``: what its files say besides its pixels.

    On a device (``device`` other than ``cpu``) the method is the one drawn there
    (:func:`camsim.render.backends.device_method`) and the sidecar records the device
    (:func:`camsim.render.backends.device_record`) and, where it differs, the scene's method as ``method_requested``.
    """
    radiance, grid = lit.radiance, scene.grid
    method, record = scene.method, None
    if device != "cpu":
        from camsim.render.backends import array_module, device_method, device_record

        method = device_method(scene.method, scene.statistics)
        record = device_record(array_module(device)) | (
            {"method_requested": scene.method} if method != scene.method else {})
    return FrameInfo(
        scene=scene.name,
        illuminant=lit.illuminant,
        intensity_factor=intensity_factor,
        seed=seed,
        photon_statistics=scene.statistics,
        method=method,
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
        exposure=exposure_record(scene),
        surround=radiance.surround,
        target=radiance.target,
        recovery=radiance.recovery,
        patch_weights=radiance.patch_weights,
        white_signal_e_per_s=None if lit.white_photon_rate is None else lit.white_signal_e_per_s,
        preset=preset_record(scene),
        device=record,
    )


def preset_record(scene: Scene) -> dict | None:
    """A camera preset's name (or file) and ISO, for the sidecar: ``{"preset": …, "iso": …}``; None for the
    model's sensor presets (their parameters are the sensor's keys)."""
    from camsim.sensor.presets import camera_preset

    camera = camera_preset(scene.preset_name, scene.base_dir)
    if camera is None:
        return None
    point = camera.point_at(scene.iso)
    # a gain set on top of the preset (a virtual camera's K, --sensor analog_gain_dn_per_v) is no ISO of the camera
    iso = point.iso if abs(scene.sensor.dn_per_electron / point.k_dn_per_e - 1) < 1e-9 else None
    return {"preset": scene.preset_name, "preset_title": camera.title, "preset_source": camera.source, "iso": iso}


def exposure_record(scene: Scene) -> dict:
    """How a frame's T (its sensor's ``exposure_s``) is chosen: the sidecar's ``exposure`` key, a dataset
    manifest's ``exposure`` keys. With ``auto``, each frame's T is in its sidecar's ``exposure_s``."""
    if scene.exposure == "fixed":
        return {"exposure": "fixed"}
    return {"exposure": "auto", "exposure_target_e": scene.exposure_target_e, "exposure_max_s": scene.exposure_max_s}


def scene_frame(scene: Scene, illuminant: str, intensity_factor: float, *, seed: int | None = None,
                lit: LitScene | None = None, camera: Camera | None = None,
                workers: int | None = None, device: str = "cpu") -> tuple[Frame, FrameInfo]:
    """One frame of ``scene`` (its sensor, statistics, method and tolerance) and its :class:`FrameInfo`.

    Parameters
    ----------
    seed : int, optional
        The run seed (default the scene's); the frame draws from
        ``camsim.core.seeding.frame_seed_sequence(seed, illuminant, intensity_factor)``, so a frame is the same
        whether it is rendered alone or in a longer run.
    lit, camera : optional
        ``light_scene(scene, illuminant)`` and the scene's camera, when the caller keeps them between frames.
    device : {'cpu', 'cuda', 'numpy'}
        Where the frame is drawn (:func:`make_frame`); its sidecar records a device other than the CPU.
    """
    seed = scene.seed if seed is None else seed
    if camera is None:
        camera = load_camera(scene.camera, scene.grid, scene.sensitivity_basis, scene.base_dir)
    lit = light_scene(scene, illuminant, camera) if lit is None else lit
    if lit.illuminant != illuminant:
        raise ValueError(f"scene_frame under {illuminant!r} was given a scene lit by {lit.illuminant!r}")
    if scene.optics is not None:  # the optics blur the expectation: the frame is drawn per pixel (render.optics)
        from camsim.render.optics import check_optics_scene, optics_frame

        check_optics_scene(scene)
        frame, record = optics_frame(lit, frame_sensor(scene, lit, intensity_factor), intensity_factor, scene.optics,
                                     rng=frame_seed_sequence(seed, illuminant, intensity_factor), workers=workers,
                                     device=device)
        info = scene_frame_info(scene, lit, camera.name, intensity_factor, seed, device)
        return frame, dataclasses.replace(info, method="poisson", optics=record)
    frame = make_frame(lit, frame_sensor(scene, lit, intensity_factor), intensity_factor,
                       statistics=scene.statistics, method=scene.method,
                       rng=frame_seed_sequence(seed, illuminant, intensity_factor), tolerance=scene.tolerance,
                       workers=workers, device=device)
    return frame, scene_frame_info(scene, lit, camera.name, intensity_factor, seed, device)


def check_frame(lit: LitScene, sensor: SensorParams, intensity_factor: float, statistics: str, *,
                per_pixel: bool = False) -> None:
    """Refuse a frame that cannot be drawn or written, before it is: its expected signal must be finite
    (:func:`camsim.sensor.expected.expected_signal`), its values must fit the frame's float32 pixels
    (:func:`camsim.render.frame.check_frame_values`) — what drawing it checks first — and what is written after the
    drawing must be finite and fit: the perfect white's signal (the sidecar's ``white_signal_e``) and a quantised
    frame's exposure (its DNG's, :data:`camsim.io.dng.MAX_EXPOSURE_S`).

    ``camsim render`` checks its frames so before any work (:func:`check_frames`), and a dataset's planning every
    frame (:mod:`camsim.dataset.spec`), so that ``camsim dataset --dry-run`` refuses what the run would.

    ``per_pixel``: the frame's expectation is made per pixel in float32 (through a lens or a motion), whose bound it
    must fit too (:func:`check_per_pixel_values`).

    Raises
    ------
    CamsimError
        The reason (an overflow names the largest F allowed).
    """
    expected = lit.expected(sensor, intensity_factor, statistics)
    check_frame_values(expected, sensor)
    if per_pixel:
        check_per_pixel_values(expected)
    if lit.white_photon_rate is not None:  # the perfect white's signal, which the sidecar records
        with np.errstate(over="ignore", invalid="ignore"):
            white = lit.white_signal_e_per_s * intensity_factor * sensor.exposure_s
        if not np.all(np.isfinite(white)):
            raise CamsimError(f"the perfect white's signal at F = {intensity_factor:g}, T = {sensor.exposure_s:g} s "
                              "overflows float64: the [camera.scale] and the luminance are beyond its range")
    if sensor.quantisation and sensor.exposure_s > MAX_EXPOSURE_S:
        raise CamsimError(f"exposure T = {sensor.exposure_s:g} s is longer than a DNG records ({MAX_EXPOSURE_S} s, "
                          "136 years): shorten it (or set exposure_max_s)")


def check_per_pixel_values(expected) -> None:
    """Refuse a frame through a lens or a motion whose mean charge passes :data:`camsim.render.frame.FRAME_VALUE_MAX`,
    saturation or not: the lens blurs the expectation, a sequence warps it, as per-pixel float32 planes
    (:mod:`camsim.render.optics`, :mod:`camsim.render.sequence`), where such a mean is infinite and its neighbours
    NaN. (A static frame's mean above the full well is drawn at the saturation cap.)

    Raises
    ------
    CamsimError
    """
    from camsim.render.frame import FRAME_VALUE_MAX

    top = float(np.max(expected.signal_e + expected.dark_e, initial=0.0))
    if not top <= FRAME_VALUE_MAX:
        raise CamsimError(f"a mean charge of {top:.3g} e⁻ per pixel is beyond {FRAME_VALUE_MAX:.0e}, the largest a "
                          "frame's per-pixel float32 expectation (through a lens or a motion) holds: lower F, the "
                          "exposure or the [camera.scale]")


def check_frames(scene: Scene, camera: Camera | None = None) -> list[str]:
    """Refuse a scene with a frame that cannot be drawn, before anything is drawn or written; return its warnings.

    Every illuminant is lit once and its brightest frame checked (every mean grows with F): its expected signal
    must be finite (:func:`camsim.sensor.expected.expected_signal`) and its values must fit the frame's float32 pixels
    (:func:`camsim.render.frame.check_frame_values`). Means far above the full well are no reason to refuse: they are
    drawn at the saturation cap (:func:`camsim.sensor.stages.cap_mean_e`).

    Parameters
    ----------
    scene : Scene
    camera : Camera, optional
        The scene's camera, when the caller has it loaded.

    Returns
    -------
    list of str
        :func:`frame_warnings` of the scene's sensor (with auto exposure: of each frame's, naming the frame), one
        line each, for the caller to print.

    Raises
    ------
    CamsimError
        Naming the frame (illuminant and F) and the reason.
    """
    if camera is None:
        camera = load_camera(scene.camera, scene.grid, scene.sensitivity_basis, scene.base_dir)
    # with a fixed exposure every mean grows with F: the brightest frame stands for all; with auto exposure T
    # changes per frame (and the dark charge with it), so every frame is checked
    factors = scene.intensity_factors if scene.exposure == "auto" else (max(scene.intensity_factors),)
    warned = []  # (illuminant, F, T, line) of each frame with a warning
    for illuminant in scene.illuminants:
        lit = light_scene(scene, illuminant, camera)
        for factor in factors:
            try:
                sensor = frame_sensor(scene, lit, factor)
                check_frame(lit, sensor, factor, scene.statistics,
                            per_pixel=scene.optics is not None or scene.sequence is not None)
            except CamsimError as exc:
                raise CamsimError(f"frame under {illuminant} at F = {factor:g}: {exc}") from None
            warned += [(illuminant, factor, sensor.exposure_s, line) for line in frame_warnings(sensor)]
    if scene.exposure == "fixed" or not warned:
        return [line for *_, line in warned]
    illuminant, factor, exposure, line = warned[0]
    others = len({(i, f) for i, f, *_ in warned}) - 1
    return [f"auto exposure under {illuminant} at F = {factor:g} (T = {exposure:.4g} s): {line}"
            + (f"; and {others} more of the {len(scene.illuminants) * len(factors)} frames" if others else "")]


#: "Every pixel" in :func:`frame_warnings`: the dark level this many standard deviations (of the dark shot noise,
#: DSNU, read and row noise) past the threshold, so that a pixel escapes with probability below 1e-9.
EVERY_PIXEL_SIGMA = 6.0


def frame_warnings(sensor: SensorParams) -> list[str]:
    """Warnings (one line each, no prefix) about frames of ``sensor`` that are valid but saturated by their dark.

    Two conditions, on the mean dark charge D̄ = σ²_dark · T of each channel (Eq. 6), with k = G · G_Ve⁻:

    * with saturation on, D̄ ≥ full well: the dark current alone fills the well, so every pixel saturates
      whatever the light ("every" when D̄_cold − 6 σ ≥ full well, σ² = D̄_cold + DSNU², D̄_cold the dark mean of a
      pixel 6 σ cold on the dark-current DSNU map (D̄ without it); else "most");
    * otherwise, with quantisation on, k · D̄ ≥ 2^nb − 1 (the white level): the dark level alone reaches the top of
      the ADC, so every pixel reads the white level ("every" when k (D̄_cold − 6 σ) ≥ 2^nb − 1,
      σ² = D̄_cold + DSNU² + σ_read² + σ_row²) — a high gain does this before the well fills.

    The offsets' σ includes issue 28's column FPN and dark shading (:attr:`SensorParams.offset_sigma_e`); with dead
    pixels (which collect no dark charge) the warning says "most", never "every". Both may put the black level (the
    mean digital number of an unlit pixel,
    :attr:`camsim.sensor.params.SensorParams.black_level_dn`) above the white level − 1; the DNG's BlackLevel is then
    written as the white level − 1 (:attr:`camsim.sensor.params.SensorParams.black_level_tag_dn`), which the warning
    says too, as it does when only that clip applies (the black level within 1 DN of the white level).

    Returns
    -------
    list of str
        Empty for every ordinary sensor; at most one line.
    """
    dark = sensor.dark_mean_e
    k, full, white = sensor.dn_per_electron, sensor.full_well_e, sensor.max_dn
    black = sensor.black_level_dn
    clipped_tag = sensor.quantisation and bool(np.any(sensor.black_level_tag_dn != black))
    tag = (f"; the DNG's BlackLevel is written as {white - 1} DN, below its WhiteLevel {white} DN (sidecar "
           f"black_level_tag_dn; black_level_dn keeps the true black level {_channels(black, range(3), '.4g')} DN)"
           if clipped_tag else "")
    read = sensor.read_noise_e if sensor.read_noise else 0.0
    # the coldest pixels' dark charge: the dark-current DSNU map's factor 6 σ below its normal's mean (1 when off)
    cold = dark * dark_gain_at(sensor, -EVERY_PIXEL_SIGMA)
    dead = sensor.dead_pixel_fraction > 0  # dead pixels collect no dark charge: then "most", never "every"
    when = f"at T = {sensor.exposure_s:g} s"
    if sensor.saturation and np.any(dark >= full):
        hit = [c for c in range(3) if dark[c] >= full]
        sigma = np.sqrt(cold + sensor.offset_sigma_e**2)
        every = all(cold[c] - EVERY_PIXEL_SIGMA * sigma[c] >= full for c in hit) and not dead
        return [f"dark current alone fills the well: σ²_dark·T = {_channels(dark, hit)} e⁻ ≥ full well {full:g} e⁻ "
                f"{when}; {_pixels(every, hit)} saturate{'s' if every else ''}, whatever the light{tag}"]
    if sensor.quantisation and np.any(k * dark >= white):
        hit = [c for c in range(3) if k * dark[c] >= white]
        sigma = np.sqrt(cold + sensor.offset_sigma_e**2 + read**2 + sensor.row_noise_e**2)
        every = all(k * (cold[c] - EVERY_PIXEL_SIGMA * sigma[c]) >= white for c in hit) and not dead
        below = f"; the full well, {full:g} e⁻, is not reached" if sensor.saturation else ""
        return [f"dark current alone reaches the top of the ADC: k·σ²_dark·T = {_channels(k * dark, hit, '.4g')} DN ≥ "
                f"white level {white} DN {when} (k = {k:.4g} DN/e⁻{below}); {_pixels(every, hit)} "
                f"read{'s' if every else ''} {white} DN, whatever the light{tag}"]
    if clipped_tag:
        hit = [c for c in range(3) if black[c] > white - 1]
        return [f"the black level (the mean digital number of an unlit pixel) = {_channels(black, hit, '.4g')} DN "
                f"{when} is within 1 DN of the white level {white} DN{tag}"]
    return []


def _channels(values, channels, spec: str = ".6g") -> str:
    """``R 9750, G 11500``: the values of some channels, each after its name."""
    return ", ".join(f"{'RGB'[c]} {format(float(values[c]), spec)}" for c in channels)


def _pixels(every: bool, channels) -> str:
    """``every pixel`` / ``most G pixels``, naming the channels unless all three."""
    which = "" if len(channels) == 3 else " " + "/".join("RGB"[c] for c in channels)
    return f"every{which} pixel" if every else f"most{which} pixels"
