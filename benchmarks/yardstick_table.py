"""The yardstick of several evaluations side by side: controller × reading.

Reads the ``summary.json`` that ``dualpilot evaluate --controllers ...,oracle`` writes in
each run directory (and its ``results.csv``: the missions any controller completed that
the oracle calls impossible, which must be none) and prints one Markdown table a measure:
success, success as % of the achievable missions (95 % interval), avoidable failures, mean mission
time (s) and energy (N²) over each controller's successes. The columns are the run
directories' names. ::

    .venv/bin/python benchmarks/yardstick_table.py runs/yardstick/today runs/yardstick/grass-15
"""

from __future__ import annotations

import argparse
import csv
import json
import math
from pathlib import Path
from typing import Any

import harness  # noqa: F401 - the repository on the path


def _pct(x: float) -> str:
    return "—" if not math.isfinite(x) else f"{100 * x:.1f}"


def cell(c: dict[str, Any], measure: str) -> str:
    """One controller's value of ``measure`` in one reading's yardstick."""
    if measure == "success":
        return f"{100 * c['successes'] / max(c['n'], 1):.1f}"
    if measure == "achievable":
        lo, hi = c["of_achievable_ci95"]
        return f"{_pct(c['of_achievable'])} ({_pct(lo)}–{_pct(hi)})"
    if measure == "avoidable":
        return str(c["failures"]["avoidable"])
    value = c["mission_time_s_mean" if measure == "time" else "energy_mean"]
    return "—" if not math.isfinite(value) else f"{value:.{1 if measure == 'time' else 0}f}"


TITLES = {"success": "success, % of missions",
          "achievable": "success, % of achievable (95 % CI)",
          "avoidable": "avoidable failures",
          "time": "mean mission time on successes (s)",
          "energy": "mean energy on successes (N²)"}


def completed_but_impossible(run: Path) -> int:
    """Missions the oracle calls impossible that some controller completed (the yardstick
    raises on those its certificate covers; this counts every controller's)."""
    with (run / "results.csv").open(newline="") as fh:
        rows = list(csv.DictReader(fh))
    impossible = {r["mission"] for r in rows
                  if r["controller"] == "oracle" and r["failure_cause"] == "impossible"}
    return len({r["mission"] for r in rows if r["success"] == "1"} & impossible)


def tables(runs: list[Path]) -> str:
    """The Markdown tables, one per measure, and a line of missions per reading."""
    yards = {run.name: json.loads((run / "summary.json").read_text())["yardstick"]
             for run in runs}
    names = list(dict.fromkeys(c for ys in yards.values() for c in ys["controllers"]))
    head = "| controller | " + " | ".join(yards) + " |"
    rule = "|---" * (len(yards) + 1) + "|"
    out = ["| | " + " | ".join(yards) + " |", rule,
           "| missions (achievable; oracle feasible / impossible / unknown) | " + " | ".join(
               f"{ys['missions']} ({ys['achievable']}; {ys['oracle']['feasible']} / "
               f"{ys['oracle']['impossible']} / {ys['oracle']['unknown']})"
               for ys in yards.values()) + " |",
           "| completed by a controller but called impossible | " + " | ".join(
               str(completed_but_impossible(run)) for run in runs) + " |", ""]
    for measure, title in TITLES.items():
        out += [f"**{title}**", "", head, rule]
        for name in names:
            out.append(f"| {name} | " + " | ".join(
                cell(ys["controllers"][name], measure) if name in ys["controllers"] else "—"
                for ys in yards.values()) + " |")
        out.append("")
    return "\n".join(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("runs", type=Path, nargs="+", help="run directories of dualpilot evaluate")
    args = ap.parse_args()
    print(tables(args.runs))


if __name__ == "__main__":
    main()
