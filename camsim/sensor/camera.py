"""The camera's spectral quantum efficiency Qe_κ(λ) and its absolute scale (the docs' model page).

A camera's published sensitivities are relative. camsim turns them into the paper's Qe, in
e⁻ · m² · sr / photon (electrons per pixel per unit photon radiance), in one of two ways:

* ``AnchorScale`` (default): scaled once so that a stated reference — the perfect white at 100 cd/m² under a
  stated reference illuminant (D65 by default), F = 1, T = 1 s — yields a stated number of electrons (8000) in the
  strongest channel.
* ``PhysicalScale``: the pixel's étendue times its peak QE: Qe = (π τ p² / 4N²) · QE_peak · QE_rel(λ), for pixel
  pitch p, f-number N and lens transmittance τ (Lambertian scene, on axis, object far away).

Either way Qe is a property of the camera: the same for every illuminant, F and frame of a run. Under
another light at the same luminance the electrons differ, and may saturate; a run that wants every light exposed
to the same level changes the exposure time per frame (``exposure = "auto"``,
:func:`camsim.render.pipeline.frame_sensor`), never Qe.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from camsim.core.errors import CamsimError
from camsim.light.photons import photon_radiance, scale_to_luminance
from camsim.light.spectra import WavelengthGrid, camera_sensitivities, cmfs_on_grid, illuminant_spd

DEFAULT_CAMERA = "Nikon 5100 (NPL)"
SENSITIVITY_BASES = ("energy", "photon")


@dataclass(frozen=True)
class AnchorScale:
    """Absolute scale from a reference white: the perfect white under ``reference_illuminant`` at
    ``reference_luminance_cd_m2``, F = 1 and ``reference_exposure_s`` yields ``reference_electrons`` in the
    camera's strongest channel. Anchored once: Qe is then fixed for every illuminant, F and frame.

    Attributes
    ----------
    reference_electrons : float
        Electrons in the strongest channel for the reference. Unit: e⁻.
    reference_luminance_cd_m2 : float
        Luminance of the perfect white reference at F = 1. Unit: cd/m².
    reference_exposure_s : float
        Exposure at which the reference gives ``reference_electrons``. Unit: s.
    reference_illuminant : str
        colour-science name of the light of the reference white.
    """

    reference_electrons: float = 8000.0
    reference_luminance_cd_m2: float = 100.0
    reference_exposure_s: float = 1.0
    reference_illuminant: str = "D65"

    def __post_init__(self):
        if not isinstance(self.reference_illuminant, str) or not self.reference_illuminant:
            raise CamsimError(f"scale parameter reference_illuminant must be an illuminant name, "
                              f"got {self.reference_illuminant!r}")
        for name in ("reference_electrons", "reference_luminance_cd_m2", "reference_exposure_s"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise CamsimError(f"scale parameter {name} must be a positive number, got {value!r}")
        if self.reference_electrons > REFERENCE_ELECTRONS_MAX:
            raise CamsimError(f"scale parameter reference_electrons must be at most {REFERENCE_ELECTRONS_MAX:g} e⁻, "
                              f"got {self.reference_electrons!r}")

    kind = "anchor"


#: The most charge the anchor may give the perfect white at F = 1: 10³⁰ e⁻, 10²² of the largest full well the schema
#: allows (:data:`camsim.sensor.params.CHARGE_MAX_E`); beyond about 10²⁸⁰ the DNG's colour matrix overflows float64.
#: Unit: e⁻.
REFERENCE_ELECTRONS_MAX = 1e30


@dataclass(frozen=True)
class PhysicalScale:
    """Absolute scale from the optics and the pixel.

    Attributes
    ----------
    pixel_pitch_um : float
        Pixel pitch. Unit: µm.
    f_number : float
        Lens f-number N.
    transmittance : float
        Lens transmittance τ in (0, 1].
    peak_qe : float
        Quantum efficiency at the peak of the strongest channel, in (0, 1]. Unit: e⁻ / photon.
    """

    pixel_pitch_um: float = 4.65
    f_number: float = 2.8
    transmittance: float = 0.9
    peak_qe: float = 0.5

    def __post_init__(self):
        for name in ("pixel_pitch_um", "f_number", "transmittance", "peak_qe"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise CamsimError(f"scale parameter {name} must be a positive number, got {value!r}")
        if self.transmittance > 1 or self.peak_qe > 1:
            raise CamsimError("transmittance and peak_qe must not exceed 1")
        try:
            etendue = self.etendue_m2_sr
        except OverflowError:  # p² or N² beyond float64
            etendue = math.inf
        if not (math.isfinite(etendue) and etendue > 0):
            raise CamsimError(f"scale: pixel_pitch_um = {self.pixel_pitch_um:g} and f_number = {self.f_number:g} "
                              "give a pixel étendue π τ p² / (4 N²) outside float64's range")

    kind = "physical"

    @property
    def etendue_m2_sr(self) -> float:
        """Pixel area times the solid angle of the lens, weighted by τ: π τ p² / (4 N²). Unit: m² · sr."""
        pitch_m = self.pixel_pitch_um * 1e-6
        return math.pi * self.transmittance * pitch_m**2 / (4.0 * self.f_number**2)


@dataclass(frozen=True)
class Camera:
    """A camera's relative per-photon quantum efficiency on the scene grid.

    Attributes
    ----------
    name : str
        colour-science dataset name, or the CSV file name.
    relative_qe : numpy.ndarray, shape (3, N)
        Relative QE per photon for R, G, B, peak 1 over all channels.
    sensitivity_basis : str
        How the source curves were given: ``energy`` (response per unit radiant power, converted with
        QE ∝ s(λ) / λ) or ``photon`` (already per photon).
    """

    name: str
    relative_qe: np.ndarray
    sensitivity_basis: str = "energy"


def load_camera(name_or_csv: str, grid: WavelengthGrid, sensitivity_basis: str = "energy", base_dir=None) -> Camera:
    """Load a camera from colour-science or a CSV (wavelength, R, G, B) and resample it to ``grid``."""
    if sensitivity_basis not in SENSITIVITY_BASES:
        raise CamsimError(f"sensitivity_basis must be one of {SENSITIVITY_BASES}, got {sensitivity_basis!r}")
    label, sens = camera_sensitivities(name_or_csv, grid, base_dir)
    if sensitivity_basis == "energy":
        # A per-energy responsivity s(λ) means electrons ∝ Σ L s δ = Σ g (hc/λ) s: per-photon QE ∝ s / λ.
        sens = sens / grid.wavelengths_nm
    return Camera(name=label, relative_qe=sens / sens.max(), sensitivity_basis=sensitivity_basis)


def reference_white_photon_radiance(scale: AnchorScale, grid: WavelengthGrid) -> np.ndarray:
    """g(λ) of the anchor's reference: the perfect white under ``scale.reference_illuminant`` at
    ``scale.reference_luminance_cd_m2``, F = 1, shape (N,). Unit: photons / (s m² sr) per bin."""
    spd = illuminant_spd(scale.reference_illuminant, grid)
    white = scale_to_luminance(spd, cmfs_on_grid(grid)[1], grid.step_nm, scale.reference_luminance_cd_m2)
    return photon_radiance(white, grid.wavelengths_nm, grid.step_nm)


def absolute_qe(camera: Camera, scale, grid: WavelengthGrid) -> np.ndarray:
    """The paper's Qe_κ(λ) with its absolute scale: one per camera and scale, whatever the scene's light.

    Parameters
    ----------
    camera : Camera
    scale : AnchorScale or PhysicalScale
    grid : WavelengthGrid
        The camera's grid (that of :attr:`Camera.relative_qe`).

    Returns
    -------
    numpy.ndarray, shape (3, N)
        Unit: e⁻ · m² · sr / photon.
    """
    with np.errstate(over="ignore", divide="ignore", invalid="ignore"):  # refused below, with the reason
        if isinstance(scale, PhysicalScale):
            qe = camera.relative_qe * (scale.etendue_m2_sr * scale.peak_qe)
        else:
            white = reference_white_photon_radiance(scale, grid)
            per_channel = scale.reference_exposure_s * (camera.relative_qe @ white)
            qe = camera.relative_qe * (scale.reference_electrons / per_channel.max())
    if not (np.all(np.isfinite(qe)) and qe.max() >= np.finfo(np.float64).tiny):
        what = "zero" if np.all(np.isfinite(qe)) else "not finite"
        raise CamsimError(f"the camera's absolute Qe is {what} under the [camera.scale] {scale.kind} scale: its "
                          "values are beyond float64's range")
    return qe
