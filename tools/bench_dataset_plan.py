"""How planning a dataset scales: wall time and peak memory of ``camsim dataset SPEC --dry-run`` (and of
``load_spec``, the frame list a run holds) for specs of 1 000 to 120 000 frames.

The spec: the ColorChecker of ``scenes/macbeth_26.toml`` at 512 × 384, the ``emva-12bit`` sensor, 3 illuminants
× ``count`` random draws of F (log-uniform 1e-3 … 1) and read noise (uniform 1.5 … 6 e⁻), written into a temporary
folder. Each measurement is a fresh process (``python -m camsim dataset SPEC --dry-run``, its output thrown away,
or ``python -c 'load_spec(SPEC)'``): its wall time from start to exit (imports included: about 2 s of it, the
same for every size) and its peak resident memory (``ru_maxrss`` of that child, from ``os.wait4``; about 185 MB
of it is the interpreter, numpy, colour-science and matplotlib).

Run:  python tools/bench_dataset_plan.py [--frames 1000 10000 120000] [--modes dry-run load] [--pythonpath DIR]
``--pythonpath`` benchmarks another checkout of camsim (e.g. an older commit unpacked with ``git archive``).
Progress goes to stderr; the last stdout line is one JSON object.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
ILLUMINANTS = ["D65", "A", "FL2"]

SPEC = """
name = "plan_{frames}"
scene = "{scene}"
seed = 0

[frame]
width = 512
height = 384

[fixed]
preset = "emva-12bit"

[grid]
illuminants = {illuminants}

[random]
count = {count}
intensity_factor = {{ log_uniform = [1e-3, 1.0] }}
read_noise_e = {{ uniform = [1.5, 6.0] }}
"""

LOAD = "import sys; from camsim.dataset.spec import load_spec; print(len(load_spec(sys.argv[1])))"


def write_spec(folder: Path, frames: int) -> Path:
    """A spec of ``frames`` frames (a multiple of 3) in ``folder``; returns its path."""
    path = folder / f"plan_{frames}.toml"
    path.write_text(SPEC.format(frames=frames, scene=(ROOT / "scenes" / "macbeth_26.toml").as_posix(),
                                illuminants=json.dumps(ILLUMINANTS), count=frames // len(ILLUMINANTS)),
                    encoding="utf-8")
    return path


def measure(command: list[str], pythonpath: Path) -> dict:
    """Run ``command`` in ``pythonpath`` (so that ``-m`` and ``-c`` import that camsim), its output discarded;
    returns its wall time and CPU time (s) and its peak resident memory (MB)."""
    env = dict(os.environ, PYTHONPATH=str(pythonpath))
    start = time.perf_counter()
    process = subprocess.Popen(command, cwd=pythonpath, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, usage = os.wait4(process.pid, 0)
    seconds = time.perf_counter() - start
    process.returncode = os.waitstatus_to_exitcode(status)
    error = process.stderr.read().decode(errors="replace")
    process.stderr.close()
    if process.returncode != 0:
        raise SystemExit(f"{' '.join(command)} failed ({process.returncode}):\n{error}")
    return {"seconds": seconds, "cpu_seconds": usage.ru_utime + usage.ru_stime,
            "peak_rss_mb": usage.ru_maxrss / 1024}  # ru_maxrss: kB on Linux


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--frames", type=int, nargs="+", default=[1000, 10000, 120000],
                        help="spec sizes, multiples of 3 (default 1000 10000 120000; rounded down)")
    parser.add_argument("--modes", nargs="+", choices=("dry-run", "load"), default=["dry-run", "load"],
                        help="what to measure (default both)")
    parser.add_argument("--pythonpath", type=Path, default=ROOT,
                        help="the camsim checkout to benchmark (default this one)")
    args = parser.parse_args()
    results = []
    with tempfile.TemporaryDirectory(prefix="camsim-bench-plan-") as tmp:
        for frames in args.frames:
            frames -= frames % len(ILLUMINANTS)
            spec = write_spec(Path(tmp), frames)
            for mode in args.modes:
                command = ([sys.executable, "-m", "camsim", "dataset", str(spec), "--dry-run"] if mode == "dry-run"
                           else [sys.executable, "-c", LOAD, str(spec)])
                result = {"frames": frames, "mode": mode, **measure(command, args.pythonpath.resolve())}
                results.append(result)
                print(f"{mode:<8} {frames:>7} frames: {result['seconds']:7.2f} s wall, {result['cpu_seconds']:7.2f} s "
                      f"CPU, peak RSS {result['peak_rss_mb']:7.1f} MB", file=sys.stderr)
    print(json.dumps({"pythonpath": str(args.pythonpath), "results": results}))


if __name__ == "__main__":
    main()
