"""Verification by rendering: frames at the chosen setting and at its neighbours on the grid (one exposure step
and one ISO point either way), their measured SNR and ΔE against the model's, and whether a neighbour beats the
choice beyond noise.

Measured per patch and channel from the frame's digital numbers less the exact black level
(:attr:`camsim.sensor.params.SensorParams.black_level_dn`): SNR = mean² / variance, in dB, with its standard error by
the delta method, 10 / ln 10 · √(4 var / (n mean²) + 2 / (n − 1)); ΔE of every pixel by the paper's procedure against
the patch's noise-free colour, the mean over pixels with its standard error. The scene's figures are the means
over patches (and channels), their standard errors √(Σ SE²) / count.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from camsim.optimise.model import lab_of, noise_terms_e2, snr_db
from camsim.optimise.search import Choice, PatchRates

#: A neighbour beats the choice only if its measured objective is better by more than this many standard errors.
BEAT_SIGMAS = 3.0
#: The model and a measurement agree when they differ by at most this many standard errors.
AGREE_SIGMAS = 4.0


def measure(frame, rates: PatchRates) -> dict:
    """Measured mean SNR (dB) and mean ΔE of a rendered frame's patches, with standard errors."""
    sensor = frame.sensor
    k = sensor.dn_per_electron
    values = frame.digital_dn if frame.digital_dn is not None else frame.noisy_dn
    black = sensor.black_level_dn if frame.digital_dn is not None else sensor.dark_level_dn
    snr, snr_se, de, de_se = [], [], [], []
    flat_labels = frame.labels.ravel()
    for p in range(len(rates.names)):
        pick = flat_labels == p
        rgb = np.stack([values[c].ravel()[pick].astype(np.float64) - black[c] for c in range(3)], axis=-1)
        n = rgb.shape[0]
        mean, var = rgb.mean(axis=0), rgb.var(axis=0, ddof=1)
        snr.extend(10 * np.log10(mean**2 / var))
        snr_se.extend(10 / np.log(10) * np.sqrt(4 * var / (n * mean**2) + 2 / (n - 1)))
        lab = lab_of(rgb / k, rates.to_xyz, rates.white_xy)
        delta = np.sqrt(np.sum((lab - rates.reference_lab[p]) ** 2, axis=-1))
        delta = delta[np.isfinite(delta)]
        de.append(delta.mean())
        de_se.append(delta.std(ddof=1) / np.sqrt(delta.size))
    return {"snr_db": float(np.mean(snr)), "snr_se": float(np.sqrt(np.sum(np.square(snr_se))) / len(snr)),
            "delta_e": float(np.mean(de)), "delta_e_se": float(np.sqrt(np.sum(np.square(de_se))) / len(de))}


def verify_choice(choice: Choice, result, lit, rates: PatchRates, sensor_at, seed: int = 0) -> list:
    """Render the choice and its grid neighbours (allowed ones); one row per setting with the model's and the
    measured SNR and ΔE, and, for the neighbours, whether they beat the choice beyond noise.

    ``sensor_at(iso, exposure_s)`` gives the :class:`camsim.sensor.params.SensorParams` of a setting.
    """
    from camsim.optimise.model import SensorAtIso, expected_delta_e
    from camsim.render.pipeline import make_frame

    exposures, isos = list(result.exposures_s), result.isos
    i, j = exposures.index(choice.exposure_s), isos.index(choice.iso)
    grid = result.snr_grid[choice.intensity_factor]
    settings = [(i, j)] + [(a, b) for a, b in ((i - 1, j), (i + 1, j), (i, j - 1), (i, j + 1))
                           if 0 <= a < len(exposures) and 0 <= b < len(isos) and np.isfinite(grid[a, b])]
    rows = []
    for n, (a, b) in enumerate(settings):
        sensor = sensor_at(isos[b], float(exposures[a]))
        at_iso = SensorAtIso.of(sensor, isos[b])
        signal = choice.intensity_factor * rates.rates_e_per_s * exposures[a]
        dark = at_iso.dark_current_e_per_s[None, :] * exposures[a]
        variance = sum(noise_terms_e2(signal, dark, at_iso).values())
        model_de = float(np.nanmean(expected_delta_e(signal, variance, rates.reference_lab, rates.to_xyz,
                                                     rates.white_xy)))
        frame = make_frame(lit, sensor, choice.intensity_factor, method="poisson",
                           rng=np.random.SeedSequence([seed, a, b]))
        measured = measure(frame, rates)
        model_snr = float(np.mean(snr_db(signal, dark, at_iso)))
        rows.append({"intensity_factor": choice.intensity_factor, "role": "chosen" if n == 0 else "neighbour",
                     "exposure_s": float(exposures[a]), "iso": isos[b], "model_snr_db": model_snr,
                     "model_delta_e": model_de, **measured,
                     "snr_agrees": bool(abs(measured["snr_db"] - model_snr) <= AGREE_SIGMAS * measured["snr_se"]),
                     "delta_e_agrees": bool(abs(measured["delta_e"] - model_de)
                                            <= AGREE_SIGMAS * measured["delta_e_se"])})
    chosen = rows[0]
    for row in rows[1:]:
        if choice.objective == "delta-e":
            margin = chosen["delta_e"] - row["delta_e"]
            se = np.hypot(chosen["delta_e_se"], row["delta_e_se"])
        else:
            margin = row["snr_db"] - chosen["snr_db"]
            se = np.hypot(chosen["snr_se"], row["snr_se"])
        row["beats_choice"] = bool(margin > BEAT_SIGMAS * se)
    return rows


def three_chip(sensor):
    """The same sensor with R, G and B at every pixel (the model's per-channel moments are a Bayer site's too)."""
    return dataclasses.replace(sensor, cfa=None)
