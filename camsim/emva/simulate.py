"""The EMVA 1288 measurement of a simulated camera, and its analysis by the reference implementation.

The measurement (EMVA 1288 Release 4.0 Linear, photon transfer method) is simulated with camsim's own renderer,
as a test bench would take it from a real camera:

* a uniform monochromatic light at the test wavelength (default 550 nm) on a region of ``size × size`` pixels, at
  one exposure time (the sensor's ``exposure_s``), its irradiation varied from dark to beyond saturation: 50
  equally spaced steps up to 1.2 × the predicted saturation, plus 10 more in its lowest 5 %;
* two frames per step and two dark frames (the temporal statistics use the difference of the pair, so the fixed
  pattern cancels);
* for the spatial non-uniformity, ``L`` dark frames and ``L`` frames at 50 % of saturation, averaged by the
  analysis to remove the temporal noise;
* where asked (:attr:`EmvaSetup.dsnu_exposure_factor`), and always for a sensor with a dark-current DSNU, ``L``
  more dark frames at a second, longer exposure time T₂: the DSNU at two exposure times, split into its offset
  part (the same at every T) and its dark-current part (∝ T), DSNU²(T) = σ_o² + (c T)². The standard's spatial
  data take one exposure time, so the DSNU at T₂ is the standard's own formula (:func:`dark_spatial_variance_dn2`)
  on that stack, with the reference implementation's K;
* where asked (:attr:`EmvaSetup.temperatures`), the dark current against the temperature: at each temperature
  (the sensor's ``temperature_c`` set to it) ``L`` dark frames at T and ``L`` at T₂; the dark current is the slope of
  the mean dark value against the exposure time, (μ_y.dark(T₂) − μ_y.dark(T)) / (T₂ − T) / K (DN/s over the
  reference implementation's K: e⁻/s), and the doubling temperature T_d the inverse slope of the straight line
  log₂ μ_I = a + ϑ / T_d through those points (:func:`doubling_temperature_fit`; EMVA 1288's law
  μ_I(ϑ) = μ_I,ref · 2^((ϑ − ϑ_ref)/T_d)). The offsets (black level, DSNU) are the same at both exposure times and
  cancel from the slope, as does the quantiser's half step.

The measurement itself is taken at the sensor's own ``temperature_c`` (none: the dark current as given): every dark
figure it configures and reports (σ_d's dark shot noise, the DSNU's dark-current part, the saturation less the dark
electrons) is the dark current there (``SensorParams.dark_mean_e``).

Every frame comes from the same sensor (one ``sensor_seed``: the same DSNU / PRNU maps) with its own temporal
noise (``SeedSequence(seed, spawn_key=(kind, step, frame))``). The G channel is analysed (a monochrome EMVA
measurement through the G filter; on a Bayer sensor, the first G site of the 2 × 2 cell).

The camera's quantum efficiency is camsim's: the default camera's relative QE (``Nikon 5100 (NPL)``) at its
physical scale (:class:`camsim.sensor.camera.PhysicalScale`, peak QE 0.5, 4.65 µm pixels), so that a pixel collects
η_G(λ) · μ_p electrons from μ_p photons, μ_p = T · g · (pixel étendue). The digital numbers (``frame.digital_dn``)
go to ``emva1288``'s in-memory entry points, :class:`Data1288` and :class:`Results1288`, with no image file.
"""

from __future__ import annotations

import contextlib
import dataclasses
import logging
import math
from dataclasses import dataclass, field

import numpy as np

from camsim.core.errors import CamsimError
from camsim.core.optional_numbers import finite_or_none
from camsim.core.seeding import emva_frame_seed_sequence
from camsim.emva.configured import (  # noqa: F401 (re-exported)
    CHANNEL,
    DEFAULT_PRESET,
    configured_split,
    configured_values,
    model_dark_temporal_dn,
    predicted_saturation_e,
    sensor_for,
)
from camsim.light.spectra import WavelengthGrid
from camsim.render.pipeline import LitScene, make_frame
from camsim.sensor.camera import DEFAULT_CAMERA, PhysicalScale, absolute_qe, load_camera
from camsim.sensor.cfa import cfa_sites
from camsim.sensor.fixed_pattern import fixed_pattern
from camsim.sensor.params import SensorParams

