#!/usr/bin/env bash
# Run a test tier N times in a row, optionally beside CPU load, and report every test that
# ever failed (how often, in which runs). A flake is a test that fails without a defect: this
# is how its rate is measured (docs/testing.md).
#
#   scripts/flake_hunt.sh [-n RUNS] [-l LOAD] [-t TIER] [-o OUT] [-- PYTEST_ARGS...]
#
#   -n RUNS   how many runs in a row (default 10)
#   -l LOAD   busy processes beside the runs (default 0; 4 on 2 cores is "2x CPU load"), each
#             a Python loop that never sleeps, killed when the hunt ends and bounded by
#             timeout(1) to the hunt's budget in any case
#   -t TIER   fast (make test-fast: unit and not slow, the default) or all (make test: every
#             test, as make test runs them: scripts/test_lanes.sh, the tiers side by side on
#             their xdist workers, the unit tier at normal priority when LOAD > 0, so that
#             the load competes with every tier); or a pytest marker expression
#   -o OUT    where each run's JUnit XML and log go (default runs/flake-hunt/<date>)
#
# Exit status: 0 when no test failed in any run, 1 otherwise. The summary is printed and
# written to OUT/summary.json.
set -euo pipefail
cd "$(dirname "$0")/.."

RUNS=10 LOAD=0 TIER=fast OUT=""
while getopts "n:l:t:o:h" opt; do
  case $opt in
    n) RUNS=$OPTARG ;;
    l) LOAD=$OPTARG ;;
    t) TIER=$OPTARG ;;
    o) OUT=$OPTARG ;;
    h) sed -n '2,18p' "$0"; exit 0 ;;
    *) exit 2 ;;
  esac
done
shift $((OPTIND - 1))
OUT=${OUT:-runs/flake-hunt/$(date +%Y%m%d-%H%M%S)}
mkdir -p "$OUT"
PY=.venv/bin/python
make --no-print-directory setup >"$OUT/setup.log" 2>&1 || { cat "$OUT/setup.log"; exit 2; }

case $TIER in
  fast) MARK="unit and not slow" ;;
  all) MARK="" ;;
  *) MARK=$TIER ;;
esac

# the load: bounded in time whatever happens to this script (4 h at most)
BUSY=()
cleanup() { for pid in "${BUSY[@]}"; do kill "$pid" 2>/dev/null || true; done; }
trap cleanup EXIT
trap 'exit 130' INT TERM  # stop the hunt (the EXIT trap ends the load), not just the load
for _ in $(seq 1 "$LOAD"); do
  timeout 4h "$PY" -c "while True: pass" &
  BUSY+=($!)
done

echo "flake hunt: $RUNS runs of '${MARK:-every test}' beside $LOAD busy processes; logs in $OUT"
for k in $(seq 1 "$RUNS"); do
  start=$(date +%s)
  set +e
  if [ "$TIER" = all ]; then
    UNIT_NICE=$(( LOAD > 0 ? 0 : 19 )) LANES_JUNIT="$OUT/run-$k" \
      scripts/test_lanes.sh -p no:cacheprovider "$@" >"$OUT/run-$k.log" 2>&1
  elif [ -n "$MARK" ]; then
    "$PY" -m pytest -q -p no:cacheprovider -m "$MARK" --junitxml="$OUT/run-$k.xml" "$@" \
      >"$OUT/run-$k.log" 2>&1
  else
    "$PY" -m pytest -q -p no:cacheprovider --junitxml="$OUT/run-$k.xml" "$@" \
      >"$OUT/run-$k.log" 2>&1
  fi
  code=$?
  set -e
  echo "run $k: exit $code in $(( $(date +%s) - start )) s: $(tail -n 1 "$OUT/run-$k.log")"
done

"$PY" - "$OUT" "$RUNS" "$LOAD" "$TIER" <<'PYEOF'
"""Every test that failed or errored in any run's JUnit XML, with the runs it failed in."""
import json
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

out, runs, load, tier = Path(sys.argv[1]), int(sys.argv[2]), int(sys.argv[3]), sys.argv[4]
failed: dict[str, list[int]] = {}
totals = []
for k in range(1, runs + 1):
    # one report a run, or one a tier (TIER=all: run-K-unit.xml and run-K-stack.xml)
    lanes = ("unit", "stack") if tier == "all" else ("",)
    paths = [out / f"run-{k}{'-' + lane if lane else ''}.xml" for lane in lanes]
    if not all(p.is_file() for p in paths):
        failed.setdefault("(run produced no report)", []).append(k)
        continue
    total = dict.fromkeys(("tests", "failures", "errors", "skipped"), 0) | {"time_s": 0.0}
    for path in paths:
        suite = ET.parse(path).getroot()
        suite = suite if suite.tag == "testsuite" else suite.find("testsuite")
        for a in ("tests", "failures", "errors", "skipped"):
            total[a] += int(suite.get(a, 0))
        total["time_s"] = max(total["time_s"], float(suite.get("time", 0.0)))
        for case in suite.iter("testcase"):
            if case.find("failure") is not None or case.find("error") is not None:
                name = f"{case.get('classname')}::{case.get('name')}"
                failed.setdefault(name, []).append(k)
    totals.append(total)
summary = {"runs": runs, "load_processes": load, "tier": tier, "per_run": totals,
           "failed": failed}
(out / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
n = sum(t["tests"] for t in totals)
print(f"\n{runs} runs, {n} test executions, {len(failed)} test(s) ever failed")
for name, ks in sorted(failed.items()):
    print(f"  {name}: failed in {len(ks)} of {runs} runs ({', '.join(map(str, ks))})")
sys.exit(1 if failed else 0)
PYEOF
