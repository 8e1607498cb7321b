"""What a whole evaluation costs with the multirotor plant against the ideal plant (docs/plant.md).

    flock /tmp/dualpilot-heavy.lock .venv/bin/python benchmarks/plant_cost.py \\
        --missions 200 --controllers cc,lookahead+risk --profile today --repeats 1 \\
        --out runs/plant-cost

Runs ``dualpilot evaluate`` on the same missions (``--seed``, paper timing, ``--jobs``) with
the ideal plant and with the multirotor plant (``--wind`` m/s, ``--turbulence``,
``--gps-sigma`` m, the "auto" tube), alternating, ``--repeats`` times each, and times each
run's wall clock from the command's start to its end (the worker pool's start, the Numba
kernel loaded from its disk cache, the missions and the writing of results.csv all
included). Prints the wall times, their medians and the ratio multirotor / ideal of the
medians (the goal: at most 2). Each run's directory stays under ``--out``
(``ideal-r0/``, ``multirotor-r0/`` ...), so its rows can be read as an evaluation too.
Run it under the project's lock; on a shared machine say so with the numbers.
"""

from __future__ import annotations

import argparse
import statistics
from pathlib import Path

import harness


def evaluate(args: argparse.Namespace, out: Path, plant: list[str]) -> float:
    """Wall time (s) of one ``dualpilot evaluate`` run into ``out``."""
    return harness.run_evaluate(args.missions, args.seed, args.jobs, args.controllers, out,
                                ["--profile", args.profile, *plant])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--missions", type=int, default=200)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--controllers", default="cc,lookahead+risk")
    ap.add_argument("--profile", default="today")
    ap.add_argument("--wind", type=float, default=10.0, help="mean wind (m/s)")
    ap.add_argument("--turbulence", default="moderate")
    ap.add_argument("--gps-sigma", type=float, default=1.5, help="gps_sigma_m (m)")
    ap.add_argument("--repeats", type=int, default=1)
    ap.add_argument("--out", type=Path, default=Path("runs/plant-cost"))
    args = ap.parse_args()
    multirotor = ["--set", "plant=multirotor", "--set", f"wind_speed_mps={args.wind:g}",
                  "--set", f"turbulence={args.turbulence}",
                  "--set", f"gps_sigma_m={args.gps_sigma:g}"]
    walls: dict[str, list[float]] = {"ideal": [], "multirotor": []}
    for r in range(args.repeats):
        walls["ideal"].append(evaluate(args, args.out / f"ideal-r{r}", []))
        walls["multirotor"].append(evaluate(args, args.out / f"multirotor-r{r}", multirotor))
    medians = {k: statistics.median(v) for k, v in walls.items()}
    harness.emit({
        "missions": args.missions, "seed": args.seed, "jobs": args.jobs,
        "controllers": args.controllers, "profile": args.profile,
        "multirotor": {"wind_speed_mps": args.wind, "turbulence": args.turbulence,
                       "gps_sigma_m": args.gps_sigma},
        "wall_s": {k: [round(x, 1) for x in v] for k, v in walls.items()},
        "median_wall_s": {k: round(v, 1) for k, v in medians.items()},
        "ratio_multirotor_over_ideal": round(medians["multirotor"] / medians["ideal"], 3),
    }, args.out / "plant_cost.json")


if __name__ == "__main__":
    main()
