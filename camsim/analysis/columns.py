"""What ``camsim analyze`` writes, in words: every CSV column, the printed table's columns, SNR, ΔE and the flags.

:func:`guide_text` is the companion text written beside the CSVs (``OUT/README.txt``); :func:`legend_text` the
short legend printed under the tables. Every column of ``analysis.csv`` and ``frame_statistics.csv`` has an entry
here (a test derives the columns from the CSVs it writes), so a new column needs its explanation.
"""

from __future__ import annotations

#: SNR as camsim reports it (the paper's Eq. 14).
SNR_DEFINITION = (
    "SNR is a power ratio: signal² / variance, both in DN (signal = the patch's mean less the black level, "
    "variance = the pixels' variance), so unitless; snr_*_db = 10 log10(SNR). It is not the amplitude ratio "
    "signal / σ, which is √SNR (20 log10 of it gives the same dB). For pure shot noise S² / S = S: 100 "
    "electrons give SNR 100 = 20 dB.")

#: Why ΔE explodes at low F, and what to look at instead.
DELTA_E_AT_LOW_LIGHT = (
    "ΔE_ab follows the paper's 5 steps: every pixel's XYZ is scaled to Y = 100 before CIELAB, so ΔE compares "
    "chromaticity only, pixel by pixel, to the patch's mean colour at F = 1, and averages. Where the signal nears "
    "0 (low F, dark patches such as black, most of all with --subtract-black) a pixel's X, Y, Z are noise around "
    "0: scaling a Y of 0.01 to 100 multiplies its noise by 10⁴, so single pixels reach ΔE in the thousands and "
    "the mean follows (samples with Y ≤ 0 are left out and counted in n_y_nonpositive). Without black "
    "subtraction the chromaticity is also pulled toward the camera black point (the star in the xy figures). "
    "Such a ΔE says how noisy each pixel's colour is, not how far the patch's colour moved: look at the SNR "
    "(the lower, the more of a pixel's chromaticity is noise), at the ellipse centre (center_x, center_y: where "
    "the colour moved) and size, and compare ΔE between patches and F of similar SNR.")

#: The printed table's ``flags`` column.
FLAGS = ("flags: the number of the frame's patches with a degenerate noise ellipse (ellipse_status not 'ok': "
         "too-few-samples, constant, rank-1) or with pixels whose chromaticity is undefined (X + Y + Z ≤ 0, "
         "n_xy_undefined > 0); 0 = every patch measured in full. analysis.csv says which patch and why.")

#: The per-frame table printed by ``camsim analyze`` (:func:`camsim.analysis.analyze.table`): header → meaning.
TABLE_COLUMNS = {
    "frame": "the frame file",
    "F": "the intensity factor of the frame (sidecar)",
    "stats": "photon statistics: pixel (physical) or paper (Eq. 4)",
    "ellipse size": "mean over patches of the 1 σ noise ellipse size √(a² + b²), CIE 1931 xy units",
    "mean ΔE": "mean over patches of ΔE_ab to the same patch at F = 1 (see 'ΔE at low light')",
    "SNR G dB": "mean over patches of the G channel's measured SNR in dB, 10 log10(signal² / variance)",
    "flags": FLAGS.split(": ", 1)[1],
}

_FRAME = {
    "frame_file": "path of the frame file measured",
    "source": "dng (the quantised digital numbers) or exr (the values before quantisation)",
    "scene": "scene name (sidecar)",
    "illuminant": "illuminant name (sidecar)",
    "intensity_factor": "F, the scene's light relative to the scene file's luminance (unitless)",
    "photon_statistics": "pixel (Poisson per pixel, physical) or paper (the paper's Eq. 4)",
    "method": "how the frame was drawn: poisson, spectral, gaussian or auto",
    "seed": "the run seed",
}

