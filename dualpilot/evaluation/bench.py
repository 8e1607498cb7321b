"""Benchmarks of System 2 (fast vs exact) and System 1: ``dualpilot bench system2|system1``.

Instances come from :mod:`dualpilot.evaluation.instances` (the paper's fire setup,
1–10 hulls cycled over the instances). Every method is timed from state in
to verified plan out. The exact MIQP is the reference: it runs in a
:class:`dualpilot.system2.worker.Worker` killed past its time limit, so a
solver crash or hang costs one reference, never the benchmark.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from dualpilot.evaluation.instances import SPEC, Instance, check_plan, make_instance
from dualpilot.plan import Plan
from dualpilot.system2.problem import System2Params


# ------------------------------------------------------------------ helpers
def percentile(values: Sequence[float], q: float) -> float | None:
    vals = [v for v in values if v is not None and math.isfinite(v)]
    return float(np.percentile(vals, q)) if vals else None


def stats(rows: Sequence[dict[str, Any]]) -> dict[str, Any]:
    """The issue's summary fields for one method over some instance rows."""
    times = [r["time_s"] for r in rows if r.get("time_s") is not None]
    gaps = [r["gap"] for r in rows if r.get("gap") is not None]
    ver = [bool(r.get("verified")) for r in rows]
    ver_ok = [bool(r.get("verified")) for r in rows if r.get("status") == "ok"]
    statuses: dict[str, int] = {}
    for r in rows:
        statuses[str(r.get("status"))] = statuses.get(str(r.get("status")), 0) + 1
    return {
        "n": len(rows),
        "time_s_median": percentile(times, 50),
        "time_s_p95": percentile(times, 95),
        "cpu_s_median": percentile([r["cpu_s"] for r in rows if r.get("cpu_s") is not None], 50),
        "gap_median": percentile(gaps, 50),
        "gap_p95": percentile(gaps, 95),
        "gap_max": percentile(gaps, 100),
        "certified_gap_median": percentile(
            [r["certified_gap"] for r in rows if r.get("certified_gap") is not None], 50),
        "n_gaps": len(gaps),
        "verified_fraction": float(np.mean(ver)) if ver else None,
        "verified_fraction_of_ok": float(np.mean(ver_ok)) if ver_ok else None,
        "statuses": statuses,
    }


def _timed(planner: Any, inst: Instance) -> tuple[Plan, float, float]:
    c0, t0 = time.thread_time(), time.perf_counter()
    plan = planner.plan(inst.state, inst.hulls, inst.objective, inst.prev_control)
    return plan, time.perf_counter() - t0, time.thread_time() - c0


def _instances(n: int, seed: int, max_hulls: int) -> list[Instance]:
    return [make_instance(i, seed, 1 + i % max_hulls) for i in range(n)]


def _bins(rows_by_method: dict[str, list[dict[str, Any]]]) -> dict[str, dict[str, Any]]:
    out: dict[str, dict[str, Any]] = {}
    for method, rows in rows_by_method.items():
        by: dict[int, list[dict[str, Any]]] = {}
        for r in rows:
            by.setdefault(int(r["n_hulls"]), []).append(r)
        out[method] = {str(k): stats(v) for k, v in sorted(by.items())}
    return out


