"""The mission loop's settings: controller, timing and the readings of Sec. IV."""

from __future__ import annotations

import enum
from dataclasses import dataclass


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
    #: Reading of d_t in Eq. (KSI): "active" (nearest active region) or
    #: "newborn" (only regions born at this step; inf otherwise).
    d_t_reading: str = "active"
    fallback: bool = True
    #: None: fronts ignite anywhere (b_t uniform over the area), so one can
    #: ignite on the UAV, a failure no planner can avoid. A distance (m): no
    #: front ignites with its region that close to the UAV (README, evaluation).
    ignition_clearance_m: float | None = None

    def __post_init__(self) -> None:
        if self.max_steps < 1:
            raise ValueError("max_steps >= 1 is required")
        if self.fire_substeps_per_motion < 0:
            raise ValueError("fire_substeps_per_motion must be >= 0")
        if self.d_t_reading not in ("active", "newborn"):
            raise ValueError(f"d_t_reading must be 'active' or 'newborn', not {self.d_t_reading!r}")
        if self.ignition_clearance_m is not None and not self.ignition_clearance_m >= 0:
            raise ValueError("ignition_clearance_m must be >= 0 or None")
