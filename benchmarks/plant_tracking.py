"""Tracking error of the multirotor plant under the paper's plans, in wind (docs/plant.md).

Flies in-process missions with the ideal plant (today's vehicle), then replays
every step's Eq. (1) segment on the multirotor plant at each wind speed with the
given turbulence and GPS error. Two replays:

- ``measured``: each step's segment starts at the plant's *measured* state, with
  the step's recorded control, as the mission step will fly it: the error is
  the distance from the segment planned from where the vehicle believed it was
  to where it truly flew (the quantity a planning margin has to cover);
- ``trajectory``: the recorded ideal trajectory as one reference, never
  re-anchored (how far the plant drifts from the ideal flight as a whole).

Distances are taken at every integration step (100 Hz) against Eq. (1)'s straight
segment, in 3-D (``path``) and horizontally (``path_horizontal``, what the 2-D
missions' d_safe measures), and at the step ends. The mean wind blows towards a
direction drawn per mission; wind and sensor streams come from the mission seed.
Run it alone on the machine (it times the plant)::

    .venv/bin/python benchmarks/plant_tracking.py \\
        --missions 20 --winds 0,5,10 --turbulence moderate --gps-sigma 1.5 --out runs/plant
"""

from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path
from typing import Any

import numpy as np

from dualpilot.evaluation.missions import Task
from dualpilot.mission.local import local_mission
from dualpilot.model.dynamics import Array, DynamicsParams
from dualpilot.plant import GpsParams, PlantParams, WindParams, make_plant
from dualpilot.plant.wind import Turbulence

#: seed-sequence key of the replay's plant stream, apart from the mission's own streams
_PLANT_KEY = 13


def flown_plans(missions: int, controller: str) -> list[tuple[int, list[tuple[Array, Array]]]]:
    """(seed, [(x_t, u_t) per step]) of in-process missions with the ideal plant."""
    out = []
    for i in range(missions):
        result = local_mission(Task.of(i, 0, controller).mission()).run()
        out.append((result.seed, [(r.state, r.control) for r in result.records]))
    return out


def replay(steps: list[tuple[Array, Array]], plant_params: PlantParams, seed: int,
           dyn: DynamicsParams, mode: str) -> tuple[Array, Array, Array, float]:
    """3-D and horizontal errors at 100 Hz (m), 3-D errors at the step ends (m), and the
    plant's wall time per step (s)."""
    rng = np.random.default_rng(np.random.SeedSequence([seed, _PLANT_KEY]))
    plant = make_plant(plant_params, steps[0][0], dyn, rng)
    errs, flat, ends = [], [], []
    t0 = time.perf_counter()
    for state, control in steps:
        start = plant.measure() if mode == "measured" else state
        flight = plant.fly(start, control)
        e = flight.tracking_error_m()
        errs.append(e[1:])
        flat.append(flight.tracking_error_m(axes=2)[1:])
        ends.append(e[-1])
    wall = (time.perf_counter() - t0) / len(steps)
    return np.concatenate(errs), np.concatenate(flat), np.array(ends), wall


def stats(e: Array) -> dict[str, float]:
    p50, p99, p999 = np.percentile(e, [50, 99, 99.9])
    return {"p50": float(p50), "p99": float(p99), "p99_9": float(p999), "max": float(e.max())}


def main(argv: list[str] | None = None) -> dict[str, Any]:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--missions", type=int, default=20)
    ap.add_argument("--controller", default="concurrent")
    ap.add_argument("--winds", default="0,5,10", help="mean wind speeds (m/s)")
    ap.add_argument("--turbulence", default="moderate")
    ap.add_argument("--gps-sigma", type=float, default=1.5)
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args(argv)
    dyn = DynamicsParams()
    t0 = time.perf_counter()
    plans = flown_plans(args.missions, args.controller)
    plan_wall = time.perf_counter() - t0
    steps = sum(len(s) for _, s in plans)
    report: dict[str, Any] = {"missions": args.missions, "controller": args.controller,
                              "steps": steps, "turbulence": args.turbulence,
                              "gps_sigma_m": args.gps_sigma,
                              "ideal_missions_wall_s_per_step": plan_wall / steps, "winds": {}}
    for wind in [float(w) for w in args.winds.split(",")]:
        row: dict[str, Any] = {}
        for mode in ("measured", "trajectory"):
            errs, flats, ends, walls = [], [], [], []
            for seed, mission_steps in plans:
                direction = np.random.default_rng(seed).uniform(0.0, 2.0 * math.pi)
                turb: Turbulence = args.turbulence  # checked by WindParams
                params = PlantParams(
                    kind="multirotor",
                    wind=WindParams(wind_speed_mps=wind, wind_dir_rad=float(direction),
                                    turbulence=turb),
                    gps=GpsParams(gps_sigma_m=args.gps_sigma))
                e, flat, end, wall = replay(mission_steps, params, seed, dyn, mode)
                errs.append(e)
                flats.append(flat)
                ends.append(end)
                walls.append(wall)
            row[mode] = {"path": stats(np.concatenate(errs)),
                         "path_horizontal": stats(np.concatenate(flats)),
                         "step_end": stats(np.concatenate(ends)),
                         "plant_wall_s_per_step": float(np.median(walls))}
        report["winds"][f"{wind:g}"] = row
    text = json.dumps(report, indent=2)
    print(text)
    if args.out is not None:
        args.out.mkdir(parents=True, exist_ok=True)
        (args.out / "plant_tracking.json").write_text(text + "\n")
    return report


if __name__ == "__main__":
    main()