# ---------------------------------------------------------------- system 2
def run_system2(n_instances: int, seed: int, out_dir: Path, reference_timeout: float,
                methods: Sequence[str], horizon: int = 80, max_hulls: int = 10,
                reference_cache: Path | None = None, seeded_reference: bool = True,
                anytime_budget_s: float = 2.0, log: Any = print) -> dict[str, Any]:
    """Benchmark System 2 methods against the exact MIQP; writes out_dir/system2.json.

    Per instance: every method in ``methods`` except "exact" runs in-process
    and is timed; "exact" (the cvxpy + SCIP MIQP of :mod:`dualpilot.system2.exact`)
    and, with ``seeded_reference``, SCIP seeded with the fast plan
    (:mod:`dualpilot.system2.scip`) run in worker processes killed past
    ``reference_timeout`` (+ 60 s for start-up). The reference cost is the
    proven optimum when either exact solve proves it, else the best verified
    cost any method found; gaps are (cost − reference) / reference. The best
    dual bound also gives a certified gap bound for each method.
    """
    from dualpilot.planners import build_planner

    params = System2Params(horizon=horizon)
    insts = _instances(n_instances, seed, max_hulls)
    references = _References(reference_cache, seed, horizon, reference_timeout, seeded_reference)
    planners = _timed_planners(methods, params, anytime_budget_s)
    fast_seed = planners.get("fast") or build_planner(2, SPEC, "fast", params)
    rows: list[dict[str, Any]] = []
    try:
        for p in planners.values():  # warm-up: imports, caches, worker start
            p.plan(insts[0].state, insts[0].hulls, insts[0].objective, insts[0].prev_control)
        for inst in insts:
            results = {name: _run_method(planner, inst) for name, planner in planners.items()}
            seed_plan = results["fast"]["_plan"] if "fast" in results else fast_seed.plan(
                inst.state, inst.hulls, inst.objective, inst.prev_control)
            refs = references.solve(inst, seed_plan)
            row = _scored_row(inst, results, refs, methods)
            rows.append(row)
            log(_line(row))
    finally:
        references.stop()
        for p in planners.values():
            if hasattr(p, "close"):
                p.close()
    result = _system2_result(rows, n_instances, seed, reference_timeout, methods, horizon)
    out_dir.mkdir(parents=True, exist_ok=True)
    (out_dir / "system2.json").write_text(json.dumps(result, indent=1, default=_json_default))
    return result


def _timed_planners(methods: Sequence[str], params: System2Params,
                    anytime_budget_s: float) -> dict[str, Any]:
    """The in-process planners of ``methods`` ("exact" runs in a worker instead)."""
    from dualpilot.planners import build_planner
    from dualpilot.system2.anytime import AnytimeSystem2

    planners: dict[str, Any] = {}
    for m in methods:
        if m == "fast+exact":
            planners[m] = AnytimeSystem2(SPEC, params, exact_budget_s=anytime_budget_s)
        elif m != "exact":
            planners[m] = build_planner(2, SPEC, m, params)
    return planners


def _run_method(planner: Any, inst: Instance) -> dict[str, Any]:
    """One method on one instance: its time (s), status, cost and the plan's verification."""
    if hasattr(planner, "reset"):
        planner.reset()
    plan, wall, cpu = _timed(planner, inst)
    ok, why = check_plan(plan, inst)
    if plan.ok and not ok:
        why = "RETURNED OK BUT FAILED VERIFICATION: " + why
    return {"time_s": wall, "cpu_s": cpu, "status": plan.status.value,
            "cost": plan.cost if plan.ok else None, "verified": ok,
            "why": why, "info": _small(plan.info), "_plan": plan}


