#!/usr/bin/env bash
# make test: the unit tier beside the integration and e2e tiers, as two pytest processes
# (docs/testing.md). The stack tiers run in the foreground at normal priority on
# STACK_WORKERS pytest-xdist workers (default 2), a test file whole on one worker (--dist
# loadfile: a stack the file's tests share starts once; the files with the most tests
# first), and list their 25 slowest tests; the unit tier runs beside them on UNIT_WORKERS
# workers (default 2) at the lowest CPU priority (UNIT_NICE, default 19), taking the cycles
# the stacks leave and both cores once the stacks are done, its output kept in
# runs/test-unit.log and printed at the end. A worker count of 1 runs that tier in one
# process, one test at a time. Exit status: 0 when both passed.
#
#   scripts/test_lanes.sh [PYTEST_ARGS...]   (passed to both processes)
#
# LANES_JUNIT=PREFIX writes each tier's JUnit XML to PREFIX-unit.xml and PREFIX-stack.xml
# (scripts/flake_hunt.sh, which also sets UNIT_NICE=0 beside its busy processes: at nice 19
# the unit tier would get almost no CPU beside them).
set -uo pipefail
cd "$(dirname "$0")/.."
mkdir -p runs
log=runs/test-unit.log

# -n N --dist loadfile for N > 1 workers, nothing for one
spread() { if [ "$1" -gt 1 ]; then echo "-n $1 --dist loadfile"; fi; }
junit() { if [ -n "${LANES_JUNIT:-}" ]; then echo "--junitxml=$LANES_JUNIT-$1.xml"; fi; }

# shellcheck disable=SC2046  # the options split into words on purpose
nice -n "${UNIT_NICE:-19}" .venv/bin/python -m pytest -q --durations=10 \
    -o cache_dir=.pytest_cache/unit $(spread "${UNIT_WORKERS:-2}") $(junit unit) \
    "$@" tests/unit > "$log" 2>&1 &
unit=$!
trap 'kill "$unit" 2>/dev/null' EXIT INT TERM
# shellcheck disable=SC2046
.venv/bin/python -m pytest -q --durations=25 $(spread "${STACK_WORKERS:-2}") $(junit stack) \
    "$@" tests/integration tests/e2e
stack=$?
wait "$unit"
unit_rc=$?
trap - EXIT INT TERM
echo "== the unit tier ($log)"
cat "$log"
echo "== integration and e2e: exit $stack; unit: exit $unit_rc"
[ "$stack" -eq 0 ] && [ "$unit_rc" -eq 0 ]
