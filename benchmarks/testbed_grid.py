"""Missions across the test bed's radio link, one factor at a time: a fleet of missions per cell.

``run`` flies, for every cell of services/testbed/grid.py (clean; latency 100/300/1000 ms;
loss 5/20 %; bandwidth 10/1/0.25 Mbit/s; outages of 5/30 s from step 12; the goal cell
300 ms with 5 % loss) and every controller, the missions of seeds ``--seed0`` …
``--seed0 + --missions - 1`` on ``--scenario``, at real time with the planning time measured,
in rounds of a fleet of ``--vehicles``: each vehicle on its own air host and its own radio
link to one ground host (services/testbed/fleet.py), the test bed brought up once per cell.
The same seeds fly in every cell, so each mission has its twin in ``clean``. Per mission a
row goes to ``<out>/rows.csv`` as each round ends (a run that stops resumes where it
stopped: the missions already in the file are not flown again); ``<out>/grid.json`` has
per cell and controller the success rate, System 2's share of steps, plan deadline misses,
bytes per step on each vehicle's link, and against ``clean`` on the same seeds the
discordant pairs, McNemar's exact p (benchmarks/harness.py ``mcnemar``) and the paired
difference in success with its 95 % interval. ``report`` recomputes grid.json from
rows.csv; ``figure`` draws success against each factor.

    .venv/bin/python benchmarks/testbed_grid.py run --out runs/testbed-grid
    .venv/bin/python benchmarks/testbed_grid.py report runs/testbed-grid
    .venv/bin/python benchmarks/testbed_grid.py figure runs/testbed-grid \\
        --figure runs/testbed-grid/success.png

Root only (network namespaces); the full grid flies for many hours, with no other heavy run
beside it.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import os
import signal
import sys
import time
from pathlib import Path
from typing import Any

import harness  # the repository on the path: before its packages

from dualpilot.evaluation.stats import wilson_interval
from services.testbed import grid
from services.testbed.fleet import FleetPlan, fly_fleet, topology

CONTROLLERS = ("concurrent+risk", "lookahead+risk")
PANELS = {"latency_ms": "one-way latency (ms)", "loss": "loss each way (%)",
          "rate_mbit": "bandwidth each way (Mbit/s)", "outage_s": "outage from step 12 (s)"}


def cpu_times() -> tuple[int, int]:
    """The machine's (busy, total) CPU jiffies since boot (/proc/stat)."""
    with open("/proc/stat") as fh:
        parts = [int(v) for v in fh.readline().split()[1:]]
    idle = parts[3] + (parts[4] if len(parts) > 4 else 0)
    return sum(parts) - idle, sum(parts)


def read_rows(path: Path) -> list[dict[str, str]]:
    if not path.is_file():
        return []
    with path.open(newline="") as fh:
        return list(csv.DictReader(fh))


def append_rows(path: Path, rows: list[dict[str, str]]) -> None:
    new = not path.is_file()
    with path.open("a", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=grid.ROW_FIELDS)
        if new:
            w.writeheader()
        w.writerows(rows)


def records(run_dir: Path) -> tuple[dict[str, Any] | None, list[dict[str, Any]]]:
    """A vehicle's summary.json (None: absent) and the step lines of its steps.jsonl."""
    summary_path = run_dir / "summary.json"
    summary = json.loads(summary_path.read_text()) if summary_path.is_file() else None
    steps = []
    path = run_dir / "steps.jsonl"
    for line in path.read_text().splitlines() if path.is_file() else []:
        try:
            e = json.loads(line)
        except json.JSONDecodeError:
            continue
        if e.get("kind") == "step":
            steps.append(e)
    return summary, steps


