"""Importing camsim does no process-wide plotting work: no module imports matplotlib, and none changes the backend
a program has chosen. Each check runs in a fresh interpreter, since the test session has imported everything."""

import json
import os
import sys
from pathlib import Path

import pytest

from tests.support import clock

ROOT = Path(__file__).resolve().parents[1]

#: Imports camsim's modules (all but ``camsim.__main__``, which runs the command line), then runs CHECK.
IMPORT_ALL = """
import importlib, pkgutil, sys
SETUP
import camsim
names = [m.name for m in pkgutil.walk_packages(camsim.__path__, "camsim.")
         if m.name != "camsim.__main__" and m.name not in SKIP]
assert len(names) > 40, names
for name in names:
    importlib.import_module(name)
CHECK
"""

#: Imported by the dataset pool's fork server to import colour-science ahead of the workers; colour-science
#: imports matplotlib.pyplot (and resolves matplotlib's default backend) when it is imported.
PRELOAD = "camsim.dataset._preload"


def _run(setup: str, check: str, skip: tuple = ()) -> None:
    code = IMPORT_ALL.replace("SETUP", setup).replace("CHECK", check).replace("SKIP", repr(skip))
    env = {k: v for k, v in os.environ.items() if k != "MPLBACKEND"}
    done = clock.run([sys.executable, "-c", code], cpu_s=120, cwd=ROOT, env=env, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr


def test_no_module_imports_matplotlib():
    _run("", 'assert "matplotlib" not in sys.modules, "matplotlib was imported"', skip=(PRELOAD,))


@pytest.mark.slow
def test_the_backend_a_program_chose_is_kept():
    _run('import matplotlib; matplotlib.use("svg")',
         'assert matplotlib.get_backend() == "svg", f"the backend is now {matplotlib.get_backend()}"')


#: Modules that take a noticeable time to import (tens of ms to half a second each): the command line's start-up
#: (``--version``, ``--help``, ``list``, any sub-command's ``--help``) imports none of them (issue 23, point 9;
#: ``tools/bench_startup.py`` times it).
HEAVY = ("scipy", "colour", "colour_demosaicing", "OpenEXR", "OpenImageIO", "rawpy", "skimage", "matplotlib",
         "dask", "distributed", "zarr", "xarray", "tifffile", "imageio", "PIL", "pywt", "bm3d", "emva1288", "tqdm",
         "torch", "cupy", "numba", "llvmlite")

#: Runs ``camsim ARGS`` through its entry point in this interpreter, then prints the heavy modules it imported.
RUN_CLI = """
import json, sys
from camsim.cli import main
try:
    status = main(ARGS)
except SystemExit as exc:  # --version and --help exit through argparse
    status = exc.code
print(json.dumps({"status": status, "heavy": sorted(m for m in HEAVY if m in sys.modules)}), file=sys.stderr)
"""


def _heavy_imported(args: list[str]) -> tuple[int, list[str]]:
    code = RUN_CLI.replace("ARGS", repr(args)).replace("HEAVY", repr(HEAVY))
    done = clock.run([sys.executable, "-c", code], cpu_s=60, cwd=ROOT, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    report = json.loads(done.stderr.strip().splitlines()[-1])
    return report["status"], report["heavy"]


@pytest.mark.parametrize("args", [["--version"], ["--help"], ["list"]]
                         + [[name, "--help"] for name in ("render", "analyze", "experiment", "emva", "calibrate",
                                                          "optimise", "dataset", "denoise-eval")])
def test_the_command_line_starts_without_the_heavy_modules(args):
    status, heavy = _heavy_imported(args)
    assert status in (0, None), status
    assert heavy == [], f"camsim {' '.join(args)} imported {heavy}"


@pytest.mark.slow
def test_a_command_that_works_imports_them(tmp_path):
    """The check above sees the imports when they happen: a render needs colour-science, scipy and OpenEXR."""
    status, heavy = _heavy_imported(["render", "macbeth_26", "--size", "24x24", "-F", "1", "--illuminant", "D65",
                                     "-q", "--out", str(tmp_path)])
    assert status == 0
    assert {"colour", "scipy", "OpenEXR"} <= set(heavy)


def test_the_names_camsim_list_prints_are_colour_sciences():
    """``camsim list`` prints colour-science's names from a static copy (camsim.colour.colour_names); they are the names
    the installed colour-science ships, which a scene's ``illuminants``, ``camera`` and ``reflectances`` accept."""
    from camsim.colour import colour_names
    from camsim.light.spectra import camera_names, illuminant_names, reflectance_set_names

    assert list(colour_names.ILLUMINANTS) == illuminant_names()
    assert list(colour_names.CAMERAS) == camera_names()
    assert list(colour_names.REFLECTANCE_SETS) == reflectance_set_names()
    done = clock.run([sys.executable, "-m", "camsim", "list"], cpu_s=60, cwd=ROOT, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    lines = dict(line.split(": ", 1) for line in done.stdout.splitlines() if line.startswith(("illuminants",
                                                                                              "cameras")))
    assert lines["illuminants"].split(", ") == illuminant_names()
    assert lines["cameras"].split(", ") == camera_names()
