"""``camsim emva``: the EMVA 1288 measurement of the simulated camera, analysed by the reference implementation.

:func:`run` simulates the photon-transfer series and the spatial stacks (:mod:`camsim.emva.simulate`) and analyses
them with the ``emva1288`` package; :func:`write_outputs` writes ``emva.json``, ``report.md`` and the plots
(:mod:`camsim.emva.report`).
"""

from camsim.emva.simulate import DEFAULT_PRESET, QUANTITIES, EmvaResult, EmvaSetup, analyse, run, simulate


def write_outputs(result, out):
    """Write ``OUT/emva.json``, ``OUT/report.md`` and the plots (imports matplotlib only when called)."""
    from camsim.emva.report import write_outputs as _write

    return _write(result, out)


__all__ = ["DEFAULT_PRESET", "QUANTITIES", "EmvaResult", "EmvaSetup", "analyse", "run", "simulate", "write_outputs"]
