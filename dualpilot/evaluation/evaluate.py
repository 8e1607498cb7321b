"""Monte-Carlo evaluation of Sec. IV (Fig. r5): CC, S1 and S2 on the same random missions.

The one-point case of the sweep (:mod:`dualpilot.evaluation.sweep`): configuration
i (start, goal and fire stream) is drawn from the seed pair (S, i) and flown by
every controller, so the three see identical missions. Rows are appended to
``results.csv`` as missions finish (flushed and synced), so an interrupted run
loses nothing already finished and a re-run with the same directory skips what
is recorded. A mission that raises becomes an error row with its message.
"""

from __future__ import annotations

import json
import os
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

from dualpilot.evaluation.missions import COLUMNS, CONTROLLERS, ORACLE, Task
from dualpilot.evaluation.results import check_config, read_results
from dualpilot.evaluation.runner import run
from dualpilot.evaluation.stats import summarize
from dualpilot.evaluation.yardstick import markdown, yardstick
from dualpilot.readings import get_profile


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
    first_mission: int = 0,
) -> dict[str, object]:
    """Run (or resume) the evaluation in ``out``; returns the summary it writes.

    ``profile`` and ``settings`` (field name → value or its text) choose the
    reading (:mod:`dualpilot.readings`); ``ignition_clearance_m``, when set,
    overrides the profile's. Configurations ``first_mission`` .. ``first_mission +
    missions − 1`` are flown. With the controller ``oracle`` the summary has the
    yardstick (:mod:`dualpilot.evaluation.yardstick`), also written to ``yardstick.md``.
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
    indices = range(first_mission, first_mission + missions)
    tasks = [Task.of(i, seed, c, timing, s2_method, profile=profile, settings=pinned)
             for i in indices for c in controllers]
    wall = run(tasks, path, COLUMNS, ("mission", "controller"),
               jobs or os.cpu_count() or 1, scheduler, progress)
    rows = [r for r in read_results(path) if int(r["mission"]) in indices]
    summary = summarize(rows, missions, timing, wall_s=wall)
    summary["first_mission"] = first_mission
    summary["ignition_clearance_m"] = reading.mission.ignition_clearance_m
    summary["s2_method"] = s2_method
    summary["profile"] = profile
    summary["readings"] = reading.readings()
    if ORACLE in controllers:
        ys = yardstick(rows, tasks[0].config)
        summary["yardstick"] = ys
        (out / "yardstick.md").write_text(markdown(ys, f"{profile} {dict(pinned)}, missions "
                                                       f"{indices.start}–{indices.stop - 1}"))
    (out / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    from dualpilot.viz.evaluation import plot_fig_r5

    plot_fig_r5(summary, out / "fig_r5.png")
    return summary
