"""The image sensor's parameters (the paper's Table I and beyond) and named presets.

The stages themselves are pure array functions in :mod:`camsim.sensor.stages`. Every stage can be switched off on its
own, and a switched-off stage costs nothing.
"""

from __future__ import annotations

import copy
import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from camsim.core.errors import CamsimError
from camsim.core.schema import param, params_of, record, validate
from camsim.sensor.cfa import CFA_PATTERNS

READ_NOISE_MODELS = ("gaussian", "tukey-lambda")
#: The least dark current of the ordinary pixels where hot pixels are on
#: (:attr:`SensorParams.dark_current_base_e_per_s`): a channel whose ``dark_current_e_per_s`` is 0 takes this (one
#: electron per 10¹² pixel-seconds: one in 40 000 frames of 24 MP at 1 s), so that the hot pixels' factor on it has
#: something to scale (a float32 factor holds h / 10⁻¹² for any h up to 10²⁶ e⁻/s). Unit: e⁻/s.
HOT_PIXEL_BASE_E_PER_S = 1e-12

# The physics' bounds of the schema: what no sensor reaches, far enough beyond every real one that no camera is
# refused, and near enough that nothing derived from an accepted value (a square, a sum of squares, a Poisson mean,
# an exposure's charge) leaves float64's range.
#: The most charge any figure in electrons may be (a full well, a noise or fixed-pattern σ): 10⁸ e⁻, a thousand
#: times the largest full well of the sensors in ``../shared/data/cameras`` (70 000 e⁻) and a hundred times a
#: large-pixel scientific CCD's (~10⁶ e⁻). Unit: e⁻.
CHARGE_MAX_E = 1e8
#: The largest dark current (of a pixel, hot or not): 10¹⁰ e⁻/s fills the largest full well in 10 ms. Unit: e⁻/s.
DARK_CURRENT_MAX_E_PER_S = 1e10
#: The longest exposure: 10⁶ s (11.6 days). Unit: s.
EXPOSURE_MAX_S = 1e6
#: The widest σ of a per-frame black-level error: a 16-bit ADC's range. Unit: DN.
BLACK_LEVEL_ERROR_MAX_DN = 65535.0
#: The overall gain's range: 10⁻⁶ to 10⁶ DN/e⁻ (real cameras: 0.01 – 20 DN/e⁻; ``ideal`` counts electrons, 1).
DN_PER_ELECTRON_RANGE = (1e-6, 1e6)
#: The hottest sensor: silicon melts at 1414 °C. Unit: °C.
TEMPERATURE_MAX_C = 1414.0
#: The most dark charge a pixel may collect in an exposure: 2⁵³ e⁻, beyond which float64 no longer counts single
#: electrons (the Poisson draws' means are float64). Unit: e⁻.
DARK_CHARGE_MAX_E = 2.0**53


def _layout_record(sensor) -> dict:
    return {"sensor_layout": "three-chip" if sensor.cfa is None else "bayer", "cfa_pattern": sensor.cfa}


def _adc_record(sensor) -> dict:
    record = {"bits": sensor.bits, "white_level_dn": sensor.max_dn, "dn_per_electron": sensor.dn_per_electron,
              "black_level_dn": sensor.black_level_dn.tolist(), "dark_level_dn": sensor.dark_level_dn.tolist()}
    tag = sensor.black_level_tag_dn
    if sensor.quantisation and np.any(tag != sensor.black_level_dn):  # only where the DNG says something else
        record["black_level_tag_dn"] = tag.tolist()
    return record


def _tukey_record(sensor) -> dict:
    return {"tukey_lambda": sensor.tukey_lambda if sensor.read_noise_model == "tukey-lambda" else None}


