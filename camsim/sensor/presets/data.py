"""The built-in camera presets: published figures, each with its source.

The figures are facts copied from their sources (``../shared/data/cameras`` in the development tree lists them with
the same citations; the package needs no file at run time). What a source does not give is stated in the preset's
``notes``: the black level where only PMN publishes one, the ISO of ELD's K_min, the full well, the spectral
curves (no noise calibration comes with sensitivities: every preset renders with the scene's camera curves,
colour-science's ``Nikon 5100 (NPL)`` by default).
"""

from __future__ import annotations

import dataclasses
import math

from camsim.sensor.presets.model import NOT_PUBLISHED, CameraPreset, IsoPoint, NoiseFit

ELD = ("Wei et al., \"A Physics-based Noise Formation Model for Extreme Low-light Raw Denoising\", CVPR 2020; "
       "github.com/Vandermode/ELD camera_params/release/{file}_params.npy (Profile-1)")
PMN = ("Feng et al., \"Learnability Enhancement for Low-light Raw Denoising\", ACM MM 2022 / TPAMI 2023; "
       "github.com/megvii-research/PMN data_process/process.py, get_camera_noisy_params_max")
LED = ("Jin et al., \"Lighting Every Darkness in Two Pairs\", ICCV 2023; github.com/Srameo/LED "
       "options/base/noise_g/noise_g_SonyA7M4.yaml")

#: The curves every preset renders with unless the scene names a camera.
CURVES_NOTE = ("spectral sensitivities: none published with the noise figures; the scene's camera curves are used "
               "(colour-science's Nikon 5100 (NPL) by default)")
ELD_ISO_NOTE = ("ISO axis: ELD gives K over [K_min, K_max] only; its ranges span exactly 64× (6 stops), taken as "
                "ISO 100–6400 with K ∝ ISO (PMN's A7S2 law puts ISO 100 at K = 0.0935 against ELD's K_min = 0.0939); "
                "the σ's are the fits' centres, ln σ = slope · ln K + bias; the {n} Tukey shapes (one per "
                "calibrated ISO step, lowest first) are spread evenly in log ISO over the range")
WELL_NOTE = "full well: not published; the charge that fills the raw at ISO 100, (white − black) / K"
NO_DARK_NOTE = "dark current: not published (ELD's model folds it into the read noise); 0 e⁻/s"

# What each source publishes for the sensor effects of real low-light raws (issue 28; CameraPreset.published_effects). A
# figure stated here is the preset's sensor parameter; where a source gives none, the effect stays off.
NO_TEMPERATURE = (f"{NOT_PUBLISHED}: no temperature for the figures and no doubling temperature; "
                  "dark_current_reference_c and dark_current_doubling_c keep camsim's defaults")
NO_DEFECTS = f"{NOT_PUBLISHED}: hot_pixel_fraction, dead_pixel_fraction and stuck_pixel_fraction 0"
NO_SHADING = f"{NOT_PUBLISHED}: dark_shading_e and column_fpn_e 0, no dark_shading_map"
NO_BLACK_ERROR = f"{NOT_PUBLISHED}: black_level_error_dn 0"
ELD_COLOUR_BIAS = (f"{NOT_PUBLISHED}: ELD fits a per-ISO colour bias (a per-channel black-level error), but its "
                   "colour-bias tables are not in camsim's copy of ELD's figures; black_level_error_dn 0")
LED_COLOUR_BIAS = (f"{NOT_PUBLISHED}: LED's noise_g_SonyA7M4.yaml lists a ColorBias table (per calibrated ISO "
                   "step, four channel values in DN), a per-ISO mean offset rather than the σ of a per-frame draw, "
                   "and camsim's copy of LED's figures leaves it out; black_level_error_dn 0")
PMN_DARK_SHADING = ("published as files, not as numbers: PMN's repository holds the A7S2's dark shading as per-pixel "
                    "maps (resources/SonyA7S2/darkshading_{lowISO,highISO}_{k,b}, the map k · ISO + b + BLE(ISO), "
                    "the low-ISO maps for ISO ≤ 1600; data_process/real_datasets.py, get_darkshading); camsim ships "
                    "no map: dark_shading_e and column_fpn_e 0 (a map in e⁻ of the frame's shape, e.g. from "
                    "camsim calibrate, can be named with dark_shading_map)")
