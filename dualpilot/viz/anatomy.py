"""One figure per class of avoidable failure (dualpilot/evaluation/anatomy.py).

Each figure is one mission: the fires when it ended (regions, the one that ended it
outlined thick, and their hulls), the controller's flown path up to the failure, the
oracle's witness through the same fires (dashed), the start, G and the UAV's last
position with its d_safe disc. The title names the class, the controller, the reading
and the mission (configuration index and seed), so the mission can be flown again.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.patches import Circle, Polygon, Rectangle

from dualpilot.evaluation.anatomy import (
    CLASSES,
    DESCRIPTIONS,
    Case,
    anatomy,
    cases,
    classify,
    counts,
    replay,
)
from dualpilot.evaluation.missions import other_flags
from dualpilot.mission.config import MissionConfig
from dualpilot.oracle.oracle import solve
from dualpilot.viz.mission import (
    FIRE_EDGE,
    FIRE_FACE,
    GOAL_EDGE,
    GOAL_FACE,
    HULL_EDGE,
    HULL_FACE,
    SYSTEM_COLORS,
)

DPI = 120


def draw_case(case: Case, path: Path, reading_label: str) -> Path:
    """The figure of one avoidable failure, written to ``path``."""
    config = case.config()
    result, final = replay(config)
    failure = classify(result, final, config)
    witness = solve(config).flight
    spec = config.spec()
    fig = Figure(figsize=(6.4, 6.6))
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 1, 1)
    a = spec.area_size_m
    ax.add_patch(Rectangle((0, 0), a, a, fill=False, edgecolor="0.6", lw=0.8))
    for hull in final.hulls:
        ax.add_patch(Polygon(hull.vertices, closed=True, facecolor=HULL_FACE, edgecolor=HULL_EDGE,
                             alpha=0.35, lw=0.6))
    for region, fid in zip(final.regions, final.front_ids, strict=True):
        x0, y0, x1, y1 = region.bounds
        mine = fid == failure.front_id
        ax.add_patch(Rectangle((x0, y0), x1 - x0, y1 - y0, facecolor=FIRE_FACE,
                               edgecolor=FIRE_EDGE, alpha=0.55, lw=2.4 if mine else 0.8))
    gx0, gy0, gx1, gy1 = spec.goal.bounds
    ax.add_patch(Rectangle((gx0, gy0), gx1 - gx0, gy1 - gy0, facecolor=GOAL_FACE,
                           edgecolor=GOAL_EDGE, alpha=0.7))
    if witness is not None and witness.final_state is not None:
        w = np.array([r.state[:2] for r in witness.records] + [witness.final_state[:2]])
        ax.plot(w[:, 0], w[:, 1], "--", color="#2a9d3a", lw=1.6, label="oracle's witness")
    flown = np.array([r.state[:2] for r in result.records]
                     + ([result.final_state[:2]] if result.final_state is not None else []))
    systems = [r.system for r in result.records]
    for k in range(len(flown) - 1):
        ax.plot(flown[k:k + 2, 0], flown[k:k + 2, 1], "-",
                color=SYSTEM_COLORS.get(systems[min(k, len(systems) - 1)], "k"), lw=1.8)
    ax.plot([], [], "-", color=SYSTEM_COLORS[1], label=f"{case.controller}: System 1")
    ax.plot([], [], "-", color=SYSTEM_COLORS[2], label=f"{case.controller}: System 2")
    last = result.records[-1].state
    ax.add_patch(Circle((float(last[0]), float(last[1])), spec.d_safe_m, fill=False,
                        edgecolor="k", lw=1.0))
    ax.plot(*spec.start, "ko", ms=5)
    ax.set_xlim(-20, a + 20)
    ax.set_ylim(-20, a + 20)
    ax.set_aspect("equal")
    ax.set_xlabel("east (m)")
    ax.set_ylabel("north (m)")
    ax.legend(loc="lower right", fontsize=8)
    ax.set_title(f"{failure.cls}: {DESCRIPTIONS[failure.cls]}\n{reading_label}, "
                 f"{case.controller}, mission {case.index} (seed {config.seed}),\n"
                 f"{failure.ending.replace('_', ' ')} at step {failure.step}", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=DPI)
    return path


def replay_command(case: Case) -> str:
    """``dualpilot mission`` flying the case's mission again (its seed, start and goal)."""
    config = case.config()
    g, start = config.goal, config.start
    assert start is not None  # an evaluation's mission has its own start
    sets = "".join(f" --set {k}={v}" for k, v in config.settings)
    if config.system2_method != MissionConfig().system2_method:
        sets += f" --s2-method {config.system2_method}"
    sets += "".join(f" {flag}" for flag in other_flags(config))  # the run's other choices
    return (f"dualpilot mission --controller {case.controller} --seed {config.seed} "
            f"--start {start[0]!r},{start[1]!r} --goal {g.center_x!r},{g.center_y!r},"
            f"{g.width!r},{g.height!r} --profile {config.profile} "
            f"--timing {config.timing.value}{sets}")


