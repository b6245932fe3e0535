#!/usr/bin/env bash
# make test on a busy machine: one CPU-bound burner per core (BURNERS=N for another count) for the whole run, killed
# by PID at the end, then the test counts, the wall time and the load it ran under. Exits with make test's status.
#
#     tools/test_under_load.sh              # as many burners as cores
#     BURNERS=4 tools/test_under_load.sh    # heavier
#
# The suite's verdicts are CPU time, not wall time (tests/support/clock.py): it must pass here as on a quiet machine.
set -uo pipefail
cd "$(dirname "$0")/.."
burners=${BURNERS:-$(nproc)}
log=$(mktemp "${TMPDIR:-/tmp}/camsim-test-under-load.XXXXXX")
pids=()
stop_burners() {
    for pid in "${pids[@]}"; do kill "$pid" 2>/dev/null; done
    for pid in "${pids[@]}"; do wait "$pid" 2>/dev/null; done
    pids=()
}
trap stop_burners EXIT
trap 'stop_burners; exit 130' INT TERM
make setup >/dev/null || exit $?  # the set-up is not under test: done before the burners start
for _ in $(seq "$burners"); do
    python3 -c 'while 1: pass' &
    pids+=($!)
done
echo "== $burners CPU-bound burner(s) on $(nproc) core(s): PIDs ${pids[*]}"
start=$SECONDS
make test 2>&1 | tee "$log"
status=${PIPESTATUS[0]}
wall=$((SECONDS - start))
load=$(cut -d' ' -f1-3 /proc/loadavg)
stop_burners
summary=$(grep -E '^(=+ )?[0-9]+ (passed|failed)' "$log" | tail -1 | sed 's/=//g; s/^ *//; s/ *$//')
echo "== make test under load ($burners burners, $(nproc) cores): ${summary:-no summary line}; wall ${wall} s;" \
     "load average at the end ${load}; exit ${status}"
rm -f "$log"
exit "$status"
