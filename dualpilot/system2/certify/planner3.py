"""The certified method in 3-D over fronts taller than the band (docs/three_d.md, "6. System 2").

**The reduction, and why its bound holds.** When no prism can be kept out of by its top or
bottom within the band (:meth:`Prism.escape_faces` lists its base's faces only: z_hi + ε
above the ceiling, z_lo − ε below the floor), Eq. (P2_3)-(P2_4) can hold only by a face of
a footprint, which constrains (x, y) alone. Eq. (1) and U and X (``speed_limit = "axis"``)
are per axis, the area bounds x and y, and Eq. (S2) is a sum over the axes. So the (x, y)
part of every feasible 3-D trajectory is a feasible trajectory of the planar (P2) on the
footprints, at no more than its cost: the planar optimum, and so the planar method's
certified bound, is a lower bound on the 3-D optimum. With the UAV at G_o's altitude,
v_z = 0 and u_{t|t,z} = 0 the planar plan lifted to that altitude (z constant, u_z ≡ 0) is
a 3-D plan of the same cost, and it keeps d_safe by the planar distances (its altitude lies
within every prism's altitudes). Then the 3-D answer is the planar
:class:`~dualpilot.system2.certify.planner.CertifiedSystem2`'s on the footprints, lifted:
its plan bit for bit, its cost, bound and certified gap.

**Otherwise** (a front lower than the ceiling less ε, or the UAV off G_o's altitude or
climbing) the 2.5-D reach sets and relaxation are not built: the request gets the fast
method's 3-D plan (:class:`~dualpilot.system2.fast.planner3.Fast3`) with **no bound**
(``Plan.bound`` None, ``info["certify"]`` says why), never an unproven certificate. A
mission is refused up front where that would be the rule (:func:`certifies_3d`, read by
:mod:`dualpilot.mission.dimension`).
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Sequence
from typing import Protocol

import numpy as np

from dualpilot.arrays import Array
from dualpilot.model.altitude import lift_controls, lift_state
from dualpilot.model.fire_height import FireHeightParams
from dualpilot.model.geometry import Polytope
from dualpilot.model.prism import Prism
from dualpilot.plan import Objective, Plan
from dualpilot.spec import MissionSpec
from dualpilot.system2.fast.planner3 import Fast3
from dualpilot.system2.problem import check_request


def certifies_3d(spec: MissionSpec, heights: FireHeightParams, scenario: str) -> str:
    """"" when every request of a 3-D mission on ``scenario`` under ``heights`` starts in
    the reduction (module docstring) as long as the UAV keeps G_o's altitude: every front's
    top + ε above the ceiling (``"above-ceiling"``: the ceiling + ε; ``"uniform"``: from
    ``fire_height_min_m``; a scenario's plume: not known before it burns) and the start at
    G_o's altitude; else why not, for the refusal."""
    band, eps = spec.band, spec.clearance_m
    reading = heights.resolved(scenario)
    tall = (reading == "above-ceiling"
            or (reading == "uniform" and heights.fire_height_min_m + eps > band.ceiling_m))
    level = band.ceiling_m - eps
    scope = (f"plans dim=3 only where every front's top is above the ceiling less ε "
             f"({level:g} m) and the start is at G_o's altitude (fire_height=above-ceiling, "
             f"or uniform with fire_height_min_m above {level:g} m)")
    if not tall:
        here = (f"fire_height=uniform from {heights.fire_height_min_m:g} m"
                if reading == "uniform" else f"fire_height={reading}, its fronts' tops "
                "following their fire")
        return f"{scope}; here {here}"
    if band.start_altitude_m != band.goal_z_m:
        return (f"{scope}; here the start at {band.start_altitude_m:g} m and G_o at "
                f"{band.goal_z_m:g} m")
    return ""


class PlanarCertified(Protocol):
    """The plane's certified planner, as :class:`Certified3` uses it."""

    trace: list[tuple[float, float, float]]

    def plan(self, state: Array, hulls: Sequence[Polytope], objective: Objective,
             prev_control: Array | None) -> Plan: ...

    def reset(self) -> None: ...


class Certified3:
    """The 3-D half of :class:`~dualpilot.system2.certify.planner.CertifiedSystem2` (module
    docstring): ``flat`` is the plane's certified planner, ``fast3`` the fast method in 3-D
    for the requests outside the reduction (it seeds ``flat``'s fast planner, as the fast
    method's 3-D half seeds its plane's)."""

    def __init__(self, spec: MissionSpec, flat: PlanarCertified, fast3: Fast3) -> None:
        self.spec, self.flat, self.fast3 = spec, flat, fast3
        self.trace: list[tuple[float, float, float]] = []

    def reset(self) -> None:
        """Forget the previous plans (the plane's and the fast method's in 3-D)."""
        self.flat.reset()
        self.fast3.reset()
        self.trace = []

    def reduces(self, x0: Array, u_prev: Array, prisms: Sequence[Prism]) -> bool:
        """No prism kept out of by its top or bottom within the band, and the UAV at G_o's
        altitude with v_z = 0 and u_{t|t,z} = 0 (module docstring)."""
        band, eps = self.spec.band, self.spec.clearance_m
        at_rest = bool(x0[2] == self.spec.goal_center[2] and x0[5] == 0.0 and u_prev[2] == 0.0)
        return at_rest and all(len(p.escape_faces(band, eps)) == p.base.n_faces
                               for p in prisms)

    def plan(self, state: Array, hulls: Sequence[Prism], objective: Objective,
             prev_control: Array | None) -> Plan:
        """The plane's certified plan lifted under the reduction, else the fast 3-D plan
        without a bound."""
        t0 = time.perf_counter()
        checked = check_request(state, hulls, objective, prev_control, dim=3)
        if isinstance(checked, str) or not self.reduces(*checked):
            plan = self.fast3.plan(state, tuple(hulls), objective, prev_control)
            self.trace = []
            why = ("the request is invalid" if isinstance(checked, str) else
                   "no bound: a front lower than the ceiling less ε, or the UAV off G_o's "
                   "altitude or climbing (docs/three_d.md, 6. System 2, Certified)")
            return dataclasses.replace(plan, bound=None, info={**plan.info, "certify": why})
        x0, u_prev, prisms = checked
        flat = self.flat.plan(np.array([x0[0], x0[1], x0[3], x0[4]]),
                              [p.base for p in prisms], objective, u_prev[:2])
        self.trace = list(self.flat.trace)
        info = {**flat.info, "reduction": True}
        if not flat.ok:
            failed = Plan.failed(2, flat.status, time.perf_counter() - t0, flat.message, dim=3)
            plan = dataclasses.replace(failed, objective=flat.objective, info=info)
        else:
            z = float(x0[2])
            plan = dataclasses.replace(
                flat, states=np.array([lift_state(s, z) for s in flat.states]),
                controls=lift_controls(flat.controls),
                compute_time_s=time.perf_counter() - t0, info=info)
        self.fast3.last = plan if plan.ok else None
        return plan
