"""``dualpilot bench certify``: the certified gap of System 2 against SCIP at equal budgets.

On the same instances (the paper's fires,
:func:`~dualpilot.evaluation.instances.make_instance`, and fire-behaviour scenarios,
:func:`~dualpilot.evaluation.instances.make_physics_instance`):

* "certified" (:class:`dualpilot.system2.certify.planner.CertifiedSystem2`, tolerance 1 %)
  runs once per budget; the certified gap (cost − bound) / bound its trace shows at that
  budget (a last node may end after it and does not count) is the gap at that budget;
  the largest budget's trace gives the gap against time (the figure) and the time to 1 %;
* SCIP (:func:`dualpilot.system2.scip.solve_seeded`) runs once per budget as its time limit,
  seeded with the same fast plan, and gives its primal and dual bound.

Per budget: each solver's gap, the share of instances proved within 1 %, and how often
ours is worse than SCIP's (above 1 %, where the search stops, and above SCIP's gap); per
instance, our time to 1 % (from the request, the fast plan included). Writes
``certify.json`` and the figure (gap vs time, both solvers).
"""

from __future__ import annotations

import argparse
import json
import math
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from dualpilot.evaluation.instances import (
    SPEC,
    Instance,
    check_plan,
    make_instance,
    make_physics_instance,
)
from dualpilot.plan import certified_gap
from dualpilot.system2.certify.bnb import CertifyParams
from dualpilot.system2.certify.planner import CertifiedSystem2, relaxation_of
from dualpilot.system2.problem import System2Params
from dualpilot.warmup import warm_certificate, warm_up

BUDGETS = (0.1, 1.0, 10.0)
TARGET = 0.01


def gap_at(trace: Sequence[tuple[float, float, float]], t: float) -> float:
    """The certified gap of the last trace point at or before ``t`` s (inf before any)."""
    gap = math.inf
    for when, bound, cost in trace:
        if when > t:
            break
        gap = certified_gap(cost, bound)
    return gap


def time_to(trace: Sequence[tuple[float, float, float]], target: float) -> float | None:
    """The first time (s) the certified gap is at most ``target`` (None: never)."""
    for when, bound, cost in trace:
        if certified_gap(cost, bound) <= target:
            return when
    return None


def _ours(planners: dict[float, CertifiedSystem2], inst: Instance) -> dict[str, Any]:
    """Our certified method once per budget (its gap at that budget is the one its plan
    proves); the largest budget's run is reported in full (its trace gives the time to
    1 %)."""
    gaps: dict[str, float] = {}
    walls: dict[str, float] = {}
    checks = []
    for budget, planner in sorted(planners.items()):
        planner.reset()
        t0 = time.perf_counter()
        plan = planner.plan(inst.state, inst.hulls, inst.objective, inst.prev_control)
        wall = time.perf_counter() - t0
        # what the run had proven when its budget ran out (a last node may end after it)
        gaps[str(budget)] = gap_at(planner.trace, budget)
        walls[str(budget)] = wall
        checks.append(check_plan(plan, inst))
    ok = all(c[0] for c in checks)
    why = "; ".join(sorted({c[1] for c in checks}))
    trace = planner.trace
    return {"status": plan.status.value, "verified": ok, "why": why, "cost": plan.cost,
            "bound": plan.bound, "time_s": wall, "fast_cost": plan.info.get("fast_cost"),
            "nodes": plan.info.get("certify_nodes"), "stop": plan.info.get("certify_stop"),
            "gap": gaps, "wall_s": walls, "time_to_target_s": time_to(trace, TARGET),
            "trace": [(round(t, 4), b, c) for t, b, c in trace]}


def _plain_bound_time(params: System2Params, inst: Instance) -> float:
    """Seconds to certify the plainest bound (every disjunction dropped): what a bound on
    the default ("fast") plan path would cost at least."""
    t0 = time.perf_counter()
    relaxation_of(SPEC, params, inst.state, inst.hulls, inst.objective,
                  inst.prev_control, reach=False).solve({}, {})
    return time.perf_counter() - t0