def fly_cell(args: argparse.Namespace, cell: grid.Cell, todo: dict[str, list[int]],
             out: Path) -> None:
    """Every round of ``todo`` ({controller: seeds}) in ``cell``, on one test bed."""
    from services.testbed.bed import TestBed

    plans = {c: grid.rounds(seeds, args.vehicles) for c, seeds in todo.items()}
    width = max(len(r) for rs in plans.values() for r in rs)
    cell_dir = out / "cells" / cell.name
    with TestBed(topology=topology(width), impairer=args.impairer, seed=args.link_seed,
                 logs=cell_dir / "testbed") as bed:
        for controller, rs in plans.items():
            for k, seeds in enumerate(rs, start=1):
                run_dir = cell_dir / controller.replace("+", "-") / f"round{k}"
                plan = FleetPlan(
                    seeds=tuple(seeds), radio=cell.impairment(),
                    mission=("--controller", controller, "--timing", args.timing,
                             "--set", f"scenario={args.scenario}"),
                    outage_at_step=grid.OUTAGE_AT_STEP if cell.outage_s > 0 else None,
                    outage_s=cell.outage_s, speed_factor=args.speed_factor,
                    timeout_s=args.timeout_s, stagger_s=args.stagger_s,
                    system2=args.system2)
                busy0, total0, t0 = *cpu_times(), time.monotonic()
                flown = fly_fleet(bed, run_dir, plan)
                busy1, total1 = cpu_times()
                wall, busy = time.monotonic() - t0, (busy1 - busy0) / max(1, total1 - total0)
                rows = []
                for v in flown:
                    summary, steps = records(v.run_dir)
                    rows.append(grid.row(cell, controller, v.seed, v.uav, k, summary, steps,
                                         v.wire, v.outage, v.air_exit,
                                         str(v.run_dir.relative_to(out))))
                append_rows(out / "rows.csv", rows)
                meta = {"cell": cell.name, "controller": controller, "round": k,
                        "seeds": seeds, "wall_s": round(wall, 1),
                        "machine_cpu_busy": round(busy, 3),
                        "load_avg_1min": os.getloadavg()[0]}
                with (out / "rounds.jsonl").open("a") as fh:
                    fh.write(json.dumps(meta) + "\n")
                ok = sum(r["success"] == "1" for r in rows)
                print(f"{cell.name} {controller} round {k}: {ok}/{len(rows)} reached the goal, "
                      f"{wall:.0f} s, machine {100 * busy:.0f} % busy",
                      flush=True)
                report(out)


def run(args: argparse.Namespace) -> int:
    out = Path(args.out).resolve()
    out.mkdir(parents=True, exist_ok=True)
    cells = grid.cells([c for c in args.cells.split(",") if c] if args.cells else ())
    controllers = [c for c in args.controllers.split(",") if c]
    seeds = list(range(args.seed0, args.seed0 + args.missions))
    config = {k: v for k, v in vars(args).items() if k != "func"}
    path = out / "config.json"  # every invocation that flew into ``out``, in order
    before = json.loads(path.read_text()) if path.is_file() else {"invocations": []}
    runs = before.get("invocations", [before])
    runs.append({**config, "cells": [c.name for c in cells], "seeds": seeds,
                 "started": time.strftime("%Y-%m-%dT%H:%M:%S%z")})
    path.write_text(json.dumps({"invocations": runs}, indent=1) + "\n")
    for cell in cells:
        done = {(r["controller"], int(r["seed"])) for r in read_rows(out / "rows.csv")
                if r["cell"] == cell.name}
        todo = {c: [s for s in seeds if (c, s) not in done] for c in controllers}
        todo = {c: s for c, s in todo.items() if s}
        if todo:
            fly_cell(args, cell, todo, out)
    report(out)
    return 0


def compare(rows: list[dict[str, str]], entry: dict[str, Any]) -> dict[str, Any]:
    """``entry``'s cell against clean on the same seeds: pairs, McNemar, paired difference."""
    matched = grid.pairs(rows, entry["controller"], grid.BASELINE, entry["cell"])
    only_clean, only_cell, p = harness.mcnemar(matched)
    delta, lo, hi = grid.paired_difference(matched)
    return {"pairs": len(matched), "only_clean": only_clean, "only_cell": only_cell,
            "mcnemar_p": None if p is None else round(p, 4),
            "delta_points": None if math.isnan(delta) else round(delta, 2),
            "delta_ci95": None if math.isnan(delta) else [round(lo, 2), round(hi, 2)]}


