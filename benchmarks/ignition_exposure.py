"""How often a fire ignites where a flight is already committed: the causal ceiling's arithmetic.

At one planning sub-step a step, the birth drawn during step t's sub-step meets a UAV whose
next positions are already fixed: p_t (where it idles now), p_{t+1} = p_t + ΔT·v_t (v_t set by
u_{t−1}) and p_{t+2} (v_{t+1} set by u_t, committed before this sub-step). A fire born within
d_safe of that polyline fails the mission whatever the controller does next (the anatomy's
class "ignition", proof "committed"). For a physics scenario a birth ignites one cell, uniform
over the area's cells (pyretechnics' grid), with probability p_b a sub-step, its region the
cell grown by the scenario's pad: the chance that step t's birth is one of them is
p_b · (cells whose grown box comes within d_safe of the polyline) / (all cells), and a flight's
exposure is 1 − Π_t (1 − that chance). Averaged over the flights of a controller (its
successes, flown again in-process), it is the share of missions no causal controller flying
those paths could have saved: the ceiling it flies under. Growth after birth and cells
already burned are neglected (both make the true exposure larger). ::

    .venv/bin/python benchmarks/ignition_exposure.py runs/yardstick/grass-15 \
        --controller lookahead+risk
"""

from __future__ import annotations

import argparse
import json
from dataclasses import replace
from pathlib import Path

import harness
import numpy as np

from dualpilot.evaluation.missions import Task, base_of
from dualpilot.evaluation.results import read_results
from dualpilot.mission.local import local_mission
from dualpilot.mission.params import Timing
from dualpilot.model.physics_fire import PhysicsFire
from dualpilot.model.scenarios import get_scenario
from dualpilot.spacetime.lattice import segment_box_d2


def killing_share(polyline: np.ndarray, centres: np.ndarray, half: float, d: float) -> float:
    """The share of cells whose box (centre ± half) lies within ``d`` of the polyline."""
    hit = np.zeros(len(centres), dtype=bool)
    lo, hi = polyline.min(axis=0) - half - d, polyline.max(axis=0) + half + d
    near = np.all((centres >= lo) & (centres <= hi), axis=1)
    for k in np.nonzero(near)[0]:
        cx, cy = centres[k]
        for a, b in zip(polyline[:-1], polyline[1:], strict=True):
            if segment_box_d2(a[0], a[1], b[0], b[1], cx - half, cy - half, cx + half,
                              cy + half) < d * d:
                hit[k] = True
                break
    return float(hit.sum()) / len(centres)


def exposure(positions: np.ndarray, p_birth: float, centres: np.ndarray, half: float,
             d: float) -> float:
    """1 − Π_t (1 − p_b · share_t) over the flight's steps (module docstring)."""
    survive = 1.0
    for t in range(len(positions) - 1):
        poly = positions[t:t + 3]
        survive *= 1.0 - p_birth * killing_share(poly, centres, half, d)
    return 1.0 - survive


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("run", type=Path, help="an evaluation's run directory (physics scenario)")
    ap.add_argument("--controller", default="lookahead+risk")
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args()
    meta = json.loads((args.run / "run.json").read_text())
    rows = [r for r in read_results(args.run / "results.csv")
            if r["controller"] == args.controller and r["success"] == "1"]
    base = base_of(meta, rows[0]["timing"])
    reading = base.reading()
    fire = PhysicsFire(get_scenario(reading.fire.scenario).params, reading.fire, 1000.0)
    ticks = (np.arange(fire.n) + 0.5) * fire.cell_m
    centres = np.array([(x, y) for y in ticks for x in ticks])
    half = fire.cell_m / 2 + fire.pad_m
    d = base.spec().d_safe_m
    values = []
    for r in rows:
        task = Task.of(int(r["mission"]), meta["seed"], args.controller,
                       replace(base, timing=Timing(r["timing"])))
        result = local_mission(task.mission()).run()
        track = [rec.state[:2] for rec in result.records]
        if result.final_state is not None:
            track.append(result.final_state[:2])
        pos = np.array(track)
        values.append(exposure(pos, reading.fire.p_birth, centres, half, d))
    harness.emit({"run": str(args.run), "controller": args.controller,
                  "flights": len(values), "box_side_m": 2 * half,
                  "exposure_mean": round(float(np.mean(values)), 4),
                  "exposure_p10_p90": [round(float(np.percentile(values, q)), 4)
                                       for q in (10, 90)],
                  "expected_per_200": round(200 * float(np.mean(values)), 1)}, args.out)


if __name__ == "__main__":
    main()
