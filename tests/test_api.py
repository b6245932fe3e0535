"""The public API: ``import camsim`` is light, its objects are the modules' own, and the docs' example runs."""

import contextlib
import io
import re
import subprocess
import sys

import numpy as np

import camsim
from tests.support.helpers import ROOT


def test_import_camsim_loads_nothing_heavy():
    code = ("import sys, camsim; print(sorted(m for m in ('numpy', 'colour', 'scipy', 'matplotlib') "
            "if m in sys.modules))")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=ROOT)
    assert done.stdout.strip() == "[]"


def test_exports_are_the_implementations():
    from camsim.analysis.analyze import analyse_paths
    from camsim.render.frame_files import load_frame, write_frame
    from camsim.render.pipeline import scene_frame
    from camsim.scene.scene_file import load_scene

    assert camsim.load_scene is load_scene and camsim.scene_frame is scene_frame
    assert camsim.write_frame is write_frame and camsim.load_frame is load_frame
    assert camsim.analyse_paths is analyse_paths
    assert set(camsim.__all__) >= {"load_scene", "scene_frame", "render_scene", "write_frame", "load_frame",
                                   "analyse_paths", "SensorParams", "PRESETS", "METHODS", "__version__"}
    for name in camsim.__all__:
        assert getattr(camsim, name) is not None


def test_readme_python_example_runs(tmp_path, monkeypatch):
    """The Python API example of the docs' getting-started page (the first python block of "The Python API")."""
    text = (ROOT / "docs" / "getting-started.md").read_text(encoding="utf-8")
    section = text[text.index("## The Python API"):]
    code = re.search(r"```python\n(.*?)```", section, re.S).group(1)
    monkeypatch.chdir(tmp_path)
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        exec(compile(code, "docs/getting-started.md", "exec"), {})
    lines = out.getvalue().splitlines()
    assert lines[0] == "(3, 160, 240) uint8"
    assert lines[1] == "float32 (3, 160, 240)"
    assert lines[2] == "['dng', 'exr', 'json', 'xmp']"  # xmp: darktable's sidecar of the three-chip DNG
    assert lines[3].startswith("white 9.5")
    # the white patch reflects ~88 %: at F = 0.1 the strongest channel (G) holds ~0.088 of the 8000 e⁻ anchor
    green_e = eval(lines[3][lines[3].index("["):])[1]
    assert 0.085 * 8000 < green_e < 0.092 * 8000
    mean_dn, snr = map(float, lines[4].split())
    # Table I with σ_read = 2 e⁻: power SNR = S² / (S + D + σ_read² + (1 / k)² / 12), D = 230 e⁻, k = 0.028334 DN/e⁻
    k = 0.0002 * 141.67
    assert np.isclose(snr, green_e**2 / (green_e + 230 + 2.0**2 + 1 / k**2 / 12), rtol=0.1)
    assert np.isclose(mean_dn, k * (green_e + 230) - 0.5, atol=0.5)  # Eq. 11's floor lowers the mean by ½ DN
    assert (tmp_path / "api_demo" / "d65_f0.1.dng").is_file()
