"""The paper's decision dynamics, Sec. III-C: attention → Ψ → the system in control.

Ψ_t = H Ψ_{t−1} + B Q A_t   (Eq. Psi),   S_t = argmax_i Ψ_t(i)   (Eq. maxPsi),

with B = [[1, −1], [−1, 1]], Q the 2 × 3 performance matrix (rows: systems,
columns: attributes) and A_t the one-hot attention vector.

The attention also chooses System 2's objective: attribute 2 → mission time,
attribute 3 → energy; attribute 1 (response time) keeps the previous objective.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal, get_args

import numpy as np

from dualpilot.model.dynamics import Array
from dualpilot.plan import Objective
from dualpilot.supervisor.paper.attention import AttentionParams, sample_attention, xi

B_MATRIX = np.array([[1.0, -1.0], [-1.0, 1.0]])

#: How A_t is drawn: "sample" (P_t ~ Dir(Ξ_t), A_t ~ Cat(P_t), as the paper) or
#: "argmax" (A_t = argmax Ξ_t, P_t = Ξ_t / ΣΞ_t, the mean of Dir(Ξ_t); analysis only).
AttentionDraw = Literal["sample", "argmax"]


@dataclass(frozen=True)
class SupervisorParams:
    """Sec. IV-A values: Q = [[0.8, 0.5, 0.3], [0.4, 0.9, 0.9]], H = 0.5·I."""

    q: tuple[tuple[float, ...], ...] = ((0.8, 0.5, 0.3), (0.4, 0.9, 0.9))
    h: float = 0.5
    attention: AttentionParams = field(default_factory=AttentionParams)
    #: Reading of Eqs. (dir), (categorical), see :data:`AttentionDraw`.
    attention_draw: AttentionDraw = "sample"

    def __post_init__(self) -> None:
        if self.attention_draw not in get_args(AttentionDraw):
            raise ValueError(f"attention_draw must be one of {get_args(AttentionDraw)}, "
                             f"not {self.attention_draw!r}")

    @property
    def q_matrix(self) -> Array:
        return np.array(self.q, dtype=float)


@dataclass(frozen=True)
class Decision:
    """What a supervisor decided at one step, as the records keep it (every supervisor
    writes one). ``attention`` is 1-based (1..3), ``system`` is 1 or 2."""

    t: int
    d_t: float
    xi: Array
    p: Array
    attention: int
    psi: Array
    system: int
    objective: Objective


def psi_update(psi_prev: Array, attention_index: int, params: SupervisorParams) -> Array:
    """Eq. (Psi) for a 0-based attention index."""
    a = np.zeros(3)
    a[attention_index] = 1.0
    return np.asarray(params.h * np.asarray(psi_prev) + B_MATRIX @ params.q_matrix @ a)


class DecisionDynamics:
    """The paper's decision dynamics over a mission: draws the attention (Eqs. KSI, dir,
    categorical), holds Ψ (Eq. Psi) and System 2's objective between steps; ``decide`` is
    its one step method (Eq. maxPsi)."""

    def __init__(self, rng: np.random.Generator, params: SupervisorParams = SupervisorParams()):
        self.params = params
        self.rng = rng
        self.psi = np.zeros(2)
        self.objective = Objective.MISSION_TIME

    def decide(self, t: int, d_t: float) -> Decision:
        """Attention at step t with fire distance d_t (m), then Ψ and the system in control."""
        xi_t = xi(t, d_t, self.params.attention)
        if self.params.attention_draw == "argmax":  # no draw from the stream
            p, a = xi_t / xi_t.sum(), int(np.argmax(xi_t))
        else:
            p, a = sample_attention(xi_t, self.rng)
        self.psi = psi_update(self.psi, a, self.params)
        system = int(np.argmax(self.psi)) + 1  # ties (only Ψ = 0) go to System 1
        if a == 1:
            self.objective = Objective.MISSION_TIME
        elif a == 2:
            self.objective = Objective.ENERGY
        return Decision(
            t=t,
            d_t=d_t,
            xi=xi_t,
            p=p,
            attention=a + 1,
            psi=self.psi.copy(),
            system=system,
            objective=self.objective,
        )
