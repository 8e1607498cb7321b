"""The multirotor's own 3-D tracking error in the 3-D missions (docs/plant.md, "In 3-D").

    flock /tmp/dualpilot-heavy.lock .venv/bin/python benchmarks/plant_tube3d.py \\
        --missions 4 --controllers cc,lookahead+risk --winds 0,10 --jobs 2

Flies configurations 0..N−1 of ``--seed`` in-process (paper timing, ``dim=3``,
``plant=multirotor``, exact measurements, ``--turbulence``, fronts U[5, 40] m tall, the
``--set`` readings), by each of ``--controllers`` at each mean wind of ``--winds``, and
prints, pooled over every integration step of every mission, the 3-D distance (m) between
the flown path and the planned straight segment (p50 / p99 / p99.9 / max), the horizontal
and the vertical parts' p99.9, the endings and the altitudes flown. The 3-D tube's
:data:`~dualpilot.plant.reading.TRACKING3_P999_M` rests on it.
"""

from __future__ import annotations

import argparse
import collections
from concurrent.futures import ProcessPoolExecutor
from typing import Any

import harness  # noqa: F401 - the repository on the path
import numpy as np

from dualpilot.evaluation.missions import Task
from dualpilot.mission.config import MissionConfig
from dualpilot.mission.flight import PlantVehicle
from dualpilot.mission.local import local_mission

FRONTS = {"fire_height": "uniform", "fire_height_min_m": "5", "fire_height_max_m": "40"}


def fly(job: tuple[int, int, str, str, str, dict[str, str]]) -> dict[str, Any]:
    """One mission: its ending, steps, altitudes and the flights' errors (m)."""
    index, seed, controller, wind, turbulence, settings = job
    base = MissionConfig().with_settings({
        "dim": "3", "plant": "multirotor", "gps_sigma_m": "0", "turbulence": turbulence,
        "wind_speed_mps": wind, **FRONTS, **settings})
    mission = local_mission(Task.of(index, seed, controller, base).mission())
    vehicle = mission.vehicle
    assert isinstance(vehicle, PlantVehicle)
    horizontal: list[np.ndarray] = []
    vertical: list[np.ndarray] = []
    observe = vehicle.observe

    def observed() -> Any:  # each flight's horizontal and vertical parts beside the 3-D one
        out = observe()
        f = vehicle.flight
        if f is not None and len(vehicle.tracking_error_m) > len(horizontal):
            horizontal.append(f.tracking_error_m(axes=2)[1:])
            vertical.append(np.abs(f.positions[1:, 2] - f.reference[1:, 2]))
        return out

    vehicle.observe = observed  # type: ignore[method-assign]
    result = mission.run()
    assert result.ending is not None
    z = [float(r.state[2]) for r in result.records]
    return {"controller": controller, "wind": wind, "ending": result.ending.value,
            "steps": result.steps, "z": (min(z), max(z)),
            "e3": np.concatenate(result.tracking_error_m or [np.zeros(0)]),
            "eh": np.concatenate(horizontal or [np.zeros(0)]),
            "ez": np.concatenate(vertical or [np.zeros(0)])}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--missions", type=int, default=4)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--controllers", default="cc,lookahead+risk")
    ap.add_argument("--winds", default="0,10")
    ap.add_argument("--turbulence", default="moderate")
    ap.add_argument("--set", action="append", default=[], metavar="NAME=VALUE")
    ap.add_argument("--jobs", type=int, default=1)
    args = ap.parse_args()
    settings = dict(s.split("=", 1) for s in args.set)
    jobs = [(i, args.seed, c, w, args.turbulence, settings)
            for c in args.controllers.split(",") for w in args.winds.split(",")
            for i in range(args.missions)]
    with ProcessPoolExecutor(args.jobs) as pool:
        rows = list(pool.map(fly, jobs))
    endings = collections.Counter(r["ending"] for r in rows)
    e3, eh, ez = (np.concatenate([r[k] for r in rows]) for k in ("e3", "eh", "ez"))
    q = (50, 99, 99.9)
    print(f"{len(rows)} missions, {sum(r['steps'] for r in rows)} steps, {len(e3)} samples; "
          f"endings {dict(endings)}")
    print("3-D p50/p99/p99.9 (max):", np.round(np.percentile(e3, q), 3), round(float(e3.max()), 3))
    print("horizontal p99.9 (max):", round(float(np.percentile(eh, 99.9)), 3),
          round(float(eh.max()), 3))
    print("vertical p99.9 (max):", round(float(np.percentile(ez, 99.9)), 3),
          round(float(ez.max()), 3))
    print("altitude flown, lowest / highest (m):", round(min(r["z"][0] for r in rows), 2),
          round(max(r["z"][1] for r in rows), 2))


if __name__ == "__main__":
    main()
