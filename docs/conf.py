"""Sphinx configuration of camsim's documentation (``make docs`` builds it into ``docs/_build/html/``).

Pages are Markdown (MyST). The reference pages (commands, scene-file and dataset-spec keys, sidecar keys) are
generated from the code by the directives of ``docs/_ext/camsim_reference.py``; the API reference by autosummary
from ``camsim.__all__``; the gallery by sphinx-gallery, which runs every ``docs/examples/plot_*.py`` at build time.
No extension reaches the network (no intersphinx): the build runs offline, in CI.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

DOCS = Path(__file__).resolve().parent
ROOT = DOCS.parent
# The checkout's camsim, whatever the environment has installed: the docs describe the code beside them.
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(DOCS / "_ext"))
os.environ.setdefault("MPLBACKEND", "Agg")  # no display in CI; the gallery's figures are files

import camsim  # noqa: E402

project = "camsim"
author = "the camsim authors"
copyright = "camsim authors, MIT licence"
release = camsim.__version__
version = ".".join(release.split(".")[:2])

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.mathjax",
    "numpydoc",
    "sphinx_gallery.gen_gallery",
    "camsim_reference",
]

source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
root_doc = "index"
# _build: the output; examples/: sphinx-gallery reads the scripts and writes auto_examples/ (which it adds itself)
exclude_patterns = ["_build", "examples", "**.ipynb_checkpoints", "Thumbs.db", ".DS_Store"]
templates_path = []

# --- MyST (Markdown pages) -----------------------------------------------------------------------------------------
myst_enable_extensions = ["colon_fence", "dollarmath", "amsmath", "deflist"]
myst_heading_anchors = 3  # page.md#a-heading links resolve to headings down to level 3
myst_dmath_double_inline = True

# --- API reference: autosummary + autodoc + numpydoc ---------------------------------------------------------------
autosummary_generate = True  # stub pages of reference/api.md's names into reference/generated/ (not committed)
autosummary_imported_members = False
autodoc_default_options = {"members": False, "no-value": True}  # a preset table's repr is pages long
autodoc_typehints = "none"  # numpydoc's "Parameters" sections say the types; signatures stay short
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_xref_param_type = False
numpydoc_validation_checks: set = set()

# --- The gallery ---------------------------------------------------------------------------------------------------
sphinx_gallery_conf = {
    "examples_dirs": "examples",
    "gallery_dirs": "auto_examples",
    "filename_pattern": r"/plot_",  # every plot_*.py is executed at build time
    "ignore_pattern": r"__init__\.py",
    "image_scrapers": ("matplotlib",),
    "matplotlib_animations": False,
    "abort_on_example_error": True,
    "only_warn_on_example_error": False,
    "download_all_examples": False,
    "remove_config_comments": True,
    "within_subsection_order": "FileNameSortKey",
    "backreferences_dir": None,
    "plot_gallery": "True",
    "show_memory": False,
}

# Text as written: no "smart" quotes or dashes (an option's --name must stay two hyphens)
smartquotes = False

# --- HTML ----------------------------------------------------------------------------------------------------------
html_theme = "pydata_sphinx_theme"
html_title = f"camsim {release}"
html_static_path = []
html_show_sourcelink = False
html_theme_options = {
    "navigation_with_keys": False,
    "show_toc_level": 2,
    "secondary_sidebar_items": ["page-toc"],
    "footer_start": ["copyright"],
    "footer_end": ["sphinx-version"],
}
html_context = {"default_mode": "light"}

# Warnings are errors (make docs: sphinx-build -W --keep-going); nothing is silenced here.
nitpicky = False
