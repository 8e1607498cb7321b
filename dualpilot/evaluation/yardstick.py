"""The yardstick: every controller's success against what was achievable, mission by mission.

An evaluation with the controller ``oracle`` (``dualpilot evaluate --controllers
...,oracle``) has, per mission, the oracle's verdict (:mod:`dualpilot.oracle`) in
its row: ``success`` 1 for feasible (the witness's flight fills time and energy),
else ``failure_cause`` "impossible" or "unknown". From the rows of all controllers:

* a mission is **achievable** when the oracle flew a witness to G or any controller
  completed it (a completed flight is a witness too);
* a controller's success **as % of achievable** is its successes over the achievable
  missions; the interval is the 95 % Wilson interval, widened below by the
  undetermined missions (neither achievable nor certified impossible for every
  controller) counted as achievable;
* its failures are **avoidable** (the mission was achievable), **unavoidable** (the
  certificate covers its flight: :class:`dualpilot.oracle.certificate.Scope`) or
  **undetermined**.

:func:`yardstick` asserts what the certificate promises: no flight it covers reached
G on a mission it calls impossible (:class:`ContradictionError` otherwise).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from dualpilot.evaluation.missions import ORACLE
from dualpilot.evaluation.stats import mean_interval, wilson_interval
from dualpilot.mission.config import MissionConfig, controller_names
from dualpilot.oracle.certificate import CertificateParams, Scope, scope_of
from dualpilot.oracle.oracle import FEASIBLE, IMPOSSIBLE, UNKNOWN

Row = dict[str, str]


class ContradictionError(AssertionError):
    """A flight the certificate covers reached G on a mission it calls impossible."""


def verdict_of(row: Row) -> str:
    """The oracle's verdict in its results.csv row."""
    return FEASIBLE if row["success"] == "1" else row["failure_cause"] or UNKNOWN


class Verdicts:
    """The oracle's verdicts of an evaluation and what the flights add to them."""

    def __init__(self, rows: Sequence[Row], config: MissionConfig,
                 params: CertificateParams = CertificateParams()):
        self.scope: Scope = scope_of(config, params)
        self.per_step = 1 + config.reading().mission.fire_substeps_per_motion
        self.oracle = {int(r["mission"]): verdict_of(r) for r in rows
                       if r["controller"] == ORACLE}
        flights = [r for r in rows if r["controller"] != ORACLE]
        completed = {int(r["mission"]) for r in flights if r["success"] == "1"}
        self.achievable = {i for i, v in self.oracle.items() if v == FEASIBLE} | (
            completed & set(self.oracle))
        #: impossible for every controller of the table (None: the scope is one pace only)
        self.impossible_for_all = set() if self.scope.one_substep_steps else {
            i for i, v in self.oracle.items() if v == IMPOSSIBLE}
        self.contradictions = [(int(r["mission"]), r["controller"]) for r in flights
                               if r["success"] == "1" and self.covered_impossible(r)]

    def covered_impossible(self, row: Row) -> bool:
        """Whether the row's mission is certified impossible for a flight like the row's."""
        if self.oracle.get(int(row["mission"])) != IMPOSSIBLE:
            return False
        return self.scope.covers(int(float(row["fire_substeps"] or 0)),
                                 int(float(row["steps"] or 0)), self.per_step)

    def kind_of_failure(self, row: Row) -> str:
        """"avoidable", "unavoidable" or "undetermined" for a failed row (the oracle's own:
        "unavoidable" for its impossible verdicts)."""
        i = int(row["mission"])
        if i in self.achievable:
            return "avoidable"
        if row["controller"] == ORACLE:
            return "unavoidable" if self.oracle[i] == IMPOSSIBLE else "undetermined"
        return "unavoidable" if self.covered_impossible(row) else "undetermined"


def yardstick(rows: Sequence[Row], config: MissionConfig,
              params: CertificateParams = CertificateParams()) -> dict[str, Any]:
    """Per controller: success, % of achievable with its interval, failures by kind, time and
    energy over successes; and the oracle's counts. Raises :class:`ContradictionError` when a
    covered flight completed a mission the certificate calls impossible."""
    v = Verdicts(rows, config, params)
    if v.contradictions:
        raise ContradictionError(f"missions certified impossible but completed: "
                                 f"{v.contradictions}")
    out: dict[str, Any] = {
        "missions": len(v.oracle), "achievable": len(v.achievable),
        "oracle": {k: sum(1 for x in v.oracle.values() if x == k)
                   for k in (FEASIBLE, IMPOSSIBLE, UNKNOWN)},
        "scope": {"substeps": v.scope.substeps, "one_substep_steps": v.scope.one_substep_steps},
        "controllers": {},
    }
    present = {r["controller"] for r in rows}
    names = [c for c in (*controller_names(), *sorted(present)) if c in present and c != ORACLE]
    names = list(dict.fromkeys(names)) + ([ORACLE] if ORACLE in present else [])
    for name in names:
        mine = [r for r in rows if r["controller"] == name and int(r["mission"]) in v.oracle]
        out["controllers"][name] = _line(mine, v)
    return out


def _line(rows: Sequence[Row], v: Verdicts) -> dict[str, Any]:
    """One controller's line of the yardstick."""
    ok = [r for r in rows if r["success"] == "1"]
    missions = {int(r["mission"]) for r in rows}
    a = len(missions & v.achievable)
    open_ = len(missions - v.achievable - v.impossible_for_all)
    lo = wilson_interval(len(ok), a + open_)[0] if a + open_ else float("nan")
    hi = wilson_interval(len(ok), a)[1] if a else float("nan")
    kinds = {"avoidable": 0, "unavoidable": 0, "undetermined": 0}
    for r in rows:
        if r["success"] != "1":
            kinds[v.kind_of_failure(r)] += 1
    t = mean_interval([float(r["mission_time_s"]) for r in ok])
    e = mean_interval([float(r["energy"]) for r in ok])
    return {"n": len(rows), "successes": len(ok), "achievable": a,
            "of_achievable": len(ok) / a if a else float("nan"),
            "of_achievable_ci95": [lo, hi], "failures": kinds,
            "mission_time_s_mean": t[0], "energy_mean": e[0]}


def markdown(ys: dict[str, Any], title: str = "") -> str:
    """The yardstick as a Markdown table (one row per controller)."""
    lines = [f"**{title}**" if title else "",
             f"{ys['missions']} missions, achievable {ys['achievable']} (oracle: feasible "
             f"{ys['oracle'][FEASIBLE]}, impossible {ys['oracle'][IMPOSSIBLE]}, unknown "
             f"{ys['oracle'][UNKNOWN]})", "",
             "| controller | success | % of achievable (95 % CI) | avoidable failures | "
             "unavoidable | undetermined | time (s) | energy (N²) |",
             "|---|---|---|---|---|---|---|---|"]
    for name, c in ys["controllers"].items():
        lo, hi = c["of_achievable_ci95"]
        f = c["failures"]
        lines.append(
            f"| {name} | {100 * c['successes'] / max(c['n'], 1):.1f} % | "
            f"{_pct(c['of_achievable'])} ({_pct(lo)}–{_pct(hi)}) | {f['avoidable']} | "
            f"{f['unavoidable']} | {f['undetermined']} | {_num(c['mission_time_s_mean'], 1)} | "
            f"{_num(c['energy_mean'], 0)} |")
    return "\n".join(line for line in lines if line is not None) + "\n"


def _pct(x: float) -> str:
    return "—" if not np.isfinite(x) else f"{100 * x:.1f}"


def _num(x: float, digits: int) -> str:
    return "—" if not np.isfinite(x) else f"{x:.{digits}f}"
