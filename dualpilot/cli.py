"""`dualpilot` command line: missions, figures and benchmarks."""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

from dualpilot.mission.config import controller_names
from dualpilot.mission.config_args import (
    READING_FLAGS,
    add_config_arguments,
    config_from_args,
)
from dualpilot.model.scenarios import scenario_table
from dualpilot.readings import profile_table


def _mission(args: argparse.Namespace) -> int:
    from dualpilot.mission.local import local_mission
    from dualpilot.mission.records import write_all

    mission = local_mission(config_from_args(args))
    t0 = time.perf_counter()
    for record in iter(mission.step, None):
        if not args.quiet:
            x, y = record.state[:2]
            print(
                f"t={record.t:3d} S{record.system} pos=({x:6.1f},{y:6.1f})"
                f" fires={record.fires_active} d_t={record.d_t:7.1f} plan={record.plan_status}",
                flush=True,
            )
    result = mission.result
    out = Path(args.out)
    paths = write_all(result, out)
    if not args.no_figures:
        from dualpilot.viz.mission import make_figures

        paths += make_figures(out)
    summary = result.summary()
    print(
        json.dumps(
            {
                k: summary[k]
                for k in (
                    "controller_name",
                    "controller",
                    "seed",
                    "timing",
                    "success",
                    "ending",
                    "steps",
                    "mission_time_s",
                    "energy",
                    "switches",
                )
            }
        )
    )
    print(f"wall time {time.perf_counter() - t0:.1f} s; results in {out}/:")
    for p in paths:
        print(f"  {p}")
    return 0


def _figures(args: argparse.Namespace) -> int:
    from dualpilot.viz.mission import make_figures

    steps = [int(s) for s in args.steps.split(",")] if args.steps else None
    for p in make_figures(Path(args.run), steps=steps):
        print(p)
    return 0


def _evaluate(args: argparse.Namespace) -> int:
    from dualpilot.evaluation.evaluate import evaluate
    from dualpilot.viz.evaluation import plot_fig_r5

    out = Path(args.out)
    summary = evaluate(
        args.missions,
        out,
        config_from_args(args),
        controllers=args.controllers.split(","),
        jobs=args.jobs,
        scheduler=args.scheduler,
        first_mission=args.first_mission,
        figure=plot_fig_r5,
    )
    print(json.dumps(summary, indent=2))
    if (out / "yardstick.md").exists():
        print((out / "yardstick.md").read_text())
    print(f"results in {out}/: results.csv summary.json fig_r5.png"
          + (" yardstick.md" if "yardstick" in summary else ""))
    return 0


def _sweep(args: argparse.Namespace) -> int:
    from dualpilot.evaluation.sweep import grid_points, load_grid, parse_axes, sweep
    from dualpilot.viz.sweep import plot_sweep

    doc = load_grid(Path(args.grid)) if args.grid else {}
    axes = {**{k: list(v) for k, v in (doc.get("grid") or {}).items()}, **parse_axes(args.set)}
    for _, name in READING_FLAGS:  # a named reading flag: a grid axis of one value
        if getattr(args, f"reading_{name}"):
            axes.setdefault(name, [getattr(args, f"reading_{name}")])
    # the sweep file's seed, timing and System 2 method, unless a flag gives them
    args = argparse.Namespace(**{
        **vars(args), "seed": args.seed if args.seed is not None else int(doc.get("seed", 0)),
        "timing": args.timing or str(doc.get("timing", "paper")),
        "s2_method": args.s2_method or str(doc.get("s2_method", "fast"))})
    base = config_from_args(args, settings={})  # the grid points give the reading's settings
    points = grid_points(axes, doc.get("profile", base.profile), doc.get("points") or ())
    controllers = args.controllers or ",".join(doc.get("controllers") or ["cc", "s1", "s2"])
    summary = sweep(
        points, args.missions or int(doc.get("missions", 200)), Path(args.out), base,
        controllers=controllers.split(","), jobs=args.jobs, scheduler=args.scheduler,
        figure=None if args.no_figures else plot_sweep,
    )
    for p in summary["points"]:
        rates = " ".join(f"{c.upper()} {100 * v['success_rate']:5.1f}%"
                         for c, v in p["controllers"].items())
        print(f"[{p['point']:2d}] {rates}  {p['label']}")
    print(f"wall time {summary['wall_s']:.1f} s; results in {args.out}/: results.csv "
          "results.parquet summary.json" + ("" if args.no_figures else " fig_sweep.png"))
    return 0


def _profiles(args: argparse.Namespace) -> int:
    print(profile_table())
    return 0