def _scip(inst: Instance, params: System2Params, incumbent: Any) -> dict[str, Any]:
    from dualpilot.system2.scip import solve_seeded

    out: dict[str, Any] = {}
    kappa = params.kappa(inst.objective)
    for budget in BUDGETS:
        res = solve_seeded(inst.state, inst.hulls, SPEC.goal.center, kappa, inst.prev_control,
                           params, SPEC.dynamics, incumbent, budget, SPEC.clearance_m,
                           SPEC.area_size_m)
        dual = res.dual_bound if res.dual_bound > -1e19 else -math.inf
        out[str(budget)] = {"primal": res.objective, "dual": dual, "status": res.status,
                            "time_s": res.time_s,
                            "gap": certified_gap(res.objective, dual)
                            if math.isfinite(res.objective) else math.inf}
    return out


def instances(n_paper: int, n_physics: int, seed: int, scenarios: Sequence[str],
              max_hulls: int = 10) -> list[tuple[str, Instance]]:
    """The paper's instances (1..max_hulls hulls cycled), then each scenario's in turn."""
    out = [("paper", make_instance(i, seed, 1 + i % max_hulls)) for i in range(n_paper)]
    for i in range(n_physics):
        scenario = scenarios[i % len(scenarios)]
        out.append((scenario, make_physics_instance(i, seed, scenario)))
    return out


def run(n_paper: int, n_physics: int, seed: int, scenarios: Sequence[str], out_dir: Path,
        figure: Path | None, log: Callable[[str], object] = print,
        scip_from: Path | None = None) -> dict[str, Any]:
    """Benchmark every instance; writes ``out_dir/certify.json`` (and ``figure``).

    ``scip_from``: a previous certify.json of the same instances whose SCIP runs are
    taken instead of solving again (SCIP's side does not depend on our method).
    """
    reuse = _scip_rows(scip_from)
    params = System2Params()
    planners = {b: CertifiedSystem2(SPEC, params, CertifyParams(tolerance=TARGET,
                                                                time_budget_s=b))
                for b in BUDGETS}
    planner = planners[max(BUDGETS)]
    warm_up()  # every Numba kernel loaded before the first timed plan
    warm_certificate()
    warm = make_instance(0, seed, 1)
    planner.plan(warm.state, warm.hulls, warm.objective, warm.prev_control)
    rows: list[dict[str, Any]] = []
    for kind, inst in instances(n_paper, n_physics, seed, scenarios):
        ours = _ours(planners, inst)
        planner.fast_planner.reset()
        t0 = time.perf_counter()
        fast = planner.fast_planner.plan(inst.state, inst.hulls, inst.objective,
                                         inst.prev_control)
        ours["fast_time_s"] = time.perf_counter() - t0
        ours["plain_bound_time_s"] = _plain_bound_time(params, inst)
        key = (kind, inst.index, inst.n_hulls)
        scip = reuse[key] if key in reuse else _scip(inst, params,
                                                      fast.controls if fast.ok else None)
        row = {"kind": kind, "index": inst.index, "n_hulls": inst.n_hulls,
               "objective": inst.objective.value, "ours": ours, "scip": scip}
        rows.append(row)
        log(_line(row))
    result = {"command": _command(n_paper, n_physics, seed, scenarios), "budgets": BUDGETS,
              "target": TARGET, "summary": summary(rows), "instances": rows}
    out_dir.mkdir(parents=True, exist_ok=True)
    (out_dir / "certify.json").write_text(json.dumps(result, indent=1, default=_jsonable))
    if figure is not None:
        plot(rows, figure)
    return result


def _scip_rows(path: Path | None) -> dict[tuple[str, int, int], Any]:
    if path is None:
        return {}
    doc = json.loads(Path(path).read_text())
    return {(r["kind"], r["index"], r["n_hulls"]): r["scip"] for r in doc["instances"]}


