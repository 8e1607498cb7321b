"""The 3-D evaluation under fires taller than the band against the 2-D evaluation, paired.

    .venv/bin/python benchmarks/paired3d.py --missions 200 --profile today \
        --controllers cc,s1,s2,cc+risk,s1+risk,s2+risk --out runs/paired3d

Runs ``dualpilot evaluate`` twice on the same missions (same ``--seed``): in 2-D, and with
``--set dim=3 --set fire_height=above-ceiling`` (every cuboid taller than the ceiling, the
start and G_o at one altitude: the top-down evaluation's world, docs/three_d.md "The 2-D
case and the consistency test"). The 3-D planners draw differently where they search the
band (System 1's samples), so the missions are compared in pairs, per controller:

* identical: the rows equal in every column the two results share but wall and planning
  times;
* success: McNemar's exact test, a two-sided binomial test on the discordant pairs
  (``scipy.stats.binomtest``), and the difference in points;
* time and energy: Wilcoxon's signed-rank test over the missions both complete
  (``scipy.stats.wilcoxon``; "-" when every pair is equal).

Prints a Markdown table; the two runs' directories stay under ``--out`` (``2d/``, ``3d/``).
``--fire-height reading`` keeps the mission's own heights in 3-D (on a scenario the fire's
physics: flame and plume) to measure what altitude buys over the plane.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import harness  # noqa: F401  (the repository on the path: before its packages)
from scipy.stats import wilcoxon

#: columns that differ run to run on one machine (times of the wall clock)
UNPAIRED = {"wall_s", "planning_time_s_median", "planning_time_s_p95", "planning_time_s_total"}


def evaluate(args: argparse.Namespace, out: Path, extra: list[str]) -> dict[tuple[str, str],
                                                                          harness.Row]:
    """Rows of one ``dualpilot evaluate`` run, keyed (mission, controller)."""
    harness.run_evaluate(args.missions, args.seed, args.jobs, args.controllers, out,
                         [*args.where, *extra])
    return harness.read_results(out)


def p_text(p: float | None) -> str:
    return "-" if p is None else f"{p:.3f}"


def wilcoxon_p(a: list[float], b: list[float]) -> float | None:
    """Two-sided Wilcoxon signed-rank p of the pairs (None: every pair equal, or none)."""
    if not a or all(x == y for x, y in zip(a, b, strict=True)):
        return None
    return float(wilcoxon(a, b).pvalue)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--missions", type=int, default=200)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--controllers", default="cc,s1,s2,cc+risk,s1+risk,s2+risk")
    ap.add_argument("--profile", help="a readings profile (evaluate's --profile)")
    ap.add_argument("--scenario", help="a fire-behaviour scenario (evaluate's --scenario)")
    ap.add_argument("--fire-height", default="above-ceiling",
                    help="the 3-D run's fire_height reading; 'reading': the mission's own "
                         "(the physics tops on a scenario): what altitude buys")
    ap.add_argument("--out", type=Path, default=Path("runs/paired3d"))
    args = ap.parse_args()
    args.where = ([f"--profile={args.profile}"] if args.profile else []) + (
        [f"--scenario={args.scenario}"] if args.scenario else [])
    flat = evaluate(args, args.out / "2d", [])
    heights = [] if args.fire_height == "reading" else ["--set",
                                                         f"fire_height={args.fire_height}"]
    tall = evaluate(args, args.out / "3d", ["--set", "dim=3", *heights])
    print(f"{args.missions} missions from seed {args.seed}, {' '.join(args.where) or 'paper'}, "
          f"3-D fire_height {args.fire_height}\n")
    print("| controller | identical | success 2-D | success 3-D | Δ points | discordant "
          "(2-D only / 3-D only) | McNemar p | time p | energy p |")
    print("|---|---|---|---|---|---|---|---|---|")
    for name in args.controllers.split(","):
        keys = sorted((k for k in flat if k[1] == name), key=lambda k: int(k[0]))
        pairs = [(flat[k], tall[k]) for k in keys]
        shared = [c for c in pairs[0][0] if c in pairs[0][1] and c not in UNPAIRED]
        same = sum(all(a[c] == b[c] for c in shared) for a, b in pairs)
        s2d = sum(a["success"] == "1" for a, _ in pairs)
        s3d = sum(b["success"] == "1" for _, b in pairs)
        only2, only3, mcnemar = harness.mcnemar(pairs)
        both = [(a, b) for a, b in pairs if a["success"] == b["success"] == "1"]
        p_time = wilcoxon_p([float(a["mission_time_s"]) for a, _ in both],
                            [float(b["mission_time_s"]) for _, b in both])
        p_energy = wilcoxon_p([float(a["energy"]) for a, _ in both],
                              [float(b["energy"]) for _, b in both])
        n = len(pairs)
        print(f"| {name} | {same}/{n} | {100 * s2d / n:.1f} % | {100 * s3d / n:.1f} % | "
              f"{100 * (s3d - s2d) / n:+.1f} | {only2} / {only3} | {p_text(mcnemar)} | "
              f"{p_text(p_time)} | {p_text(p_energy)} |")


if __name__ == "__main__":
    main()
