""""fast+exact": the fast plan, then SCIP seeded with it in a killable worker (anytime).

The worker solves (P2) exactly (:class:`dualpilot.system2.scip.SeededExactSystem2`:
native SCIP, tight big-M, the fast plan of :mod:`dualpilot.system2.fast.planner`
as the starting incumbent) within ``exact_budget_s`` (its time limit is set a little
below); the better verified plan is returned. A worker crash or overrun leaves the
fast plan as the answer. Not the default: its latency is the exact budget whenever
SCIP cannot prove optimality quickly. In 3-D both plan with prisms within the band
(docs/three_d.md, 6), and the exact plan is checked with the band.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Sequence

import numpy as np

from dualpilot.arrays import Array
from dualpilot.model.geometry import Polytope
from dualpilot.model.prism import Prism
from dualpilot.plan import Objective, Plan, PlanStatus
from dualpilot.spec import MissionSpec
from dualpilot.system2.fast.params import FastParams
from dualpilot.system2.fast.planner import FastSystem2
from dualpilot.system2.problem import System2Params, verify_p2_plan
from dualpilot.system2.scip import SeededExactSystem2
from dualpilot.system2.worker import PlannerFactory, Worker


class AnytimeSystem2:
    """"fast+exact" (see the module docstring): a fast planner and an exact worker.

    Parameters
    ----------
    spec : MissionSpec
        Goal, area, ε, d_safe and Eq. (1).
    params : System2Params
        T and κ of both planners.
    exact_budget_s : float
        The whole plan's budget (s); SCIP's time limit is 0.8 of it (at least 0.2 s).
    worker : Worker, optional
        The exact planner's worker (default: a :class:`SeededExactSystem2` one).
    fast : FastParams
        The fast method's knobs.
    """

    system = 2
    method = "fast+exact"

    def __init__(self, spec: MissionSpec, params: System2Params = System2Params(), *,
                 exact_budget_s: float = 2.0, worker: Worker | None = None,
                 fast: FastParams = FastParams()) -> None:
        if spec.dim == 3 and spec.dynamics.speed_limit == "norm":
            raise ValueError("System 2 method 'fast+exact' plans in 3-D under speed_limit = "
                             "'axis' only")
        if exact_budget_s <= 0:
            raise ValueError("exact_budget_s must be positive")
        self.spec, self.params, self.dynamics = spec, params, spec.dynamics
        self.goal = spec.goal
        self.exact_budget_s = float(exact_budget_s)
        self.fast_planner = FastSystem2(spec, params, fast)
        if worker is None:
            limit = max(0.2, 0.8 * exact_budget_s)
            exact_params = dataclasses.replace(params, time_limit_s=float(limit))
            worker = Worker(PlannerFactory(SeededExactSystem2, spec, exact_params))
        self.worker = worker
        worker.start()  # imports and model set-up happen before the first request

    def plan(self, state: Array, hulls: Sequence[Polytope] | Sequence[Prism],
             objective: Objective = Objective.MISSION_TIME,
             prev_control: Array | None = None) -> Plan:
        """Plan from ``state`` avoiding ``hulls`` (polygons in 2-D, prisms in 3-D);
        ``prev_control`` is u_{t|t} (N)."""
        t0 = time.perf_counter()
        fast = self.fast_planner.plan(state, hulls, objective, prev_control)
        if fast.status in (PlanStatus.INVALID_INPUT, PlanStatus.INFEASIBLE):
            return fast
        if fast.ok and fast.info.get("optimal"):
            # the relaxation's optimum is feasible: nothing to improve
            return dataclasses.replace(
                fast, compute_time_s=time.perf_counter() - t0,
                info={**fast.info, "source": "fast",
                      "exact_outcome": "skipped (fast plan proven optimal)"})
        request = (np.asarray(state, dtype=float), tuple(hulls), objective, prev_control,
                   fast.controls if fast.ok else None)
        left = max(0.05, self.exact_budget_s - (time.perf_counter() - t0))
        answer, why = self.worker.solve(request, left)
        exact = answer if isinstance(answer, Plan) else None
        if answer is not None and exact is None:
            why = "bad answer"
        best = fast
        if exact is not None and exact.ok and exact.cost is not None:
            spec = self.spec
            area = spec.area_size_m if self.params.keep_in_area else None
            verdict = verify_p2_plan(exact.states, exact.controls, tuple(hulls), self.dynamics,
                                     spec.clearance_m, spec.d_safe_m, area, tol=1e-3,
                                     band=spec.band if spec.dim == 3 else None)
            if verdict.ok and (
                    not fast.ok or fast.cost is None or exact.cost < fast.cost):
                best = exact
        info = dict(best.info)
        info.update(source="exact" if best is exact else "fast", exact_outcome=why,
                    exact_status=None if exact is None else exact.status.value,
                    fast_cost=fast.cost)
        return Plan(system=2, status=best.status, states=best.states, controls=best.controls,
                    compute_time_s=time.perf_counter() - t0, objective=objective,
                    cost=best.cost, message=best.message, info=info)

    def close(self) -> None:
        """Stop the exact worker."""
        self.worker.stop()
