"""What the forecast changes, mission by mission: each "+risk" controller against its paper twin.

Reads the ``results.csv`` of a ``dualpilot evaluate`` run that flew both (the
same configurations for every controller) and prints, per pair, the missions
only one of the two completed (b: only the risk-aware one, c: only the paper's;
an exact two-sided McNemar test on b and c), the difference in success rate
with a 95 % interval (normal, paired), and the mean differences in mission
time and energy over the missions both completed, with 95 % intervals.

    .venv/bin/python benchmarks/risk_pairs.py runs/forecast_eval/today/results.csv [...]
"""

from __future__ import annotations

import argparse
import csv
import math
from pathlib import Path

import harness  # the repository on the path
import numpy as np

PAIRS = (("cc", "cc+risk"), ("s1", "s1+risk"), ("s2", "s2+risk"),
         ("concurrent", "concurrent+risk"))


def mean_ci(values: list[float], z: float = 1.96) -> tuple[float, float, float]:
    if not values:
        return (math.nan, math.nan, math.nan)
    a = np.asarray(values, dtype=float)
    half = z * float(a.std(ddof=1)) / math.sqrt(len(a)) if len(a) > 1 else 0.0
    return float(a.mean()), float(a.mean()) - half, float(a.mean()) + half


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("results", nargs="+", type=Path)
    args = ap.parse_args()
    for path in args.results:
        with path.open(newline="") as fh:
            rows = {(r["mission"], r["controller"]): r for r in csv.DictReader(fh)}
        missions = sorted({m for m, _ in rows}, key=int)
        print(f"\n{path} ({len(missions)} missions)\n")
        print("| pair | only +risk / only paper | McNemar p | Δ success, points (95 % CI) "
              "| both | Δ time s (95 % CI) | Δ energy N² (95 % CI) |")
        print("|---|---|---|---|---|---|---|")
        for base, risk in PAIRS:
            pairs = [(rows[(m, base)], rows[(m, risk)]) for m in missions
                     if (m, base) in rows and (m, risk) in rows]
            if not pairs:
                continue
            flags = [(a["success"] == "1", b["success"] == "1") for a, b in pairs]
            ok = np.array(flags, dtype=bool)
            c_only, b_only, p_or_none = harness.mcnemar(pairs)
            p = 1.0 if p_or_none is None else p_or_none
            n = len(pairs)
            d = ok[:, 1].astype(float) - ok[:, 0].astype(float)
            dm, dlo, dhi = mean_ci(d.tolist())
            both = [(a, b) for (a, b), (fa, fb) in zip(pairs, flags, strict=True) if fa and fb]
            tm = mean_ci([float(b["mission_time_s"]) - float(a["mission_time_s"])
                          for a, b in both])
            em = mean_ci([float(b["energy"]) - float(a["energy"]) for a, b in both])
            print(f"| {base} → {risk} | {b_only} / {c_only} | {p:.3f} | {100 * dm:+.1f} "
                  f"({100 * dlo:+.1f}, {100 * dhi:+.1f}) | {len(both)} of {n} | "
                  f"{tm[0]:+.2f} ({tm[1]:+.2f}, {tm[2]:+.2f}) | "
                  f"{em[0]:+.1f} ({em[1]:+.1f}, {em[2]:+.1f}) |")


if __name__ == "__main__":
    main()