#: Wavelength grid of the monochromatic test light (5 nm bins, so that 550 nm is a bin centre).
GRID = WavelengthGrid(380.0, 780.0, 5.0)
#: EMVA 1288 lower limit of the dark variance used by the reference implementation (DN²): below it, the
#: temporal dark noise is quantisation-limited and ``Results1288.sigma_y_dark`` returns √0.24.
S2_YDARK_FLOOR_DN2 = 0.24
#: The quantities compared, in ``emva.json``'s order: key → (unit, relative-error target or None).
QUANTITIES = {
    "K_dn_per_e": ("DN/e⁻", 0.02),
    "dark_noise_e": ("e⁻", 0.02),
    "qe": ("e⁻/photon", 0.02),
    "saturation_e": ("e⁻", None),
    "dsnu_e": ("e⁻", 0.05),
    "prnu_percent": ("%", 0.05),
}
#: The DSNU's split by exposure time, in ``emva.json`` after :data:`QUANTITIES` when the second dark stack was
#: taken: the offset part σ_o and the dark-current part's rate c (DSNU²(T) = σ_o² + (c T)²). Targets: see the tests.
SPLIT_QUANTITIES = {
    "dsnu_offset_e": ("e⁻", 0.05),
    "dsnu_dark_current_e_per_s": ("e⁻/s", 0.05),
}
#: T₂ / T of the second dark stack of a sensor with a dark-current DSNU, when the setup names none.
DEFAULT_DSNU_EXPOSURE_FACTOR = 4.0
#: The doubling temperature, in ``emva.json`` after the others when the dark current was measured at several
#: temperatures (:attr:`EmvaSetup.temperatures`). Target: see the tests.
TEMPERATURE_QUANTITIES = {
    "dark_current_doubling_c": ("°C", 0.05),
}
#: The measurement kind of the dark stacks at several temperatures (their frames' seeds: kind, 2 · i + e, frame).
TEMPERATURE_KIND = 3


def _asfarray(a, dtype=float):
    return np.asarray(a, dtype=dtype)


#: NumPy 1 names that emva1288 still calls and NumPy 2 removed, with what they stood for.
_NUMPY1_NAMES = {"asfarray": _asfarray, "int": int}


@contextlib.contextmanager
def emva1288_numpy_shims():
    """Within the block, ``np.asfarray`` and ``np.int`` exist, as emva1288 (written for NumPy 1) needs.

    Only the names NumPy lacks are added, and exactly those are removed when the block ends (also on an
    exception): outside it, every other module sees NumPy as it was. emva1288's routines look the names up when
    they run, so every call into emva1288 goes inside the block, including reading the lazily computed properties
    of ``Results1288`` (``K``, ``QE``, ...).
    """
    added = [name for name in _NUMPY1_NAMES if not hasattr(np, name)]
    for name in added:
        setattr(np, name, _NUMPY1_NAMES[name])
    try:
        yield
    finally:
        for name in added:
            vars(np).pop(name, None)


def emva1288_process():
    """``emva1288.process``; call into it within :func:`emva1288_numpy_shims`.

    Raises
    ------
    CamsimError
        emva1288 is not installed.
    """
    try:
        import emva1288.process as process
    except ImportError as exc:  # pragma: no cover - a declared dependency
        raise CamsimError(f"camsim emva needs the emva1288 package (pip install emva1288): {exc}") from None
    return process


