"""The closed-form MTF of a camsim frame: what the optics record of its sidecar says the edge-SFR should measure.

Written from the optics literature, independently of the optics that render the frame (:mod:`camsim.optics` is not
imported here: this module is its oracle). Frequencies are in cycles per pixel (cy/px) of the sensor's pitch; a
two-dimensional transfer function is evaluated along the edge's normal ``(nx, ny)`` (a unit vector), which is what
the slanted-edge method measures: the MTF of a 2-D PSF along a direction is the MTF of its projection (its line
spread function) on that direction.

Stages (the sidecar's ``optics`` record, contract of issue 30):

* diffraction of a circular pupil at wavelength λ, f-number N and pixel pitch p: cut-off f_c = p / (λ N) cy/px,
  OTF(ν) = (2/π)(acos ν − ν √(1 − ν²)), ν = f / f_c (Goodman, *Introduction to Fourier Optics*, 3rd ed., §6.3);
* defocus W020 (peak wavefront error, waves at 550 nm; W020·0.55/λ_µm waves at λ): the exact OTF is the pupil's
  autocorrelation with the defocus phase (Hopkins 1955, Proc. R. Soc. A 231, 91), one integral per frequency,
  :func:`defocus_otf`; the product "diffraction OTF × geometric blur disk" is only an approximation
  (:func:`defocus_product_otf`, its distance from the exact one in :func:`product_approximation_error`);
* the birefringent 4-spot OLPF, spots at (±s/2, ±s/2) px with equal weights: OTF cos(π fx s)·cos(π fy s);
* the pixel: a square aperture of side √ff px (ff the fill factor), sinc(√ff fx)·sinc(√ff fy) (numpy's sinc,
  sin(πx)/(πx)), the frame's total pixel factor. A camsim source's pixels are already area integrals over the whole
  pixel (the slanted-edge target holds each pixel's exact bright area fraction, a box of one pixel, sinc(fx)·sinc(fy);
  a chart's patches are constant on pixel boundaries; an image's pixels are area samples), and the renderer's
  aperture stage is relative to that sampling (sinc(√ff f) / sinc(f) per axis): the two make one box of side √ff,
  not a separate source box (at ff = 1, a perfect lens: MTF at Nyquist sinc(½) = 0.637).

A channel's MTF is |Σ_λ w_c(λ)·OTF_optics(f; λ) × OLPF × pixel| with w_c the channel's weights over wavelength
(``channel_wavelength_weights``, each channel's sum 1).
"""

from __future__ import annotations

import functools
import math

import numpy as np

from camsim.core.errors import CamsimError

#: The wavelength at which ``defocus_waves`` is stated (contract of issue 30), µm.
DEFOCUS_REFERENCE_UM = 0.55
#: Gauss–Legendre nodes of :func:`defocus_otf`'s integral (smooth integrand: 1e-10 for W020 ≤ 4 waves).
_QUADRATURE_NODES = 256
#: The channels' names, in the order of the optics record's weights.
CHANNELS = ("R", "G", "B")
#: The one-line statement of this module's model (the figure's and the summary's caption).
MODEL_STATEMENT = ("MTF_c(f) = |sum_l w_c(l) OTF_pupil(f; l) * OLPF(f) * sinc(sqrt(ff) f n_x) sinc(sqrt(ff) f n_y) "
                   "[the pixel: the source's full-pixel area sampling and the aperture stage together, a box of side "
                   "sqrt(ff)]|, OTF_pupil = Hopkins' defocused pupil autocorrelation (the Airy OTF without defocus), "
                   "along the edge normal n")


def cutoff_cy_per_px(wavelength_um, f_number: float, pitch_um: float):
    """The diffraction cut-off of a circular pupil, f_c = p / (λ N), cy/px (p the pixel pitch, µm; λ in µm)."""
    return pitch_um / (np.asarray(wavelength_um, dtype=np.float64) * f_number)