@dataclass(frozen=True)
class SensorParams:
    """Sensor model parameters (the paper's Table I by default), with each stage's on/off switch.

    Every field is declared with :func:`camsim.core.schema.param` (type, unit, range, help): that declaration is the
    only one, and the scene-file reader, the dataset spec, the command line (``--sensor NAME=VALUE``), the
    sidecar and the analysis's grouping keys all derive from it. Values are checked (and ints made floats where
    a float is meant) on construction; a bad one is a :class:`CamsimError`.
    """

    cfa: str | None = param(
        None, "str", "Bayer colour filter array (colours of the 2 × 2 cell, row by row; one channel per pixel), or "
        "none: a three-chip sensor with R, G and B at every pixel, like the paper's Sony DXC-930",
        choices=CFA_PATTERNS, optional=True, sidecar=_layout_record)
    bits: int = param(8, "int", "ADC resolution nb: digital numbers lie in [0, 2^nb − 1]", "bits", low=1, below=17,
                      sidecar=_adc_record)
    full_well_e: float = param(9000.0, "float", "full-well capacity", "e⁻", above=0, high=CHARGE_MAX_E)
    read_noise_e: float = param(4.0, "float", "σ_read, standard deviation of the read noise", "e⁻", low=0,
                                high=CHARGE_MAX_E)
    exposure_s: float = param(1.0, "float", "exposure (integration) time T", "s", above=0, high=EXPOSURE_MAX_S)
    conversion_gain_v_per_e: float = param(0.0002, "float", "G_Ve⁻, charge-to-voltage conversion", "V/e⁻",
                                           above=0)
    analog_gain_dn_per_v: float = param(141.67, "float", "G, the gain in front of the ADC", "DN/V", above=0)
    dark_current_e_per_s: tuple = param(
        (195.0, 230.0, 218.0), "rgb", "(σ_dark^κ)², mean dark electrons per pixel per second for R, G, B "
        "(one number or three)", "e⁻/s", low=0, high=DARK_CURRENT_MAX_E_PER_S)
    photon_noise: bool = param(True, "bool", "photon (shot) noise; off gives the mean signal exactly", stage=True)
    dark_current: bool = param(True, "bool", "dark current; off removes the dark electrons (mean and noise)",
                               stage=True)
    saturation: bool = param(True, "bool", "clipping at the full well", stage=True)
    read_noise: bool = param(True, "bool", "read noise", stage=True)
    quantisation: bool = param(True, "bool", "the nb-bit ADC; off keeps the float DN (no DNG is then written)",
                               stage=True)
    dsnu_e: float = param(0.0, "float", "dark signal non-uniformity: spatial σ of a fixed per-pixel dark offset "
                          "(Gaussian map fixed for a sensor_seed) added to the charge before saturation; 0 = off",
                          "e⁻", low=0, high=CHARGE_MAX_E)
    dsnu_dark_current_percent: float = param(
        0.0, "float", "dark-current DSNU: spatial σ of a fixed per-pixel factor d on the dark-current rate "
        "(log-normal map of mean 1 fixed for a sensor_seed), so that a pixel collects Poisson(σ²_dark · T · d) dark "
        "electrons: its spatial σ grows ∝ T, while dsnu_e's does not; 0 = off (and not written to records)", "%",
        low=0, below=100, omit_default=True)
    prnu_percent: float = param(0.0, "float", "photo-response non-uniformity: spatial σ of a fixed per-pixel gain on "
                                "the mean signal, so that a pixel collects Poisson(g S̄); 0 = off", "%", low=0,
                                below=30)
    pedestal_dn: int = param(0, "int", "black-level pedestal: a constant the ADC adds to every digital number before "
                             "its clip to [0, 2^nb − 1], as raw cameras do (Sony 14-bit: 512); the DNG carries it, "
                             "the EXR's values (before the ADC) do not; 0 = off (and not written to records)", "DN",
                             low=0, omit_default=True)
    row_noise_e: float = param(0.0, "float", "temporal row noise: one Gaussian offset per row, channel and frame, "
                               "added at readout; 0 = off", "e⁻", low=0, high=CHARGE_MAX_E)
    read_noise_model: str = param("gaussian", "str", "law of the read noise (its σ is read_noise_e either way); "
                                  "Tukey lambda has heavier tails, as in the ELD low-light noise model",
                                  choices=READ_NOISE_MODELS)
    tukey_lambda: float = param(-0.1, "float", "shape of the Tukey lambda read noise (0: logistic; < 0.14: heavier "
                                "tails than the Gaussian)", above=-0.5, below=1, sidecar=_tukey_record)
    sensor_seed: int = param(0, "int", "seed of the fixed-pattern maps: frames of one sensor share them, while "
                             "their temporal noise changes", low=0)
    # issue 28: the effects a denoiser meets in real low-light raws; each off by default (and then not recorded)
    temperature_c: float | None = param(
        None, "float", "the sensor's temperature: the dark current (and its DSNU, hot pixels included) is "
        "dark_current_e_per_s · 2^((T − dark_current_reference_c) / dark_current_doubling_c); none: as given",
        "°C", low=-273.15, optional=True, omit_default=True, high=TEMPERATURE_MAX_C)
    dark_current_reference_c: float = param(
        25.0, "float", "the temperature at which dark_current_e_per_s (and hot_pixel_dark_e_per_s) holds", "°C",
        low=-273.15, omit_default=True, high=TEMPERATURE_MAX_C)
    dark_current_doubling_c: float = param(
        6.0, "float", "doubling temperature T_d of the dark current (EMVA 1288 Release 4.0's law "
        "D(T) = D_ref · 2^((T − T_ref)/T_d); about 6 °C for silicon near room temperature)", "°C", above=0,
        omit_default=True)
    hot_pixel_fraction: float = param(
        0.0, "float", "share of pixels (of each chip on a three-chip sensor) with an extra dark current, "
        "exponential of mean hot_pixel_dark_e_per_s (EMVA 1288's exponential tail of the dark-signal histogram), a "
        "fixed population from sensor_seed; 0 = off", "", low=0, below=1, omit_default=True)
    hot_pixel_dark_e_per_s: float = param(
        2000.0, "float", "mean extra dark current of a hot pixel at dark_current_reference_c (exponential law; "
        "the default, ten times Table I's dark current, is a choice, not a measurement)",
        "e⁻/s", above=0, omit_default=True, high=DARK_CURRENT_MAX_E_PER_S)
    dead_pixel_fraction: float = param(
        0.0, "float", "share of pixels that collect nothing (no signal, no dark charge: PRNU gain and dark factor "
        "0) yet are read out (offset, read and row noise, black level): they read black; a fixed population from "
        "sensor_seed; 0 = off", "", low=0, below=1, omit_default=True)
    stuck_pixel_fraction: float = param(
        0.0, "float", "share of pixels stuck at a fixed level, uniform on [0, 2^nb − 1] DN (an integer), the same "
        "in every frame and without noise, written over the frame's values (float layer and ADC output); a "
        "fixed population from sensor_seed; 0 = off", "", low=0, below=1, omit_default=True)
    black_level_error_dn: float = param(
        0.0, "float", "σ of a per-frame, per-channel offset N(0, σ²) added to the DN before the ADC (ELD's colour "
        "bias), drawn from the frame's seed on a stream of its own; 0 = off", "DN", low=0, omit_default=True,
        high=BLACK_LEVEL_ERROR_MAX_DN)
    dark_shading_e: float = param(
        0.0, "float", "RMS of a fixed pattern of the dark level (a row profile, a column profile and a smooth 2-D "
        "shading, from sensor_seed) added to each pixel's charge like the offset DSNU; 0 = off", "e⁻", low=0,
        omit_default=True, high=CHARGE_MAX_E)
    dark_shading_map: str | None = param(
        None, "str", "a .npy file of the dark-shading pattern per pixel (e⁻; (H, W), or (3, H, W) for a three-chip "
        "sensor), e.g. from camsim calibrate; added to dark_shading_e's pattern; none = off", "e⁻", optional=True,
        omit_default=True)
    column_fpn_e: float = param(
        0.0, "float", "σ of a fixed per-column offset (column fixed-pattern noise, from sensor_seed) added to the "
        "charge like the offset DSNU; 0 = off", "e⁻", low=0, omit_default=True, high=CHARGE_MAX_E)
    hot_pixel_map: str | None = param(
        None, "str", "a .npy file of the extra dark current per pixel at dark_current_reference_c (e⁻/s; 0 where "
        "not hot; (H, W), or (3, H, W) for a three-chip sensor), e.g. from camsim calibrate; added to "
        "hot_pixel_fraction's; none = off", "e⁻/s", optional=True, omit_default=True)

    def __post_init__(self):
        validate(self, "sensor parameter")
        self._check_across()
        dark = tuple(float(v) for v in np.broadcast_to(np.asarray(self.dark_current_e_per_s, float), (3,)))
        object.__setattr__(self, "dark_current_e_per_s", dark)

    def _check_across(self) -> None:
        """The checks that involve more than one field (each field is checked by its schema entry)."""
        low, high = DN_PER_ELECTRON_RANGE
        if not low <= self.dn_per_electron <= high:  # each gain is in range, their product may not be
            raise CamsimError(f"sensor parameters analog_gain_dn_per_v = {self.analog_gain_dn_per_v:g} and "
                              f"conversion_gain_v_per_e = {self.conversion_gain_v_per_e:g} give a gain of "
                              f"{self.dn_per_electron:g} DN/e⁻, outside [{low:g}, {high:g}] DN/e⁻")
        if self.temperature_c is not None and (
                self.temperature_c - self.dark_current_reference_c) / self.dark_current_doubling_c > 1000:
            raise CamsimError(f"sensor parameter temperature_c = {self.temperature_c:g} °C is more than 1000 doublings "
                              f"(dark_current_doubling_c = {self.dark_current_doubling_c:g} °C) above "
                              f"dark_current_reference_c = {self.dark_current_reference_c:g} °C: the dark current "
                              f"would overflow")
        dark = float(np.max(self.dark_mean_e))
        if self.hot_pixels:  # a hot pixel's mean (the law's) counts too
            dark += self.hot_pixel_dark_e_per_s * self.temperature_factor * self.exposure_s
        if not dark <= DARK_CHARGE_MAX_E:
            raise CamsimError(f"sensor parameters dark_current_e_per_s, hot_pixel_dark_e_per_s, temperature_c and "
                              f"exposure_s give a dark charge of {dark:.3g} e⁻ in an exposure, over "
                              f"{DARK_CHARGE_MAX_E:.3g} e⁻ (2⁵³, beyond which float64 no longer counts electrons)")
        defects = self.hot_pixel_fraction + self.dead_pixel_fraction + self.stuck_pixel_fraction
        if defects > 1:
            raise CamsimError(f"sensor parameters hot_pixel_fraction + dead_pixel_fraction + stuck_pixel_fraction "
                              f"must be at most 1 (disjoint populations), got {defects:g}")
        if self.pedestal_dn >= 2**self.bits - 1:
            raise CamsimError(f"sensor parameter pedestal_dn must be below the white level {2**self.bits - 1} DN "
                              f"of a {self.bits}-bit ADC, got {self.pedestal_dn}")

    @property
    def fixed_pattern(self) -> bool:
        """Whether a fixed-pattern map (DSNU offset, dark-current DSNU, PRNU, dark shading, column FPN, hot, dead
        or stuck pixels) is on."""
        return (self.dsnu_e > 0 or self.prnu_percent > 0 or self.dsnu_dark_current_percent > 0
                or self.dark_offsets or self.hot_pixels or self.dead_pixel_fraction > 0
                or self.stuck_pixel_fraction > 0)

    @property
    def dark_offsets(self) -> bool:
        """Whether a fixed dark-level pattern beyond the offset DSNU (dark shading, column FPN) is on."""
        return self.dark_shading_e > 0 or self.column_fpn_e > 0 or self.dark_shading_map is not None

    @property
    def hot_pixels(self) -> bool:
        """Whether hot pixels (drawn or from a map file) are on."""
        return self.hot_pixel_fraction > 0 or self.hot_pixel_map is not None

    @property
    def temperature_factor(self) -> float:
        """2^((T − T_ref) / T_d): the dark current's factor at :attr:`temperature_c` (1 where it is none).
        Unitless."""
        if self.temperature_c is None:
            return 1.0
        return 2.0 ** ((self.temperature_c - self.dark_current_reference_c) / self.dark_current_doubling_c)

    @property
    def dark_current_base_e_per_s(self) -> np.ndarray:
        """The ordinary pixels' dark current at the reference temperature, per channel, shape (3,):
        ``dark_current_e_per_s``, but with hot pixels on, at least :data:`HOT_PIXEL_BASE_E_PER_S` (a hot pixel's
        extra dark current is a factor on this rate, :mod:`camsim.sensor.fixed_pattern`, so it must not be 0: a
        camera preset that publishes no dark current still takes hot pixels). Unit: e⁻/s."""
        rate = np.asarray(self.dark_current_e_per_s)
        return np.maximum(rate, HOT_PIXEL_BASE_E_PER_S) if self.hot_pixels else rate

    @property
    def dark_current_effective_e_per_s(self) -> np.ndarray:
        """The dark current at the sensor's temperature, per channel, shape (3,): :attr:`dark_current_base_e_per_s`
        · :attr:`temperature_factor` (EMVA 1288's D(T) = D_ref · 2^((T − T_ref)/T_d)). Unit: e⁻/s."""
        return self.dark_current_base_e_per_s * self.temperature_factor

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
        """Mean dark electrons per pixel in the exposure, per channel, shape (3,): σ²_dark · T at the sensor's
        temperature (:attr:`dark_current_effective_e_per_s`), the one place the temperature acts: every user of the
        dark mean (the draws, the clean layer, the black level, the DNG's NoiseProfile) follows. Unit: e⁻."""
        if not self.dark_current:
            return np.zeros(3)
        if self.temperature_c is None and not self.hot_pixels:  # (today's numbers, bit for bit)
            return np.asarray(self.dark_current_e_per_s) * self.exposure_s
        return self.dark_current_effective_e_per_s * self.exposure_s

    def _unlit_mean_dn(self, quantisation: bool) -> np.ndarray:
        from camsim.sensor.black_level import (
            unlit_mean_dn,  # imports scipy: here, so that the command line starts without
        )

        return unlit_mean_dn(
            self.dark_mean_e, dn_per_electron=self.dn_per_electron, bits=self.bits, quantisation=quantisation,
            full_well_e=self.full_well_e if self.saturation else None, dsnu_e=self.offset_sigma_e,
            dark_rate_rel_sigma=self.dsnu_dark_current_percent / 100 if self.dark_current else 0.0,
            read_noise_e=self.read_noise_e if self.read_noise else 0.0,
            read_noise_model=self.read_noise_model, tukey_lambda=self.tukey_lambda, row_noise_e=self.row_noise_e,
            pedestal_dn=self.pedestal_dn if quantisation else 0)

    @property
    def offset_sigma_e(self) -> float:
        """The σ of a pixel's fixed offset for the black level: the offset DSNU's, with issue 28's column FPN (a
        normal too: exact) and dark shading (its population law taken as a normal of its RMS: an approximation, which
        moves the mean only through the ADC's floor and clip) in quadrature. Unit: e⁻."""
        if not (self.column_fpn_e > 0 or self.dark_shading_e > 0):
            return self.dsnu_e
        return math.hypot(self.dsnu_e, self.column_fpn_e, self.dark_shading_e)

    @property
    def black_level_dn(self) -> np.ndarray:
        """The true black level: the exact mean digital number of an unlit pixel, per channel, shape (3,). Unit: DN.

        E[clip(floor(k (min(D + o, FW) + read + row)), 0, 2^nb − 1)] over the dark charge, the noise and the
        fixed-pattern maps' law (:func:`camsim.sensor.black_level.unlit_mean_dn`): what a dark frame's mean converges
        to, and so what a raw reader must subtract. Eq. 11's floor puts it about ½ DN below :attr:`dark_level_dn`
        (Table I: 5.025, 6.018, 5.683 DN against 5.525, 6.517, 6.177). Without quantisation it is :attr:`dark_level_dn`.

        Issue 28's effects: the temperature is in (through :attr:`dark_mean_e`); the column FPN and dark shading as
        offsets of σ :attr:`offset_sigma_e` (the shading's law as a normal); left out: a ``dark_shading_map``, hot,
        dead and stuck pixels (this is the level of the ordinary pixels, not the mean over a frame that has them)
        and the black-level error (a per-frame draw of mean 0: the level about which it scatters).
        """
        return self._unlit_mean_dn(self.quantisation)

    @property
    def dark_level_dn(self) -> np.ndarray:
        """The mean dark level before the ADC, per channel, shape (3,). Unit: DN.

        k · E[min(D + o, FW)]: k · σ²_dark · T wherever the dark charge stays below the full well (every ordinary
        sensor). The mean of an unlit pixel's values before quantisation (the EXR's).
        """
        return self._unlit_mean_dn(False)

    @property
    def black_level_tag_dn(self) -> np.ndarray:
        """The black level a DNG's BlackLevel tag holds, per channel, shape (3,). Unit: DN.

        :attr:`black_level_dn`, at most the white level − 1 (:attr:`max_dn` − 1): a dark current that alone reaches
        the top of the ADC (or fills a well that maps there) would otherwise put it at or above the WhiteLevel,
        which readers cannot use (LibRaw also rounds 254.5 up to 255). Such a frame is saturated everywhere; its
        sidecar then records this value as ``black_level_tag_dn`` beside the model's ``black_level_dn``.
        """
        return np.minimum(self.black_level_dn, self.max_dn - 1)

    def with_stages(self, **switches) -> SensorParams:
        """A copy with some stage switches changed (``with_stages(dark_current=False)``)."""
        unknown = set(switches) - set(STAGES)
        if unknown:
            raise CamsimError(f"unknown sensor stage(s) {sorted(unknown)}; stages: {', '.join(STAGES)}")
        return dataclasses.replace(self, **switches)

    def to_dict(self) -> dict:
        """Parameters with units in their names, JSON-ready (those declared ``omit_default`` only when set)."""
        out = dataclasses.asdict(self)
        for p in SENSOR_PARAMS:  # parameters recorded only when set (camsim.core.schema.Param.omit_default)
            if p.omit_default and out[p.name] == p.default:
                del out[p.name]
        out["dark_current_e_per_s"] = list(self.dark_current_e_per_s)
        out["dn_per_electron"] = self.dn_per_electron
        return out

    def sidecar_record(self) -> dict:
        """The sidecar's sensor keys (:func:`camsim.core.schema.record`): parameters, derived levels and ``stages``."""
        return record(self)


