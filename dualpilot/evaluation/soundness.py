"""The certified bound against SCIP's proven optimum on small (P2) instances.

:func:`check` draws :func:`dualpilot.evaluation.instances.small_instance` (T = 3–8, one
or two rectangles), solves it to proven optimality with SCIP
(:class:`dualpilot.system2.scip.SeededExactSystem2`, no incumbent) and with the
"certified" method run to completion (tolerance 0), and compares: the bound must not
exceed SCIP's optimum and the certified gap must not be below the plan's true gap.
``benchmarks/certify_soundness.py`` runs thousands; a hypothesis test runs a few dozen.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

from dualpilot.evaluation.instances import SPEC, small_instance
from dualpilot.plan import certified_gap
from dualpilot.system2.certify.bnb import CertifyParams
from dualpilot.system2.certify.planner import CertifiedSystem2
from dualpilot.system2.problem import System2Params
from dualpilot.system2.scip import SeededExactSystem2

#: Relative slack of the comparison: SCIP's optimum is exact to its feasibility
#: tolerance (1e-6 on the big-M rows), not to the last digit.
SLACK = 1e-5


@dataclass(frozen=True)
class Check:
    """One instance: SCIP's verified cost (``upper``) and optimum (None unless proven),
    our bound, cost and gaps."""

    seed: int
    horizon: int
    upper: float | None
    optimum: float | None
    bound: float | None
    cost: float | None
    certified_gap: float | None
    true_gap: float | None

    @property
    def sound(self) -> bool:
        """The bound is at most SCIP's cost (so at most the optimum) and the certified gap at
        least the true gap."""
        if self.upper is None or self.bound is None:
            return True  # nothing to compare
        if self.bound > self.upper + SLACK * abs(self.upper) + 1e-9:
            return False
        if self.true_gap is None or self.certified_gap is None:
            return True
        return self.certified_gap >= self.true_gap - SLACK


def check(seed: int, scip_time_limit_s: float = 20.0,
          certify: CertifyParams | None = None) -> Check:
    """Solve instance ``seed`` both ways and compare (see the module docstring)."""
    inst, horizon = small_instance(seed)
    params = System2Params(horizon=horizon, time_limit_s=scip_time_limit_s)
    ours = CertifiedSystem2(SPEC, params, certify or CertifyParams(
        tolerance=0.0, time_budget_s=30.0)).plan(
        inst.state, inst.hulls, inst.objective, inst.prev_control)
    exact = SeededExactSystem2(SPEC, params).plan(inst.state, inst.hulls, inst.objective,
                                                  inst.prev_control)
    upper = exact.cost if exact.ok else None
    optimum = upper if exact.info.get("optimal") else None
    cost = ours.cost if ours.ok else None
    true_gap = None
    if optimum is not None and cost is not None and optimum > 0:
        true_gap = max(0.0, (cost - optimum) / optimum)
    bound = ours.bound
    if bound is None and ours.status.value == "infeasible":
        bound = math.inf
    gap = certified_gap(cost, bound) if cost is not None else None
    return Check(seed, horizon, upper, optimum, bound, cost, gap, true_gap)


def as_row(c: Check) -> dict[str, object]:
    """A JSON row of one check."""
    return {**dataclasses.asdict(c), "sound": c.sound}
