"""Imported once by the fork server of the local process pool (and by nothing else).

It binds the fork server's life to the main process's (Linux: killed when the main process dies, so that its
workers, bound to it, die too; :func:`camsim.dataset._pool.bind_to_parent`), and imports camsim's frame task and
colour-science, so that every worker it forks starts warm (about 1.2 s that each spawned worker would otherwise
spend)."""

from camsim.dataset._pool import bind_to_parent

bind_to_parent()  # first: before the imports, which take a second or two

import camsim.dataset.task  # noqa: E402, F401
from camsim.light.spectra import import_colour  # noqa: E402

import_colour()
