"""W1 render speed of this checkout against another commit, side by side in one run.

For a refactor that must not slow the renderer: checks out ``--base`` (a git ref) into a temporary worktree,
then alternates fresh child processes of the two trees, each of which sets up W1 (``tools/bench_w1.py``'s own
``setup`` and ``render`` of its tree) and times, interleaved, the bare numpy Poisson draws of the frame on 2
threads (the floor) and the render with ``poisson`` and ``auto`` on 2 workers. Prints the medians per tree, each
render against its own floor, and the new/base ratio; the last stdout line is one JSON object. The machine is
shared and noisy: compare the ratios, which are measured in the same processes.

Run:  python tools/bench_compare.py --base HEAD~3 [--rounds 3] [--repeats 3] [--quick]
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

CHILD = r"""
import json, sys, time
from concurrent.futures import ThreadPoolExecutor
tree, width, height, repeats = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4])
sys.path[:0] = [tree, tree + "/tools"]
import numpy as np
import bench_w1
import camsim
assert camsim.__file__.startswith(tree), camsim.__file__
w = bench_w1.setup(width, height)
ex, labels = w["expected"], w["radiance"].labels
lam = np.stack([(ex.signal_e[:, c] + ex.dark_e[c])[labels] for c in range(3)])
def timed(fn, *args):
    t0 = time.perf_counter(); fn(*args); return time.perf_counter() - t0
bench_w1.render(w, "auto", 2)  # warm-up: auto tabulates its KS distances once per process
out = {"floor": [], "poisson": [], "auto": []}
for _ in range(repeats):
    out["floor"].append(timed(bench_w1.floor_draws, lam, 2))
    out["poisson"].append(timed(bench_w1.render, w, "poisson", 2))
    out["auto"].append(timed(bench_w1.render, w, "auto", 2))
print(json.dumps(out))
"""


def run_child(tree: Path, width: int, height: int, repeats: int) -> dict:
    done = subprocess.run([sys.executable, "-c", CHILD, str(tree), str(width), str(height), str(repeats)],
                          capture_output=True, text=True, check=True)
    return json.loads(done.stdout.strip().splitlines()[-1])


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--base", required=True, help="git ref to compare against (e.g. HEAD~3, main)")
    parser.add_argument("--rounds", type=int, default=3, help="child processes per tree, alternated (default 3)")
    parser.add_argument("--repeats", type=int, default=3, help="timings of each kind per child (default 3)")
    parser.add_argument("--quick", action="store_true", help="1000x750 instead of W1's 4000x3000")
    args = parser.parse_args(argv)
    width, height = (1000, 750) if args.quick else (4000, 3000)
    with tempfile.TemporaryDirectory(prefix="bench_compare_") as tmp:
        base = Path(tmp) / "base"
        subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "--detach", "-q", str(base), args.base], check=True)
        try:
            times = {"base": {"floor": [], "poisson": [], "auto": []}, "new": {"floor": [], "poisson": [], "auto": []}}
            for r in range(args.rounds):
                for label, tree in (("base", base), ("new", ROOT)):
                    print(f"[bench_compare] round {r + 1}/{args.rounds}: {label}", file=sys.stderr, flush=True)
                    for key, values in run_child(tree, width, height, args.repeats).items():
                        times[label][key].extend(values)
        finally:
            subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(base)], check=False)
    med = {t: {k: statistics.median(v) for k, v in times[t].items()} for t in times}
    best = {t: {k: min(v) for k, v in times[t].items()} for t in times}
    result = {"size": f"{width}x{height}", "base": args.base}
    print(f"W1 {width}x{height}, 2 threads, medians of {args.rounds * args.repeats} timings per tree")
    print(f"{'':10}{'floor s':>10}{'poisson s':>11}{'auto s':>9}{'poisson/floor':>15}{'auto/floor':>12}")
    for tree in ("base", "new"):
        m = med[tree]
        print(f"{tree:10}{m['floor']:10.3f}{m['poisson']:11.3f}{m['auto']:9.3f}"
              f"{m['poisson'] / m['floor']:15.3f}{m['auto'] / m['floor']:12.3f}")
        for key in ("floor", "poisson", "auto"):
            result[f"{tree}_{key}_2t_s"] = m[key]
        result[f"{tree}_poisson_over_floor"] = m["poisson"] / m["floor"]
        result[f"{tree}_auto_over_floor"] = m["auto"] / m["floor"]
    for key in ("poisson", "auto"):
        ratio = result[f"new_{key}_over_floor"] / result[f"base_{key}_over_floor"]
        result[f"{key}_new_over_base"] = ratio
        fastest = (best["new"][key] / best["new"]["floor"]) / (best["base"][key] / best["base"]["floor"])
        result[f"{key}_new_over_base_fastest"] = fastest
        print(f"{key}: new/base (each against its own floor) = {ratio:.3f} with medians, {fastest:.3f} with the "
              "fastest timings")
    print(json.dumps(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())
