"""The image sensor: parameters, presets and one pure array function per physical stage (Eqs. 6–12).

Work stays in electrons until readout; the conversion to digital numbers happens once, in
:func:`electrons_to_dn`. Every stage can be switched off on its own, and a switched-off stage costs nothing.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from camsim.errors import CamsimError

STAGES = ("photon_noise", "dark_current", "saturation", "read_noise", "quantisation")
READ_NOISE_MODELS = ("gaussian", "tukey-lambda")
CFA_PATTERNS = ("RGGB", "BGGR", "GRBG", "GBRG")


def cfa_sites(pattern: str) -> list[tuple[int, int, int]]:
    """The 2 × 2 cell of a Bayer pattern as ``[(row offset, column offset, channel), ...]`` (channel 0 = R)."""
    return [(i // 2, i % 2, "RGB".index(colour)) for i, colour in enumerate(pattern)]


@dataclass(frozen=True)
class SensorParams:
    """Sensor model parameters (the paper's Table I by default), with each stage's on/off switch.

    Attributes
    ----------
    conversion_gain_v_per_e : float
        G_Ve⁻, charge-to-voltage conversion. Unit: V / e⁻.
    analog_gain_dn_per_v : float
        G, the gain in front of the ADC. Unit: DN / V.
    dark_current_e_per_s : tuple of 3 float
        (σ_dark^κ)², mean dark electrons per pixel per second for R, G, B. Unit: e⁻ / s.
    read_noise_e : float
        σ_read, standard deviation of the read noise. Unit: e⁻.
    full_well_e : float
        Full-well capacity. Unit: e⁻.
    exposure_s : float
        Exposure (integration) time T. Unit: s.
    bits : int
        ADC resolution nb; digital numbers lie in [0, 2^nb − 1].
    photon_noise, dark_current, saturation, read_noise, quantisation : bool
        Stage switches. ``photon_noise`` off gives the mean signal exactly; ``dark_current`` off removes the
        dark electrons (mean and noise); ``quantisation`` off keeps the float DN (no DNG can then be written).
    dsnu_e : float
        Dark signal non-uniformity: spatial standard deviation of a fixed per-pixel dark offset (Gaussian map,
        fixed for a ``sensor_seed``), added to the charge before saturation. 0 = off. Unit: e⁻.
    prnu_percent : float
        Photo-response non-uniformity: spatial standard deviation of a fixed per-pixel gain on the mean signal
        (Gaussian map around 1, fixed for a ``sensor_seed``), so that a pixel collects Poisson(g S̄). 0 = off.
        Unit: %.
    row_noise_e : float
        Temporal row noise: one Gaussian offset per row, channel and frame, added at readout. 0 = off. Unit: e⁻.
    read_noise_model : {'gaussian', 'tukey-lambda'}
        Law of the read noise (its standard deviation is ``read_noise_e`` either way); Tukey lambda with shape
        ``tukey_lambda`` < 0.14 has heavier tails than the Gaussian, as in the ELD low-light noise model.
    tukey_lambda : float
        Shape of the Tukey lambda read noise (0: logistic).
    sensor_seed : int
        Seed of the fixed-pattern maps: frames of the same sensor share them, while temporal noise changes.
    cfa : str or None
        None for a three-chip sensor (every pixel has R, G and B, like the paper's Sony DXC-930), or a Bayer
        colour filter array ``RGGB``, ``BGGR``, ``GRBG`` or ``GBRG`` (colours of the 2 × 2 cell, row by row):
        one channel per pixel.
    """

    conversion_gain_v_per_e: float = 0.0002
    analog_gain_dn_per_v: float = 141.67
    dark_current_e_per_s: tuple = (195.0, 230.0, 218.0)
    read_noise_e: float = 4.0
    full_well_e: float = 9000.0
    exposure_s: float = 1.0
    bits: int = 8
    photon_noise: bool = True
    dark_current: bool = True
    saturation: bool = True
    read_noise: bool = True
    quantisation: bool = True
    dsnu_e: float = 0.0
    prnu_percent: float = 0.0
    row_noise_e: float = 0.0
    read_noise_model: str = "gaussian"
    tukey_lambda: float = -0.1
    sensor_seed: int = 0
    cfa: str | None = None

    def __post_init__(self):
        dark = tuple(float(v) for v in np.broadcast_to(np.asarray(self.dark_current_e_per_s, float), (3,)))
        object.__setattr__(self, "dark_current_e_per_s", dark)
        positive = ("conversion_gain_v_per_e", "analog_gain_dn_per_v", "full_well_e", "exposure_s")
        for name in positive:
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and np.isfinite(value) and value > 0):
                raise CamsimError(f"sensor parameter {name} must be a positive number, got {value!r}")
        if not (np.isfinite(self.read_noise_e) and self.read_noise_e >= 0):
            raise CamsimError(f"sensor parameter read_noise_e must be ≥ 0, got {self.read_noise_e!r}")
        if not all(np.isfinite(v) and v >= 0 for v in dark):
            raise CamsimError(f"sensor parameter dark_current_e_per_s must be ≥ 0, got {dark!r}")
        if not (isinstance(self.bits, int) and 1 <= self.bits <= 16):
            raise CamsimError(f"sensor parameter bits must be an integer from 1 to 16, got {self.bits!r}")
        for name in ("dsnu_e", "prnu_percent", "row_noise_e"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and np.isfinite(value) and value >= 0):
                raise CamsimError(f"sensor parameter {name} must be a number ≥ 0, got {value!r}")
        if self.prnu_percent >= 30:
            raise CamsimError(f"prnu_percent {self.prnu_percent} is not a small non-uniformity (must be < 30 %)")
        if self.read_noise_model not in READ_NOISE_MODELS:
            raise CamsimError(f"read_noise_model must be one of {READ_NOISE_MODELS}, got {self.read_noise_model!r}")
        if not (isinstance(self.tukey_lambda, (int, float)) and -0.5 < self.tukey_lambda < 1):
            raise CamsimError(f"tukey_lambda must be in (−0.5, 1) (finite variance), got {self.tukey_lambda!r}")
        if self.cfa is not None and self.cfa not in CFA_PATTERNS:
            raise CamsimError(f"cfa must be one of {', '.join(CFA_PATTERNS)} (or none), got {self.cfa!r}")
        if not (isinstance(self.sensor_seed, int) and self.sensor_seed >= 0):
            raise CamsimError(f"sensor_seed must be a non-negative integer, got {self.sensor_seed!r}")
        for name in STAGES:
            if not isinstance(getattr(self, name), bool):
                raise CamsimError(f"sensor switch {name} must be true or false, got {getattr(self, name)!r}")

    @property
    def fixed_pattern(self) -> bool:
        """Whether a fixed-pattern map (DSNU or PRNU) is on."""
        return self.dsnu_e > 0 or self.prnu_percent > 0

    @property
    def gaussian_read_noise(self) -> bool:
        """Whether the read noise (if on) is Gaussian."""
        return self.read_noise_model == "gaussian"

    @property
    def dn_per_electron(self) -> float:
        """Overall gain G · G_Ve⁻ from electrons to digital numbers. Unit: DN / e⁻."""
        return self.analog_gain_dn_per_v * self.conversion_gain_v_per_e

    @property
    def max_dn(self) -> int:
        """Largest digital number, 2^nb − 1. Unit: DN."""
        return 2**self.bits - 1

    @property
    def dark_mean_e(self) -> np.ndarray:
        """Mean dark electrons per pixel in the exposure, per channel, shape (3,). Unit: e⁻."""
        if not self.dark_current:
            return np.zeros(3)
        return np.asarray(self.dark_current_e_per_s) * self.exposure_s

    @property
    def black_level_dn(self) -> np.ndarray:
        """Mean dark level in DN (before quantisation), per channel, shape (3,). Unit: DN."""
        return self.dark_mean_e * self.dn_per_electron

    def with_stages(self, **switches) -> SensorParams:
        """A copy with some stage switches changed (``with_stages(dark_current=False)``)."""
        unknown = set(switches) - set(STAGES)
        if unknown:
            raise CamsimError(f"unknown sensor stage(s) {sorted(unknown)}; stages: {', '.join(STAGES)}")
        return dataclasses.replace(self, **switches)

    def to_dict(self) -> dict:
        """Parameters with units in their names, JSON-ready."""
        out = dataclasses.asdict(self)
        out["dark_current_e_per_s"] = list(self.dark_current_e_per_s)
        out["dn_per_electron"] = self.dn_per_electron
        return out


#: Named presets. ``paper-table1``: Table I with every stage on (scenario III). ``paper-photon-dark``: photon and
#: dark noise only (scenario II). ``ideal``: photon noise only, output in electrons (scenario I).
PRESETS = {
    "paper-table1": SensorParams(),
    "paper-photon-dark": SensorParams(saturation=False, read_noise=False, quantisation=False),
    "ideal": SensorParams(
        conversion_gain_v_per_e=1.0,
        analog_gain_dn_per_v=1.0,
        dark_current=False,
        saturation=False,
        read_noise=False,
        quantisation=False,
    ),
    # A 12-bit machine-vision-like sensor for `camsim emva`: K = 40 µV/e⁻ · 10 000 DN/V = 0.4 DN/e⁻, so the
    # 10 000 e⁻ full well reads 4000 DN, below the ADC's 4095; 3 e⁻ read noise (1.2 DN ≫ the 0.29 DN of the
    # quantiser); 25 e⁻/s of dark current over the 1 s exposure lifts the dark level to 10 DN, clear of the ADC's
    # zero (camsim has no black-level pedestal); DSNU 2 e⁻ and PRNU 1 % on.
    "emva-12bit": SensorParams(
        conversion_gain_v_per_e=4e-5,
        analog_gain_dn_per_v=1e4,
        dark_current_e_per_s=(25.0, 25.0, 25.0),
        read_noise_e=3.0,
        full_well_e=10000.0,
        bits=12,
        dsnu_e=2.0,
        prnu_percent=1.0,
    ),
}


def preset(name: str, **overrides) -> SensorParams:
    """A named preset, optionally with fields overridden."""
    if name not in PRESETS:
        raise CamsimError(f"unknown sensor preset {name!r}; presets: {', '.join(PRESETS)}")
    fields = {f.name for f in dataclasses.fields(SensorParams)}
    unknown = set(overrides) - fields
    if unknown:
        raise CamsimError(f"unknown sensor parameter(s) {sorted(unknown)}; known: {', '.join(sorted(fields))}")
    try:
        return dataclasses.replace(PRESETS[name], **overrides)
    except TypeError as exc:
        raise CamsimError(f"bad sensor parameter: {exc}") from None


# --- stages: pure array functions -----------------------------------------------------------------------------


def saturate_e(electrons: np.ndarray, full_well_e: float, out: np.ndarray | None = None) -> np.ndarray:
    """f_sat: clip the collected charge at the full well (Eq. 8).

    Unit: e⁻ in, e⁻ out.
    """
    return np.minimum(electrons, electrons.dtype.type(full_well_e), out=out)


def add_read_noise_e(electrons: np.ndarray, read_noise_e: float, rng: np.random.Generator, scratch=None, work=None,
                     model: str = "gaussian", shape: float = -0.1):
    """Add white read noise of standard deviation σ_read in place (Eqs. 7 and 10, referred to the charge domain).

    The paper adds N(0, σ_read · G_Ve⁻) to the voltage; dividing by G_Ve⁻ gives this. Unit: e⁻.
    float32 arrays draw with :func:`camsim.sampling.standard_normal_f32` (Box–Muller), float64 with numpy.

    Parameters
    ----------
    electrons : numpy.ndarray, float32 or float64
        Modified in place.
    scratch : numpy.ndarray, optional
        C-contiguous buffer of the same shape and dtype for the normal draws.
    work : numpy.ndarray, optional
        float32 buffer of at least half that size (Box–Muller's scratch).
    model, shape : str, float
        ``gaussian``, or ``tukey-lambda`` with its shape λ (the same standard deviation, heavier tails).
    """
    from camsim.fixed_pattern import tukey_lambda
    from camsim.sampling import standard_normal_f32

    z = scratch if scratch is not None else np.empty_like(electrons)
    if model == "tukey-lambda":
        tukey_lambda(rng, z, shape, read_noise_e)
    elif z.dtype == np.float32:
        standard_normal_f32(rng, z, work if work is not None else np.empty(z.size // 2, np.float32), read_noise_e)
    else:
        rng.standard_normal(out=z)
        z *= read_noise_e
    electrons += z
    return electrons


def add_row_noise_e(electrons: np.ndarray, row_noise_e: float, rng: np.random.Generator) -> np.ndarray:
    """Add one Gaussian offset N(0, σ_row) per row (temporal row noise), in place. Unit: e⁻."""
    electrons += rng.standard_normal((electrons.shape[0], 1), dtype=electrons.dtype) * electrons.dtype.type(row_noise_e)
    return electrons


def electrons_to_dn(electrons: np.ndarray, dn_per_electron: float, out: np.ndarray | None = None) -> np.ndarray:
    """Readout and gain: I = G · G_Ve⁻ · e (Eqs. 8, 11 before quantisation). Unit: e⁻ in, DN out."""
    return np.multiply(electrons, electrons.dtype.type(dn_per_electron), out=out)


def quantise_dn(dn: np.ndarray, bits: int, out: np.ndarray | None = None) -> np.ndarray:
    """nb-bit quantisation: the integer part of the DN, clipped to [0, 2^nb − 1] (Eq. 11).

    Parameters
    ----------
    dn : numpy.ndarray, float
        Unquantised digital numbers. Unit: DN.
    out : numpy.ndarray, optional
        Integer output array (uint8 for nb ≤ 8, uint16 otherwise).

    Returns
    -------
    numpy.ndarray
        Quantised digital numbers. Unit: DN.
    """
    # clip straight into the integer output: for values in [0, 2^nb − 1] the cast's truncation is the floor
    if out is None:
        out = np.empty(np.shape(dn), dtype=dn_dtype(bits))
    np.clip(dn, 0, 2**bits - 1, out=out, casting="unsafe")
    return out


def dn_dtype(bits: int):
    """The smallest unsigned integer type holding ``bits``-bit digital numbers."""
    return np.uint8 if bits <= 8 else np.uint16