def summary(rows: Sequence[dict[str, Any]]) -> dict[str, Any]:
    """Per budget and instance kind: shares within 1 %, median gaps, ours worse than SCIP."""
    out: dict[str, Any] = {}
    for kind in sorted({r["kind"] for r in rows}) + ["all"]:
        sel = [r for r in rows if kind in ("all", r["kind"])]
        per: dict[str, Any] = {"n": len(sel)}
        for b in BUDGETS:
            ours = [r["ours"]["gap"][str(b)] for r in sel]
            scip = [r["scip"][str(b)]["gap"] for r in sel]
            per[str(b)] = {
                "ours_within_target": float(np.mean([g <= TARGET for g in ours])),
                "scip_within_target": float(np.mean([g <= TARGET for g in scip])),
                "ours_gap_median": float(np.median(ours)),
                "scip_gap_median": float(np.median(scip)),
                # worse: ours not within the target and above SCIP's (we stop at the target)
                "ours_worse_than_scip": int(sum(o > max(s, TARGET) for o, s in
                                                zip(ours, scip, strict=True))),
            }
        reach = [r["ours"]["time_to_target_s"] for r in sel]
        hit = [t for t in reach if t is not None]
        per["time_to_target_s_median"] = float(np.median(hit)) if hit else None
        per["time_to_target_s_p90"] = float(np.percentile(hit, 90)) if hit else None
        per["reached_target"] = len(hit)
        per["verified"] = int(sum(bool(r["ours"]["verified"]) for r in sel))
        per["fast_time_s_median"] = float(np.median([r["ours"]["fast_time_s"] for r in sel]))
        per["plain_bound_time_s_median"] = float(np.median(
            [r["ours"]["plain_bound_time_s"] for r in sel]))
        out[kind] = per
    return out


def markdown(result: dict[str, Any]) -> str:
    """The docs' table: per instance kind and budget, both solvers' share within 1 % and
    median certified gap, and how often ours is worse than SCIP's."""
    lines = ["| instances | budget | within 1 %: ours | within 1 %: SCIP | median gap: ours "
             "| median gap: SCIP | ours worse than SCIP |", "|---|---|---|---|---|---|---|"]
    for kind, per in result["summary"].items():
        for b in BUDGETS:
            x = per[str(b)]
            lines.append(
                f"| {kind} ({per['n']}) | {b:g} s | {100 * x['ours_within_target']:.0f} % | "
                f"{100 * x['scip_within_target']:.0f} % | {_pct(x['ours_gap_median']).strip()} "
                f"| {_pct(x['scip_gap_median']).strip()} | {x['ours_worse_than_scip']} |")
    return "\n".join(lines)


def improved(rows: Sequence[dict[str, Any]]) -> list[tuple[str, int, float]]:
    """Instances where the search found a cheaper plan than the fast method's: (kind,
    index, relative saving)."""
    out = []
    for r in rows:
        fast, cost = r["ours"].get("fast_cost"), r["ours"].get("cost")
        if fast is not None and cost is not None and cost < fast * (1 - 1e-9):
            out.append((r["kind"], r["index"], (fast - cost) / fast))
    return out