def class_table(counted: dict[str, dict[str, int]]) -> str:
    """Controller × class counts of avoidable failures as a Markdown table."""
    classes = [c for c in CLASSES if any(c in per for per in counted.values())]
    lines = ["| controller | " + " | ".join(classes) + " | total |",
             "|---|" + "---|" * (len(classes) + 1)]
    for name, per in counted.items():
        cells = [str(per.get(c, 0)) for c in classes]
        lines.append(f"| {name} | " + " | ".join(cells) + f" | {sum(per.values())} |")
    return "\n".join(lines) + "\n"


def figure_cases(todo: list[Case], rows: list[dict[str, Any]],
                 controllers: list[str] | None) -> list[tuple[Case, str]]:
    """One case per class: the first controller's first of that class, else the first
    case of it of the next controller (in ``controllers``' order) that has one."""
    order = {c: k for k, c in enumerate(controllers or [])}
    ranked = sorted(zip(todo, rows, strict=True),
                    key=lambda cr: (order.get(cr[0].controller, len(order)), cr[0].controller,
                                    cr[0].index))
    chosen: dict[str, Case] = {}
    for case, row in ranked:
        cls = str(row["class"])
        if cls in CLASSES and cls not in chosen:
            chosen[cls] = case
    return [(chosen[c], c) for c in CLASSES if c in chosen]


def _anatomy(args: argparse.Namespace) -> int:
    run_dir = Path(args.run)
    controllers = args.controllers.split(",") if args.controllers else None
    rows = anatomy(run_dir, controllers, args.jobs)
    table = class_table(counts(rows))
    (run_dir / "anatomy.md").write_text(table)
    print(table)
    if args.figures:
        out = Path(args.figures)
        out.mkdir(parents=True, exist_ok=True)
        for case, cls in figure_cases(cases(run_dir, controllers), rows, controllers):
            path = out / f"anatomy_{args.label or run_dir.name}_{cls}.png"
            print(draw_case(case, path, args.label or run_dir.name))
            line = f"- {path.name}: `{replay_command(case)}`"
            print(line)
            table += line + "\n"
        (run_dir / "anatomy.md").write_text(table)
    print(f"rows in {run_dir / 'anatomy.csv'}; table in {run_dir / 'anatomy.md'}")
    return 0


def add_anatomy_parser(sub: Any) -> None:
    """``dualpilot anatomy``: the avoidable failures of an evaluation with the oracle."""
    p = sub.add_parser("anatomy", help="classify the avoidable failures of an evaluation run "
                       "with the oracle (docs/yardstick.md)")
    p.add_argument("run", help="the run directory of dualpilot evaluate --controllers ...,oracle")
    p.add_argument("--controllers", default="", help="only these (default: all but the oracle); "
                   "a class's figure shows the first of them that has one")
    p.add_argument("--jobs", type=int, default=1, help="Dask workers (default: in this process)")
    p.add_argument("--figures", default="", metavar="DIR",
                   help="one figure per class into DIR (anatomy_<label>_<class>.png)")
    p.add_argument("--label", default="", help="the reading's name in titles and file names")
    p.set_defaults(func=_anatomy)
