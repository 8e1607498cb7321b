""""fast+risk": the fast method with a chance constraint on the fire forecast.

Each planned position p_τ (τ = 2..T) also keeps ε from the risk zones of its
step (:mod:`dualpilot.model.risk`: the cells whose forecast occupancy exceeds
α while the UAV is there), as keep-outs of that step only in the same convex
restrictions (:meth:`dualpilot.system2.fast.planner.FastSystem2.plan_with_zones`);
homotopies and the target still come from the hulls. In 3-D the zones are as tall as the
spec's ``zone_heights`` (:func:`dualpilot.model.risk.risk_map`, the run-time monitor's
reading): footprints kept out as prisms taller than the band under the default
``"band"``, or prisms passed around or over like the fronts'
(:mod:`dualpilot.system2.fast.planner3`).
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Sequence

from dualpilot.arrays import Array
from dualpilot.model.geometry import Polytope
from dualpilot.model.prism import Prism
from dualpilot.model.risk import ForecastView, RiskParams, risk_map
from dualpilot.plan import Objective, Plan
from dualpilot.spec import MissionSpec
from dualpilot.system2.fast.params import FastParams
from dualpilot.system2.fast.planner import FastSystem2
from dualpilot.system2.problem import System2Params


class RiskSystem2(FastSystem2):
    """"fast+risk" (see the module docstring).

    The plan is verified against the hulls exactly as "fast" (never less), and
    against each zone at its steps. When no plan meets the chance constraint,
    the "fast" plan is returned (``info["risk"]`` says so); without a forecast
    the method is "fast".
    """

    method = "fast+risk"
    uses_forecast = True

    def __init__(self, spec: MissionSpec, params: System2Params = System2Params(),
                 fast: FastParams = FastParams(), risk: RiskParams | None = None) -> None:
        super().__init__(spec, params, fast)
        self.risk = risk or RiskParams()

    def plan(self, state: Array, hulls: Sequence[Polytope] | Sequence[Prism],
             objective: Objective = Objective.MISSION_TIME, prev_control: Array | None = None,
             forecast: ForecastView | None = None) -> Plan:
        """Plan from ``state`` avoiding ``hulls`` and, at their steps, ``forecast``'s risk zones."""
        if forecast is None:
            return super().plan(state, hulls, objective, prev_control)
        t0 = time.perf_counter()
        zones = risk_map(forecast, self.risk, self.spec).step_masks(self.params.horizon, first=2)
        plan = self.plan_with_zones(state, hulls, objective, prev_control, zones)
        note: dict[str, object] = {"risk_zones": len(zones)}
        if not plan.ok and zones:
            note["risk"] = f"unmet ({plan.status.value}: {plan.message[:120]})"
            plan = super().plan(state, hulls, objective, prev_control)
        else:
            note["risk"] = "met" if zones else "no zones"
        return dataclasses.replace(plan, compute_time_s=time.perf_counter() - t0,
                                   info={**plan.info, **note})
