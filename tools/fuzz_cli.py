"""The long fuzz run of the ``camsim`` command line (issue 24): mutated scene files, dataset specs, sidecars, preset
files and DNG, EXR, PNG and cube files through the real CLI, with totals per kind and outcome.

The mutators and the runner are :mod:`tests.support.fuzz` (the suite ``tests/cli/test_fuzz.py`` runs a few hundred of
the same cases). The cases are Hypothesis's, drawn from ``--seed``: the same command gives the same cases on any
machine. Each runs in a forked copy of this process with a CPU-time and an address-space limit.

    python tools/fuzz_cli.py --cases 3000 --seed 1 --json /tmp/fuzz.json
    python tools/fuzz_cli.py --cases 200 --seed 2 --kinds sidecar,png -v

Prints a table (cases per kind and outcome: ok = exit 0; refused = exit 2 with one ``camsim: error:`` line; hang =
over --time-limit of CPU time, or as long without any progress; busy = still working after 20 × --time-limit of
wall-clock time, no finding (the machine was too busy to judge); memory = over --memory-limit; crash = killed by a
signal; traceback; outside = a file written, changed or removed outside the output folder; partial = a ``*.partial``
file left; multiline = a failure with more than one stderr line; bad_exit = another exit status, or exit 2 without the
error line), a few examples of each finding, and a JSON line last (also written to --json).
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import tempfile
import time
from collections import Counter, defaultdict
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from hypothesis import HealthCheck, Phase, given, settings  # noqa: E402
from hypothesis import seed as hypothesis_seed  # noqa: E402

from tests.support import fuzz  # noqa: E402

EXAMPLES_PER_FINDING = 3


def run_kind(seeds, kind: str, cases: int, seed: int, work: Path, args, totals, examples, flags) -> None:
    """Run ``cases`` Hypothesis cases of ``kind`` (all its families), adding to the totals."""
    count = [0]

    @hypothesis_seed(seed)
    @settings(max_examples=cases, database=None, deadline=None, phases=[Phase.generate],
              suppress_health_check=list(HealthCheck))
    @given(case=fuzz.case_strategy(seeds, kind))
    def one(case):
        count[0] += 1
        container = work / f"{kind}-{count[0]}"  # the case's folder and whatever escapes beside it
        container.mkdir()
        result = fuzz.run_case(case, container / "case", time_limit=args.time_limit,
                               memory_limit_mb=args.memory_limit)
        shutil.rmtree(container, ignore_errors=True)
        totals[kind][result.outcome] += 1
        totals[kind]["cases"] += 1
        for flag, on in (("traceback", bool(result.traceback)), ("outside", bool(result.outside)),
                         ("partial", bool(result.partial)), ("noisy_success", fuzz.noisy_success(result)),
                         ("multiline", result.rc not in (0, None) and len(result.stderr) > 1)):
            flags[kind][flag] += on
        if result.outcome not in (*fuzz.GOOD, "busy") and len(examples[kind][result.outcome]) < EXAMPLES_PER_FINDING:
            examples[kind][result.outcome].append(f"{case!r} -> {result.summary()}")
        if args.verbose:
            print(f"{kind} {count[0]}: {case!r} -> {result.summary()}", file=sys.stderr, flush=True)

    one()


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--cases", type=int, default=800, help="cases in all, shared evenly by the kinds")
    parser.add_argument("--seed", type=int, default=0, help="Hypothesis seed: the same seed, the same cases")
    parser.add_argument("--kinds", default=",".join(fuzz.KINDS), help=f"comma-separated, of {', '.join(fuzz.KINDS)}")
    parser.add_argument("--time-limit", type=float, default=10.0,
                        help="seconds of CPU time per case (and of no progress at all) before it counts as a hang")
    parser.add_argument("--memory-limit", type=float, default=2048.0,
                        help="MB of address space a case may add (RLIMIT_AS) before it counts as memory")
    parser.add_argument("--json", type=Path, help="also write the totals JSON here")
    parser.add_argument("-v", "--verbose", action="store_true", help="one line per case on stderr")
    args = parser.parse_args(argv)
    kinds = [k.strip() for k in args.kinds.split(",") if k.strip()]
    unknown = sorted(set(kinds) - set(fuzz.KINDS))
    if unknown:
        parser.error(f"unknown kind(s) {', '.join(unknown)}")
    totals = {kind: Counter() for kind in kinds}
    flags = {kind: Counter() for kind in kinds}
    examples = {kind: defaultdict(list) for kind in kinds}
    start = time.monotonic()
    with tempfile.TemporaryDirectory(prefix="camsim-fuzz-") as tmp:
        seeds = fuzz.build_seeds(Path(tmp) / "seeds")
        for i, kind in enumerate(kinds):
            share = args.cases // len(kinds) + (i < args.cases % len(kinds))
            kind_start = time.monotonic()
            run_kind(seeds, kind, share, args.seed, Path(tmp), args, totals, examples, flags)
            print(f"{kind}: {totals[kind]['cases']} cases in {time.monotonic() - kind_start:.0f} s", file=sys.stderr,
                  flush=True)
    columns = ["cases", *fuzz.OUTCOMES]
    print("| kind | " + " | ".join(columns) + " | noisy success |")
    print("|---" * (len(columns) + 2) + "|")
    for kind in kinds:
        cells = " | ".join(str(totals[kind][c]) for c in columns)
        print(f"| {kind} | {cells} | {flags[kind]['noisy_success']} |")
    all_totals = sum(totals.values(), Counter())
    all_flags = sum(flags.values(), Counter())
    print("| all | " + " | ".join(str(all_totals[c]) for c in columns) + f" | {all_flags['noisy_success']} |")
    for kind in kinds:
        for outcome, lines in examples[kind].items():
            for line in lines:
                print(f"{kind} {outcome}: {line[:600]}")
    report = {"seed": args.seed, "cases": args.cases, "kinds": kinds, "time_limit_s": args.time_limit,
              "memory_limit_mb": args.memory_limit, "seconds": round(time.monotonic() - start, 1),
              "totals": {kind: {c: totals[kind][c] for c in columns} for kind in kinds},
              "flags": {kind: dict(flags[kind]) for kind in kinds},
              "all": {c: all_totals[c] for c in columns},
              "examples": {kind: dict(examples[kind]) for kind in kinds}}
    line = json.dumps(report, ensure_ascii=False)
    if args.json:
        args.json.write_text(line + "\n", encoding="utf-8")
    print(line)
    return 0


if __name__ == "__main__":
    sys.exit(main())