@dataclass(frozen=True)
class EmvaSetup:
    """How the measurement is taken.

    Attributes
    ----------
    size : int
        Side of the square region of interest. Unit: pixels.
    steps : int
        Equally spaced irradiation steps from dark to ``overshoot`` × the predicted saturation.
    low_steps : int
        Extra steps in the lowest 5 % of the predicted saturation.
    overshoot : float
        Last step relative to the predicted saturation (> 1: beyond it).
    stack_frames : int
        L, frames averaged in the dark and in the bright for DSNU / PRNU.
    spatial_level : float
        Level of the bright stack, as a fraction of the predicted saturation (EMVA 1288: 50 %).
    wavelength_nm : float
        Test wavelength, a centre of :data:`GRID`'s bins. Unit: nm.
    seed : int
        Seed of the temporal noise (the fixed pattern is the sensor's ``sensor_seed``).
    camera : str
        camsim camera whose relative QE, at :class:`PhysicalScale`, is the sensor's spectral QE.
    workers : int
        Threads per frame (the output does not depend on it).
    dsnu_exposure_factor : float or None
        T₂ / T: also take ``stack_frames`` dark frames at T₂, for the DSNU at two exposure times. None: only for a
        sensor with a dark-current DSNU (``dsnu_dark_current_percent`` > 0), at :data:`DEFAULT_DSNU_EXPOSURE_FACTOR`.
    temperatures : tuple of float
        Sensor temperatures at which to measure the dark current (at T and at T₂, T₂ / T the
        ``dsnu_exposure_factor`` or :data:`DEFAULT_DSNU_EXPOSURE_FACTOR`), for the doubling temperature; empty: none.
        At least two distinct ones. Unit: °C.
    """

    size: int = 256
    steps: int = 50
    low_steps: int = 10
    overshoot: float = 1.2
    stack_frames: int = 100
    spatial_level: float = 0.5
    wavelength_nm: float = 550.0
    seed: int = 0
    camera: str = DEFAULT_CAMERA
    workers: int = 2
    dsnu_exposure_factor: float | None = None
    temperatures: tuple = ()

    def __post_init__(self):
        if not (isinstance(self.size, int) and 16 <= self.size <= 4096):
            raise CamsimError(f"the EMVA region of interest must be 16 to 4096 pixels on a side, got {self.size!r}")
        if not (isinstance(self.steps, int) and self.steps >= 10):
            raise CamsimError(f"EMVA needs at least 10 irradiation steps, got {self.steps!r}")
        if not (isinstance(self.low_steps, int) and self.low_steps >= 0):
            raise CamsimError(f"low_steps must be an integer ≥ 0, got {self.low_steps!r}")
        if not (isinstance(self.stack_frames, int) and self.stack_frames >= 2):
            raise CamsimError(f"the spatial stacks need at least 2 frames each, got {self.stack_frames!r}")
        if not (math.isfinite(self.overshoot) and 1.0 < self.overshoot <= 3.0):
            raise CamsimError(f"overshoot must be in (1, 3] (the series must go beyond saturation), "
                              f"got {self.overshoot}")
        if not (math.isfinite(self.spatial_level) and 0.0 < self.spatial_level < 1.0):
            raise CamsimError(f"spatial_level must be in (0, 1), got {self.spatial_level}")
        if not (isinstance(self.seed, int) and self.seed >= 0):
            raise CamsimError(f"seed must be an integer ≥ 0, got {self.seed!r}")
        if not (isinstance(self.workers, int) and self.workers >= 1):
            raise CamsimError(f"workers must be an integer ≥ 1, got {self.workers!r}")
        factor = self.dsnu_exposure_factor
        if factor is not None and not (isinstance(factor, (int, float)) and not isinstance(factor, bool)
                                       and math.isfinite(factor) and 1.0 < factor <= 100.0):
            raise CamsimError(f"dsnu_exposure_factor (the DSNU's second exposure time over the first) must be > 1 "
                              f"and ≤ 100, got {factor!r}")
        temps = tuple(self.temperatures) if isinstance(self.temperatures, (tuple, list)) else (self.temperatures,)
        if temps and not (len(set(temps)) == len(temps) >= 2
                          and all(isinstance(t, (int, float)) and not isinstance(t, bool) and math.isfinite(t)
                                  and t > -273.15 for t in temps)):
            raise CamsimError(f"the dark current against the temperature needs at least two distinct temperatures "
                              f"above −273.15 °C, got {list(temps)!r}")
        object.__setattr__(self, "temperatures", tuple(float(t) for t in temps))
        wl = GRID.wavelengths_nm
        if not np.any(np.isclose(wl, self.wavelength_nm)):
            raise CamsimError(f"test wavelength {self.wavelength_nm} nm is not a centre of the {GRID.step_nm:g} nm "
                              f"bins from {GRID.start_nm:g} to {GRID.end_nm:g} nm")


@dataclass
class Measurement:
    """The simulated measurement: ``data`` is the dictionary :class:`emva1288.process.Data1288` takes.

    Attributes
    ----------
    sensor : SensorParams
    setup : EmvaSetup
    preset_name : str or None
    eta : float
        Configured quantum efficiency of the analysed channel at the test wavelength. Unit: e⁻ / photon.
    photons : numpy.ndarray
        μ_p of the bright steps (photons per pixel in the exposure), ascending.
    photons_spatial : float
        μ_p of the bright spatial stack.
    predicted_saturation_e : float
        Signal electrons at which the model saturates, ignoring noise: min(full well, ADC full scale / K) minus the
        dark electrons. Unit: e⁻.
    data : dict
        ``{'temporal': {texp_ns: {μ_p: {'sum', 'pvar', 'dmean'}}}, 'spatial': {texp_ns: {μ_p: {'L', 'sum',
        'pvar', 'dmean'}}}, 'width', 'height'}``, μ_p = 0.0 for the dark frames (the loader's format).
    realised_dsnu_e, realised_prnu_percent : float or None
        Standard deviation of the sensor's actual maps over the analysed pixels (None when off).
    frames : int
        Frames rendered.
    dsnu_exposure_s : float or None
        T₂, the exposure time of the second dark stack (None: not taken). Unit: s.
    dark_stack_long : dict or None
        That stack, reduced as the spatial stacks (``{'L', 'sum', 'pvar', 'dmean'}``).
    realised_dark_dsnu_e_per_s : float or None
        Standard deviation over the analysed pixels of the actual dark-current rates σ²_dark,G · d (None when the
        dark-current DSNU is off). Unit: e⁻/s.
    dark_vs_temperature : list of dict
        Per temperature of :attr:`EmvaSetup.temperatures`: ``temperature_c``, ``exposures_s`` (T, T₂) and
        ``frame_means_dn`` (the mean over the analysed pixels of each dark frame, (2, L)).
    """

    sensor: SensorParams
    setup: EmvaSetup
    preset_name: str | None
    eta: float
    photons: np.ndarray
    photons_spatial: float
    predicted_saturation_e: float
    data: dict
    realised_dsnu_e: float | None = None
    realised_prnu_percent: float | None = None
    frames: int = 0
    camera: str = ""
    dsnu_exposure_s: float | None = None
    dark_stack_long: dict | None = None
    realised_dark_dsnu_e_per_s: float | None = None
    dark_vs_temperature: list = field(default_factory=list)


