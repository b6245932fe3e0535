"""Frame-level scores of a denoised (or noisy) frame against the clean layer: PSNR and SSIM (scikit-image)."""

from __future__ import annotations

import numpy as np

from camsim.core.optional_numbers import finite_or_none

SSIM_MIN_SIDE = 7  # scikit-image's default SSIM window


def image_scores(clean: np.ndarray, test: np.ndarray, data_range: float) -> tuple[float | None, float | None]:
    """PSNR (dB) and SSIM of ``test`` against ``clean``, both (H, W, 3); None where undefined.

    PSNR is undefined (infinite) for a perfect result; SSIM for frames smaller than its 7 × 7 window.
    """
    from skimage.metrics import mean_squared_error, peak_signal_noise_ratio, structural_similarity

    clean = clean.astype(np.float64)
    test = test.astype(np.float64)
    psnr = None
    if mean_squared_error(clean, test) > 0:
        psnr = finite_or_none(peak_signal_noise_ratio(clean, test, data_range=data_range))
    ssim = None
    if min(clean.shape[:2]) >= SSIM_MIN_SIDE:
        ssim = finite_or_none(structural_similarity(clean, test, data_range=data_range, channel_axis=-1))
    return psnr, ssim
