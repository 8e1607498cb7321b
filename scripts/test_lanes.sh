#!/usr/bin/env bash
# make test: the unit tier beside the integration and e2e tiers, as two pytest processes
# (docs/testing.md). The stack tiers run in the foreground at normal priority, one test at a
# time, and list their 25 slowest tests; the unit tier runs beside them at the lowest CPU
# priority (nice 19), taking the cycles the stacks leave, its output kept in
# runs/test-unit.log and printed at the end. Exit status: 0 when both passed.
#
#   scripts/test_lanes.sh [PYTEST_ARGS...]   (passed to both processes)
#
# STACK_WORKERS=N (default 1) runs the stack tiers on N pytest-xdist workers, a test file
# whole on one worker (--dist loadfile), for machines with cores to spare (docs/testing.md).
set -uo pipefail
cd "$(dirname "$0")/.."
mkdir -p runs
log=runs/test-unit.log
nice -n 19 .venv/bin/python -m pytest -q --durations=10 -o cache_dir=.pytest_cache/unit \
    "$@" tests/unit > "$log" 2>&1 &
unit=$!
trap 'kill "$unit" 2>/dev/null' EXIT INT TERM
workers=${STACK_WORKERS:-1}
spread=()
if [ "$workers" -gt 1 ]; then spread=(-n "$workers" --dist loadfile); fi
.venv/bin/python -m pytest -q --durations=25 "${spread[@]}" "$@" tests/integration tests/e2e
stack=$?
wait "$unit"
unit_rc=$?
trap - EXIT INT TERM
echo "== the unit tier ($log)"
cat "$log"
echo "== integration and e2e: exit $stack; unit: exit $unit_rc"
[ "$stack" -eq 0 ] && [ "$unit_rc" -eq 0 ]