def diffraction_otf(f_cy_per_px, wavelength_um: float, f_number: float, pitch_um: float) -> np.ndarray:
    """The OTF of an aberration-free circular pupil (incoherent light).

    Parameters
    ----------
    f_cy_per_px : array_like
        Radial spatial frequency, cy/px (≥ 0).
    wavelength_um : float
        Wavelength λ, µm.
    f_number : float
        N = focal length / pupil diameter.
    pitch_um : float
        Pixel pitch p, µm.

    Returns
    -------
    numpy.ndarray, float64, shape of ``f_cy_per_px``
        (2/π)(acos ν − ν √(1 − ν²)), ν = f / f_c, f_c = p / (λ N); 0 beyond the cut-off.
    """
    nu = np.clip(np.abs(np.asarray(f_cy_per_px, dtype=np.float64)) / cutoff_cy_per_px(wavelength_um, f_number,
                                                                                       pitch_um), 0.0, 1.0)
    return (2 / np.pi) * (np.arccos(nu) - nu * np.sqrt(1 - nu * nu))


def defocus_waves_at(wavelength_um: float, w020_waves_550: float) -> float:
    """The defocus wavefront error in waves at λ: W020 (waves at 550 nm) × 0.55 / λ_µm (the error in µm is fixed)."""
    return w020_waves_550 * DEFOCUS_REFERENCE_UM / wavelength_um


def w020_from_focus_shift(defocus_um: float, f_number: float) -> float:
    """W020 in waves at 550 nm of an image-plane focus shift Δz (µm): W020 = Δz / (8 N²) µm, / 0.55 µm."""
    return defocus_um / (8 * f_number ** 2) / DEFOCUS_REFERENCE_UM


@functools.lru_cache(maxsize=2)
def _gauss_legendre(n: int):
    return np.polynomial.legendre.leggauss(n)


def pupil_otf(nu, w020_waves: float) -> np.ndarray:
    """The OTF of a circular pupil with defocus, exactly: Hopkins' integral of the pupil's autocorrelation.

    With the pupil of unit radius, the two copies shifted by ±ν (ν = f / f_c, the cut-off at a shift of one
    diameter) and the phase 2π W020 ρ², the phase difference across the overlap is 2π W020 · 4 ν x, so

        OTF(ν) = (1/π) ∬_overlap cos(8π W020 ν x) dx dy = (4/π) ∫_0^{1−ν} cos(8π W020 ν x) √(1 − (x + ν)²) dx,

    and with x + ν = cos φ: (4/π) ∫_0^{acos ν} cos(8π W020 ν (cos φ − ν)) sin² φ dφ, a smooth integrand
    integrated by Gauss–Legendre quadrature. W020 = 0 gives the Airy OTF (2/π)(acos ν − ν√(1 − ν²)).

    Parameters
    ----------
    nu : array_like
        Normalised frequency f / f_c (its absolute value is used; 0 beyond 1).
    w020_waves : float
        Peak defocus wavefront error at the pupil's rim, waves at the wavelength considered.

    Returns
    -------
    numpy.ndarray, float64, shape of ``nu``
        The (real, possibly negative) OTF.
    """
    nu = np.clip(np.abs(np.asarray(nu, dtype=np.float64)), 0.0, 1.0)
    if w020_waves == 0:
        return (2 / np.pi) * (np.arccos(nu) - nu * np.sqrt(1 - nu * nu))
    nodes, weights = _gauss_legendre(_QUADRATURE_NODES)
    top = np.arccos(nu)[..., None]
    phi = 0.5 * top * (nodes + 1)  # nodes on [0, acos ν]
    integrand = np.cos(8 * np.pi * w020_waves * nu[..., None] * (np.cos(phi) - nu[..., None])) * np.sin(phi) ** 2
    return (4 / np.pi) * 0.5 * top[..., 0] * (integrand @ weights)


def defocus_otf(f_cy_per_px, wavelength_um: float, f_number: float, pitch_um: float,
                w020_waves_550: float = 0.0) -> np.ndarray:
    """The exact OTF of a circular pupil with defocus at one wavelength (:func:`pupil_otf` at ν = f / f_c, W020
    converted to waves at λ by :func:`defocus_waves_at`), frequencies in cy/px. Real, may be negative."""
    nu = np.abs(np.asarray(f_cy_per_px, dtype=np.float64)) / cutoff_cy_per_px(wavelength_um, f_number, pitch_um)
    return pupil_otf(nu, defocus_waves_at(wavelength_um, w020_waves_550))