PMN_BLE = (f"{NOT_PUBLISHED} as a σ: PMN's per-ISO black-level error BLE(ISO) is a file (resources/SonyA7S2/"
           "darkshading_BLE.pkl), a per-ISO mean offset that PMN adds to its dark shading, not the σ of a per-frame "
           "draw; black_level_error_dn 0")
ELD_EFFECTS = {"temperature": NO_TEMPERATURE, "dark_current": f"{NOT_PUBLISHED} (ELD's model folds the dark "
               "current into the read noise): 0 e⁻/s, DSNU 0", "defects": NO_DEFECTS,
               "black_level_error": ELD_COLOUR_BIAS, "dark_shading": NO_SHADING}


def _levels_note(black: int, bits: int, published: bool) -> str:
    if published:
        return f"black {black} DN and white {2**bits - 1} DN of the {bits}-bit raw: published by the source"
    return (f"black {black} DN, white {2**bits - 1} DN: nominal values typical of the maker's {bits}-bit raws, not "
            "from the cited source")


#: ELD's (and LED's) log-linear fits: camera → (K_min, K_max, {quantity: (slope, bias, residual σ)}), DN and DN/e⁻.
ELD_FITS = {
    "Canon EOS 5D Mark IV": (0.2181895124454343, 13.964128796507795, {
        "tukey_scale_dn": (0.6558756156508007, 1.09268679594838, 0.28604721742277756),
        "gaussian_sigma_dn": (0.6771267783987617, 1.5121876510805845, 0.24641096601611254),
        "row_sigma_dn": (0.4712797750747537, -0.8078958947116487, 0.2436176299944695)}),
    "Canon EOS 700D": (0.44762889266510675, 28.648249130566832, {
        "tukey_scale_dn": (0.5982361749821256, 1.5370438794284738, 0.3888189465002228),
        "gaussian_sigma_dn": (0.6524587630931787, 2.079863926921898, 0.25781594662342805),
        "row_sigma_dn": (0.6220587550621577, -0.7756471105987757, 0.24848083434051538)}),
    "Canon EOS 70D": (0.40749699481911256, 26.079807668423204, {
        "tukey_scale_dn": (0.4868061424083776, 1.4642678570994598, 0.3820056048326114),
        "gaussian_sigma_dn": (0.5681183926808191, 1.9982663724918939, 0.24870223821017215),
        "row_sigma_dn": (0.7292220505388829, -0.9370565150367796, 0.2502155842967251)}),
    "Nikon D850": (0.4150393264348262, 26.562516891828878, {
        "tukey_scale_dn": (0.4773896839219417, -0.09044499670414502, 0.23920060971003035),
        "gaussian_sigma_dn": (0.5634612649498357, 0.799410107756515, 0.21408231874600314),
        "row_sigma_dn": (0.44829219631519307, -1.7977103277112132, 0.2321799439489326)}),
    "Sony A7S2": (0.09391607086816033, 6.010628535562261, {
        "tukey_scale_dn": (0.46210495986526035, 0.5657147358616816, 0.2633712220097871),
        "gaussian_sigma_dn": (0.5407496082896145, 1.218237123334061, 0.26751211630129734),
        "row_sigma_dn": (0.5275360468633209, -0.5917002648887661, 0.29428813016491145)}),
    "Sony A7M4": (0.5177, 37.483, {
        "tukey_scale_dn": (0.8741, -0.7834, 0.2436),
        "gaussian_sigma_dn": (0.9469, 0.1605, 0.2052),
        "row_sigma_dn": (0.8499, -2.5081, 0.254)}),
}