@dataclass
class EmvaResult:
    """The analysis: the reference implementation's results and the comparison with the configuration."""

    measurement: Measurement
    results: object  # emva1288.process.Results1288: read its properties within emva1288_numpy_shims()
    configured: dict
    recovered: dict
    details: dict = field(default_factory=dict)

    @property
    def quantities(self) -> dict:
        """:data:`QUANTITIES`, then :data:`SPLIT_QUANTITIES` where the second dark stack was taken."""
        out = dict(QUANTITIES)
        if self.measurement.dark_stack_long is not None:
            out.update(SPLIT_QUANTITIES)
        if self.measurement.dark_vs_temperature:
            out.update(TEMPERATURE_QUANTITIES)
        return out

    def comparison(self) -> dict:
        """``{key: {"configured", "recovered", "relative_error"}}`` for :attr:`quantities` (None = undefined)."""
        out = {}
        for key in self.quantities:
            c, r = self.configured[key], self.recovered[key]
            rel = None if c is None or r is None or c == 0 else (r - c) / c
            out[key] = {"configured": c, "recovered": r, "relative_error": rel}
        return out

    def within_target(self, key: str) -> bool | None:
        """Whether ``key`` meets its target; None when it has none (saturation) or is off (DSNU/PRNU = 0)."""
        target = self.quantities[key][1]
        rel = self.comparison()[key]["relative_error"]
        if target is None or not self.configured[key]:
            return None
        return rel is not None and abs(rel) <= target


def channel_image(digital_dn: np.ndarray, sensor: SensorParams) -> np.ndarray:
    """The analysed pixels of a frame: the G plane, or on a Bayer sensor its first G site, (H', W') integers."""
    if sensor.cfa is None:
        return digital_dn[CHANNEL]
    dy, dx = next((dy, dx) for dy, dx, c in cfa_sites(sensor.cfa) if c == CHANNEL)
    return digital_dn[0, dy::2, dx::2]


def _channel_map(maps: np.ndarray, sensor: SensorParams) -> np.ndarray:
    if sensor.cfa is None:
        return maps[CHANNEL]
    dy, dx = next((dy, dx) for dy, dx, c in cfa_sites(sensor.cfa) if c == CHANNEL)
    return maps[CHANNEL, dy::2, dx::2]


class IntStack:
    """Running reduction of integer frames, exactly emva1288's ``routines.get_int_imgs`` (which needs them all).

    ``result()`` gives ``{'L', 'sum', 'pvar', 'dmean'}``: the number of frames, their sum image (int64), the
    pseudo-variance image L (L Σ y² − (Σ y)²) and the sum of the differences of consecutive frames' means.
    """

    def __init__(self):
        self.count, self.total, self.squares, self.dmean, self._previous_mean = 0, 0, 0, 0, None

    def add(self, image: np.ndarray) -> None:
        i = image.astype(np.int64)
        self.total = self.total + i
        self.squares = self.squares + np.square(i)
        mean = np.mean(i)
        if self._previous_mean is not None:
            self.dmean += mean - self._previous_mean
        self._previous_mean = mean
        self.count += 1

    def result(self) -> dict:
        n = self.count
        return {"L": n, "sum": self.total, "pvar": n * (n * self.squares - np.square(self.total)), "dmean": self.dmean}