def blur_disk_otf(f_cy_per_px, diameter_px: float) -> np.ndarray:
    """The OTF of a uniform disk of diameter b px (the geometric defocus blur): 2 J1(π b f) / (π b f)."""
    from scipy.special import j1

    x = np.pi * diameter_px * np.abs(np.asarray(f_cy_per_px, dtype=np.float64))
    safe = np.where(x > 0, x, 1.0)
    return np.where(x > 0, 2 * j1(safe) / safe, 1.0)


def defocus_product_otf(f_cy_per_px, wavelength_um: float, f_number: float, pitch_um: float,
                        w020_waves_550: float) -> np.ndarray:
    """The product approximation: the Airy OTF × the geometric blur disk's OTF.

    The geometric blur disk of a focus shift Δz = 8 N² W020 (W020 in µm) has diameter b = Δz / N = 8 N W020 µm,
    b / p px. Exact at W020 = 0 and in the geometric limit of large W020; in between it is not (see
    :func:`product_approximation_error`).
    """
    w020_um = w020_waves_550 * DEFOCUS_REFERENCE_UM
    diameter_px = 8 * f_number * w020_um / pitch_um
    return diffraction_otf(f_cy_per_px, wavelength_um, f_number, pitch_um) * blur_disk_otf(f_cy_per_px, diameter_px)


def product_approximation_error(wavelength_um: float, f_number: float, pitch_um: float, w020_waves_550: float,
                                f_max_cy_per_px: float = 0.5, n: int = 501) -> float:
    """The largest |exact − product| of the defocused OTF on [0, ``f_max_cy_per_px``] (:func:`defocus_otf` against
    :func:`defocus_product_otf`), absolute (OTF units)."""
    f = np.linspace(0.0, f_max_cy_per_px, n)
    exact = defocus_otf(f, wavelength_um, f_number, pitch_um, w020_waves_550)
    product = defocus_product_otf(f, wavelength_um, f_number, pitch_um, w020_waves_550)
    return float(np.max(np.abs(exact - product)))


def olpf_otf(fx, fy, shift_px: float) -> np.ndarray:
    """The birefringent 4-spot OLPF's OTF, spots at (±s/2, ±s/2) px, equal weights: cos(π fx s)·cos(π fy s)."""
    return np.cos(np.pi * np.asarray(fx) * shift_px) * np.cos(np.pi * np.asarray(fy) * shift_px)


def box_otf(fx, fy, side_px: float) -> np.ndarray:
    """The OTF of a uniform square of side ``side_px``: sinc(side·fx)·sinc(side·fy) (sinc(x) = sin(πx)/(πx))."""
    return np.sinc(side_px * np.asarray(fx)) * np.sinc(side_px * np.asarray(fy))


