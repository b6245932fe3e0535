"""The long fuzz run of the ``camsim`` command line: mutated scene files, dataset specs, sidecars, preset files and
DNG, EXR, PNG, TIFF and cube files, and special files where they are read, through the real CLI, with totals per
kind and family of mutation and per outcome.

The mutators and the runner are :mod:`tests.support.fuzz` (the suite ``tests/cli/test_fuzz.py`` runs a few hundred of
the same cases). The cases are Hypothesis's, drawn from ``--seed``: the same command gives the same cases on any
machine. Each runs in a forked copy of this process with a CPU-time and an address-space limit.

    python tools/fuzz_cli.py --cases 3000 --seed 1 --json /tmp/fuzz.json
    python tools/fuzz_cli.py --cases 200 --seed 2 --kinds sidecar,png -v
    python tools/fuzz_cli.py --cases 300 --seed 1 --families special,controls,numbers,lists,oversize,headers

``--kinds`` and ``--families`` (:data:`tests.support.fuzz.FAMILIES`) pick the (kind, family) pairs that run; the
cases are shared evenly by them. The families of the second round of hostile inputs
(:data:`tests.support.fuzz.SECOND_ROUND`): ``special`` (a FIFO, ``/dev/zero``, ``/dev/null``, a folder, a socket, a
link to itself or an 8 GiB sparse file at each path camsim reads), ``controls`` (NUL and control characters in each
string that becomes a path), ``numbers`` (±1e300, ±1e-300, 5e-324, ±1.7976931348623157e308 in every number),
``lists`` (a sidecar's lists × 10⁵, or millions of entries), ``oversize`` (a sidecar over 64 MB), ``headers``
(headers that declare 10⁸ to 10¹⁰ pixels).

Prints a table (cases per kind/family, per family and in all, and per outcome: ok = exit 0; refused = exit 2 with
one ``camsim: error:`` line; hang = over --time-limit of CPU time, or as long without any progress (a case blocked
opening a FIFO); busy = still working after 20 × --time-limit of wall-clock time, no finding (the machine was too busy
to judge); memory = over --memory-limit; crash = killed by a signal; traceback; outside = a file written, changed or
removed outside the output folder; partial = a ``*.partial`` file left; multiline = a failure with more than one
stderr line; bad_exit = another exit status, or exit 2 without the error line), a few examples of each finding, and
a JSON line last (also written to --json). Every case should be ok or refused. Two more columns count cases that
are no finding by outcome: noisy success (exit 0 with a library's lines on stderr) and control in stderr (a control
character written as it is, such as an ESC that a terminal obeys, which the line count does not see).
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
#: Every family of mutation, in the order :data:`tests.support.fuzz.FAMILIES` first names them.
ALL_FAMILIES = tuple(dict.fromkeys(family for kind in fuzz.KINDS for family in fuzz.FAMILIES[kind]))


def run_pair(seeds, kind: str, family: str, cases: int, seed: int, work: Path, args, totals, examples,
             flags) -> None:
    """Run ``cases`` Hypothesis cases of ``kind`` and ``family``, adding to the totals under ``kind/family``."""
    count = [0]
    pair = f"{kind}/{family}"

    @hypothesis_seed(seed)
    @settings(max_examples=cases, database=None, deadline=None, phases=[Phase.generate],
              suppress_health_check=list(HealthCheck))
    @given(case=fuzz.case_strategy(seeds, kind, family))
    def one(case):
        count[0] += 1
        container = work / f"{kind}-{family}-{count[0]}"  # the case's folder and whatever escapes beside it
        container.mkdir()
        result = fuzz.run_case(case, container / "case", time_limit=args.time_limit,
                               memory_limit_mb=args.memory_limit)
        shutil.rmtree(container, ignore_errors=True)  # a 65 MB sidecar goes at once: the disk holds one case's
        totals[pair][result.outcome] += 1
        totals[pair]["cases"] += 1
        for flag, on in (("traceback", bool(result.traceback)), ("outside", bool(result.outside)),
                         ("partial", bool(result.partial)), ("noisy_success", fuzz.noisy_success(result)),
                         ("multiline", result.rc not in (0, None) and len(result.stderr) > 1),
                         ("control_in_stderr", fuzz.raw_controls(result))):
            flags[pair][flag] += on
        if result.outcome not in (*fuzz.GOOD, "busy") and len(examples[pair][result.outcome]) < EXAMPLES_PER_FINDING:
            examples[pair][result.outcome].append(f"{case!r} -> {result.summary()}")
        elif fuzz.raw_controls(result) and len(examples[pair]["control_in_stderr"]) < EXAMPLES_PER_FINDING:
            examples[pair]["control_in_stderr"].append(f"{case!r} -> {result.summary()}")
        if args.verbose:
            print(f"{pair} {count[0]}: {case!r} -> {result.summary()}", file=sys.stderr, flush=True)

    one()


def table_row(name: str, counts: Counter, flags: Counter, columns) -> str:
    return (f"| {name} | " + " | ".join(str(counts[c]) for c in columns)
            + f" | {flags['noisy_success']} | {flags['control_in_stderr']} |")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--cases", type=int, default=800, help="cases in all, shared evenly by the kinds")
    parser.add_argument("--seed", type=int, default=0, help="Hypothesis seed: the same seed, the same cases")
    parser.add_argument("--kinds", default=",".join(fuzz.KINDS), help=f"comma-separated, of {', '.join(fuzz.KINDS)}")
    parser.add_argument("--families", default="",
                        help=f"comma-separated, of {', '.join(ALL_FAMILIES)} (default: every family of each kind)")
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
    families = [f.strip() for f in args.families.split(",") if f.strip()]
    unknown = sorted(set(families) - set(ALL_FAMILIES))
    if unknown:
        parser.error(f"unknown family(ies) {', '.join(unknown)}")
    pairs = [(kind, family) for kind in kinds for family in fuzz.FAMILIES[kind] if not families or family in families]
    if not pairs:
        parser.error(f"none of the kinds {', '.join(kinds)} has the families {', '.join(families)}")
    names = [f"{kind}/{family}" for kind, family in pairs]
    totals = {name: Counter() for name in names}
    flags = {name: Counter() for name in names}
    examples = {name: defaultdict(list) for name in names}
    start = time.monotonic()
    with tempfile.TemporaryDirectory(prefix="camsim-fuzz-") as tmp:
        seeds = fuzz.build_seeds(Path(tmp) / "seeds")
        for i, (kind, family) in enumerate(pairs):
            share = args.cases // len(pairs) + (i < args.cases % len(pairs))
            if not share:
                continue
            pair_start = time.monotonic()
            run_pair(seeds, kind, family, share, args.seed, Path(tmp), args, totals, examples, flags)
            print(f"{kind}/{family}: {totals[names[i]]['cases']} cases in {time.monotonic() - pair_start:.0f} s",
                  file=sys.stderr, flush=True)
    by_family = {family: (sum((totals[f"{k}/{f}"] for k, f in pairs if f == family), Counter()),
                          sum((flags[f"{k}/{f}"] for k, f in pairs if f == family), Counter()))
                 for family in dict.fromkeys(family for _, family in pairs)}
    columns = ["cases", *fuzz.OUTCOMES]
    print("| kind/family | " + " | ".join(columns) + " | noisy success | control in stderr |")
    print("|---" * (len(columns) + 3) + "|")
    for name in names:
        print(table_row(name, totals[name], flags[name], columns))
    for family, (counts, family_flags) in by_family.items():
        print(table_row(f"all/{family}", counts, family_flags, columns))
    all_totals = sum(totals.values(), Counter())
    all_flags = sum(flags.values(), Counter())
    print(table_row("all", all_totals, all_flags, columns))
    for name in names:
        for outcome, lines in examples[name].items():
            for line in lines:
                print(f"{name} {outcome}: {line[:600]}")
    report = {"seed": args.seed, "cases": args.cases, "kinds": kinds, "families": families or None,
              "time_limit_s": args.time_limit, "memory_limit_mb": args.memory_limit,
              "seconds": round(time.monotonic() - start, 1),
              "totals": {name: {c: totals[name][c] for c in columns} for name in names},
              "family_totals": {family: {c: counts[c] for c in columns} for family, (counts, _) in by_family.items()},
              "flags": {name: dict(flags[name]) for name in names},
              "all": {c: all_totals[c] for c in columns},
              "examples": {name: dict(examples[name]) for name in names}}
    line = json.dumps(report, ensure_ascii=False)
    if args.json:
        args.json.write_text(line + "\n", encoding="utf-8")
    print(line)
    return 0


if __name__ == "__main__":
    sys.exit(main())
