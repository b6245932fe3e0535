"""``tools/bench_gpu.py`` runs without a GPU: one JSON line, device "none", the GPU keys null, the CPU figures filled,
exit 0 (with a GPU, every key filled)."""

import json
import sys

import pytest

from tests.support import clock
from tests.support.helpers import ROOT


@pytest.mark.slow
def test_bench_gpu_quick_prints_its_json_line():
    done = clock.run([sys.executable, str(ROOT / "tools" / "bench_gpu.py"), "--quick"], cpu_s=120, cwd=ROOT,
                     capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    result = json.loads(done.stdout.strip().splitlines()[-1])
    gpu = ("w1_render_s", "w1_transfer_s", "pairs_per_s_512", "poisson_chi2_p_min")
    for key in ("cpu_w1_generic_s", "cpu_w1_fast_s", "cpu_pairs_per_s_512", "cpu_poisson_chi2_p_min"):
        assert result[key] > 0, key
    assert result["cpu_poisson_chi2_p_min"] > 1e-4
    if result["device"] == "none":
        assert all(result[key] is None for key in gpu) and set(result["met"].values()) == {None}
    else:
        assert all(result[key] is not None for key in gpu)