#: ELD's Tukey shapes per calibrated ISO step, lowest ISO first.
ELD_TUKEY_SHAPES = {
    "Canon EOS 5D Mark IV": (0.15714, 0.14286, 0.08571, 0.08571, 0.2, 0.2, 0.1, 0.08571, 0.05714, 0.07143, 0.02857,
                             0.02857, 0.01429, 0.02857, 0.08571, 0.07143, 0.11429, 0.11429),
    "Canon EOS 700D": (0.12857, 0.12857, 0.1, 0.1, 0.01429, 0.01429, -0.08571, -0.1, -0.14286, -0.15714, -0.12857,
                       -0.12857, -0.02857, -0.02857, 0.01429, 0.01429),
    "Canon EOS 70D": (0.14286, 0.14286, 0.11429, 0.11429, 0.02857, 0.02857, -0.1, -0.08571, -0.17143, -0.17143,
                      -0.15714, -0.15714, -0.08571, -0.08571, -0.02857, -0.02857),
    "Nikon D850": (-0.11429, -0.11429, -0.2, -0.2, -0.21429, -0.21429, -0.22857, -0.22857, -0.24286, -0.24286,
                   -0.17143, -0.17143, -0.14286, -0.14286, -0.1, -0.1),
    "Sony A7S2": (0.11429, 0.12857, 0.05714, 0.04286, 0.0, 0.0, -0.04286, -0.05714, -0.08571, -0.08571, -0.08571,
                  -0.08571, -0.11429, -0.11429, -0.14286, -0.12857, -0.14286, -0.14286),
}

#: PMN's Sony A7S2 per ISO: (ISO, K DN/e⁻, Tukey λ, Tukey scale DN, Gaussian σ DN, row σ DN); 14-bit, black 512.
PMN_A7S2 = (
    (50, 0.04782, 0.1475, 0.707, 1.016, 0.140), (64, 0.0612, 0.1324, 0.715, 1.051, 0.143),
    (80, 0.0765, 0.1121, 0.780, 1.181, 0.195), (100, 0.09563, 0.1488, 0.702, 1.007, 0.139),
    (125, 0.1195, 0.1290, 0.696, 1.028, 0.145), (160, 0.153, 0.0941, 0.726, 1.129, 0.198),
    (200, 0.1913, 0.0790, 0.812, 1.293, 0.228), (250, 0.2391, 0.0517, 0.863, 1.435, 0.263),
    (320, 0.306, 0.0407, 1.033, 1.748, 0.310), (400, 0.3825, 0.0223, 1.182, 2.060, 0.362),
    (500, 0.4782, -0.0031, 1.318, 2.396, 0.425), (640, 0.612, 0.0026, 1.647, 2.966, 0.488),
    (800, 0.765, -0.0082, 1.935, 3.548, 0.572), (1000, 0.9563, -0.0211, 2.280, 4.273, 0.685),
    (1250, 1.195, -0.0324, 2.708, 5.178, 0.818), (1600, 1.53, -0.0441, 3.228, 6.299, 0.989),
    (2000, 1.913, -0.0130, 1.436, 2.654, 0.331), (2500, 2.391, -0.0271, 1.690, 3.200, 0.383),
    (3200, 3.06, -0.0349, 2.042, 3.919, 0.445), (4000, 3.825, -0.0437, 2.463, 4.802, 0.523),
    (5000, 4.782, -0.0532, 2.976, 5.900, 0.619), (6400, 6.12, -0.0752, 3.450, 7.116, 0.722),
    (8000, 7.65, -0.0821, 4.270, 8.917, 0.878), (10000, 9.563, -0.0733, 5.495, 11.291, 1.052),
    (12800, 12.24, -0.0650, 7.038, 14.246, 1.275), (16000, 15.3, -0.0607, 8.878, 17.834, 1.556),
    (20000, 19.13, -0.0602, 11.002, 22.085, 1.881), (25600, 24.48, -0.0909, 12.176, 25.853, 2.276),
)


def _fits(camera: str) -> dict:
    return {q: NoiseFit(*v) for q, v in ELD_FITS[camera][2].items()}


def _eld_preset(name: str, camera: str, source: str, black: int, shapes: tuple, black_published: bool = False,
                title: str | None = None) -> CameraPreset:
    """A preset from ELD-style fits: ISO points at the Tukey shapes' steps, spread evenly in log ISO from ISO 100
    (K_min) with K ∝ ISO, each σ at its fit's centre."""
    k_min, k_max, _ = ELD_FITS[camera]
    fits = _fits(camera)
    n = len(shapes)
    points = []
    for i, shape in enumerate(shapes):
        ratio = (k_max / k_min) ** (i / (n - 1))
        k = k_min * ratio
        points.append(IsoPoint(iso=100.0 * ratio, k_dn_per_e=k, tukey_lambda=shape,
                               **{q: float(f.at(k)) for q, f in fits.items()}))
    notes = (ELD_ISO_NOTE.format(n=n), _levels_note(black, 14, black_published), WELL_NOTE, NO_DARK_NOTE,
             CURVES_NOTE)
    return CameraPreset(name=name, title=title or camera, source=source, iso_points=tuple(points), bits=14,
                        pedestal_dn=black, fits=fits, k_range_dn_per_e=(k_min, k_max), tukey_shapes=tuple(shapes),
                        notes=notes, published_effects=ELD_EFFECTS)


