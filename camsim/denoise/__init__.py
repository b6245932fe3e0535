"""``camsim denoise-eval``: run denoisers on rendered frames and score them against the clean layer.

* :mod:`camsim.denoise.denoisers` — the built-in baselines (:data:`DENOISERS`, BM3D among them) and user targets
  (``MODULE:FUNCTION``, ``cmd:PROGRAM ... {input} {output}``);
* :mod:`camsim.denoise.frames` — the scorable frames of a dataset (camsim EXR with a clean layer, three-chip or
  Bayer);
* :mod:`camsim.denoise.bayer` — a Bayer frame's denoiser input (normalised packed R, G1, G2, B planes, or the
  mosaic) and its scores in the raw domain (per plane) and after the ISP (:mod:`camsim.isp`);
* :mod:`camsim.denoise.image_scores` — PSNR / SSIM of a frame against its clean layer;
* :mod:`camsim.denoise.patch_colour` — the colour quantities per patch (bias, noise ellipse, ΔE against F = 1);
* :mod:`camsim.denoise.colour_fidelity` — chart-free colour: mean ΔE00 of every pixel against the clean layer;
* :mod:`camsim.denoise.summary` — means per light level and per band of F, the criteria and the verdicts;
* :mod:`camsim.denoise.evaluate` — the loop: every denoiser on every frame, scored;
* :mod:`camsim.denoise.report` — CSV, plots, ``report.md`` and ``summary.json``;
* the sub-command itself is :mod:`camsim.cli.commands.denoise_eval`.
"""

from camsim.denoise.denoisers import DENOISERS, Denoiser, estimate_noise_sigma, resolve_denoiser
from camsim.denoise.evaluate import EvalSettings, Evaluation, evaluate
from camsim.denoise.summary import Criterion

__all__ = ["DENOISERS", "Denoiser", "estimate_noise_sigma", "resolve_denoiser", "Criterion", "EvalSettings",
           "Evaluation", "evaluate", "write_outputs"]


def write_outputs(evaluation, out_dir):
    """Write the CSV tables, plots, report.md and summary.json (see :mod:`camsim.denoise.report`)."""
    from camsim.denoise.report import write_outputs as _write

    return _write(evaluation, out_dir)
