"""Mission records on disk: summary.json, steps.csv and trace.json.

``steps.csv`` has one row per step (``system`` and ``attention`` 1-based as in
the paper; ``system`` 0 means no plan was flown and the UAV braked).
``trace.json`` keeps what the figures need: per step the planned positions
and the fire regions and hulls the planners saw.
"""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np

from .mission import MissionResult

STEP_COLUMNS = [
    "t",
    "x",
    "y",
    "vx",
    "vy",
    "ux",
    "uy",
    "system",
    "d_t",
    "xi1",
    "xi2",
    "xi3",
    "p1",
    "p2",
    "p3",
    "attention",
    "psi1",
    "psi2",
    "fires_active",
    "objective",
    "planning_time_s",
    "fire_substeps",
    "plan_status",
    "source",
]


def _num(v: float) -> float | str:
    return v if np.isfinite(v) else "inf" if v > 0 else "nan"


def write_summary(result: MissionResult, out: Path) -> Path:
    path = out / "summary.json"
    path.write_text(json.dumps(result.summary(), indent=2) + "\n")
    return path


def write_steps_csv(result: MissionResult, out: Path) -> Path:
    path = out / "steps.csv"
    with path.open("w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow(STEP_COLUMNS)
        for r in result.records:
            d = r.decision
            writer.writerow(
                [
                    r.t,
                    *(f"{v:.6g}" for v in r.state),
                    *(f"{v:.6g}" for v in r.control),
                    r.system,
                    _num(r.d_t),
                    *(f"{v:.6g}" for v in d.xi),
                    *(f"{v:.6g}" for v in d.p),
                    d.attention,
                    *(f"{v:.6g}" for v in d.psi),
                    r.fires_active,
                    d.objective.value,
                    f"{r.planning_time_s:.6g}",
                    r.fire_substeps,
                    r.plan_status,
                    r.info.get("source", ""),
                ]
            )
    return path


def write_trace(result: MissionResult, out: Path) -> Path:
    cfg = result.config
    steps = []
    for r in result.records:
        steps.append(
            {
                "t": r.t,
                "system": r.system,
                "position": [round(float(v), 3) for v in r.state[:2]],
                "plan": np.round(r.planned_positions, 2).tolist(),
                "regions": [
                    [rc.center_x, rc.center_y, rc.width, rc.height] for rc in r.snapshot.regions
                ],
                "hulls": [np.round(h.vertices, 2).tolist() for h in r.snapshot.hulls],
            }
        )
    final = result.final_state if result.final_state is not None else np.full(4, np.nan)
    doc = {
        "controller": result.controller,
        "seed": result.seed,
        "success": result.success,
        "failure_cause": result.failure_cause,
        "start": list(cfg.start),
        "goal": [cfg.goal.center_x, cfg.goal.center_y, cfg.goal.width, cfg.goal.height],
        "area_size_m": cfg.area_size_m,
        "final_position": [float(v) for v in final[:2]],
        "steps": steps,
    }
    path = out / "trace.json"
    path.write_text(json.dumps(doc) + "\n")
    return path


def write_all(result: MissionResult, out: Path) -> list[Path]:
    out.mkdir(parents=True, exist_ok=True)
    return [write_summary(result, out), write_steps_csv(result, out), write_trace(result, out)]


def read_steps_csv(path: Path) -> dict[str, np.ndarray]:
    """Numeric columns of steps.csv as float arrays (text columns as object arrays)."""
    with Path(path).open() as fh:
        rows = list(csv.DictReader(fh))
    cols: dict[str, np.ndarray] = {}
    for name in STEP_COLUMNS:
        vals = [row.get(name, "") for row in rows]
        try:
            cols[name] = np.array([float(v) for v in vals])
        except ValueError:
            cols[name] = np.array(vals, dtype=object)
    return cols