def _a7s2_pmn() -> CameraPreset:
    points = tuple(IsoPoint(iso=float(iso), k_dn_per_e=k, tukey_lambda=lam, tukey_scale_dn=scale,
                            gaussian_sigma_dn=sigma, row_sigma_dn=row)
                   for iso, k, lam, scale, sigma, row in PMN_A7S2)
    k_min, k_max, _ = ELD_FITS["Sony A7S2"]
    notes = ("per ISO 50–25600 as published; K ∝ ISO (PMN's law K = 0.0009546 · ISO − 0.00193); between points "
             "log-log interpolation; dual conversion gain: ISO ≥ 2000 is the high-gain mode (read noise 6.30 → 2.65 "
             "DN between ISO 1600 and 2000), an ISO between 1600 and 2000 is the low-gain mode extended",
             _levels_note(512, 14, True), WELL_NOTE, NO_DARK_NOTE, CURVES_NOTE,
             "virtual cameras draw from ELD's A7S2 fits (sony-a7s2-eld)")
    effects = {"temperature": NO_TEMPERATURE, "dark_current": f"{NOT_PUBLISHED}: 0 e⁻/s, DSNU 0",
               "defects": NO_DEFECTS, "black_level_error": PMN_BLE, "dark_shading": PMN_DARK_SHADING}
    return CameraPreset(name="sony-a7s2", title="Sony A7S2 (ILCE-7SM2)", source=PMN, iso_points=points, bits=14,
                        pedestal_dn=512, dual_gain_iso=2000.0, fits=_fits("Sony A7S2"), k_range_dn_per_e=(k_min, k_max),
                        tukey_shapes=ELD_TUKEY_SHAPES["Sony A7S2"], notes=notes, published_effects=effects)


def _a7m4() -> CameraPreset:
    k_min, k_max, _ = ELD_FITS["Sony A7M4"]
    fits = _fits("Sony A7M4")
    shape = -0.19  # the middle of LED's stated span −0.28 … −0.10
    points = tuple(IsoPoint(iso=100.0 * k / k_min, k_dn_per_e=k, tukey_lambda=shape,
                            **{q: float(f.at(k)) for q, f in fits.items()}) for k in (k_min, k_max))
    notes = ("ISO axis: LED gives K over [0.5177, 37.483] DN/e⁻ only (72.4×); K_min is taken as ISO 100 with K ∝ ISO "
             "(as for the ELD cameras), so the range is ISO 100–7240; σ's at the fits' centres",
             "Tukey shape: LED lists none, only the span −0.28 … −0.10; −0.19, its middle, at every ISO",
             _levels_note(512, 14, False), WELL_NOTE, NO_DARK_NOTE, CURVES_NOTE)
    return CameraPreset(name="sony-a7m4", title="Sony A7M4 (ILCE-7M4)", source=LED, iso_points=points, bits=14,
                        pedestal_dn=512, fits=fits, k_range_dn_per_e=(k_min, k_max),
                        tukey_shapes=(-0.28, -0.10), notes=notes,
                        published_effects={**ELD_EFFECTS, "black_level_error": LED_COLOUR_BIAS})


def _datasheet_point(k: float, read_e: float, iso: float = 100.0, prnu_percent: float = 0.0) -> IsoPoint:
    """A single published setting with Gaussian read noise ``read_e`` e⁻ (the Tukey fields: λ = 0.14, the
    Gaussian-like shape, scaled to the same σ)."""
    sigma = read_e * k
    return IsoPoint(iso=iso, k_dn_per_e=k, tukey_lambda=0.14, tukey_scale_dn=sigma / math.sqrt(_tukey_var(0.14)),
                    gaussian_sigma_dn=sigma, prnu_percent=prnu_percent)


