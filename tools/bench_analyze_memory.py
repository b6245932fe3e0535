"""Peak memory and wall time of ``camsim analyze`` against the number of frames, from DNG and from EXR.

The frames: the ColorChecker of ``scenes/macbeth_26.toml`` (default sensor, method ``poisson``, D65) at
``--size`` (default 4000 × 3000 = 12 MP), ``max(--counts)`` distinct intensity factors (F = 1, 0.9, 0.81, …,
0.9^(n−1): the first n frames are the same whatever the largest count), rendered once into a cache folder (``--cache``,
default under /tmp) and reused by later runs. A 12 MP frame takes about 36 MB as DNG and 150 MB as EXR. For each count
n, a folder of hard links to the first n frames' files (DNG, EXR, sidecar) is analysed.

Each case runs ``python -m camsim analyze FOLDER [--source exr] -q`` in a fresh process, started by a small
wrapper process that reports the child's peak resident set size (``resource.getrusage(RUSAGE_CHILDREN)``,
``ru_maxrss``) and the wall time. The ``imports`` row is the same wrapper around a process that only imports
the analysis (the floor every case pays).

Run:  python tools/bench_analyze_memory.py [--counts 1 10 50] [--size 4000x3000] [--sources dng exr] [--json]
      [--repo PATH]   (the camsim source tree to measure, e.g. an older checkout; default this one)
Progress goes to stderr; the table (or with ``--json`` one JSON object) to stdout.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
FRAME_KINDS = (".dng", ".exr", ".json")
#: Bytes a frame of one pixel takes on disk, roughly (3 uint8 in the DNG; 6 float32 in the ZIP'ed EXR).
BYTES_PER_PIXEL = 16

# The wrapper: runs argv[1:] as a child and prints its peak RSS (KiB, as Linux reports ru_maxrss) and wall time.
WRAPPER = """
import json, resource, subprocess, sys, time
start = time.perf_counter()
rc = subprocess.run(sys.argv[1:], stdout=subprocess.DEVNULL).returncode
wall = time.perf_counter() - start
print(json.dumps({"rc": rc, "maxrss_kib": resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss, "wall_s": wall}))
"""


def parse_size(text: str) -> tuple[int, int]:
    """``'4000x3000'`` → (4000, 3000): width and height in pixels."""
    try:
        width, height = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"size must be WIDTHxHEIGHT, got {text!r}") from None
    return width, height


def factors(n: int) -> list[float]:
    """``n`` distinct intensity factors 0.9^i, i = 0 … n − 1, to 4 significant digits (unitless)."""
    return [float(f"{0.9**i:.4g}") for i in range(n)]


def env_for(repo: Path) -> dict:
    """The environment of a child: ``PYTHONPATH`` = the camsim source tree measured.

    Children also run in ``repo``: ``python -m`` puts the working folder first on ``sys.path``, so that another
    working folder holding a camsim tree would be imported instead.
    """
    return {**os.environ, "PYTHONPATH": str(repo)}


def render_cache(cache: Path, n: int, size: tuple[int, int], repo: Path) -> list[str]:
    """Render ``n`` frames into ``cache/all`` unless already there; returns their stems, F = 1 first."""
    stems = [f"macbeth_26_D65_F{f:g}" for f in factors(n)]
    frames = cache / "all"
    missing = [f for f, stem in zip(factors(n), stems)
               if not all((frames / f"{stem}{kind}").is_file() for kind in FRAME_KINDS)]
    if missing:
        need = len(missing) * size[0] * size[1] * BYTES_PER_PIXEL
        free = shutil.disk_usage(cache).free
        if need > 0.8 * free:
            sys.exit(f"bench_analyze_memory: {len(missing)} frames need about {need / 1e9:.1f} GB, "
                     f"{free / 1e9:.1f} GB free under {cache}: use fewer --counts or a smaller --size")
        print(f"rendering {len(missing)} frame(s) of {size[0]}x{size[1]} into {frames} ...", file=sys.stderr)
        subprocess.run([sys.executable, "-m", "camsim", "render", "macbeth_26", "--size", f"{size[0]}x{size[1]}",
                        "--illuminant", "D65", "--intensity", *map(str, missing), "--out", str(frames), "--quiet"],
                       check=True, env=env_for(ROOT), cwd=ROOT, stdout=sys.stderr)
    return stems


def folder_of(cache: Path, stems: list[str]) -> Path:
    """A folder of hard links to the frames ``stems`` (made once): what one case analyses."""
    folder = cache / f"n{len(stems)}"
    if not folder.is_dir():
        tmp = Path(tempfile.mkdtemp(prefix=".tmp-", dir=cache))
        for stem in stems:
            for kind in FRAME_KINDS:
                os.link(cache / "all" / f"{stem}{kind}", tmp / f"{stem}{kind}")
        tmp.rename(folder)
    return folder


def measure(command: list[str], repo: Path) -> dict:
    """Peak RSS (MiB) and wall time (s) of ``command`` run in a fresh process."""
    out = subprocess.run([sys.executable, "-c", WRAPPER, *command], capture_output=True, text=True, check=True,
                         env=env_for(repo), cwd=repo)
    result = json.loads(out.stdout.strip().splitlines()[-1])
    return {"rc": result["rc"], "peak_rss_mib": result["maxrss_kib"] / 1024, "wall_s": result["wall_s"]}


def imported_from(repo: Path) -> str:
    """The camsim package a child imports (a check that ``--repo`` is the tree measured)."""
    out = subprocess.run([sys.executable, "-c", "import camsim; print(camsim.__file__)"], capture_output=True,
                         text=True, check=True, env=env_for(repo), cwd=repo)
    return str(Path(out.stdout.strip()).parent)


def run_cases(args) -> list[dict]:
    """Every (source, count) case, plus the imports-only floor."""
    cache = args.cache or Path(tempfile.gettempdir()) / f"camsim-bench-analyze-{args.size[0]}x{args.size[1]}"
    cache.mkdir(parents=True, exist_ok=True)
    stems = render_cache(cache, max(args.counts), args.size, args.repo)
    rows = [{"case": "imports", "source": "-", "frames": 0,
             **measure([sys.executable, "-c", "import camsim.analysis.analyze"], args.repo)}]
    for source in args.sources:
        for n in args.counts:
            folder = folder_of(cache, stems[:n])
            with tempfile.TemporaryDirectory(prefix="camsim-bench-out-") as out:
                command = [sys.executable, "-m", "camsim", "analyze", str(folder), "--source", source, "--out", out,
                           "-q"]
                print(f"analysing {n} frame(s) from {source} ...", file=sys.stderr)
                rows.append({"case": f"{source} x{n}", "source": source, "frames": n, **measure(command, args.repo)})
    return rows


def table(rows: list[dict], size: tuple[int, int]) -> str:
    """The rows as a text table."""
    lines = [f"camsim analyze, {size[0]}x{size[1]} frames ({size[0] * size[1] / 1e6:.1f} MP)",
             f"{'case':10s} {'frames':>6s} {'peak RSS MiB':>12s} {'wall s':>8s} {'s/frame':>8s} rc"]
    for r in rows:
        per = f"{r['wall_s'] / r['frames']:8.2f}" if r["frames"] else f"{'':8s}"
        lines.append(f"{r['case']:10s} {r['frames']:6d} {r['peak_rss_mib']:12.0f} {r['wall_s']:8.1f} {per} {r['rc']}")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--counts", type=int, nargs="+", default=[1, 10, 50], help="frame counts (default 1 10 50)")
    parser.add_argument("--size", type=parse_size, default=(4000, 3000), help="WxH in pixels (default 4000x3000)")
    parser.add_argument("--sources", nargs="+", choices=("dng", "exr"), default=["dng", "exr"],
                        help="which file of each frame to analyse (default both)")
    parser.add_argument("--cache", type=Path, help="folder of the rendered frames (default under /tmp, reused)")
    parser.add_argument("--repo", type=lambda p: Path(p).resolve(), default=ROOT,
                        help="camsim source tree to measure (default this one)")
    parser.add_argument("--json", action="store_true", help="print one JSON object instead of the table")
    args = parser.parse_args()
    if min(args.counts) < 1:
        parser.error("--counts must be positive")
    package = imported_from(args.repo)
    print(f"measuring camsim from {package}", file=sys.stderr)
    rows = run_cases(args)
    if args.json:
        print(json.dumps({"size": list(args.size), "camsim": package, "rows": rows}))
    else:
        print(f"camsim from {package}\n{table(rows, args.size)}")


if __name__ == "__main__":
    main()