#: Sidecar keys of the sensor that change with the exposure time T alone: frames of one auto-exposed series
#: (``exposure = "auto"``) differ in them and are still one measurement.
EXPOSURE_KEYS = ("exposure_s", "black_level_dn", "dark_level_dn", "black_level_tag_dn")

#: Parameters that name a map file (.npy): a scene or preset file's are relative to that file.
MAP_FILE_PARAMS = ("dark_shading_map", "hot_pixel_map")

#: The sensor's parameters (:class:`camsim.core.schema.Param`), in declaration order.
SENSOR_PARAMS = params_of(SensorParams)
#: Names of the stage switches.
STAGES = tuple(p.name for p in SENSOR_PARAMS if p.stage)


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


#: The figures a batch of frames drawn together may not mix (:class:`SensorBatch`): its Bayer pattern (the planes'
#: layout) and the switches and read-noise law that pick which stages and draws run.
BATCH_SHARED = ("cfa", "saturation", "photon_noise", "read_noise", "read_noise_model", "quantisation")
#: The figures a :class:`SensorBatch` holds per frame, as arrays.
BATCH_PER_FRAME = ("full_well_e", "read_noise_e", "tukey_lambda", "dn_per_electron", "row_noise_e", "bits",
                   "pedestal_dn", "black_level_error_dn")


