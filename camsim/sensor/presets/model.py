"""A real camera's noise calibration with an ISO axis, and its conversion to the model's units.

Published calibrations (ELD, PMN, LED) give every noise figure in digital numbers (DN) of the camera's raw, per ISO
step or as log-linear fits against the system gain K (DN/e⁻). camsim's sensor model
(:class:`camsim.sensor.params.SensorParams`) holds charges in electrons, the conversion gain in V/e⁻ and the analog gain
in DN/V. :meth:`CameraPreset.sensor` converts, explicitly:

==============================  ===============================================================================
published (raw DN)              model
==============================  ===============================================================================
K (DN/e⁻)                       ``conversion_gain_v_per_e`` · ``analog_gain_dn_per_v`` = K, with the conversion
                                gain fixed per preset (:attr:`CameraPreset.conversion_gain_v_per_e`) and the
                                analog gain K / G_Ve⁻ (so ISO moves the analog gain, as in a camera)
Gaussian read σ (DN)            ``read_noise_e`` = σ_DN / K, ``read_noise_model = "gaussian"``
Tukey-λ scale s (DN), shape λ   ``read_noise_e`` = s · √Var(Tukey λ) / K (camsim's σ is the law's standard
                                deviation), ``read_noise_model = "tukey-lambda"``, ``tukey_lambda`` = λ
row σ (DN)                      ``row_noise_e`` = σ_row,DN / K
DSNU (DN)                       ``dsnu_e`` = DSNU_DN / K
black level, white level        ``pedestal_dn``, ``bits`` (white = 2^bits − 1)
==============================  ===============================================================================

Between published ISO points every figure is interpolated linearly in log ISO — K and the σ's as log-log lines
(K ∝ ISO and ELD's fits ln σ = a ln K + b are straight lines there), the Tukey shape λ linearly — within one
gain mode. A camera with a dual conversion gain (the Sony A7S2 between ISO 1600 and 2000) has two modes: an ISO
below the first point of the high-gain mode is in the low-gain mode, extended as a log-log line through its last
two points. Outside the published range an ISO is refused.
"""

from __future__ import annotations

import dataclasses
import math
import re
from dataclasses import dataclass

import numpy as np

from camsim.core.errors import CamsimError
from camsim.sensor.kernels import tukey_lambda_variance
from camsim.sensor.params import READ_NOISE_MODELS, SENSOR_PARAMS, SensorParams

#: The published noise quantities of an ISO point, in DN of the raw (ELD's and PMN's names).
NOISE_QUANTITIES = ("tukey_scale_dn", "gaussian_sigma_dn", "row_sigma_dn")


@dataclass(frozen=True)
class IsoPoint:
    """One calibrated ISO setting: the system gain and the read-noise figures, in DN of the raw.

    Attributes
    ----------
    iso : float
        The ISO setting.
    k_dn_per_e : float
        System gain K. Unit: DN/e⁻.
    tukey_lambda : float
        Shape λ of the Tukey-λ read noise.
    tukey_scale_dn : float
        Scale of the Tukey-λ read noise (scipy's ``tukeylambda(λ, scale=s)``). Unit: DN.
    gaussian_sigma_dn : float
        σ of the Gaussian read-noise alternative. Unit: DN.
    row_sigma_dn : float
        σ of the row noise (one offset per row and frame). Unit: DN.
    dsnu_dn : float
        Spatial σ of the per-pixel dark offset. Unit: DN.
    prnu_percent : float
        Spatial σ of the per-pixel gain. Unit: %.
    """

    iso: float
    k_dn_per_e: float
    tukey_lambda: float
    tukey_scale_dn: float
    gaussian_sigma_dn: float
    row_sigma_dn: float = 0.0
    dsnu_dn: float = 0.0
    prnu_percent: float = 0.0

    def __post_init__(self):
        for name in ("iso", "k_dn_per_e"):
            if not (math.isfinite(getattr(self, name)) and getattr(self, name) > 0):
                raise CamsimError(f"camera preset: {name} must be positive, got {getattr(self, name)!r}")
        for name in ("tukey_scale_dn", "gaussian_sigma_dn", "row_sigma_dn", "dsnu_dn", "prnu_percent"):
            if not (math.isfinite(getattr(self, name)) and getattr(self, name) >= 0):
                raise CamsimError(f"camera preset: {name} must be ≥ 0, got {getattr(self, name)!r}")
        if not -0.5 < self.tukey_lambda < 1:
            raise CamsimError(f"camera preset: tukey_lambda must lie in (−0.5, 1), got {self.tukey_lambda!r}")

    @property
    def tukey_sigma_dn(self) -> float:
        """Standard deviation of the Tukey-λ read noise, s · √Var(Tukey λ). Unit: DN."""
        return self.tukey_scale_dn * math.sqrt(tukey_lambda_variance(self.tukey_lambda))

    def read_sigma_dn(self, read_noise_model: str) -> float:
        """The read noise's standard deviation under ``read_noise_model``. Unit: DN."""
        return self.tukey_sigma_dn if read_noise_model == "tukey-lambda" else self.gaussian_sigma_dn