def simulate(sensor: SensorParams, setup: EmvaSetup = EmvaSetup(), preset_name: str | None = None,
             progress: bool = False) -> Measurement:
    """Render the EMVA 1288 series of ``sensor`` and reduce it to the reference implementation's input."""
    if not sensor.quantisation:
        raise CamsimError("an EMVA 1288 measurement needs digital numbers: this sensor has quantisation off "
                          "(try --preset emva-12bit or paper-table1)")
    if not sensor.photon_noise:
        raise CamsimError("the photon transfer method needs photon noise: this sensor has it off")
    camera = load_camera(setup.camera, GRID)
    scale = PhysicalScale()
    qe_abs = absolute_qe(camera, scale, GRID)  # e⁻ m² sr / photon, (3, N)
    bin_index = int(np.argmin(np.abs(GRID.wavelengths_nm - setup.wavelength_nm)))
    eta = float(camera.relative_qe[CHANNEL, bin_index] * scale.peak_qe)
    if not eta > 0:
        raise CamsimError(f"the camera's G channel has no sensitivity at {setup.wavelength_nm} nm")
    sat_e = predicted_saturation_e(sensor)
    if not sat_e > 0:
        raise CamsimError("the dark signal alone saturates this sensor: no photon transfer curve to measure")
    sat_p = sat_e / eta
    main = np.linspace(0.0, setup.overshoot * sat_p, setup.steps + 1)[1:]
    low = np.linspace(0.0, 0.05 * sat_p, setup.low_steps + 1)[1:]
    photons = np.unique(np.round(np.concatenate([main, low]), 6))
    photons_spatial = float(np.round(setup.spatial_level * sat_p, 6))

    n = GRID.wavelengths_nm.size
    labels = np.zeros((setup.size, setup.size), np.uint8)
    if sensor.cfa is not None and setup.size % 2:
        raise CamsimError(f"a {sensor.cfa} sensor needs an even region of interest, got {setup.size}")
    per_photon = 1.0 / (scale.etendue_m2_sr * sensor.exposure_s)  # photon radiance of one photon per pixel

    def field_at(mu_p: float) -> LitScene:
        """The uniform monochromatic field giving μ_p photons per pixel in the exposure."""
        photon_rate = np.zeros((1, n))
        photon_rate[0, bin_index] = mu_p * per_photon
        return LitScene(labels, photon_rate, qe_abs, GRID)

    factor = setup.dsnu_exposure_factor
    if factor is None and sensor.dsnu_dark_current_percent > 0:
        factor = DEFAULT_DSNU_EXPOSURE_FACTOR
    long_sensor = None if factor is None else dataclasses.replace(sensor, exposure_s=sensor.exposure_s * factor)
    if long_sensor is not None and not predicted_saturation_e(long_sensor) > 0:
        raise CamsimError(f"the dark signal alone saturates this sensor at the DSNU's second exposure time, "
                          f"{long_sensor.exposure_s:g} s: choose a smaller dsnu_exposure_factor")

    temperatures = setup.temperatures
    temperature_factor = factor or DEFAULT_DSNU_EXPOSURE_FACTOR
    if temperatures and not sensor.dark_current:
        raise CamsimError("the dark current against the temperature needs the dark-current stage on")
    for temperature in temperatures:  # the longer dark exposure at the warmest temperature must not saturate
        hot = dataclasses.replace(sensor, temperature_c=temperature, exposure_s=sensor.exposure_s * temperature_factor)
        if not predicted_saturation_e(hot) > 0:
            raise CamsimError(f"the dark signal alone saturates this sensor at {temperature:g} °C and "
                              f"{hot.exposure_s:g} s: measure at lower temperatures or a smaller "
                              "dsnu_exposure_factor")
    frames = 2 * (len(photons) + 1) + 2 * setup.stack_frames + (0 if long_sensor is None else setup.stack_frames)
    frames += 2 * len(temperatures) * setup.stack_frames
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=frames, desc="EMVA 1288 frames", unit="frame", leave=False)

    def frame_at(mu_p: float, key: tuple, j: int, camera_sensor: SensorParams) -> np.ndarray:
        """Frame ``j`` of measurement ``key`` at μ_p: its digital numbers."""
        ss = emva_frame_seed_sequence(setup.seed, *key, j)
        frame = make_frame(field_at(mu_p), camera_sensor, 1.0, statistics="pixel", method="poisson", rng=ss,
                           workers=setup.workers)
        if bar is not None:
            bar.update()
        return frame.digital_dn

    def shoot(mu_p: float, key: tuple, count: int, camera_sensor: SensorParams = sensor) -> dict:
        """``count`` frames at μ_p, reduced as emva1288's ``routines.get_int_imgs`` does, without keeping them."""
        stack = IntStack()
        for j in range(count):
            stack.add(channel_image(frame_at(mu_p, key, j, camera_sensor), sensor))
        return stack.result()

    def temporal_entry(imgs):  # as emva1288's LoadImageData keeps a temporal pair: totals only
        return {"sum": np.sum(imgs["sum"]), "pvar": np.sum(imgs["pvar"]), "dmean": imgs["dmean"]}

    try:
        texp = float(sensor.exposure_s * 1e9)  # the reference implementation's exposure times are in ns
        temporal = {0.0: temporal_entry(shoot(0.0, (0, 0), 2))}
        for i, mu_p in enumerate(photons):
            temporal[float(mu_p)] = temporal_entry(shoot(float(mu_p), (1, i), 2))
        spatial = {
            0.0: shoot(0.0, (2, 0), setup.stack_frames),
            photons_spatial: shoot(photons_spatial, (2, 1), setup.stack_frames),
        }
        dark_long = None if long_sensor is None else shoot(0.0, (2, 2), setup.stack_frames, long_sensor)
        dark_vs_temperature = []
        for i, temperature in enumerate(temperatures):
            at = dataclasses.replace(sensor, temperature_c=temperature)
            exposures = (sensor.exposure_s, sensor.exposure_s * temperature_factor)
            means = [[float(np.mean(channel_image(frame_at(0.0, (TEMPERATURE_KIND, 2 * i + e), j,
                                                           dataclasses.replace(at, exposure_s=t)), sensor),
                                    dtype=np.float64)) for j in range(setup.stack_frames)]
                     for e, t in enumerate(exposures)]
            dark_vs_temperature.append({"temperature_c": temperature, "exposures_s": exposures,
                                        "frame_means_dn": np.asarray(means)})
    finally:
        if bar is not None:
            bar.close()
    height, width = spatial[0.0]["sum"].shape
    data = {"temporal": {texp: temporal}, "spatial": {texp: spatial}, "width": width, "height": height}

    maps = fixed_pattern(sensor, labels.shape)
    dsnu = prnu = None
    if maps is not None and maps.offset_e is not None:
        dsnu = float(np.std(_channel_map(maps.offset_e, sensor), dtype=np.float64))
    if maps is not None and maps.gain is not None:
        prnu = float(100 * np.std(_channel_map(maps.gain, sensor), dtype=np.float64))
    dark_dsnu = None
    if maps is not None and maps.dark_gain is not None and sensor.dark_current:
        rate = sensor.dark_current_effective_e_per_s[CHANNEL]  # at the sensor's temperature
        dark_dsnu = float(rate * np.std(_channel_map(maps.dark_gain, sensor), dtype=np.float64))
    return Measurement(sensor, setup, preset_name, eta, photons, photons_spatial, sat_e, data, dsnu, prnu, frames,
                       camera.name, None if long_sensor is None else long_sensor.exposure_s, dark_long, dark_dsnu,
                       dark_vs_temperature)