def _scenarios(args: argparse.Namespace) -> int:
    print(scenario_table())
    if args.measure:
        from dualpilot.model.physics_fire import measure
        from dualpilot.model.scenarios import SCENARIOS

        seeds = range(args.seeds)
        checkpoints = [int(v) for v in args.substeps.split(",")]
        print(f"\nseeds 0..{args.seeds - 1}, births anywhere (p_b per sub-step), means:")
        print(f"{'scenario':18s} {'sub-steps':>9s} {'fronts':>6s} {'burned m2':>10s} "
              f"{'hulls m2':>10s} {'hulls/burned':>12s} {'vertices':>8s} {'ms/sub-step':>11s}")
        for name in SCENARIOS:
            for r in measure(name, seeds, checkpoints):
                print(f"{name:18s} {r['substeps']:9.0f} {r['fronts']:6.1f} "
                      f"{r['burned_m2']:10.0f} {r['hull_union_m2']:10.0f} "
                      f"{r['hull_union_m2'] / max(r['burned_m2'], 1.0):12.2f} "
                      f"{r['hull_vertices']:8.2f} {r['ms_per_substep']:11.2f}", flush=True)
    return 0


def _add_mission(sub: Any) -> None:
    m = sub.add_parser("mission", help="fly one mission in-process")
    add_config_arguments(m)
    m.add_argument("--out", default="runs/latest")
    m.add_argument("--no-figures", action="store_true")
    m.add_argument("--quiet", action="store_true")
    m.set_defaults(func=_mission)
    f = sub.add_parser("figures", help="draw the paper's figures for a recorded run")
    f.add_argument("--run", required=True, help="run directory with steps.csv and trace.json")
    f.add_argument("--steps", default="", help="comma-separated steps for the Fig. r1 panels")
    f.set_defaults(func=_figures)


def _add_evaluate(sub: Any) -> None:
    e = sub.add_parser("evaluate", help="Monte-Carlo comparison of CC, S1 and S2 (Fig. r5)",
                       description="Every controller of --controllers flies configurations "
                       "I .. I + missions − 1 of --seed with the mission configuration's other "
                       "flags (those of dualpilot mission; the start, goal and area are each "
                       "configuration's).")
    e.add_argument("--missions", type=int, default=200)
    e.add_argument("--first-mission", type=int, default=0, metavar="I",
                   help="fly configurations I .. I + missions − 1 of --seed (held-out sets)")
    e.add_argument("--jobs", type=int, default=0, help="worker processes (default: all cores)")
    e.add_argument("--controllers", default="cc,s1,s2",
                   help=f"any of {','.join(controller_names())} (concurrent: cc with the "
                        "concurrent supervisor; +risk: with the fire forecast), and oracle: "
                        "the clairvoyant yardstick (docs/yardstick.md)")
    e.add_argument("--out", default="runs/eval")
    e.add_argument("--scheduler", default=None, metavar="tcp://HOST:8786",
                   help="run on this Dask cluster (default: a LocalCluster of --jobs workers)")
    add_config_arguments(e, seed=0, per_mission=False)
    e.set_defaults(func=_evaluate)


def _add_sweep(sub: Any) -> None:
    w = sub.add_parser("sweep", help="a grid of readings × controllers × missions on Dask")
    w.add_argument("--grid", default="", help="YAML: profile, grid (name: [values]), points, "
                   "missions, controllers, seed, timing")
    w.add_argument("--missions", type=int, default=0, help="per grid point (default 200)")
    w.add_argument("--controllers", default="")
    w.add_argument("--jobs", type=int, default=0, help="LocalCluster workers (default: cores)")
    w.add_argument("--scheduler", default=None, metavar="tcp://HOST:8786",
                   help="use this Dask cluster (workers: dask worker tcp://HOST:8786)")
    w.add_argument("--out", default="runs/sweep")
    w.add_argument("--no-figures", action="store_true")
    add_config_arguments(w, seed=0, per_mission=False, grid=True)
    # unset unless given: the sweep file's (else 0, paper, fast)
    w.set_defaults(func=_sweep, seed=None, timing=None, s2_method=None)


def _add_readings(sub: Any) -> None:
    pr = sub.add_parser("profiles", help="the named readings and their parameter values")
    pr.set_defaults(func=_profiles)
    sc = sub.add_parser("scenarios", help="the fire processes: the paper's and the "
                        "fire-behaviour scenarios (--scenario NAME)")
    sc.add_argument("--measure", action="store_true",
                    help="run each scenario's fires: the area its hulls cover against the area "
                         "burned, and the cost of a sub-step")
    sc.add_argument("--seeds", type=int, default=5, help="with --measure: seeds 0..N-1")
    sc.add_argument("--substeps", default="100,200,400",
                    help="with --measure: the sub-steps of T_f at which to measure")
    sc.set_defaults(func=_scenarios)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="dualpilot", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)
    _add_mission(sub)
    _add_evaluate(sub)
    _add_sweep(sub)
    _add_readings(sub)
    from dualpilot.evaluation.bench import add_bench_parser
    from dualpilot.viz.anatomy import add_anatomy_parser  # the yardstick's failure anatomy
    from dualpilot.viz.bound import add_bound_parser  # the supervisor's bound
    from dualpilot.viz.showcase import add_showcase_parser  # the Fig. r1 story

    add_showcase_parser(sub)
    add_bench_parser(sub)
    add_bound_parser(sub)
    add_anatomy_parser(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return int(args.func(args))
    except ValueError as err:
        print(f"dualpilot: error: {err}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