#: analysis.csv: one row per frame × patch × channel.
ANALYSIS_COLUMNS = _FRAME | {
    "patch_index": "patch number in the sidecar, from 0",
    "patch_name": "patch name (a chart's colour, or a [[region]]'s name)",
    "n_xy_valid": "pixels whose xy chromaticity is defined (X + Y + Z > 0): the ellipse's samples",
    "n_xy_undefined": "pixels with X + Y + Z ≤ 0, left out of xy and the ellipse (counted, never NaN)",
    "ellipse_status": "ok, or why the ellipse is degenerate: too-few-samples (< 3), constant (all equal), "
                      "rank-1 (on a line)",
    "center_x": "ellipse centre: mean CIE 1931 x of the pixels",
    "center_y": "ellipse centre: mean CIE 1931 y of the pixels",
    "semi_major_xy": "1 σ semi-major axis a of the PCA noise ellipse, xy units",
    "semi_minor_xy": "1 σ semi-minor axis b ≤ a, xy units",
    "angle_deg": "inclination of the major axis to the x axis, degrees in (−90, 90]",
    "size_xy": "ellipse size √(a² + b²), xy units",
    "frac_in_2sigma": "share of pixels inside the 2 σ ellipse (0.865 for a Gaussian cloud)",
    "n_distinct_values": "distinct RGB values among the patch's pixels (quantised three-chip frames; else empty)",
    "delta_e_ab_mean": "mean ΔE_ab (CIE 1976) of the pixels to the mean Lab of the same patch at F = 1, each "
                       "pixel scaled to Y = 100 first (chromaticity only; see 'ΔE at low light')",
    "delta_e_ab_std": "standard deviation of the pixels' ΔE_ab",
    "n_y_nonpositive": "pixels with Y ≤ 0, left out of ΔE (they cannot be scaled to Y = 100)",
    "delta_e_status": "ok, no-reference (no F = 1 frame of the same scene, light and camera) or no-valid-sample",
    "channel": "R, G or B (a Bayer frame: that colour's sites)",
    "n_pixels": "pixels of this channel in the patch, less the border",
    "black_dn": "black level subtracted before measuring, DN (0 unless --subtract-black or --dark)",
    "mean_dn": "mean of the pixels less black_dn, DN",
    "var_dn2": "sample variance of the pixels (ddof = 1), DN²",
    "std_dn": "standard deviation of the pixels, DN",
    "mean_e": "mean_dn / k (k = dn_per_electron), e⁻",
    "var_e2": "var_dn2 / k², e⁻²",
    "std_e": "std_dn / k, e⁻",
    "saturated_pixels": "pixels at or above the saturation level (the ADC's full scale, or the full well less "
                        "3 σ of read noise)",
    "constant": "true when all the channel's pixels are equal (no variance: SNR undefined)",
    "snr_model": "model SNR (Eqs. 13–14), power ratio (k S)² / (k² (Var S + D + σ_read²) + 1/12 DN² when "
                 "quantised): S signal, D dark electrons (sidecar)",
    "snr_model_db": "10 log10(snr_model), dB",
    "snr_model_eq13": "model SNR with Eqs. 13–14 as printed (photon term k² S, quantisation 1/3 DN², numerator "
                      "the quantised noise-free signal [k S]_nb), power ratio",
    "snr_model_eq13_db": "10 log10(snr_model_eq13), dB",
    "snr_empirical": "measured SNR, power ratio: (mean of the pixels − the frame's expected black level)² / "
                     "var_dn2, with the sidecar's black level whatever --subtract-black",
    "snr_empirical_db": "10 log10(snr_empirical), dB (empty where the SNR is 0)",
    "snr_status": "ok, too-few-samples or constant (SNR undefined)",
}

#: frame_statistics.csv: one row per frame × channel, the whole frame.
FRAME_STATISTICS_COLUMNS = _FRAME | {
    "channel": "R, G or B (a Bayer frame: that colour's sites)",
    "n_pixels": "pixels of this channel in the whole frame",
    "black_dn": "black level subtracted, DN (the --subtract-black/--dark level, else the sidecar's)",
    "mean_dn": "mean of the frame's values less black_dn, DN",
    "std_dn": "standard deviation of the frame's values (scene content and noise together), DN",
    "clip_low_fraction": "share of values at or below 0 DN",
    "clip_high_fraction": "share of values at or above the white level (an EXR: what the ADC would clip)",
    "residual_status": "ok, or why there is no residual: no-clean-layer (no EXR beside the frame), "
                       "exr-unreadable (there, but truncated or corrupt: a warning names it), exr-of-another-frame, "
                       "paper-statistics (no prediction), no-pixel-clear-of-clipping",
    "n_residual": "pixels in the residual noisy − clean (those clear of clipping)",
    "n_near_clip": "pixels left out of the residual: clean value within 5 σ of 0, the white level or the full well",
    "residual_mean_dn": "mean of noisy − clean (a DNG: I + ½ − clean; with a pedestal P: I − P − clean), the bias, DN "
                        "(~0 expected)",
    "residual_mean_se_dn": "standard error of residual_mean_dn (over rows), DN",
    "residual_var_dn2": "variance of the residual, DN²",
    "residual_var_se_dn2": "standard error of residual_var_dn2, DN²",
    "predicted_var_dn2": "the model's noise variance averaged over those pixels, DN²",
    "residual_var_ratio": "residual_var_dn2 / predicted_var_dn2 (~1 expected)",
}

