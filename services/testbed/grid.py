"""The test bed's grid: the radio link varied one factor at a time, the same missions in each cell.

A **cell** is one shaping of every vehicle's radio link (both directions) and one outage rule:
``clean`` (no delay, no loss, no bandwidth limit, no outage: only the impairer's own few tenths
of a millisecond) and, from it, one factor changed — the one-way latency (100, 300, 1000 ms),
the loss (5, 20 % of frames each way), the bandwidth (10, 1, 0.25 Mbit/s each way, each
vehicle's own link) or an outage (5, 30 s, from the step :data:`OUTAGE_AT_STEP` of each
mission) — plus the goal cell, 300 ms with 5 % loss. :func:`cells` lists them.

Every cell flies the same seeds with each controller, so a mission of a cell has its twin in
``clean``: :func:`pairs` matches them and :func:`paired_difference` gives the difference in
success with a 95 % interval (the exact McNemar test on the same pairs is
benchmarks/harness.py ``mcnemar``). A mission's row (:func:`row`, the columns
:data:`ROW_FIELDS`) is text, as in the CSV it is written to; :func:`summarise` sums rows up per
cell and controller.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from dualpilot.evaluation.stats import mean_interval
from services.testbed.impairment import Impairment

#: the step of each mission at which its link is cut in an outage cell (as make testbed-check)
OUTAGE_AT_STEP = 12
BASELINE = "clean"
#: the factors, in the order of the figure's panels, with the levels their cells take
FACTORS: dict[str, tuple[float, ...]] = {
    "latency_ms": (100.0, 300.0, 1000.0),
    "loss": (0.05, 0.20),
    "rate_mbit": (10.0, 1.0, 0.25),
    "outage_s": (5.0, 30.0),
}
ROW_FIELDS = ("cell", "factor", "level", "controller", "seed", "uav", "round", "success",
              "ended", "ending", "failure_cause", "steps", "s2_steps", "s2_share",
              "plan_deadline", "link_lost_steps", "link_degraded_steps", "outage_at_step",
              "wire_bytes", "wire_bytes_per_step", "air_exit", "run_dir")


@dataclass(frozen=True)
class Cell:
    """One cell: every radio link's one-way latency (ms), loss (fraction of frames, each way),
    bandwidth (Mbit/s each way, None: not limited) and outage (s, from step
    :data:`OUTAGE_AT_STEP`; 0: none); ``factor`` and ``level`` say what differs from clean."""

    name: str
    factor: str
    level: float | None
    latency_ms: float = 0.0
    loss: float = 0.0
    rate_mbit: float | None = None
    outage_s: float = 0.0

    def impairment(self) -> Impairment:
        return Impairment(delay_ms=self.latency_ms, loss=self.loss, rate_mbit=self.rate_mbit)

    def wire(self) -> dict[str, Any]:
        return {"name": self.name, "factor": self.factor, "level": self.level,
                "latency_ms": self.latency_ms, "loss": self.loss, "rate_mbit": self.rate_mbit,
                "outage_s": self.outage_s,
                "outage_at_step": OUTAGE_AT_STEP if self.outage_s > 0 else None}


def _name(factor: str, level: float) -> str:
    return {"latency_ms": f"latency-{level:g}ms", "loss": f"loss-{100 * level:g}pct",
            "rate_mbit": f"rate-{level:g}mbit", "outage_s": f"outage-{level:g}s"}[factor]


def cells(names: Iterable[str] = ()) -> list[Cell]:
    """The grid's cells, clean first, then each factor's levels, then the goal cell; with
    ``names``, those alone (in the grid's order; KeyError names an unknown one)."""
    out = [Cell(BASELINE, BASELINE, None)]
    for factor, levels in FACTORS.items():  # a factor is named after its Cell field
        out += [Cell(_name(factor, v), factor, v, **{factor: v}) for v in levels]
    out.append(Cell("goal-300ms-5pct", "goal", None, latency_ms=300.0, loss=0.05))
    wanted = list(names)
    if not wanted:
        return out
    known = {c.name for c in out}
    unknown = [n for n in wanted if n not in known]
    if unknown:
        raise KeyError(f"unknown cells {unknown} (cells: {sorted(known)})")
    return [c for c in out if c.name in wanted]


def rounds(seeds: Sequence[int], vehicles: int) -> list[list[int]]:
    """``seeds`` in rounds of at most ``vehicles`` missions, as even as they go (50 seeds on
    15 vehicles: 13, 13, 12, 12)."""
    if vehicles < 1:
        raise ValueError("a round has at least one vehicle")
    n = math.ceil(len(seeds) / vehicles) if seeds else 0
    out, start = [], 0
    for k in range(n):
        size = len(seeds) // n + (1 if k < len(seeds) % n else 0)
        out.append(list(seeds[start:start + size]))
        start += size
    return out


def _count_faults(steps: Sequence[Mapping[str, Any]], name: str) -> int:
    return sum(1 for s in steps for f in s.get("faults", []) if str(f).split(":")[0] == name)


def row(cell: Cell, controller: str, seed: int, uav: str, round_no: int,
        summary: Mapping[str, Any] | None, steps: Sequence[Mapping[str, Any]],
        wire: Mapping[str, Any], outage: Mapping[str, Any], air_exit: int | None,
        run_dir: str) -> dict[str, str]:
    """One mission's CSV row from its ``summary.json`` (None, or no ``ending``: the mission
    never ended, a failure; its time limit ran out or a process died), its
    ``steps.jsonl`` step lines, its link's bytes over the mission (``wire_per_step`` of
    services/testbed/mission.py) and the outage it got. System 2's steps are those whose
    flown plan was System 2's (``system`` 2); plan deadline misses are summary.json's
    ``stack.faults.plan_deadline`` (the steps' ``plan_deadline`` faults without it). The
    failure cause is a failed mission's ending (results.csv's column), ``no_end`` for one that
    never ended, empty for a success."""
    n = len(steps)
    s2 = sum(1 for s in steps if s.get("system") == 2)
    stack = (summary or {}).get("stack", {})
    faults = stack.get("faults", {})
    deadline = int(faults.get("plan_deadline", _count_faults(steps, "plan_deadline")))
    link_steps = stack.get("link", {}).get("steps", {})
    nbytes = (int(wire["air_to_ground_bytes"]) + int(wire["ground_to_air_bytes"])
              if wire else None)
    values: dict[str, Any] = {
        "cell": cell.name, "factor": cell.factor,
        "level": "" if cell.level is None else f"{cell.level:g}", "controller": controller,
        "seed": seed, "uav": uav, "round": round_no,
        "success": int(bool(summary and summary.get("success"))),
        "ended": int(bool((summary or {}).get("ending"))),
        "ending": (summary or {}).get("ending") or "",
        "failure_cause": "" if summary and summary.get("success")
        else (summary or {}).get("ending") or "no_end", "steps": n,
        "s2_steps": s2, "s2_share": f"{s2 / n:.4f}" if n else "",
        "plan_deadline": deadline,
        "link_lost_steps": int(link_steps.get("link_lost", _count_faults(steps, "link_lost"))),
        "link_degraded_steps": int(link_steps.get("link_degraded",
                                                  _count_faults(steps, "link_degraded"))),
        "outage_at_step": outage.get("at_step", ""),
        "wire_bytes": "" if nbytes is None else nbytes,
        "wire_bytes_per_step": "" if nbytes is None or not n else f"{nbytes / n:.1f}",
        "air_exit": "" if air_exit is None else air_exit, "run_dir": run_dir,
    }
    return {k: str(values[k]) for k in ROW_FIELDS}


def _int(text: str) -> int:
    return int(text) if text not in ("", None) else 0


def summarise(rows: Iterable[Mapping[str, str]]) -> list[dict[str, Any]]:
    """Per cell and controller (in the order first seen): missions, successes and their rate,
    missions that never ended, System 2's share of all steps flown (pooled), plan deadline
    misses (in all, per mission, missions with any), steps with the link lost, and the bytes
    on the wire per step (both ways, pooled over the missions with counters)."""
    groups: dict[tuple[str, str], list[Mapping[str, str]]] = {}
    for r in rows:
        groups.setdefault((r["cell"], r["controller"]), []).append(r)
    out = []
    for (cell, controller), rs in groups.items():
        n = len(rs)
        steps = sum(_int(r["steps"]) for r in rs)
        wired = [r for r in rs if r["wire_bytes"] not in ("", None)]
        wired_steps = sum(_int(r["steps"]) for r in wired)
        deadline = sum(_int(r["plan_deadline"]) for r in rs)
        ok = sum(_int(r["success"]) for r in rs)
        out.append({
            "cell": cell, "controller": controller, "factor": rs[0]["factor"],
            "level": float(rs[0]["level"]) if rs[0]["level"] else None,
            "missions": n, "successes": ok, "success_rate": round(ok / n, 4),
            "unfinished": sum(1 for r in rs if r["ended"] != "1"), "steps": steps,
            "s2_share": round(sum(_int(r["s2_steps"]) for r in rs) / steps, 4) if steps else None,
            "plan_deadline": deadline, "plan_deadline_per_mission": round(deadline / n, 3),
            "missions_with_deadline_miss": sum(1 for r in rs if _int(r["plan_deadline"]) > 0),
            "link_lost_steps": sum(_int(r["link_lost_steps"]) for r in rs),
            "wire_bytes_per_step": (round(sum(_int(r["wire_bytes"]) for r in wired)
                                          / wired_steps, 1) if wired_steps else None),
        })
    return out


def pairs(rows: Iterable[Mapping[str, str]], controller: str, baseline: str,
          cell: str) -> list[tuple[Mapping[str, str], Mapping[str, str]]]:
    """(baseline row, cell row) of every seed ``controller`` flew in both cells, by seed."""
    by: dict[tuple[str, str], Mapping[str, str]] = {}
    for r in rows:
        if r["controller"] == controller and r["cell"] in (baseline, cell):
            by[(r["cell"], r["seed"])] = r
    seeds = sorted({s for c, s in by if c == baseline} & {s for c, s in by if c == cell},
                   key=int)
    return [(by[(baseline, s)], by[(cell, s)]) for s in seeds]


def paired_difference(matched: Sequence[tuple[Mapping[str, str], Mapping[str, str]]],
                      z: float = 1.96) -> tuple[float, float, float]:
    """The cell's success rate minus the baseline's over ``matched`` pairs, in points, with a
    normal interval of the paired differences (``z`` 1.96: 95 %); NaNs without pairs."""
    mean, lo, hi = mean_interval([float(_int(b["success"]) - _int(a["success"]))
                                  for a, b in matched], z)
    return (100 * mean, 100 * lo, 100 * hi)
