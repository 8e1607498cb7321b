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
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

from dualpilot.evaluation.missions import (
    COLUMNS,
    CONTROLLERS,
    ORACLE,
    Task,
    check_dimensions,
    run_config,
)
from dualpilot.evaluation.results import check_config, read_results
from dualpilot.evaluation.runner import run
from dualpilot.evaluation.stats import summarize
from dualpilot.evaluation.yardstick import markdown, yardstick
from dualpilot.mission.config import MissionConfig

#: draws a summary into a file (dualpilot.viz.evaluation.plot_fig_r5): (summary, path) -> path
Figure = Callable[[dict[str, Any], Path], Path]


def evaluate(
    missions: int,
    out: Path,
    base: MissionConfig | None = None,
    controllers: Iterable[str] = CONTROLLERS,
    jobs: int | None = None,
    progress: bool = True,
    scheduler: str | None = None,
    first_mission: int = 0,
    figure: Figure | None = None,
) -> dict[str, object]:
    """Run (or resume) the evaluation in ``out``; returns the summary it writes.

    Every task is ``base`` (default: the defaults; its seed is the run's seed S, its
    timing, reading, methods and parameters every mission's) flown by one controller of
    ``controllers`` on configuration i, drawn from (S, i): configurations
    ``first_mission`` .. ``first_mission + missions − 1`` are flown. With the controller
    ``oracle`` the summary has the yardstick (:mod:`dualpilot.evaluation.yardstick`), also
    written to ``yardstick.md``; with ``figure``, Fig. r5 is drawn to ``fig_r5.png``.
    """
    base = base or MissionConfig()
    controllers = tuple(controllers)
    check_dimensions(base, controllers)
    out.mkdir(parents=True, exist_ok=True)
    path = out / "results.csv"
    timing = base.timing.value
    for row in read_results(path):
        if row.get("timing") != timing:
            raise ValueError(f"{path} holds timing={row.get('timing')!r}; use another --out")
    reading = base.reading()
    check_config(out, run_config(base))
    indices = range(first_mission, first_mission + missions)
    tasks = [Task.of(i, base.seed, c, base) for i in indices for c in controllers]
    wall = run(tasks, path, COLUMNS, ("mission", "controller"),
               jobs or os.cpu_count() or 1, scheduler, progress)
    rows = [r for r in read_results(path) if int(r["mission"]) in indices]
    summary = summarize(rows, missions, timing, wall_s=wall)
    summary["first_mission"] = first_mission
    summary["ignition_clearance_m"] = reading.mission.ignition_clearance_m
    summary["s2_method"] = base.system2_method
    summary["profile"] = base.profile
    summary["readings"] = reading.readings()
    summary["plant"] = {**reading.plant_readings(),
                        "tracking_margin_m_used": base.spec().tracking_margin_m}
    if ORACLE in controllers:
        ys = yardstick(rows, tasks[0].config)
        summary["yardstick"] = ys
        (out / "yardstick.md").write_text(markdown(ys, f"{base.profile} {dict(base.settings)}, "
                                                       f"missions {indices.start}–"
                                                       f"{indices.stop - 1}"))
    (out / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    if figure is not None:
        figure(summary, out / "fig_r5.png")
    return summary