def plot(rows: Sequence[dict[str, Any]], path: Path) -> Path:
    """Share of instances within 1 % and median certified gap vs time, both solvers."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    times = np.logspace(-2, 1, 61)
    ours = np.array([[gap_at(r["ours"]["trace"], t) for t in times] for r in rows])
    scip = np.array([[r["scip"][str(b)]["gap"] for b in BUDGETS] for r in rows])
    fig, (ax_share, ax_gap) = plt.subplots(1, 2, figsize=(11, 4.2))
    runs = np.array([[r["ours"]["gap"][str(b)] for b in BUDGETS] for r in rows])
    ax_share.plot(times, 100 * np.mean(ours <= TARGET, axis=0),
                  label=f"certified (ours), the {max(BUDGETS):g} s run's trace")
    ax_share.plot(BUDGETS, 100 * np.mean(runs <= TARGET, axis=0), "s", color="C0",
                  label="certified (ours), one run per budget")
    ax_share.plot(BUDGETS, 100 * np.mean(scip <= TARGET, axis=0), "o--",
                  label="SCIP (seeded with the fast plan)")
    ax_share.axhline(90, color="grey", lw=0.8, ls=":")
    ax_share.set(xscale="log", xlabel="budget (s)", ylabel="instances within 1 % (%)",
                 ylim=(0, 100), title=f"certified gap ≤ 1 %, {len(rows)} instances")
    floor, cap = 1e-4, 10.0  # 0.01 % and 1000 %: a proven optimum and no bound at all
    shown = np.clip(ours, floor, cap)
    for q, style in ((50, "-"), (90, ":")):
        ax_gap.plot(times, 100 * np.percentile(shown, q, axis=0), style, color="C0",
                    label=f"certified (ours), {'median' if q == 50 else '90th percentile'}")
        ax_gap.plot(BUDGETS, 100 * np.percentile(np.clip(runs, floor, cap), q, axis=0),
                    "s", color="C0")
        ax_gap.plot(BUDGETS, 100 * np.percentile(np.clip(scip, floor, cap), q, axis=0),
                    "o" + ("--" if q == 50 else ":"), color="C1",
                    label=f"SCIP, {'median' if q == 50 else '90th percentile'}")
    ax_gap.axhline(100 * TARGET, color="grey", lw=0.8, ls=":")
    ax_gap.set(xscale="log", yscale="log", xlabel="budget (s)", ylim=(100 * floor / 2, 200 * cap),
               ylabel="certified gap (%), clipped to [0.01, 1000]",
               title="(cost − bound) / bound")
    for ax in (ax_share, ax_gap):
        ax.grid(True, which="both", lw=0.3)
        ax.legend(loc="best", fontsize=8)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _line(row: dict[str, Any]) -> str:
    o, s = row["ours"], row["scip"]
    parts = [f"{row['kind']:>9s} #{row['index']:3d} hulls={row['n_hulls']:2d}"]
    for b in BUDGETS:
        parts.append(f"{b:g}s ours {_pct(o['gap'][str(b)])} scip {_pct(s[str(b)]['gap'])}")
    t = o["time_to_target_s"]
    parts.append("1% at " + ("-" if t is None else f"{t:.2f}s"))
    return " | ".join(parts)


def _pct(g: float) -> str:
    return "  inf  " if not math.isfinite(g) else f"{100 * g:6.2f}%"


def _command(n_paper: int, n_physics: int, seed: int, scenarios: Sequence[str]) -> str:
    return (f"dualpilot bench certify --instances {n_paper} --physics-instances {n_physics} "
            f"--seed {seed} --scenarios {','.join(scenarios)}")


def _jsonable(obj: Any) -> Any:
    if isinstance(obj, np.generic):
        return obj.item()
    return str(obj)


def add_parser(sub: Any) -> None:
    """``bench certify …``."""
    c = sub.add_parser("certify", help="System 2's certified gap against SCIP at equal budgets")
    c.add_argument("--instances", type=int, default=30, help="paper instances")
    c.add_argument("--physics-instances", type=int, default=20,
                   help="fire-behaviour instances, the scenarios taken in turn")
    c.add_argument("--scenarios", default="grass-15,shrub")
    c.add_argument("--seed", type=int, default=1)
    c.add_argument("--out", default="runs/bench")
    c.add_argument("--figure", default="docs/figures/certify_gap_vs_time.png")
    c.add_argument("--scip-from", default="",
                   help="a certify.json of the same instances: reuse its SCIP runs")
    c.set_defaults(func=_cli)


def _cli(args: argparse.Namespace) -> int:
    if args.instances < 0 or args.physics_instances < 0:
        raise ValueError("--instances and --physics-instances must be >= 0")
    scenarios = [s.strip() for s in args.scenarios.split(",") if s.strip()]
    result = run(args.instances, args.physics_instances, args.seed, scenarios,
                 Path(args.out), Path(args.figure) if args.figure else None,
                 scip_from=Path(args.scip_from) if args.scip_from else None)
    print(json.dumps(result["summary"], indent=1))
    print(markdown(result))
    for kind, index, saving in improved(result["instances"]):
        print(f"search improved the fast plan: {kind} #{index} by {100 * saving:.2f} %")
    print(f"wrote {Path(args.out) / 'certify.json'}")
    return 0