class _References:
    """The exact solves (plain and seeded SCIP) in worker processes, cached by instance."""

    def __init__(self, cache_path: Path | None, seed: int, horizon: int,
                 timeout_s: float, seeded: bool) -> None:
        from dualpilot.system2.exact import ExactSystem2
        from dualpilot.system2.scip import SeededExactSystem2
        from dualpilot.system2.worker import PlannerFactory, Worker

        self.cache_path, self.seed, self.horizon, self.timeout_s = (cache_path, seed, horizon,
                                                                    timeout_s)
        self.cache: dict[str, Any] = {}
        if cache_path is not None and cache_path.exists():
            self.cache = json.loads(cache_path.read_text())
        params = System2Params(horizon=horizon, time_limit_s=timeout_s)
        self.workers = {"exact": Worker(PlannerFactory(ExactSystem2, SPEC, params))}
        if seeded:
            self.workers["exact-seeded"] = Worker(PlannerFactory(SeededExactSystem2, SPEC,
                                                                 params))

    def solve(self, inst: Instance, seed_plan: Plan) -> dict[str, Any]:
        """Each reference's answer on ``inst`` (from the cache where it holds one)."""
        refs: dict[str, Any] = {}
        for name, worker in self.workers.items():
            key = f"{name}/{self.seed}/{inst.index}/{self.horizon}/{self.timeout_s}"
            if key not in self.cache:
                self.cache[key] = self._solve(name, worker, inst, seed_plan)
                self._save()
            refs[name] = self.cache[key]
        return refs

    def _solve(self, name: str, worker: Any, inst: Instance, seed_plan: Plan) -> dict[str, Any]:
        request: tuple[Any, ...] = (inst.state, inst.hulls, inst.objective, inst.prev_control)
        if name == "exact-seeded":
            request += (seed_plan.controls if seed_plan.ok else None,)
        t0 = time.perf_counter()
        answer, outcome = worker.solve(request, self.timeout_s + 60.0)
        ref = {"outcome": outcome, "time_s": time.perf_counter() - t0, "status": None,
               "cost": None, "optimal": False, "verified": False, "dual_bound": None}
        if isinstance(answer, Plan):
            ok, why = check_plan(answer, inst)
            ref.update(status=answer.status.value, cost=answer.cost if ok else None,
                       optimal=bool(answer.info.get("optimal")) and ok, verified=ok,
                       why=why, time_s=answer.compute_time_s,
                       simplified=answer.info.get("simplified_hulls", []),
                       dual_bound=answer.info.get("dual_bound"))
        return ref

    def _save(self) -> None:
        if self.cache_path is not None:
            self.cache_path.parent.mkdir(parents=True, exist_ok=True)
            self.cache_path.write_text(json.dumps(self.cache, default=_json_default))

    def stop(self) -> None:
        for w in self.workers.values():
            w.stop()


def _scored_row(inst: Instance, results: dict[str, Any], refs: dict[str, Any],
                methods: Sequence[str]) -> dict[str, Any]:
    """One instance's row: every method's result with its gap to the reference cost."""
    for name, ref in refs.items():
        if name == "exact" and "exact" not in methods:
            continue
        results[name] = {"time_s": ref["time_s"], "cpu_s": None,
                         "status": ref["status"] or ref["outcome"], "cost": ref["cost"],
                         "verified": ref["verified"], "optimal": ref["optimal"]}
    best, source, proven = _reference_cost(results, refs)
    lower = _lower_bound(results, refs)
    if proven:
        lower = max(lower or -math.inf, best)
    for v in results.values():
        v.pop("_plan", None)
        v["gap"] = (None if best is None or v["cost"] is None or not v["verified"]
                    else (v["cost"] - best) / abs(best))
        v["certified_gap"] = (None if lower is None or v["cost"] is None
                              or not v["verified"]
                              else max(0.0, (v["cost"] - lower) / abs(v["cost"])))
    return {"index": inst.index, "n_hulls": inst.n_hulls, "objective": inst.objective.value,
            "faces": [h.n_faces for h in inst.hulls], "methods": results,
            "references": refs, "reference_cost": best, "reference_source": source,
            "reference_optimal": proven, "lower_bound": lower}


def _reference_cost(results: dict[str, Any],
                    refs: dict[str, Any]) -> tuple[Any, str, bool]:
    """The reference cost, where it comes from, and whether it is a proven optimum."""
    costs = {k: v["cost"] for k, v in results.items()
             if v["verified"] and v["cost"] is not None}
    proven = [r["cost"] for r in refs.values() if r["optimal"] and r["cost"] is not None]
    # a method whose plan is the relaxation's optimum (no hull binds) proves it too
    proven += [v["cost"] for v in results.values() if v["verified"]
               and v.get("info", {}).get("optimal") and v["cost"] is not None]
    if proven:
        return min(proven), "proven optimum", True
    if costs:
        source = min(costs, key=lambda k: costs[k])
        return costs[source], f"best found ({source})", False
    return None, "none", False


