"""The mission loop's settings: controller, timing and the readings of Sec. IV."""

from __future__ import annotations

import enum
from dataclasses import dataclass
from typing import Literal, get_args

#: Readings of d_t in Eq. (KSI), see :attr:`MissionParams.d_t_reading`.
DtReading = Literal["active", "newborn", "hull"]
#: Readings of the failure rule of Sec. IV, see :attr:`MissionParams.failure_rule`.
FailureRule = Literal["any", "newborn", "become"]
#: What the UAV flies with no OK plan, see :attr:`MissionParams.no_plan`.
NoPlan = Literal["brake", "escape"]


class Controller(enum.Enum):
    CC = "cc"
    S1 = "s1"
    S2 = "s2"


class Timing(enum.Enum):
    MEASURED = "measured"
    PAPER = "paper"


@dataclass(frozen=True)
class MissionParams:
    """Sec. IV values; ``paper_planning_time_s`` are the paper's S1/S2 averages (s).

    The geometry and the margins (d_safe, the planners' clearance) are in the
    mission spec (:class:`dualpilot.spec.MissionSpec`), not here.
    """

    max_steps: int = 150
    paper_planning_time_s: tuple[float, float] = (0.155, 5.0)
    #: Fire sub-steps while the UAV moves for ΔT. The paper propagates fires only
    #: while a plan is computed (0); 2 would also let fires evolve in flight.
    fire_substeps_per_motion: int = 0
    #: Reading of d_t in Eq. (KSI) ("the nearest firefront, which emerged at
    #: time-step t"): "active" (nearest active region), "newborn" (only the
    #: fronts that emerged since the last decision: those born during step
    #: t − 1's sub-steps, ``born_step == t - 1``; inf otherwise) or "hull"
    #: (nearest hull △(C^i_{1:t}), what the planners avoid).
    d_t_reading: DtReading = "active"
    #: Reading of the failure rule of Sec. IV ("the distance between the agent
    #: and a newly emerged firefront becomes less than d_safe"): "any" active
    #: region within d_safe; "newborn": only fronts born during this step;
    #: "become": a front whose distance was >= d_safe at the previous check
    #: and is below it now (a front born within d_safe does not fail the
    #: mission until it has been clear of the UAV once).
    failure_rule: FailureRule = "any"
    fallback: bool = True
    #: What the UAV flies when no system gives an OK plan (the paper is silent: its plans
    #: never fail to exist in Sec. IV). "brake": the force that stops it in one ΔT (Eq. 1);
    #: "escape": braking, unless braking would leave it within the planners' clearance of a
    #: hull, where no plan can start, and then the heading that lands it farthest from
    #: the hulls (dualpilot/mission/braking.py). An estimate error or a tracking lag can
    #: put a real vehicle there; Eq. (1) flown exactly rarely does.
    no_plan: NoPlan = "brake"
    #: None: fronts ignite anywhere (b_t uniform over the area), so one can
    #: ignite on the UAV, a failure no planner can avoid. A distance (m): no
    #: front ignites with its region that close to the UAV (README, evaluation);
    #: with ``FireParams.redraw_clearance`` no extent redraw puts it that close either.
    ignition_clearance_m: float | None = None

    def __post_init__(self) -> None:
        if self.max_steps < 1:
            raise ValueError("max_steps >= 1 is required")
        if self.fire_substeps_per_motion < 0:
            raise ValueError("fire_substeps_per_motion must be >= 0")
        if self.d_t_reading not in get_args(DtReading):
            raise ValueError(f"d_t_reading must be one of {get_args(DtReading)}, "
                             f"not {self.d_t_reading!r}")
        if self.failure_rule not in get_args(FailureRule):
            raise ValueError(f"failure_rule must be one of {get_args(FailureRule)}, "
                             f"not {self.failure_rule!r}")
        if self.no_plan not in get_args(NoPlan):
            raise ValueError(f"no_plan must be one of {get_args(NoPlan)}, not {self.no_plan!r}")
        if self.ignition_clearance_m is not None and not self.ignition_clearance_m >= 0:
            raise ValueError("ignition_clearance_m must be >= 0 or None")