@dataclass(frozen=True)
class NoiseFit:
    """ELD's log-linear fit of one noise quantity against the system gain: ln σ = slope · ln K + bias, with a
    camera instance's extra N(0, residual_sigma) scatter of ln σ (for virtual cameras). σ in DN, K in DN/e⁻."""

    slope: float
    bias: float
    residual_sigma: float

    def at(self, k_dn_per_e) -> np.ndarray:
        """The fit's σ at K (no scatter). Unit: DN."""
        return np.exp(self.slope * np.log(k_dn_per_e) + self.bias)


#: The sensor effects of real low-light raws (issue 28) for which every built-in preset says what its source
#: publishes: key → the effect in words (:attr:`CameraPreset.published_effects`).
EFFECTS = {
    "temperature": "temperature",
    "dark_current": "dark current and DSNU",
    "defects": "hot, dead and stuck pixels",
    "black_level_error": "black-level error (colour bias)",
    "dark_shading": "dark shading and column FPN",
}
#: What a preset says of an effect its source gives no figure for.
NOT_PUBLISHED = "not published in camsim's sources"

#: The fields of a camera preset that are sensor parameters of the same name, checked by the sensor's schema.
_SENSOR_FIELDS = ("bits", "pedestal_dn", "full_well_e", "conversion_gain_v_per_e", "dark_current_e_per_s",
                  "dark_current_reference_c")
_SENSOR = {p.name: p for p in SENSOR_PARAMS}