def report(out: Path) -> dict[str, Any]:
    """grid.json from rows.csv (and rounds.jsonl, config.json); a table on stdout."""
    rows = read_rows(out / "rows.csv")
    summary = grid.summarise(rows)
    for entry in summary:
        if entry["cell"] != grid.BASELINE:
            entry["vs_clean"] = compare(rows, entry)
    rounds_path = out / "rounds.jsonl"
    config_path = out / "config.json"
    doc = {"config": json.loads(config_path.read_text()) if config_path.is_file() else {},
           "cells": [c.wire() for c in grid.cells()], "summary": summary,
           "rounds": [json.loads(line) for line in rounds_path.read_text().splitlines()]
           if rounds_path.is_file() else []}
    (out / "grid.json").write_text(json.dumps(doc, indent=1) + "\n")
    print(table(summary), flush=True)
    return doc


def table(summary: list[dict[str, Any]]) -> str:
    """The summary as a Markdown table."""
    lines = ["| cell | controller | missions | success | Δ vs clean, points (95 % CI) | "
             "only clean / only cell | McNemar p | System 2's steps | plan deadline misses "
             "(missions with any) | wire bytes per step |", "|" + "---|" * 10]
    for e in summary:
        v = e.get("vs_clean")
        delta = (f"{v['delta_points']:+.1f} ({v['delta_ci95'][0]:+.1f}, "
                 f"{v['delta_ci95'][1]:+.1f})" if v and v["delta_points"] is not None else "—")
        disc = f"{v['only_clean']} / {v['only_cell']}" if v else "—"
        p = f"{v['mcnemar_p']:.3f}" if v and v["mcnemar_p"] is not None else "—"
        share = f"{100 * e['s2_share']:.1f} %" if e["s2_share"] is not None else "—"
        wire = f"{e['wire_bytes_per_step']:.0f}" if e["wire_bytes_per_step"] else "—"
        unfinished = f" ({e['unfinished']} unfinished)" if e["unfinished"] else ""
        lines.append(f"| {e['cell']} | {e['controller']} | {e['missions']}{unfinished} | "
                     f"{100 * e['success_rate']:.1f} % | {delta} | {disc} | {p} | {share} | "
                     f"{e['plan_deadline']} ({e['missions_with_deadline_miss']}) | {wire} |")
    return "\n".join(lines)


