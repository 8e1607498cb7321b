"""The knobs of System 2's fast method (:mod:`dualpilot.system2.fast.planner`)."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class FastParams:
    """Knobs of the fast method.

    ``max_homotopies`` shortest paths (one per homotopy class, within
    ``length_slack`` of the shortest, classes told apart by the rays of the
    ``max_signature_hulls`` hulls nearest the start–target line);
    ``max_iterations`` QPs per homotopy; a run stops when a QP improves the
    cost by less than ``rel_tol``; half-planes are kept for (τ, i) pairs
    within ``near_m`` m of Q_i, each ``eps_margin_m`` m beyond Q_i (the
    solver's tolerance never shows as a violation); homotopies whose cost
    exceeds the best by more than ``screen_slack`` are not iterated;
    references move at ``speed_factor`` of the speed and force limits;
    once a feasible plan exists, no improving QP is started after ``max_qp``
    QPs in all. ``time_budget_s`` (s of wall clock, off by default) adds a
    second stop; it makes a plan depend on how loaded the machine is, so a
    seed no longer reproduces a mission exactly when it is set.
    """

    max_homotopies: int = 4
    max_iterations: int = 12
    rel_tol: float = 5e-4
    near_m: float = 60.0
    eps_margin_m: float = 0.01
    length_slack: float = 1.0
    max_signature_hulls: int = 5
    use_previous: bool = True
    screen_slack: float = 0.3
    speed_factor: float = 0.85
    max_qp: int = 14
    time_budget_s: float | None = None
    max_prefeasible: int = 5
    warm_start: bool = True

    def __post_init__(self) -> None:
        if self.max_homotopies < 1 or self.max_iterations < 1:
            raise ValueError("max_homotopies and max_iterations must be >= 1")
        if not (self.near_m > 0 and self.eps_margin_m >= 0 and self.length_slack >= 0):
            raise ValueError("near_m > 0, eps_margin_m >= 0 and length_slack >= 0 required")
