"""A supervisor against the others, mission by mission, and its time and energy against System 2's.

Reads the ``results.csv`` of ``dualpilot evaluate`` runs (the same configurations for every
controller) and prints, per run and comparison controller, the missions only one of the two
completed (an exact two-sided McNemar test on them) and the difference in success, then the
supervisor's mean mission time and energy over its successes against System 2's over
System 2's (the ratio the targets name), and over the missions both completed (paired). ::

    .venv/bin/python benchmarks/yardstick_pairs.py --supervisor lookahead+risk \\
        runs/yardstick/today/results.csv runs/yardstick/grass-15/results.csv
"""

from __future__ import annotations

import argparse
import csv
from pathlib import Path

import harness  # the repository on the path
import numpy as np

OTHERS = ("s1", "s2", "cc", "concurrent")


def rows_of(path: Path) -> dict[tuple[str, str], dict[str, str]]:
    with path.open(newline="") as fh:
        return {(r["mission"], r["controller"]): r for r in csv.DictReader(fh)}


def pair_line(rows: dict[tuple[str, str], dict[str, str]], missions: list[str], mine: str,
              other: str) -> str:
    pairs = [(rows[(m, mine)], rows[(m, other)]) for m in missions
             if (m, mine) in rows and (m, other) in rows]
    ok = np.array([(a["success"] == "1", b["success"] == "1") for a, b in pairs], dtype=bool)
    only_mine, only_other, p_or_none = harness.mcnemar(pairs)
    p = 1.0 if p_or_none is None else p_or_none
    d = 100.0 * (ok[:, 0].mean() - ok[:, 1].mean())
    return (f"| {other} | {100 * ok[:, 1].mean():.1f} % | {only_mine} / {only_other} | "
            f"{p:.3f} | {d:+.1f} |")


def ratio_line(rows: dict[tuple[str, str], dict[str, str]], missions: list[str],
               mine: str) -> str:
    def ok(c: str) -> list[dict[str, str]]:
        return [rows[(m, c)] for m in missions if (m, c) in rows and rows[(m, c)]["success"] == "1"]

    a, b = ok(mine), ok("s2")
    if not a or not b:
        return f"| {len(a)} | {len(b)} | — | — | — |"
    t = np.mean([float(r["mission_time_s"]) for r in a]) / np.mean(
        [float(r["mission_time_s"]) for r in b])
    e = np.mean([float(r["energy"]) for r in a]) / np.mean([float(r["energy"]) for r in b])
    both = [m for m in missions if (m, mine) in rows and (m, "s2") in rows
            and rows[(m, mine)]["success"] == rows[(m, "s2")]["success"] == "1"]
    if both:
        pt = np.mean([float(rows[(m, mine)]["mission_time_s"]) for m in both]) / np.mean(
            [float(rows[(m, "s2")]["mission_time_s"]) for m in both])
        pe = np.mean([float(rows[(m, mine)]["energy"]) for m in both]) / np.mean(
            [float(rows[(m, "s2")]["energy"]) for m in both])
        paired = f"{pt:.3f}, {pe:.3f} ({len(both)})"
    else:
        paired = "—"
    return f"| {len(a)} | {len(b)} | {t:.3f} | {e:.3f} | {paired} |"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("results", nargs="+", type=Path)
    ap.add_argument("--supervisor", default="lookahead+risk")
    args = ap.parse_args()
    for path in args.results:
        rows = rows_of(path)
        missions = sorted({m for m, _ in rows}, key=int)
        mine = args.supervisor
        share = np.mean([rows[(m, mine)]["success"] == "1" for m in missions
                         if (m, mine) in rows])
        print(f"\n{path} ({len(missions)} missions; {mine} {100 * share:.1f} %)\n")
        print(f"| against | its success | only {mine} / only it | McNemar p | Δ points |")
        print("|---|---|---|---|---|")
        for other in OTHERS:
            print(pair_line(rows, missions, mine, other))
        print(f"\n| {mine} successes | s2 successes | time / s2 | energy / s2 | "
              "paired time, energy (missions) |")
        print("|---|---|---|---|---|")
        print(ratio_line(rows, missions, mine))


if __name__ == "__main__":
    main()
