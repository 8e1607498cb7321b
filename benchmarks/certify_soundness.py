"""The certified bound against SCIP's proven optimum on thousands of small (P2) instances.

Each seed draws :func:`dualpilot.evaluation.instances.small_instance` (T = 3–8, one or two
rectangles near the path) and :func:`dualpilot.evaluation.soundness.check` solves it with
SCIP to proven optimality and with the "certified" method to completion: the bound must
never exceed SCIP's verified cost, and where SCIP proves the optimum the certified gap must
be at least the true gap. Writes ``--out`` (JSON: every row and the counts) and prints the
counts; exits 1 if any instance is unsound.

    .venv/bin/python benchmarks/certify_soundness.py --instances 2000 --seed 0
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from dualpilot.evaluation.soundness import Check, as_row, check


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--instances", type=int, default=2000)
    ap.add_argument("--seed", type=int, default=0, help="first seed (seeds run consecutively)")
    ap.add_argument("--scip-time-limit", type=float, default=10.0)
    ap.add_argument("--out", default="runs/certify_soundness.json")
    args = ap.parse_args(argv)
    checks: list[Check] = []
    t0 = time.perf_counter()
    for seed in range(args.seed, args.seed + args.instances):
        c = check(seed, args.scip_time_limit)
        checks.append(c)
        if not c.sound:
            print(f"UNSOUND seed {seed}: {c}", flush=True)
        if len(checks) % 100 == 0:
            print(f"{len(checks)} instances, {time.perf_counter() - t0:.0f} s", flush=True)
    proven = [c for c in checks if c.optimum is not None]
    over = [c.bound / c.optimum - 1.0 for c in proven
            if c.bound is not None and c.optimum is not None and c.optimum > 0]
    gaps = [c.certified_gap for c in proven if c.certified_gap is not None]
    counts = {
        "instances": len(checks),
        "scip_feasible": sum(c.upper is not None for c in checks),
        "scip_proven_optimal": len(proven),
        "unsound": sum(not c.sound for c in checks),
        "max_bound_over_optimum": max(over, default=None),
        "max_certified_gap_when_proven": max(gaps, default=None),
        "seconds": time.perf_counter() - t0,
        "command": f"benchmarks/certify_soundness.py --instances {args.instances} "
                   f"--seed {args.seed} --scip-time-limit {args.scip_time_limit:g}",
    }
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps({"counts": counts, "rows": [as_row(c) for c in checks]},
                              indent=1))
    print(json.dumps(counts, indent=1))
    return 1 if counts["unsound"] else 0


if __name__ == "__main__":
    sys.exit(main())