#: temporal.csv: one row per sequence × region × channel (:mod:`camsim.analysis.temporal`), written only when the
#: frames analysed hold a sequence (two or more frames of one static scene and sensor, differing in their noise).
TEMPORAL_COLUMNS = {
    "sequence": "the sequence: its folder and its sidecars' sequence stem (else its first frame's stem)",
    "scene": "scene name (sidecar)",
    "illuminant": "illuminant name (sidecar)",
    "intensity_factor": "F, the scene's light relative to the scene file's luminance (unitless)",
    "sensor_seed": "the sensor's seed: its fixed-pattern maps, shared by the sequence's frames",
    "n_frames": "N, the frames of the sequence (each its own seed or frame_index)",
    "first_frame": "path of the sequence's first frame",
    "source": "dng (the quantised digital numbers) or exr (the values before quantisation)",
    "region": "patch name, or 'frame' for the whole frame",
    "region_index": "patch number in the sidecar, from 0 (empty for the whole frame)",
    "channel": "R, G or B (a Bayer frame: that colour's sites)",
    "n_pixels": "pixels of this channel in the region (a patch less --border pixels along each edge)",
    "mean_dn": "mean over the region of the mean image, less the sidecar's black level, DN",
    "temporal_var_dn2": "EMVA 1288 temporal variance: the mean over the region's pixels of each pixel's unbiased "
                        "variance over the N frames, DN²",
    "temporal_var_se_dn2": "standard error of temporal_var_dn2 over rows (row noise makes a row's pixels vary "
                           "together), DN²",
    "temporal_model_dn2": "the model's temporal variance from the sidecar: k² (clean / k + σ_read² + σ_row²) "
                          "(+ 1/12 DN² for a DNG, + black_level_error_dn²) averaged over the region, with the "
                          "EXR's clean layer, else the patch's signal_e + dark_e; empty under paper statistics or "
                          "for the whole frame without an EXR, DN²",
    "temporal_ratio": "temporal_var_dn2 / temporal_model_dn2 (~1 expected)",
    "mean_image_var_dn2": "s²_ȳ: the variance over the region's pixels of the mean image (ddof = 1), DN²",
    "spatial_var_dn2": "EMVA 1288 spatial variance: mean_image_var_dn2 − temporal_var_dn2 / N (the temporal "
                       "noise left in the mean image removed), DN²; the fixed pattern plus, for a region that is "
                       "not uniform (the whole frame of a chart or an image), the scene's own structure",
    "spatial_var_se_dn2": "standard error of spatial_var_dn2, pixels of the mean image taken as independent "
                          "(right for DSNU and PRNU; a column pattern spreads more), DN²",
    "spatial_model_dn2": "the model's spatial variance, the expectation over sensors: k² (dsnu_e² + column_fpn_e² "
                         "+ (S̄ prnu_percent/100)² + (D̄ dsnu_dark_current_percent/100)² [+ dark_shading_e² for the "
                         "whole frame of a flat target]), S̄, D̄ the region's mean signal and dark charge; empty "
                         "where the region is not uniform, DN²",
    "spatial_model_terms": "the sidecar keys whose patterns spatial_model_dn2 holds (those set)",
    "spatial_not_modelled": "the keys set whose patterns it does not hold (hot, dead, stuck pixels, a dark-shading "
                            "map, dark shading over a patch; scene-not-uniform: no prediction at all)",
    "spatial_clean_dn2": "this sensor's spatial variance: the variance over the region of the EXR's clean layer "
                         "(each pixel's expectation, every fixed pattern and the scene's structure in it), DN²",
    "temporal_e2": "temporal_var_dn2 / k², e⁻²",
    "spatial_e2": "spatial_var_dn2 / k², e⁻²",
}

