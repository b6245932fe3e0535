"""``camsim calibrate``: a camera's noise parameters from its raw dark frames and flat-field pairs, as a preset.

* :mod:`~camsim.calibration.rawfiles` reads raw files through LibRaw and splits them into planes (CFA sites, or
  the colours of a stack);
* :mod:`~camsim.calibration.dark` — black level, dark temporal variance, read noise (Sheppard), row noise, DSNU;
* :mod:`~camsim.calibration.ptc` — the photon transfer fit of K, and the PRNU;
* :mod:`~camsim.calibration.tukey` — the Tukey λ of the read noise by the PPCC (ELD), matched to the law of the
  samples;
* :mod:`~camsim.calibration.fixed_pattern` — the dark-shading map, hot pixels, column FPN, the black-level error;
* :mod:`~camsim.calibration.flats` — pairing flats by level, refusing unusable ones;
* :mod:`~camsim.calibration.measure` — :func:`calibrate`, which runs them all over the files;
* :mod:`~camsim.calibration.outputs` — ``preset.toml``, ``calibration.json``, ``report.md`` and the plots.
"""

from camsim.calibration.measure import Calibration, calibrate


def write_outputs(calibration, out, maps: bool = True):
    """Write the preset, the JSON record, the report, the plots and the maps into ``out`` (matplotlib imported only
    now); ``maps``: whether the preset names the maps."""
    from camsim.calibration.outputs import write_outputs as _write

    return _write(calibration, out, maps)


__all__ = ["Calibration", "calibrate", "write_outputs"]
