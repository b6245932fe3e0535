"""``camsim optimise``: the exposure time and ISO that measure colour best at each light level (the paper's future
work), searched from the model's closed-form moments and checked by rendering.

* :mod:`camsim.optimise.model` — the moments: SNR (Eqs. 13–14), E[ΔE], the saturation constraint;
* :mod:`camsim.optimise.search` — the grid search per light level;
* :mod:`camsim.optimise.verify` — frames at the chosen and neighbouring settings;
* :mod:`camsim.optimise.report` — tables, maps and ``report.md``.
"""
