"""Attention parameters Ξ_t, Eq. (KSI), and the probabilistic attention of Sec. III-C.

Attributes: a = 1 response time, a = 2 mission completion time, a = 3 energy.

ξ1(t) = w1c − w1c / (1 + w1a·exp(−w1b (d_t − w1a))) + w1d      (d_t in m)
ξ2(t) = w2c − w2c / (1 + w2a·exp(−w2b (t − w2a)))   + w2d      (t in steps)
ξ3(t) = w3c / (1 + w3a·exp(−w3b (t − w3a)))          + w3d

P_t ~ Dirichlet(Ξ_t), Eq. (dir);  A_t ~ Categorical(P_t), Eq. (categorical).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dualpilot.model.dynamics import Array


@dataclass(frozen=True)
class Logistic:
    """One attention profile's hyper-parameters (w_a, w_b, w_c, w_d) of Eq. (KSI)."""

    a: float
    b: float
    c: float
    d: float

    def rising(self, s: float) -> float:
        """w_c / (1 + w_a exp(−w_b (s − w_a))) + w_d: from ≈ w_d up to w_c + w_d."""
        z = -self.b * (s - self.a)
        # exp overflow guard: the logistic is 0 there anyway
        denom = 1.0 + self.a * np.exp(min(z, 700.0))
        return float(self.c / denom + self.d)

    def falling(self, s: float) -> float:
        """w_c − w_c / (1 + w_a exp(−w_b (s − w_a))) + w_d: from ≈ w_c + w_d down to w_d."""
        return float(self.c + 2 * self.d - self.rising(s))


@dataclass(frozen=True)
class AttentionParams:
    """Sec. IV-A / Fig. 3 values."""

    response: Logistic = Logistic(a=40.0, b=0.02, c=9.0, d=1.0)
    mission_time: Logistic = Logistic(a=10.0, b=0.05, c=7.0, d=1.0)
    energy: Logistic = Logistic(a=10.0, b=0.15, c=7.0, d=1.0)


def xi(t: float, d_t: float, params: AttentionParams = AttentionParams()) -> Array:
    """Ξ_t = (ξ1, ξ2, ξ3) of Eq. (KSI) at step ``t`` and fire distance ``d_t`` (m).

    ``d_t = inf`` (no active fire) gives ξ1 = w1d, its lower limit.
    """
    if not np.isfinite(t) or t < 0:
        raise ValueError(f"t must be finite and >= 0, got {t}")
    if np.isnan(d_t) or d_t < 0:
        raise ValueError(f"d_t must be >= 0 (inf allowed), got {d_t}")
    xi1 = params.response.falling(float(d_t)) if np.isfinite(d_t) else params.response.d
    return np.array([xi1, params.mission_time.falling(float(t)), params.energy.rising(float(t))])


def sample_attention(xi_t: Array, rng: np.random.Generator) -> tuple[Array, int]:
    """Draw P_t ~ Dirichlet(Ξ_t) and A_t ~ Categorical(P_t); returns (P_t, a) with a in {0,1,2}."""
    xi_t = np.asarray(xi_t, dtype=float)
    if xi_t.shape != (3,) or not (np.isfinite(xi_t).all() and (xi_t > 0).all()):
        raise ValueError(f"Ξ must be three positive finite numbers, got {xi_t}")
    p = rng.dirichlet(xi_t)
    # Generator.choice(3, p=p) without its checks: one uniform draw against the cdf
    # (the cdf's running sums, normalised by the last; a = how many are <= the draw)
    c0 = float(p[0])
    c1 = c0 + float(p[1])
    c2 = c1 + float(p[2])
    u = rng.random()
    a = (c0 / c2 <= u) + (c1 / c2 <= u) + (c2 / c2 <= u)
    return p, int(a)