def figure(args: argparse.Namespace) -> int:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    src = Path(args.grid)
    doc = json.loads((src / "grid.json" if src.is_dir() else src).read_text())
    summary = doc["summary"]
    controllers = list(dict.fromkeys(e["controller"] for e in summary))
    clean = {e["controller"]: e for e in summary if e["cell"] == grid.BASELINE}
    fig, axes = plt.subplots(1, len(PANELS) + 1, figsize=(15.0, 3.8), sharey=True)
    for ax, (factor, label) in zip(axes, PANELS.items(), strict=False):
        levels = [0.0 if factor != "rate_mbit" else math.inf, *grid.FACTORS[factor]]
        ticks = ["unshaped" if v == math.inf else f"{100 * v:g}" if factor == "loss"
                 else f"{v:g}" for v in levels]
        for k, c in enumerate(controllers):
            pts = [(0, clean.get(c))]
            pts += [(i + 1, next((e for e in summary if e["controller"] == c
                                  and e["factor"] == factor and e["level"] == v), None))
                    for i, v in enumerate(grid.FACTORS[factor])]
            xs = [i + 0.08 * (k - 0.5) for i, e in pts if e]
            ys = [e["success_rate"] for _, e in pts if e]
            ci = [wilson_interval(e["successes"], e["missions"]) for _, e in pts if e]
            if not xs:
                continue
            err = [[y - lo for y, (lo, _) in zip(ys, ci, strict=True)],
                   [hi - y for y, (_, hi) in zip(ys, ci, strict=True)]]
            ax.errorbar(xs, ys, yerr=err, fmt="o-", color=f"C{k}", capsize=3, label=c)
        ax.set_xticks(range(len(levels)), ticks)
        ax.set_xlim(-0.4, len(levels) - 0.6)
        ax.set_xlabel(label)
        ax.grid(True, alpha=0.3)
    ax = axes[-1]
    for k, c in enumerate(controllers):
        cells = [clean.get(c), next((e for e in summary if e["controller"] == c
                                     and e["factor"] == "goal"), None)]
        for i, e in enumerate(cells):
            if e is None:
                continue
            lo, hi = wilson_interval(e["successes"], e["missions"])
            y = e["success_rate"]
            ax.errorbar([i + 0.08 * (k - 0.5)], [y], yerr=[[y - lo], [hi - y]], fmt="s",
                        color=f"C{k}", capsize=3)
    ax.set_xticks([0, 1], ["clean", "300 ms\n+ 5 %"])
    ax.set_xlim(-0.6, 1.6)
    ax.set_xlabel("the goal cell")
    ax.grid(True, alpha=0.3)
    axes[0].set_ylabel("missions reaching the goal")
    axes[0].set_ylim(-0.02, 1.02)
    axes[0].legend(fontsize=8, loc="lower left")
    n = max((e["missions"] for e in summary), default=0)
    fig.suptitle(f"Success across the test bed's radio link, one factor at a time "
                 f"(up to {n} missions a cell, the same seeds in each; 95 % Wilson intervals)",
                 fontsize=10)
    fig.tight_layout()
    path = Path(args.figure)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    print(f"wrote {path}")
    return 0


def _terminated(signum: int, frame: object) -> None:
    """SIGTERM takes the test bed down as Ctrl-C does."""
    raise KeyboardInterrupt(f"signal {signum}")


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = p.add_subparsers(dest="action", required=True)
    r = sub.add_parser("run", help="fly the grid (root)")
    r.add_argument("--out", default="runs/testbed-grid")
    r.add_argument("--controllers", default=",".join(CONTROLLERS))
    r.add_argument("--cells", default="", help="comma-separated cell names (default: all: "
                   + ",".join(c.name for c in grid.cells()) + ")")
    r.add_argument("--missions", type=int, default=50, help="missions a cell and controller")
    r.add_argument("--seed0", type=int, default=0)
    r.add_argument("--vehicles", type=int, default=10, help="vehicles flying at once")
    r.add_argument("--scenario", default="grass-15")
    r.add_argument("--timing", default="measured", choices=["measured", "paper"])
    r.add_argument("--speed-factor", type=float, default=1.0)
    r.add_argument("--timeout-s", type=float, default=1800.0,
                   help="a mission's limit, wall s (a step waits for the link: at 300 ms and "
                        "5 %% loss a mission took 2-4 times its real time)")
    r.add_argument("--stagger-s", type=float, default=1.0,
                   help="wall s between two vehicles' starts")
    r.add_argument("--system2", type=int, default=2, help="System 2 replicas on the ground")
    r.add_argument("--impairer", default="auto", choices=["auto", "impairer", "netem"])
    r.add_argument("--link-seed", type=int, default=0,
                   help="seed of the links' loss and jitter draws (the same in every cell)")
    r.set_defaults(func=run)
    rep = sub.add_parser("report", help="grid.json and a table from rows.csv")
    rep.add_argument("out")
    rep.set_defaults(func=lambda a: 0 if report(Path(a.out)) else 1)
    f = sub.add_parser("figure", help="success against each factor")
    f.add_argument("grid", help="grid.json or its run directory")
    f.add_argument("--figure", required=True, help="where the PNG goes")
    f.set_defaults(func=figure)
    args = p.parse_args(argv)
    signal.signal(signal.SIGTERM, _terminated)
    result: int = args.func(args)
    return result


if __name__ == "__main__":
    sys.exit(main())
