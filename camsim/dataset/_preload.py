"""Imported once by the fork server of the local process pool, so that every worker it forks starts warm:
camsim's frame task and colour-science imported (about 1.2 s that each spawned worker would otherwise spend)."""

import camsim.dataset.task  # noqa: F401
from camsim.spectra import import_colour

import_colour()