def _lower_bound(results: dict[str, Any], refs: dict[str, Any]) -> float | None:
    """The best dual bound: the exact solves' and the no-hull QP's (a relaxation of (P2))."""
    bounds = [float(r["dual_bound"]) for r in refs.values()
              if r.get("dual_bound") is not None and math.isfinite(r["dual_bound"])
              and r["dual_bound"] > -1e19]
    bounds += [float(v["info"]["lower_bound"]) for v in results.values()
               if v.get("info", {}).get("lower_bound") is not None]
    return max(bounds, default=None)


def _system2_result(rows: list[dict[str, Any]], n_instances: int, seed: int,
                    reference_timeout: float, methods: Sequence[str],
                    horizon: int) -> dict[str, Any]:
    """system2.json: the command, per-method summaries (also by hull count), every row."""
    names = list(rows[0]["methods"]) if rows else list(methods)
    per_method = {m: [dict(r["methods"][m], n_hulls=r["n_hulls"]) for r in rows
                      if m in r["methods"]] for m in names}
    return {
        "command": f"dualpilot bench system2 --instances {n_instances} --seed {seed} "
                   f"--reference-timeout {reference_timeout:g} --methods {','.join(methods)}"
                   + (f" --horizon {horizon}" if horizon != 80 else ""),
        "horizon": horizon,
        "reference_timeout_s": reference_timeout,
        "default": "fast",
        "summary": {m: _issue_fields(stats(v)) for m, v in per_method.items()},
        "summary_detail": {m: stats(v) for m, v in per_method.items()},
        "by_hulls": _bins(per_method),
        "reference_optimal_fraction": float(np.mean([r["reference_optimal"] for r in rows]))
        if rows else None,
        "instances": rows,
        "machine": _machine(),
    }


def _issue_fields(s: dict[str, Any]) -> dict[str, Any]:
    keys = ("time_s_median", "time_s_p95", "gap_median", "gap_p95", "verified_fraction")
    return {k: s[k] for k in keys}


def _small(info: dict[str, object]) -> dict[str, object]:
    keep = ("n_qp", "homotopy", "homotopies", "cfs_iterations", "bound_gap", "source",
            "exact_outcome", "n_hulls", "optimal", "dual_bound", "lower_bound")
    return {k: info[k] for k in keep if k in info}


def _line(row: dict[str, Any]) -> str:
    parts = [f"#{row['index']:3d} hulls={row['n_hulls']:2d} {row['objective'][:6]:6s}",
             f"ref={row['reference_source']}"]
    for name, m in row["methods"].items():
        gap = "  -  " if m["gap"] is None else f"{100 * m['gap']:+.3f}%"
        t = m["time_s"]
        ts = "-" if t is None else (f"{1e3 * t:.1f}ms" if t < 10 else f"{t:.1f}s")
        parts.append(f"{name}: {ts} {m['status']} {gap}")
    return " | ".join(parts)


def _machine() -> dict[str, Any]:
    import os
    import platform

    return {"cpus": os.cpu_count(), "python": platform.python_version(),
            "loadavg": os.getloadavg() if hasattr(os, "getloadavg") else None}


def _json_default(obj: Any) -> Any:
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    return str(obj)


