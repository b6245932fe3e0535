"""Start-up time of the ``camsim`` command line against a bare ``python -c "import numpy"`` (issue 23, point 9).

Each command runs in a fresh interpreter (``python -m camsim ...``, as the ``camsim`` script does, with this
checkout first on ``PYTHONPATH``), ``--repeats`` times, the commands interleaved round by round so that a change
in the machine's load reaches them alike; the figure of a command is its best (smallest) wall time, in seconds,
which is the least disturbed by other work on the machine. The differences are each command's best minus the
best of ``python -c "import numpy"`` (camsim cannot start without numpy); the target is 0.3 s for
``--version``, ``--help`` and ``list``.

``--base DIR`` also times another checkout (e.g. ``git worktree add /tmp/base REF``) in the same rounds.

Keys of the JSON line (the last stdout line): ``repeats``; ``best_s`` (command -> best seconds) and ``diff_s``
(command -> best minus numpy's), for this checkout and, with ``--base``, ``base_best_s`` and ``base_diff_s``;
``target_s`` (0.3) and ``met`` (whether ``--version``, ``--help`` and ``list`` are within it).

Run:  python tools/bench_startup.py [--repeats N] [--base DIR]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
NUMPY = "import numpy"
#: The timed commands: a label and the arguments after ``python``.
COMMANDS = {
    NUMPY: ["-c", "import numpy"],
    "camsim --version": ["-m", "camsim", "--version"],
    "camsim --help": ["-m", "camsim", "--help"],
    "camsim render --help": ["-m", "camsim", "render", "--help"],
    "camsim list": ["-m", "camsim", "list"],
}
#: The commands the target applies to, and the target (s above numpy's import).
TARGETED, TARGET_S = ("camsim --version", "camsim --help", "camsim list"), 0.3


def run_once(args: list[str], root: Path) -> float:
    """Wall time of ``python ARGS`` in a fresh interpreter, ``root`` first on the path. Unit: s."""
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(root), *filter(None, [os.environ.get("PYTHONPATH")])]))
    start = time.perf_counter()
    done = subprocess.run([sys.executable, *args], cwd=root, env=env, stdout=subprocess.DEVNULL,
                          stderr=subprocess.PIPE, text=True)
    elapsed = time.perf_counter() - start
    if done.returncode != 0:
        raise SystemExit(f"bench_startup: python {' '.join(args)} failed ({done.returncode}): {done.stderr.strip()}")
    return elapsed


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", type=int, default=10, help="runs of each command (default 10)")
    parser.add_argument("--base", type=Path, help="another checkout to time in the same rounds")
    args = parser.parse_args(argv)
    roots = {"this": ROOT} | ({"base": args.base.resolve()} if args.base else {})
    times = {(where, label): [] for where in roots for label in COMMANDS}
    for _ in range(args.repeats):
        for where, root in roots.items():
            for label, command in COMMANDS.items():
                times[where, label].append(run_once(command, root))
    result = {"repeats": args.repeats}
    for where in roots:
        best = {label: min(times[where, label]) for label in COMMANDS}
        diff = {label: best[label] - best[NUMPY] for label in COMMANDS if label != NUMPY}
        prefix = "" if where == "this" else "base_"
        result[f"{prefix}best_s"] = {k: round(v, 4) for k, v in best.items()}
        result[f"{prefix}diff_s"] = {k: round(v, 4) for k, v in diff.items()}
        print(f"{where} ({roots[where]}), best of {args.repeats}:")
        for label in COMMANDS:
            extra = "" if label == NUMPY else f"   {diff[label]:+.3f} s against numpy"
            print(f"  {label:24s} {best[label]:7.3f} s{extra}")
    result["target_s"] = TARGET_S
    result["met"] = all(result["diff_s"][label] <= TARGET_S for label in TARGETED)
    print(json.dumps(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())