@dataclass(frozen=True)
class SensorBatch:
    """The sensors of B frames drawn together in one chain of array calls (:mod:`camsim.pairs`): what the stages of
    :mod:`camsim.sensor.stages` read of a :class:`SensorParams`, with the figures that differ per frame as host
    numpy arrays of shape (B, 1, 1, 1), broadcasting against the frames' (B, planes, H, W) values.

    The stages take such arrays where they take a number (:func:`camsim.core.xp.on_device` copies each to the
    values' device where it enters the arithmetic); the figures of :data:`BATCH_SHARED` are one for the batch —
    frames that differ there are drawn as separate batches (:meth:`key` groups them).

    Attributes
    ----------
    cfa, saturation, photon_noise, read_noise, read_noise_model, quantisation
        As :class:`SensorParams`'s, shared by the frames.
    full_well_e, read_noise_e, tukey_lambda, dn_per_electron, row_noise_e, black_level_error_dn : numpy.ndarray
        (B, 1, 1, 1) float64, each frame's (units as :class:`SensorParams`'s: e⁻, e⁻, —, DN/e⁻, e⁻, DN).
    bits, pedestal_dn : numpy.ndarray
        (B, 1, 1, 1) int64, each frame's ADC.
    """

    cfa: str | None
    saturation: bool
    photon_noise: bool
    read_noise: bool
    read_noise_model: str
    quantisation: bool
    full_well_e: np.ndarray
    read_noise_e: np.ndarray
    tukey_lambda: np.ndarray
    dn_per_electron: np.ndarray
    row_noise_e: np.ndarray
    bits: np.ndarray
    pedestal_dn: np.ndarray
    black_level_error_dn: np.ndarray

    @staticmethod
    def key(sensor: SensorParams) -> tuple:
        """What frames drawn in one batch must share (:data:`BATCH_SHARED`)."""
        return tuple(getattr(sensor, name) for name in BATCH_SHARED)

    @classmethod
    def of(cls, sensors) -> SensorBatch:
        """The batch of ``sensors`` (one per frame, all of one :meth:`key`).

        Raises
        ------
        ValueError
            Sensors that differ in a figure of :data:`BATCH_SHARED`, or none.
        """
        sensors = list(sensors)
        keys = {cls.key(s) for s in sensors}
        if len(keys) != 1:
            raise ValueError(f"a sensor batch needs one {'/'.join(BATCH_SHARED)} for all its frames, got {keys}")
        shared = dict(zip(BATCH_SHARED, keys.pop()))

        def column(name, dtype):
            return np.array([getattr(s, name) for s in sensors], dtype=dtype).reshape(-1, 1, 1, 1)

        per_frame = {name: column(name, np.int64 if name in ("bits", "pedestal_dn") else np.float64)
                     for name in BATCH_PER_FRAME}
        return cls(**shared, **per_frame)

    def __len__(self) -> int:
        return self.full_well_e.shape[0]