def analyse(measurement: Measurement) -> EmvaResult:
    """Run the reference implementation on the measurement and compare with the configuration."""
    with emva1288_numpy_shims():
        return _analyse(measurement)


def _analyse(measurement: Measurement) -> EmvaResult:
    process = emva1288_process()
    data = process.Data1288(measurement.data, loglevel=logging.WARNING)
    pitch = PhysicalScale().pixel_pitch_um
    # EMVA 1288 (4.0 Linear) puts saturation at the maximum of the temporal variance. The reference's own search
    # walks back from the brightest step and stops at the first local maximum, which here is a wiggle of the
    # plateau past saturation (the read noise stays after the charge clips at the full well): force the maximum.
    automatic = process.Results1288(data.data, loglevel=logging.WARNING).index_u_ysat
    index_sat = int(np.argmax(data.data["temporal"]["s2_y"]))
    res = process.Results1288(data.data, pixel_area=pitch * pitch, index_u_ysat=index_sat, loglevel=logging.WARNING)
    res.id = 1  # the reference plots tag their artists with the test's id
    s2_ydark = float(res.temporal["s2_ydark"][0])
    recovered = {
        "K_dn_per_e": finite_or_none(res.K),
        "dark_noise_e": finite_or_none(res.sigma_d),
        "qe": finite_or_none(res.QE / 100.0),
        "saturation_e": finite_or_none(res.u_e_sat),
        "dsnu_e": finite_or_none(res.DSNU1288),
        "prnu_percent": finite_or_none(res.PRNU1288),
    }
    with np.errstate(invalid="ignore"):
        details = {
            "R_dn_per_photon": finite_or_none(res.R),
            "sigma_y_dark_dn": finite_or_none(res.sigma_y_dark),
            "s2_ydark_dn2": s2_ydark,
            "dark_floor_applied": s2_ydark < S2_YDARK_FLOOR_DN2,
            "u_ydark_dn": float(res.temporal["u_ydark"][0]),
            "u_p_sat": finite_or_none(res.u_p_sat),
            "index_u_ysat": int(res.index_u_ysat),
            "index_u_ysat_automatic": int(automatic),
            "u_p_sat_automatic": float(res.temporal["u_p"][automatic]),
            "fit_indices": (int(res.index_sensitivity_min), int(res.index_sensitivity_max)),
            "fit_photons": (float(res.temporal["u_p"][res.index_sensitivity_min]),
                            float(res.temporal["u_p"][res.index_sensitivity_max])),
            "u_p_min": finite_or_none(res.u_p_min),
            "u_e_min": finite_or_none(res.u_e_min),
            "SNR_max": finite_or_none(res.SNR_max),
            "DR_dB": finite_or_none(res.DR_dB()),
            "LE_min_percent": finite_or_none(res.LE_min),
            "LE_max_percent": finite_or_none(res.LE_max),
            "spatial_mean_dn": float(res.spatial["avg_mean"]),
            "spatial_mean_dark_dn": float(res.spatial["avg_mean_dark"]),
            "DSNU1288_DN": finite_or_none(res.DSNU1288_DN()),
            **{name: finite_or_none(getattr(res, name)) for name in (
                "DSNU1288_row", "DSNU1288_col", "DSNU1288_pixel", "PRNU1288_row", "PRNU1288_col", "PRNU1288_pixel")},
        }
    configured = configured_values(measurement.sensor, measurement.eta)
    if measurement.dark_stack_long is not None:  # the DSNU at a second exposure time, and its split
        t1, t2 = measurement.sensor.exposure_s, measurement.dsnu_exposure_s
        s2_long = dark_spatial_variance_dn2(measurement.dark_stack_long)
        dsnu_long = math.sqrt(s2_long) / res.K if s2_long >= 0 else None
        offset, rate = dsnu_split(recovered["dsnu_e"], t1, dsnu_long, t2)
        recovered.update({"dsnu_offset_e": offset, "dsnu_dark_current_e_per_s": rate})
        configured.update(configured_split(measurement.sensor))
        details.update({"dsnu_exposures_s": (t1, t2), "s2_ydark_long_dn2": s2_long, "dsnu_long_e": dsnu_long,
                        "dsnu_long_dn": None if dsnu_long is None else dsnu_long * res.K})
    if measurement.dark_vs_temperature:  # the dark current against the temperature, and its doubling temperature
        rows = [dark_current_slope(entry) for entry in measurement.dark_vs_temperature]
        k = finite_or_none(res.K)
        table = []
        for entry, (slope, error) in zip(measurement.dark_vs_temperature, rows):
            at = dataclasses.replace(measurement.sensor, temperature_c=entry["temperature_c"])
            t1, t2 = entry["exposures_s"]
            linear = at.dn_per_electron * (at.dark_mean_e[CHANNEL] / at.exposure_s)  # K · μ_I: the unclipped slope
            means = [model_dark_temporal_dn(dataclasses.replace(at, exposure_s=t))[0] for t in (t1, t2)]
            clip_bias = (means[1] - means[0]) / (t2 - t1) / linear - 1 if linear > 0 else None
            table.append({"temperature_c": entry["temperature_c"], "slope_dn_per_s": slope,
                          "clip_bias": clip_bias,
                          "slope_standard_error_dn_per_s": error,
                          "dark_current_e_per_s": None if k is None else slope / k,
                          "configured_e_per_s": float(at.dark_current_effective_e_per_s[CHANNEL])
                          if at.dark_current else 0.0})
        fit = doubling_temperature_fit([r["temperature_c"] for r in table], [s for s, _ in rows],
                                       [e for _, e in rows])
        recovered["dark_current_doubling_c"] = fit
        configured["dark_current_doubling_c"] = float(measurement.sensor.dark_current_doubling_c)
        details["dark_current_vs_temperature"] = table
    return EmvaResult(measurement, res, configured, recovered, details)