def _tukey_var(lam: float) -> float:
    from camsim.sensor.kernels import tukey_lambda_variance

    return tukey_lambda_variance(lam)


def _imx363() -> CameraPreset:
    # ISETCam: 10-bit, black 64, white 1023, well 6000 e⁻, read noise 5 e⁻, PRNU 0.7 %, 0.44875 mV/DN, analog gain
    # ISO / 55. The well fills the voltage swing (1023 × 0.44875 mV) at unity gain: G_Ve⁻ = 0.4591 V / 6000 e⁻
    swing_v = 1023 * 0.44875e-3
    conversion = swing_v / 6000.0
    points = tuple(_datasheet_point(conversion * (iso / 55.0) / 0.44875e-3, 5.0, iso=iso, prnu_percent=0.7)
                   for iso in (55.0, 55.0 * 64))
    notes = ("ISO axis: ISETCam's analog gain ISO / 55 (unity at ISO 55, default ISO 270) on a 0.44875 mV/DN ADC; the "
             "6000 e⁻ well taken to fill the 1023 DN swing at unity gain (G_Ve⁻ = 76.5 µV/e⁻, K = 0.1705 DN/e⁻ at "
             "ISO 55); the range ISO 55–3520 (64× analog gain) is camsim's choice, read noise 5 e⁻ at every ISO",
             "read noise Gaussian (ISETCam's model); black 64 DN and white 1023 DN published", CURVES_NOTE,
             "CFA: RGGB (nominal)")
    effects = {"temperature": NO_TEMPERATURE,
               "dark_current": f"DSNU 0 e⁻ (ISETCam's model sets none); dark current {NOT_PUBLISHED}: 0 e⁻/s",
               "defects": NO_DEFECTS, "black_level_error": NO_BLACK_ERROR, "dark_shading": NO_SHADING}
    return CameraPreset(name="sony-imx363", title="Sony IMX363 (Google Pixel 4a), ISETCam model",
                        source="ISETCam sensor/models/sensorIMX363.m (MIT licence)", iso_points=points, bits=10,
                        pedestal_dn=64, full_well_e=6000.0, conversion_gain_v_per_e=conversion,
                        read_noise_model="gaussian", notes=notes, raw_models=(("Google", "Pixel 4a"),),
                        published_effects=effects)


def _single(name: str, title: str, source: str, bits: int, k: float, full_well: float, read_e: float,
            notes: tuple, dark: float = 0.0, dark_reference_c: float | None = None) -> CameraPreset:
    """A one-setting datasheet preset (EMVA 1288 figures). ``dark``: the published dark current (e⁻/s; 0 where
    none), measured at ``dark_reference_c`` (°C; None where the source gives no temperature)."""
    if dark > 0:
        at = "" if dark_reference_c is None else f" at {dark_reference_c:g} °C"
        dark_text = f"dark current {dark:g} e⁻/s{at} as published; DSNU {NOT_PUBLISHED}: 0"
    else:
        dark_text = f"{NOT_PUBLISHED} (the quoted EMVA 1288 figures give no dark current and no DSNU): 0 e⁻/s, DSNU 0"
    if dark_reference_c is None:
        temperature = NO_TEMPERATURE
    else:
        temperature = (f"the dark current's temperature, {dark_reference_c:g} °C, is published: "
                       f"dark_current_reference_c = {dark_reference_c:g} °C; no doubling temperature published "
                       "(camsim's default dark_current_doubling_c)")
    effects = {"temperature": temperature, "dark_current": dark_text, "defects": NO_DEFECTS,
               "black_level_error": NO_BLACK_ERROR, "dark_shading": NO_SHADING}
    return CameraPreset(name=name, title=title, source=source, iso_points=(_datasheet_point(k, read_e),), bits=bits,
                        pedestal_dn=0, cfa=None, full_well_e=full_well, dark_current_e_per_s=dark,
                        dark_current_reference_c=dark_reference_c, read_noise_model="gaussian",
                        published_effects=effects,
                        notes=notes + ("one published setting, called ISO 100; no black offset published: 0 DN "
                                       "(set pedestal_dn to add one)", "monochrome: modelled with R, G and B at every "
                                       "pixel (use one channel)", CURVES_NOTE))