@dataclass(frozen=True)
class CameraPreset:
    """A real camera: published noise figures per ISO, the raw's levels, and where the figures come from.

    Attributes
    ----------
    name : str
        The preset's name (``sony-a7s2``).
    title : str
        The camera, in words.
    source : str
        Where every figure comes from (cited in ``camsim list`` and the docs).
    iso_points : tuple of IsoPoint
        The published ISO points, lowest first.
    bits : int
        ADC resolution; the white level is 2^bits − 1.
    pedestal_dn : int
        The raw's black-level pedestal. Unit: DN.
    cfa : str or None
        Bayer pattern of the raw (None: a monochrome or three-chip sensor, modelled with R, G and B at every pixel).
    full_well_e : float
        Full-well capacity (None: the charge that fills the raw at :attr:`default_iso`, (white − black) / K, for
        sources that give no well). Unit: e⁻.
    conversion_gain_v_per_e : float
        G_Ve⁻: ISO changes the analog gain K / G_Ve⁻ only. Unit: V/e⁻.
    dark_current_e_per_s : float
        Mean dark current. Unit: e⁻/s.
    dark_current_reference_c : float or None
        The temperature at which the source measured ``dark_current_e_per_s`` (None: the source states none; the
        sensor's default ``dark_current_reference_c`` holds). Unit: °C.
    read_noise_model : str
        The read-noise law used unless the scene or the command line asks for the other.
    dual_gain_iso : float or None
        First ISO of the high conversion-gain mode (points at or above it form the second mode).
    fits : dict or None
        ELD/LED fits per quantity (:data:`NOISE_QUANTITIES`) with the K range ``k_range_dn_per_e``, for virtual
        cameras.
    k_range_dn_per_e : tuple or None
        (K_min, K_max) of the fits. Unit: DN/e⁻.
    tukey_shapes : tuple
        The published Tukey shapes (ELD: one per calibrated ISO step), drawn from by virtual cameras.
    notes : tuple of str
        What the preset assumes beyond its source (levels, the ISO of K_min, the curves).
    raw_models : tuple of (str, str)
        (Make, Model) as the camera writes them into its raw files, where they differ from :meth:`identity`'s
        (a ``[raw]`` scene's file is matched against both: :meth:`matches`).
    published_effects : dict
        What the source publishes for each sensor effect of real low-light raws, :data:`EFFECTS`' key → a
        statement in words (the figure and where it is, or :data:`NOT_PUBLISHED`); the figures it states are the
        preset's sensor parameters. Empty for a preset file (``camsim calibrate`` measures them).
    """

    name: str
    title: str
    source: str
    iso_points: tuple
    bits: int = 14
    pedestal_dn: int = 0
    cfa: str | None = "RGGB"
    full_well_e: float | None = None
    conversion_gain_v_per_e: float | None = None
    dark_current_e_per_s: float = 0.0
    dark_current_reference_c: float | None = None
    read_noise_model: str = "tukey-lambda"
    dual_gain_iso: float | None = None
    fits: dict | None = None
    k_range_dn_per_e: tuple | None = None
    tukey_shapes: tuple = ()
    notes: tuple = ()
    raw_models: tuple = ()
    published_effects: dict = dataclasses.field(default_factory=dict)

    def __post_init__(self):
        if not self.iso_points:
            raise CamsimError(f"camera preset {self.name!r} has no ISO point")
        isos = [p.iso for p in self.iso_points]
        if any(b <= a for a, b in zip(isos, isos[1:])):
            raise CamsimError(f"camera preset {self.name!r}: ISO points must increase, got {isos}")
        if self.read_noise_model not in READ_NOISE_MODELS:
            raise CamsimError(f"camera preset {self.name!r}: read_noise_model must be one of {READ_NOISE_MODELS}")
        for name in _SENSOR_FIELDS:  # the sensor's own ranges (the schema): a zero conversion gain, a 99-bit ADC …
            if getattr(self, name) is not None:
                _SENSOR[name].coerce(getattr(self, name), f"camera preset {self.name!r}")
        unknown = set(self.published_effects) - set(EFFECTS)
        if unknown:
            raise CamsimError(f"camera preset {self.name!r}: unknown effect(s) {', '.join(sorted(unknown))}; "
                              f"effects: {', '.join(EFFECTS)}")
        if self.dual_gain_iso is not None and not (math.isfinite(self.dual_gain_iso) and self.dual_gain_iso > 0):
            raise CamsimError(f"camera preset {self.name!r}: dual_gain_iso must be positive, "
                              f"got {self.dual_gain_iso!r}")
        if self.full_well_e is None:  # the charge that fills the raw at the default ISO: K · FW = white − black
            well = (2**self.bits - 1 - self.pedestal_dn) / self.point_at(self.default_iso).k_dn_per_e
            object.__setattr__(self, "full_well_e", float(well))
        if self.conversion_gain_v_per_e is None:  # nominal: 1 V at the full well (only K reaches the numbers)
            object.__setattr__(self, "conversion_gain_v_per_e", 1.0 / self.full_well_e)

    def identity(self) -> dict:
        """The camera's ``make``, ``model`` and ``unique_camera_model`` (ASCII), from its title
        (:func:`camera_identity_of_title`): what camsim's DNGs of this camera say."""
        return camera_identity_of_title(self.title)

    def matches(self, make: str | None, model: str | None, unique_camera_model: str | None = None) -> bool:
        """Whether a raw file's Make and Model (or its DNG UniqueCameraModel) name this camera: compared by
        :func:`camera_key` with :meth:`identity` and :attr:`raw_models`."""
        ident = self.identity()
        mine = {camera_key(ident["make"], ident["model"])} | {camera_key(*m) for m in self.raw_models}
        theirs = {camera_key(make, model)} if make and model else set()
        if unique_camera_model:
            first, _, rest = unique_camera_model.strip().partition(" ")
            theirs.add(camera_key(first, rest or first))
        return bool(mine & theirs)

    @property
    def iso_range(self) -> tuple:
        """(lowest, highest) ISO of the published points."""
        return self.iso_points[0].iso, self.iso_points[-1].iso

    @property
    def default_iso(self) -> float:
        """The ISO used when none is given: 100 where published, else the lowest point."""
        lo, hi = self.iso_range
        return 100.0 if lo <= 100 <= hi else lo

    def _modes(self) -> list:
        if self.dual_gain_iso is None:
            return [list(self.iso_points)]
        low = [p for p in self.iso_points if p.iso < self.dual_gain_iso]
        high = [p for p in self.iso_points if p.iso >= self.dual_gain_iso]
        return [m for m in (low, high) if m]

    def point_at(self, iso: float | None = None) -> IsoPoint:
        """The figures at ``iso`` (None: :attr:`default_iso`), interpolated as the module says.

        Raises
        ------
        CamsimError
            For an ISO outside the published range.
        """
        iso = self.default_iso if iso is None else iso
        if not (isinstance(iso, (int, float)) and math.isfinite(iso) and iso > 0):
            raise CamsimError(f"ISO must be a positive number, got {iso!r}")
        lo, hi = self.iso_range
        if not lo * (1 - 1e-12) <= iso <= hi * (1 + 1e-12):
            raise CamsimError(f"ISO {iso:g} is outside preset {self.name}'s range ISO {lo:g}–{hi:g}")
        modes = self._modes()
        mode = modes[-1] if iso >= modes[-1][0].iso else modes[0]  # below the high-gain mode: the low one
        for p in mode:
            if math.isclose(p.iso, iso, rel_tol=1e-12):
                return dataclasses.replace(p, iso=float(iso))
        if len(mode) == 1:
            return dataclasses.replace(mode[0], iso=float(iso))
        i = int(np.clip(np.searchsorted([p.iso for p in mode], iso) - 1, 0, len(mode) - 2))
        a, b = mode[i], mode[i + 1]  # the segment around iso (or the mode's last one, extended)
        t = (math.log(iso) - math.log(a.iso)) / (math.log(b.iso) - math.log(a.iso))

        def log_line(x, y):
            if x <= 0 or y <= 0:
                return max(0.0, x + t * (y - x))  # a zero figure: linear (a log line has no zero)
            return math.exp(math.log(x) + t * (math.log(y) - math.log(x)))

        figures = {f.name: log_line(getattr(a, f.name), getattr(b, f.name))
                   for f in dataclasses.fields(IsoPoint) if f.name not in ("iso", "tukey_lambda")}
        shape = a.tukey_lambda + t * (b.tukey_lambda - a.tukey_lambda)
        return IsoPoint(iso=float(iso), tukey_lambda=float(np.clip(shape, -0.49, 0.99)), **figures)

    def sensor(self, iso: float | None = None, read_noise_model: str | None = None,
               point: IsoPoint | None = None) -> SensorParams:
        """The model's sensor at ``iso`` (or at the figures ``point``), every DN figure converted to electrons.

        ``read_noise_model``: None takes the preset's; ``gaussian`` uses the Gaussian σ, ``tukey-lambda`` the
        Tukey law's shape and its standard deviation.
        """
        p = point if point is not None else self.point_at(iso)
        model = read_noise_model or self.read_noise_model
        if model not in READ_NOISE_MODELS:
            raise CamsimError(f"read_noise_model must be one of {READ_NOISE_MODELS}, got {model!r}")
        k = p.k_dn_per_e
        return SensorParams(
            cfa=self.cfa,
            bits=self.bits,
            pedestal_dn=self.pedestal_dn,
            full_well_e=self.full_well_e,
            conversion_gain_v_per_e=self.conversion_gain_v_per_e,
            analog_gain_dn_per_v=k / self.conversion_gain_v_per_e,
            dark_current_e_per_s=(self.dark_current_e_per_s,) * 3,
            **({} if self.dark_current_reference_c is None
               else {"dark_current_reference_c": self.dark_current_reference_c}),
            read_noise_e=p.read_sigma_dn(model) / k,
            read_noise_model=model,
            tukey_lambda=p.tukey_lambda,
            row_noise_e=p.row_sigma_dn / k,
            dsnu_e=p.dsnu_dn / k,
            prnu_percent=p.prnu_percent,
        )

    def describe(self) -> str:
        """One line for ``camsim list``: the camera, its ISO range and K there, and the source."""
        lo, hi = self.iso_range
        k_lo, k_hi = self.iso_points[0].k_dn_per_e, self.iso_points[-1].k_dn_per_e
        if hi > lo:
            axis = f"ISO {lo:.0f}–{hi:.0f}, K {k_lo:.4g}–{k_hi:.4g} DN/e⁻"
        else:
            axis = f"one setting (ISO {lo:g}), K {k_lo:.4g} DN/e⁻"
        return (f"{self.name}: {self.title}; {axis}, {self.bits}-bit, black {self.pedestal_dn} DN; "
                f"source: {self.source}")


    def describe_effects(self, compact: bool = False) -> list:
        """Per sensor effect (:data:`EFFECTS`), what the source publishes, a line each (the preset's notes end with
        them). ``compact`` (``camsim list``): the effects with a figure or a file, a line each, then one line naming
        those :data:`NOT_PUBLISHED` (the notes say more)."""
        if not compact:
            return [f"{EFFECTS[key]}: {text}" for key, text in self.published_effects.items()]
        effects = self.published_effects.items()
        lines = [f"{EFFECTS[key]}: {text}" for key, text in effects if not text.startswith(NOT_PUBLISHED)]
        missing = [EFFECTS[key] for key, text in effects if text.startswith(NOT_PUBLISHED)]
        return lines + ([f"{NOT_PUBLISHED}: {'; '.join(missing)}"] if missing else [])


