"""Problem (P2), System 2's MPC: parameters and the true objective, Eq. (S2).

J(X, U) = κ1 Σ_{τ=1..T} ‖p_{t+τ|t} − G_o‖² + κ2 Σ_{τ=1..T} ‖u_{t+τ|t} − u_{t+τ−1|t}‖²,

with u_{t|t} the control applied at the previous step. Every System 2
method (exact MIQP or fast) is scored with :func:`p2_cost`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dualpilot.model.dynamics import Array
from dualpilot.plan import Objective


@dataclass(frozen=True)
class System2Params:
    """Sec. IV-A: T = 80, M = 1e5, κ per objective; ε is our reading (see README).

    ``epsilon_m`` is the tolerance ε of Eq. (P2_3): planned positions stay at
    least ε outside every face-inflated hull. The paper leaves ε open; we use
    d_safe + 5 m so that the straight segment between two planned positions
    (at most 15·√2 m long) still keeps more than d_safe = 20 m.
    """

    horizon: int = 80
    big_m: float = 1e5
    epsilon_m: float = 25.0
    kappa_time: tuple[float, float] = (1.0, 0.001)
    kappa_energy: tuple[float, float] = (0.001, 1.0)
    area_size_m: float = 1000.0
    keep_in_area: bool = True
    time_limit_s: float = 60.0
    max_hulls: int = 10
    max_faces: int = 12

    def __post_init__(self) -> None:
        if self.horizon < 1:
            raise ValueError(f"horizon must be >= 1, got {self.horizon}")
        if self.epsilon_m < 0 or self.big_m <= 0 or self.time_limit_s <= 0:
            raise ValueError("epsilon_m >= 0, big_m > 0 and time_limit_s > 0 are required")

    def kappa(self, objective: Objective) -> tuple[float, float]:
        """(κ1, κ2) for the attention's objective."""
        return self.kappa_time if objective is Objective.MISSION_TIME else self.kappa_energy


def p2_cost(
    states: Array,
    controls: Array,
    goal_center: Array,
    kappa: tuple[float, float],
    prev_control: Array | None = None,
) -> float:
    """Eq. (S2) for a plan; ``states`` (T+1, 2·dim) includes x_{t|t} at row 0 (not costed)."""
    states = np.asarray(states, dtype=float)
    controls = np.asarray(controls, dtype=float)
    dim = controls.shape[1]
    g = np.asarray(goal_center, dtype=float)[:dim]
    u_prev = np.zeros(dim) if prev_control is None else np.asarray(prev_control, dtype=float)
    pos = states[1:, :dim]
    du = np.diff(np.vstack([u_prev, controls]), axis=0)
    return float(kappa[0] * np.sum((pos - g) ** 2) + kappa[1] * np.sum(du**2))