# ---------------------------------------------------------------- system 1
def run_system1(n_instances: int, seed: int, out_dir: Path, max_hulls: int = 10,
                log: Any = print) -> dict[str, Any]:
    """Benchmark System 1 (RRT + shortcut + LQR); writes out_dir/system1.json.

    ``gap`` is System 1's Eq. (S2) cost relative to the fast System 2 plan on
    the same instance (how much optimality the fast heuristic gives up);
    ``verified`` is the d_safe check of :func:`verify_trajectory` (System 1
    does not promise P2's ε-disjunction).
    """
    from dualpilot.system1.planner import System1
    from dualpilot.system2.fast.planner import FastSystem2
    from dualpilot.system2.problem import p2_cost

    params = System2Params()
    insts = _instances(n_instances, seed, max_hulls)
    s2 = FastSystem2(SPEC, params)
    rows: list[dict[str, Any]] = []
    for inst in insts:
        rng = np.random.default_rng(np.random.SeedSequence([seed, inst.index, 1]))
        planner = System1(SPEC, rng=rng)
        if not rows:  # warm-up (imports, OMPL setup)
            with contextlib.suppress(ValueError):
                System1(SPEC, rng=np.random.default_rng(0)).plan(
                    inst.state, inst.hulls, inst.objective, inst.prev_control)
        try:
            plan, wall, cpu = _timed(planner, inst)
        except ValueError as err:
            rows.append({"index": inst.index, "n_hulls": inst.n_hulls, "time_s": None,
                         "cpu_s": None, "status": "invalid_input", "cost": None, "gap": None,
                         "verified": False, "why": str(err)})
            continue
        ok, why = check_plan(plan, inst, p2=False)
        kappa = params.kappa(inst.objective)
        cost = (p2_cost(plan.states, plan.controls, SPEC.goal.center, kappa, inst.prev_control)
                if plan.ok else None)
        ref = s2.plan(inst.state, inst.hulls, inst.objective, inst.prev_control)
        gap = (None if cost is None or not ref.ok or ref.cost is None
               else (cost - ref.cost) / abs(ref.cost))
        row = {"index": inst.index, "n_hulls": inst.n_hulls, "objective": inst.objective.value,
               "time_s": wall, "cpu_s": cpu, "status": plan.status.value, "cost": cost,
               "gap": gap, "verified": ok, "why": why,
               "rrt_iterations": plan.info.get("rrt_iterations"),
               "rrt_status": plan.info.get("rrt_status")}
        rows.append(row)
        log(f"#{inst.index:3d} hulls={inst.n_hulls:2d} system1: {1e3 * wall:6.1f} ms "
            f"{plan.status.value} gap vs fast S2 "
            f"{'-' if gap is None else f'{100 * gap:+.1f}%'}")
    result = {
        "command": f"dualpilot bench system1 --instances {n_instances} --seed {seed}",
        "default": "system1",
        "gap_reference": "fast System 2 plan on the same instance",
        "summary": {"system1": _issue_fields(stats(rows))},
        "summary_detail": {"system1": stats(rows)},
        "by_hulls": _bins({"system1": rows}),
        "instances": rows,
        "machine": _machine(),
    }
    out_dir.mkdir(parents=True, exist_ok=True)
    (out_dir / "system1.json").write_text(json.dumps(result, indent=1, default=_json_default))
    return result


# --------------------------------------------------------------------- CLI
def markdown_table(result: dict[str, Any], bins: Sequence[tuple[int, int]] = ((1, 3), (4, 6),
                                                                              (7, 10))) -> str:
    """Method × hull-count table (median / p95 time, median gap, verified) for the README."""
    lines = ["| method | hulls | n | median time | p95 time | median gap | p95 gap | verified |",
             "|---|---|---|---|---|---|---|---|"]
    for method in result["summary"]:
        rows_all = [dict(r["methods"][method], n_hulls=r["n_hulls"]) for r in result["instances"]
                    ] if "methods" in result["instances"][0] else [
                        r for r in result["instances"]]
        for lo, hi in [*bins, (1, 10)]:
            sel = [r for r in rows_all if lo <= r["n_hulls"] <= hi]
            if not sel:
                continue
            s = stats(sel)
            lines.append(
                f"| {method} | {lo}–{hi}{' (all)' if (lo, hi) == (1, 10) else ''} | {s['n']} | "
                f"{_ms(s['time_s_median'])} | {_ms(s['time_s_p95'])} | {_pct(s['gap_median'])} | "
                f"{_pct(s['gap_p95'])} | {_frac(s['verified_fraction'])} |")
    return "\n".join(lines)