def dark_current_slope(entry: dict) -> tuple:
    """The slope of the mean dark value against the exposure time at one temperature, and its standard error.

    ``entry``: ``{"exposures_s": (T, T₂), "frame_means_dn": (2, L)}`` (:attr:`Measurement.dark_vs_temperature`).
    Where the dark level is near 0 DN (no pedestal, a small dark current) the ADC's clip at 0 raises the shorter
    exposure's mean more than the longer one's and the slope comes out low: the analysis gives the model's relative
    bias of the slope (``clip_bias`` of ``details["dark_current_vs_temperature"]``, by
    :func:`model_dark_temporal_dn`), and the report names the temperatures where it exceeds 0.1 %.
    The slope is (μ̄₂ − μ̄₁) / (T₂ − T), μ̄ the mean of a stack's frame means; its standard error
    √(s₁² / L + s₂² / L) / (T₂ − T), s the standard deviation of the frame means (ddof 1: the temporal noise, row
    noise included, of one frame's mean). Returns (DN/s, DN/s).
    """
    t1, t2 = entry["exposures_s"]
    means = np.asarray(entry["frame_means_dn"], dtype=np.float64)
    frames = means.shape[1]
    slope = float((means[1].mean() - means[0].mean()) / (t2 - t1))
    error = float(math.sqrt(means[0].var(ddof=1) / frames + means[1].var(ddof=1) / frames) / (t2 - t1))
    return slope, error