def build_presets() -> dict:
    """Every built-in camera preset, by name."""
    presets = [
        _a7s2_pmn(),
        _eld_preset("sony-a7s2-eld", "Sony A7S2", ELD.format(file="SonyA7S2"), 512, ELD_TUKEY_SHAPES["Sony A7S2"],
                    black_published=True, title="Sony A7S2 (ILCE-7SM2), ELD's fits"),
        _eld_preset("nikon-d850", "Nikon D850", ELD.format(file="NikonD850"), 400, ELD_TUKEY_SHAPES["Nikon D850"]),
        _eld_preset("canon-eos-5d4", "Canon EOS 5D Mark IV", ELD.format(file="CanonEOS5D4"), 2048,
                    ELD_TUKEY_SHAPES["Canon EOS 5D Mark IV"]),
        _eld_preset("canon-eos-70d", "Canon EOS 70D", ELD.format(file="CanonEOS70D"), 2048,
                    ELD_TUKEY_SHAPES["Canon EOS 70D"]),
        dataclasses.replace(
            _eld_preset("canon-eos-700d", "Canon EOS 700D", ELD.format(file="CanonEOS700D"), 2048,
                        ELD_TUKEY_SHAPES["Canon EOS 700D"]),
            raw_models=(("Canon", "Canon EOS REBEL T5i"), ("Canon", "Canon EOS Kiss X7i"))),
        _a7m4(),
        _imx363(),
        _single("sony-imx174", "Sony IMX174 machine-vision camera (EMVA 1288)",
                "EMVA 1288 figures as quoted by fhotolab.fherb.de, 2016-09-07 (a datasheet reconstruction)", 12,
                1 / (0.51 * 16), 32691.0, 6.83,
                ("well 32 691 e⁻, read noise 6.83 e⁻ as quoted; the quoted 0.51 e⁻/DN is on a 16-bit scale (12-bit "
                 "values × 16: 4095 × 16 × 0.51 = 33 416 e⁻, the well), so K = 1 / (16 × 0.51) = 0.1225 DN/e⁻ at "
                 "12 bits; QE 77 % at 525 nm (quoted; camsim's curves set the QE)",)),
        _single("sony-icx625-basler", "Basler piA2400-17gm (Sony ICX625 CCD, EMVA 1288)",
                "EMVA 1288 figures as quoted by mengineer.hatenablog.com, 2016-05-02", 12, 4095 / 7000.0, 7000.0,
                13.0, ("well 7000 e⁻, read noise 13 e⁻ as quoted; no ADC figures quoted: 12 bits with the well filling "
                       "the ADC (K = 4095 / 7000 DN/e⁻) is camsim's choice",)),
        _single("sony-icx625-pointgrey", "Point Grey GS3-PGE-50S5M-C (Sony ICX625 CCD, EMVA 1288)",
                "EMVA 1288 figures as quoted by mengineer.hatenablog.com, 2016-05-02", 12, 4095 / 5903.0, 5903.0,
                8.28, ("well 5903 e⁻, read noise 8.28 e⁻ as quoted; no ADC figures quoted: 12 bits with the well "
                       "filling the ADC (K = 4095 / 5903 DN/e⁻) is camsim's choice",)),
        _single("kodak-kaf3200me", "QSI 532 (Kodak KAF-3200ME CCD), measured",
                "measured by Christian Buil, astrosurf.com/buil/cameras (QSI 532)", 16, 1 / 1.413, 70000.0, 12.6,
                ("well 70 000 e⁻, read noise 12.6 e⁻, 1.413 e⁻/DN, dark current 0.080 e⁻/s at 0 °C: measured (so "
                 "dark_current_reference_c = 0 °C: at temperature_c = T the dark current is "
                 "0.080 · 2^(T / dark_current_doubling_c) e⁻/s)",),
                dark=0.080, dark_reference_c=0.0),
    ]
    # every preset's notes end with what its source publishes for each sensor effect (CameraPreset.published_effects)
    return {p.name: dataclasses.replace(p, notes=p.notes + tuple(p.describe_effects())) for p in presets}
