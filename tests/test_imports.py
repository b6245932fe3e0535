"""Importing camsim does no process-wide plotting work: no module imports matplotlib, and none changes the backend
a program has chosen. Each check runs in a fresh interpreter, since the test session has imported everything."""

import os
import subprocess
import sys
from pathlib import Path

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
    done = subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=env, capture_output=True, text=True,
                          timeout=300)
    assert done.returncode == 0, done.stderr


def test_no_module_imports_matplotlib():
    _run("", 'assert "matplotlib" not in sys.modules, "matplotlib was imported"', skip=(PRELOAD,))


def test_the_backend_a_program_chose_is_kept():
    _run('import matplotlib; matplotlib.use("svg")',
         'assert matplotlib.get_backend() == "svg", f"the backend is now {matplotlib.get_backend()}"')