def preset(name: str, **overrides) -> SensorParams:
    """A named preset, optionally with fields overridden."""
    if name not in PRESETS:
        raise CamsimError(f"unknown sensor preset {name!r}; presets: {', '.join(PRESETS)}")
    return with_overrides(PRESETS[name], **overrides)


def with_checked_values(sensor: SensorParams, **values) -> SensorParams:
    """``sensor`` with scalar fields set to ``values`` that are already checked and typed one by one, each by its
    schema entry (:meth:`camsim.core.schema.Param.coerce`, as a dataset's own values are): only the checks across fields
    run again — a tenth of :func:`with_overrides`'s work, for a dataset's planning, which makes one per frame."""
    sensor = copy.copy(sensor)
    for name, value in values.items():
        object.__setattr__(sensor, name, value)
    sensor._check_across()
    return sensor


def with_overrides(sensor: SensorParams, **overrides) -> SensorParams:
    """``sensor`` with fields overridden; an unknown name or a bad value is a :class:`CamsimError`."""
    fields = {f.name for f in dataclasses.fields(SensorParams)}
    unknown = set(overrides) - fields
    if unknown:
        raise CamsimError(f"unknown sensor parameter(s) {sorted(unknown)}; known: {', '.join(sorted(fields))}")
    try:
        return dataclasses.replace(sensor, **overrides)
    except TypeError as exc:
        raise CamsimError(f"bad sensor parameter: {exc}") from None
