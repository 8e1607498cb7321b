"""Monte-Carlo evaluation of Sec. IV (Fig. r5): CC, S1 and S2 on the same random missions.

The one-point case of the sweep runner (:mod:`dualpilot.sweep`): configuration
i (start, goal and fire stream) is drawn from the seed pair (S, i) and flown by
every controller, so the three see identical missions. Rows are appended to
``results.csv`` as missions finish (flushed and synced), so an interrupted run
loses nothing already finished and a re-run with the same directory skips what
is recorded. A mission that raises becomes an error row with its message.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from dualpilot.mission.params import CONTROLLER_NAMES
from dualpilot.readings import get_profile
from dualpilot.sweep import (  # noqa: F401 - the runner's names, re-exported
    COLUMNS,
    CONTROLLERS,
    ResultsFile,
    Task,
    check_config,
    mission_seed,
    mission_spec,
    read_results,
    run,
    run_task,
)


def evaluate(
    missions: int,
    out: Path,
    seed: int = 0,
    timing: str = "paper",
    jobs: int | None = None,
    controllers: Iterable[str] = CONTROLLERS,
    s2_method: str = "fast",
    progress: bool = True,
    ignition_clearance_m: float | None = None,
    profile: str = "today",
    settings: Mapping[str, Any] | None = None,
    scheduler: str | None = None,
) -> dict[str, object]:
    """Run (or resume) the evaluation in ``out``; returns the summary it writes.

    ``profile`` and ``settings`` (field name → value or its text) choose the
    reading (:mod:`dualpilot.readings`); ``ignition_clearance_m``, when set,
    overrides the profile's.
    """
    out.mkdir(parents=True, exist_ok=True)
    path = out / "results.csv"
    controllers = tuple(controllers)
    for row in read_results(path):
        if row.get("timing") != timing:
            raise ValueError(f"{path} holds timing={row.get('timing')!r}; use another --out")
    extra = dict(settings or {})
    if ignition_clearance_m is not None:
        extra["ignition_clearance_m"] = ignition_clearance_m
    reading = get_profile(profile).with_settings(extra)  # checks the settings
    pinned = tuple((k, reading.values()[k]) for k in extra)
    check_config(out, {"seed": seed, "profile": profile, "s2_method": s2_method,
                       "settings": {k: v for k, v in pinned}})
    tasks = [Task(i, seed, c, timing, s2_method, profile=profile, settings=pinned)
             for i in range(missions) for c in controllers]
    wall = run(tasks, path, COLUMNS, ("mission", "controller"),
               jobs or os.cpu_count() or 1, scheduler, progress)
    rows = [r for r in read_results(path) if int(r["mission"]) < missions]
    summary = summarize(rows, missions, timing, wall_s=wall)
    summary["ignition_clearance_m"] = reading.mission.ignition_clearance_m
    summary["s2_method"] = s2_method
    summary["profile"] = profile
    summary["readings"] = reading.readings()
    (out / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    from dualpilot.viz.evaluation import plot_fig_r5

    plot_fig_r5(summary, out / "fig_r5.png")
    return summary


def wilson_interval(successes: int, n: int, z: float = 1.96) -> tuple[float, float]:
    """95 % Wilson score interval of a success rate."""
    if n == 0:
        return (float("nan"), float("nan"))
    p = successes / n
    denom = 1 + z * z / n
    centre = (p + z * z / (2 * n)) / denom
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / denom
    return (centre - half, centre + half)


def mean_interval(values: list[float], z: float = 1.96) -> tuple[float, float, float]:
    """Mean and its 95 % normal-approximation interval."""
    if not values:
        return (float("nan"), float("nan"), float("nan"))
    arr = np.asarray(values, dtype=float)
    m = float(arr.mean())
    half = z * float(arr.std(ddof=1)) / math.sqrt(len(arr)) if len(arr) > 1 else 0.0
    return (m, m - half, m + half)


def summarize(
    rows: list[dict[str, str]], missions: int, timing: str, wall_s: float = float("nan")
) -> dict[str, object]:
    """summary.json: per controller success rate, mission time, energy, planning time, with CIs."""
    result: dict[str, object] = {"missions": missions, "timing": timing, "wall_s": wall_s}
    ctrl: dict[str, object] = {}
    for c in CONTROLLER_NAMES:
        rs = [r for r in rows if r["controller"] == c]
        if not rs:
            continue
        ok = [r for r in rs if r["success"] == "1"]
        lo, hi = wilson_interval(len(ok), len(rs))
        t_mean, t_lo, t_hi = mean_interval([float(r["mission_time_s"]) for r in ok])
        e_mean, e_lo, e_hi = mean_interval([float(r["energy"]) for r in ok])
        plan_t = [float(r["planning_time_s_median"]) for r in rs if r["planning_time_s_median"]]
        causes: dict[str, int] = {}
        for r in rs:
            if r["success"] != "1":
                causes[r["failure_cause"]] = causes.get(r["failure_cause"], 0) + 1
        ctrl[c] = {
            "n": len(rs),
            "success_rate": len(ok) / len(rs),
            "success_rate_ci95": [lo, hi],
            "mission_time_s_mean": t_mean,
            "mission_time_s_ci95": [t_lo, t_hi],
            "energy_mean": e_mean,
            "energy_ci95": [e_lo, e_hi],
            "planning_time_s_median": float(np.median(plan_t)) if plan_t else float("nan"),
            "fire_substeps_per_step": float(
                np.sum([float(r.get("fire_substeps") or 0.0) for r in rs])
                / max(1.0, float(np.sum([max(1.0, float(r["steps"] or 0.0)) for r in rs])))),
            "switches_mean": float(np.mean([float(r["switches"]) for r in ok])) if ok else 0.0,
            "switch_energy_mean": float(np.mean([float(r.get("switch_energy") or 0.0)
                                                 for r in ok])) if ok else 0.0,
            "errors": sum(1 for r in rs if r["error"]),
            "failure_causes": causes,
        }
    result["controllers"] = ctrl
    return result
