"""`dualpilot` command line: missions, figures and benchmarks."""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from dualpilot.mission.params import Controller, MissionParams, Timing
from dualpilot.spec import MissionSpec


def _mission(args: argparse.Namespace) -> int:
    from dualpilot.mission.local import local_mission
    from dualpilot.mission.records import write_all

    mission = local_mission(
        Controller(args.controller),
        MissionSpec(seed=args.seed),
        timing=Timing(args.timing),
        params=MissionParams(ignition_clearance_m=args.ignition_clearance),
        system2_method=args.s2_method,
    )
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
                    "controller",
                    "seed",
                    "timing",
                    "success",
                    "failure_cause",
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
    from dualpilot.evaluate import evaluate

    out = Path(args.out)
    summary = evaluate(
        args.missions,
        out,
        seed=args.seed,
        timing=args.timing,
        jobs=args.jobs,
        controllers=args.controllers.split(","),
        s2_method=args.s2_method,
        ignition_clearance_m=args.ignition_clearance,
    )
    print(json.dumps(summary, indent=2))
    print(f"results in {out}/: results.csv summary.json fig_r5.png")
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="dualpilot", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)

    m = sub.add_parser("mission", help="fly one mission in-process")
    m.add_argument("--controller", choices=[c.value for c in Controller], default="cc")
    m.add_argument("--seed", type=int, default=7)
    m.add_argument("--timing", choices=[t.value for t in Timing], default="paper")
    m.add_argument("--s2-method", default="fast", help="System 2 solver: fast or exact")
    m.add_argument("--out", default="runs/latest")
    m.add_argument("--no-figures", action="store_true")
    m.add_argument(
        "--ignition-clearance",
        type=float,
        default=None,
        metavar="M",
        help="no front ignites within M m of the UAV (default: anywhere)",
    )
    m.add_argument("--quiet", action="store_true")
    m.set_defaults(func=_mission)

    f = sub.add_parser("figures", help="draw the paper's figures for a recorded run")
    f.add_argument("--run", required=True, help="run directory with steps.csv and trace.json")
    f.add_argument("--steps", default="", help="comma-separated steps for the Fig. r1 panels")
    f.set_defaults(func=_figures)

    e = sub.add_parser("evaluate", help="Monte-Carlo comparison of CC, S1 and S2 (Fig. r5)")
    e.add_argument("--missions", type=int, default=200)
    e.add_argument("--timing", choices=[t.value for t in Timing], default="paper")
    e.add_argument("--jobs", type=int, default=0, help="worker processes (default: all cores)")
    e.add_argument("--seed", type=int, default=0)
    e.add_argument("--controllers", default="cc,s1,s2")
    e.add_argument("--s2-method", default="fast")
    e.add_argument(
        "--ignition-clearance",
        type=float,
        default=None,
        metavar="M",
        help="no front ignites within M m of the UAV (default: anywhere, as the paper states)",
    )
    e.add_argument("--out", default="runs/eval")
    e.set_defaults(func=_evaluate)

    from dualpilot.bench import add_bench_parser

    add_bench_parser(sub)

    from dualpilot.viz.bound import add_bound_parser  # the supervisor's bound (issue 13.4)

    add_bound_parser(sub)
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