def _ms(v: float | None) -> str:
    if v is None:
        return "–"
    return f"{1e3 * v:.1f} ms" if v < 1 else f"{v:.2f} s"


def _pct(v: float | None) -> str:
    return "–" if v is None else f"{100 * v:.3f} %"


def _frac(v: float | None) -> str:
    return "–" if v is None else f"{100 * v:.0f} %"


def add_bench_parser(subparsers: Any) -> None:
    """``bench system2 …``, ``bench system1 …`` and ``bench certify …`` under ``dualpilot``."""
    b = subparsers.add_parser("bench", help="benchmark System 2 (fast vs exact, certified gap "
                              "vs SCIP) or System 1")
    sub = b.add_subparsers(dest="bench_target", required=True)
    s2 = sub.add_parser("system2", help="System 2 methods against the exact MIQP")
    s2.add_argument("--instances", type=int, default=30)
    s2.add_argument("--seed", type=int, default=1)
    s2.add_argument("--out", default="runs/bench")
    s2.add_argument("--reference-timeout", type=float, default=120.0,
                    help="time limit of each exact (reference) solve, s")
    s2.add_argument("--methods", default="fast,exact",
                    help="comma-separated: fast, exact, fast+exact, thorough")
    s2.add_argument("--horizon", type=int, default=80)
    s2.add_argument("--max-hulls", type=int, default=10)
    s2.add_argument("--reference-cache", default="",
                    help="JSON file that keeps exact solves between runs (optional)")
    s2.add_argument("--no-seeded-reference", action="store_true",
                    help="skip SCIP seeded with the fast plan (the reference improver)")
    s2.add_argument("--anytime-budget", type=float, default=2.0,
                    help="exact budget of the fast+exact method, s")
    s2.set_defaults(func=_cli_system2)
    s1 = sub.add_parser("system1", help="System 1 (RRT + shortcut + LQR)")
    s1.add_argument("--instances", type=int, default=30)
    s1.add_argument("--seed", type=int, default=1)
    s1.add_argument("--out", default="runs/bench")
    s1.add_argument("--max-hulls", type=int, default=10)
    s1.set_defaults(func=_cli_system1)
    from dualpilot.evaluation.certify_bench import add_parser as add_certify

    add_certify(sub)


def _cli_system2(args: argparse.Namespace) -> int:
    methods = [m.strip() for m in args.methods.split(",") if m.strip()]
    from dualpilot.planners import method_names

    bad = [m for m in methods if m not in method_names(2)]
    if bad or not methods:
        raise ValueError(f"unknown methods {bad}; choose from {method_names(2)}")
    if args.instances < 1 or args.reference_timeout <= 0:
        raise ValueError("--instances >= 1 and --reference-timeout > 0 are required")
    cache = Path(args.reference_cache) if args.reference_cache else None
    result = run_system2(args.instances, args.seed, Path(args.out), args.reference_timeout,
                         methods, horizon=args.horizon, max_hulls=args.max_hulls,
                         reference_cache=cache, seeded_reference=not args.no_seeded_reference,
                         anytime_budget_s=args.anytime_budget)
    print(json.dumps(result["summary"], indent=1))
    print(markdown_table(result))
    print(f"wrote {Path(args.out) / 'system2.json'}")
    return 0


def _cli_system1(args: argparse.Namespace) -> int:
    if args.instances < 1:
        raise ValueError("--instances must be >= 1")
    result = run_system1(args.instances, args.seed, Path(args.out), max_hulls=args.max_hulls)
    print(json.dumps(result["summary"], indent=1))
    print(markdown_table(result))
    print(f"wrote {Path(args.out) / 'system1.json'}")
    return 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m dualpilot.evaluation.bench",
                                     description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)
    add_bench_parser(sub)
    args = parser.parse_args(["bench", *(argv if argv is not None else sys.argv[1:])])
    return int(args.func(args))


if __name__ == "__main__":
    sys.exit(main())