def camera_identity_of_title(title: str) -> dict:
    """``make``, ``model`` and ``unique_camera_model`` (ASCII) of a camera preset's title.

    Make is the title's first word, Model the model code in its parentheses where it has one without spaces
    (``"Sony A7S2 (ILCE-7SM2)"`` → Sony, ILCE-7SM2), else the title up to a parenthesis or comma (``"Nikon D850"``),
    UniqueCameraModel Make and Model (``"Sony ILCE-7SM2"``; once where Model starts with Make).
    """
    title = " ".join(title.encode("ascii", "replace").decode("ascii").split())
    make = title.split(" ")[0]
    code = re.search(r"\(([^()\s,]+)\)", title)
    model = code.group(1) if code else re.split(r"[(,]", title)[0].strip()
    unique = model if model.lower().startswith(make.lower()) else f"{make} {model}"
    return {"make": make, "model": model, "unique_camera_model": unique}


def camera_key(make: str, model: str) -> str:
    """A camera's name for matching: the first word of Make and the Model without it, lower case, letters and
    digits only (``("NIKON CORPORATION", "NIKON D850")`` and ``("Nikon", "D850")`` → ``nikond850``)."""
    def squeeze(text: str) -> str:
        return re.sub(r"[^a-z0-9]", "", str(text).lower())

    brand = squeeze(str(make).split(" ")[0]) if str(make).split() else ""
    name = squeeze(model)
    return brand + (name[len(brand):] if brand and name.startswith(brand) else name)