def check_optics_record(optics) -> dict:
    """The sidecar's ``optics`` record, checked for what the model reads; CamsimError (one line) if unusable.

    Returns the record with defaults filled in (``olpf_shift_px`` 1.0, ``fill_factor`` 1.0, no defocus).
    """
    if not isinstance(optics, dict):
        raise CamsimError(f"the sidecar's optics record must be a table, got {type(optics).__name__}")

    def number(key, default=None, low=0.0, strict=True):
        value = optics.get(key, default)
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) \
                or (value <= low if strict else value < low):
            raise CamsimError(f"the sidecar's optics {key} must be a finite number {'>' if strict else '>='} "
                              f"{low:g}, got {value!r}")
        return float(value)

    record = dict(optics)
    for key in ("f_number", "pixel_pitch_um"):
        record[key] = number(key)
    record["olpf_shift_px"] = number("olpf_shift_px", 1.0, strict=False)
    record["fill_factor"] = number("fill_factor", 1.0)
    if record["fill_factor"] > 1:
        raise CamsimError(f"the sidecar's optics fill_factor must be in (0, 1], got {record['fill_factor']:g}")
    waves = optics.get("defocus_waves", 0.0) or 0.0
    shift = optics.get("defocus_um", 0.0) or 0.0
    for key, value in (("defocus_waves", waves), ("defocus_um", shift)):
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise CamsimError(f"the sidecar's optics {key} must be a finite number, got {value!r}")
    if waves and shift:
        raise CamsimError("the sidecar's optics has both defocus_waves and defocus_um: at most one may be non-zero")
    record["w020_waves_550"] = float(waves) if waves else w020_from_focus_shift(float(shift), record["f_number"])
    for key in ("diffraction", "olpf"):
        if not isinstance(optics.get(key, False), bool):
            raise CamsimError(f"the sidecar's optics {key} must be true or false, got {optics.get(key)!r}")
    weights = optics.get("channel_wavelength_weights")
    if record.get("diffraction") or record["w020_waves_550"]:
        try:
            wl = np.asarray(weights["wavelength_nm"], dtype=np.float64)
            w = np.asarray(weights["weights"], dtype=np.float64)
        except (TypeError, KeyError, ValueError):
            raise CamsimError("the sidecar's optics record needs channel_wavelength_weights {wavelength_nm: [...], "
                              "weights: [[R...], [G...], [B...]]} for its diffraction or defocus") from None
        if wl.ndim != 1 or w.shape != (3, wl.size) or not (np.all(np.isfinite(wl)) and np.all(np.isfinite(w))) \
                or np.any(wl <= 0):
            raise CamsimError(f"the sidecar's optics channel_wavelength_weights must be {wl.size} positive "
                              f"wavelengths and 3 rows of as many finite weights, got weights of shape {w.shape}")
        record["_wavelength_um"], record["_weights"] = wl / 1000.0, w
    return record


def channel_mtf(f_cy_per_px, normal_xy, optics: dict | None, channel: int) -> np.ndarray:
    """The model MTF of one channel along the edge normal.

    Parameters
    ----------
    f_cy_per_px : array_like, shape (n,)
        Frequencies along the normal, cy/px (≥ 0).
    normal_xy : (float, float)
        The edge's unit normal (nx, ny) in pixel coordinates.
    optics : dict or None
        The sidecar's ``optics`` record (:func:`check_optics_record`); None: no optics (the full pixel's box
        alone, as ff = 1).
    channel : int
        0, 1, 2 for R, G, B (the row of ``channel_wavelength_weights``).

    Returns
    -------
    numpy.ndarray, shape (n,), float64
        |Σ_λ w_c(λ) OTF_pupil(f; λ) × OLPF × sinc(√ff f nx) sinc(√ff f ny)|.
    """
    f = np.abs(np.asarray(f_cy_per_px, dtype=np.float64))
    nx, ny = normal_xy
    fx, fy = f * nx, f * ny
    if optics is None:
        return np.abs(box_otf(fx, fy, 1.0))
    otf = np.ones_like(f)
    record = optics if "w020_waves_550" in optics else check_optics_record(optics)
    if record.get("diffraction") or record["w020_waves_550"]:
        pupil = np.zeros_like(f)
        for wl, w in zip(record["_wavelength_um"], record["_weights"][channel]):
            if w:
                if record.get("diffraction"):
                    pupil += w * defocus_otf(f, wl, record["f_number"], record["pixel_pitch_um"],
                                             record["w020_waves_550"])
                else:  # defocus without diffraction: the geometric blur disk alone
                    diameter = 8 * record["f_number"] * record["w020_waves_550"] * DEFOCUS_REFERENCE_UM \
                        / record["pixel_pitch_um"]
                    pupil += w * blur_disk_otf(f, diameter)
        otf = otf * pupil / max(float(np.sum(record["_weights"][channel])), np.finfo(float).tiny)
    if record.get("olpf"):
        otf = otf * olpf_otf(fx, fy, record["olpf_shift_px"])
    otf = otf * box_otf(fx, fy, math.sqrt(record["fill_factor"]))
    return np.abs(otf)