def doubling_temperature_fit(temperatures_c, rates, errors=None) -> float | None:
    """The doubling temperature T_d of rates measured at several temperatures: the inverse slope of the straight
    line log₂ rate = a + ϑ / T_d, fitted by weighted least squares (weights 1 / σ²(log₂ rate), σ(log₂ r) =
    σ_r / (r ln 2); equal weights without ``errors``). Two temperatures: T_d = (ϑ₂ − ϑ₁) / log₂(r₂ / r₁) exactly.
    Any unit of the rates (only their ratios count). Unit: °C. None where a rate is not positive or the rates do not
    grow with the temperature (no finite positive T_d)."""
    t = np.asarray(temperatures_c, dtype=np.float64)
    r = np.asarray(rates, dtype=np.float64)
    if np.any(~np.isfinite(r)) or np.any(r <= 0):
        return None
    y = np.log2(r)
    w = np.ones_like(t) if errors is None else (r * math.log(2) / np.maximum(np.asarray(errors, float), 1e-300)) ** 2
    tm, ym = np.average(t, weights=w), np.average(y, weights=w)
    slope = float(np.sum(w * (t - tm) * (y - ym)) / np.sum(w * (t - tm) ** 2))
    return 1.0 / slope if slope > 0 else None


def dark_spatial_variance_dn2(stack: dict) -> float:
    """EMVA 1288's spatial variance of the dark signal, s²_y.dark, from a stack of L dark frames. Unit: DN².

    The variance over pixels (ddof = 1) of the averaged image, less the temporal variance left in the average:
    the mean over pixels of each pixel's variance over the L frames, divided by L. The reference implementation's
    ``Data1288`` (``avg_var``, ``var_mean``) and ``Results1288.s_2_y_dark`` compute it so for the one exposure
    time of their spatial data; this gives the same number for any stack reduced by :class:`IntStack`.
    """
    frames = stack["L"]
    average = stack["sum"] / frames
    temporal = float(np.mean(stack["pvar"] / (frames * frames * (frames - 1))))
    return float(np.var(average, ddof=1)) - temporal / frames


def dsnu_split(dsnu_1, t_1: float, dsnu_2, t_2: float) -> tuple:
    """The offset part σ_o and the dark-current rate c of DSNU²(T) = σ_o² + (c T)², through two measurements.

    σ_o² = (T₂² DSNU₁² − T₁² DSNU₂²) / (T₂² − T₁²) and c² = (DSNU₂² − DSNU₁²) / (T₂² − T₁²): an offset DSNU is the
    same at every T, a DSNU of the dark-current rate grows ∝ T, and independent maps add in variance.

    Parameters
    ----------
    dsnu_1, dsnu_2 : float or None
        DSNU at T₁ and T₂ (None: undefined). Unit: e⁻.
    t_1, t_2 : float
        The exposure times, T₂ > T₁. Unit: s.

    Returns
    -------
    tuple
        (σ_o in e⁻, c in e⁻/s); None where undefined or where the estimate of its square is negative (below the
        estimators' noise).
    """
    if dsnu_1 is None or dsnu_2 is None:
        return None, None
    span = t_2 * t_2 - t_1 * t_1
    offset2 = (t_2 * t_2 * dsnu_1 * dsnu_1 - t_1 * t_1 * dsnu_2 * dsnu_2) / span
    rate2 = (dsnu_2 * dsnu_2 - dsnu_1 * dsnu_1) / span
    return (math.sqrt(offset2) if offset2 >= 0 else None), (math.sqrt(rate2) if rate2 >= 0 else None)


def run(preset_name: str | None = None, setup: EmvaSetup = EmvaSetup(), sensor: SensorParams | None = None,
        progress: bool = False) -> EmvaResult:
    """Simulate and analyse: the measurement of ``sensor`` (or the preset, default :data:`DEFAULT_PRESET`)."""
    sensor, name = sensor_for(preset_name, sensor)
    return analyse(simulate(sensor, setup, name, progress))


def replace_setup(setup: EmvaSetup, **changes) -> EmvaSetup:
    """A copy of ``setup`` with fields changed (None values are ignored)."""
    return dataclasses.replace(setup, **{k: v for k, v in changes.items() if v is not None})