#: What temporal.csv's analysis is, for the companion text.
TEMPORAL_DEFINITION = (
    "A sequence is two or more frames whose sidecars agree on the scene, light, camera, exposure and sensor "
    "(sensor_seed included) and differ in their seed (or frame_index): one static scene, one sensor, independent "
    "temporal noise. EMVA 1288 Release 4.0 separates its noise: temporal = the pixels' mean variance over the "
    "frames; spatial = the mean image's variance over the pixels less temporal / N. Row noise is temporal (one "
    "offset per row and frame): it is in temporal_var_dn2 and its standard error is taken over rows.")

#: Each CSV file's name and its column explanations.
CSV_COLUMNS = {"analysis.csv": ANALYSIS_COLUMNS, "frame_statistics.csv": FRAME_STATISTICS_COLUMNS}


#: What ``mtf.csv`` measures (:mod:`camsim.analysis.mtf`).
MTF_DEFINITION = ("The slanted-edge SFR (ISO 12233:2017 e-SFR) of each channel in the edge's region (the sidecar's "
                  "slanted-edge target, or --edge-region): the edge fitted per row, the pixels projected on its normal "
                  "into quarter-pixel bins, the edge spread's derivative Hamming-windowed and Fourier transformed. A "
                  "Bayer frame's colours are each measured on their own sites; an EXR's clean layer is measured too "
                  "(channels R_clean, G_clean, B_clean). MTF50 and the MTF at Nyquist are in analysis.json (mtf).")
#: The columns of ``mtf.csv``.
MTF_COLUMNS = {
    "channel": "R, G, B (the DNG's numbers or the EXR's noisy layer); R_clean, G_clean, B_clean (the EXR's clean "
               "layer)",
    "frequency_cy_per_px": "spatial frequency along the edge normal, cycles per sensor pixel (Nyquist 0.5)",
    "mtf_measured": "the measured SFR, 1 at frequency 0",
    "mtf_model": "the closed-form MTF from the sidecar's optics record (diffraction / defocus per wavelength weighted "
                 "by the channel, OLPF, the pixel: a box of side sqrt(fill_factor), the source's full-pixel sampling "
                 "and the aperture together); empty without optics",
}


def guide_text(figures=(), temporal: bool = False, mtf=()) -> str:
    """The companion text of the CSVs (``OUT/README.txt``): SNR, ΔE, the flags, every column of each CSV (with
    ``temporal``, also of ``temporal.csv``; with ``mtf``, the MTF files' names, also of ``mtf.csv``) and the figures
    written (file names)."""
    lines = ["camsim analyze: what the files hold", "",
             "SNR", "  " + SNR_DEFINITION, "",
             "ΔE at low light", "  " + DELTA_E_AT_LOW_LIGHT, "",
             "The printed table"]
    lines += [f"  {name}: {text}" for name, text in TABLE_COLUMNS.items()]
    for file, columns in CSV_COLUMNS.items():
        what = "frame × patch × channel" if file == "analysis.csv" else "frame × channel (the whole frame)"
        lines += ["", f"{file} (one row per {what})"]
        lines += [f"  {name}: {text}" for name, text in columns.items()]
    if temporal:
        lines += ["", "temporal.csv (one row per sequence × region × channel)", "  " + TEMPORAL_DEFINITION]
        lines += [f"  {name}: {text}" for name, text in TEMPORAL_COLUMNS.items()]
    if mtf:
        lines += ["", "mtf.csv (one row per channel × frequency; several edge frames: mtf_<frame stem>.csv each)",
                  "  " + MTF_DEFINITION]
        lines += [f"  {name}: {text}" for name, text in MTF_COLUMNS.items()]
        lines += ["  files: " + ", ".join(mtf)]
    if figures:
        lines += ["", "Figures (per scene, light and camera: *_xy.png the CIE 1931 xy diagram with pixel samples "
                      "and 1 σ noise ellipses at representative F and the camera black point (a star); "
                      "*_delta_e.png mean ΔE_ab against F; *_snr.png the measured SNR in dB against F, per "
                      "channel)"]
        lines += [f"  {name}" for name in figures]
    return "\n".join(lines) + "\n"


def legend_text() -> str:
    """The legend printed under ``camsim analyze``'s tables: the SNR's definition, ΔE at low light, the flags."""
    return "\n".join(["SNR = signal² / variance (power ratio, Eq. 14; dB = 10 log10). Not signal / σ.",
                      "mean ΔE: per-pixel chromaticity ΔE_ab to the F = 1 colour; it explodes where the signal "
                      "nears 0 (low F, dark patches): judge colour there by SNR and the ellipse centre.",
                      FLAGS])
