"""P(System 1 in control | d, t) of the paper's supervisor, exactly, and the CC success it allows.

Sec. III-C: Ψ_t = H Ψ_{t−1} + B Q A_t (Eq. Psi), S_t = argmax_i Ψ_t(i) (Eq. maxPsi), with
P_t ~ Dirichlet(Ξ_t) (Eq. dir), A_t ~ Categorical(P_t) (Eq. categorical), Ξ_t of Eq. (KSI).

P_t is drawn afresh every step, so given the distances d_0..d_t the A_t are independent with
the Dirichlet–categorical marginal P(A_t = a) = ξ_a / Σξ: Ψ is a Markov chain. Ties of
Eq. (maxPsi) go to System 1 (``np.argmax`` in decision.py); Ψ_{−1} = 0 as there.

Three ways to run the chain (``BoundParams.method``):

- ``"lattice"`` (exact, finite): when (1, −1) H = λ (1, −1) only x = Ψ(1) − Ψ(2) matters,
  x_t = λ x_{t−1} + c_a with c = (1, −1) B Q. If λ = 1/n (n a positive integer) and
  c = u·k with k integers, every later decision compares y = x/u with an integer multiple
  of n, so m = ⌊y/n⌋ is a sufficient state: m' = ⌊(m + k_a)/n⌋, S_t = 1 ⇔ m_t ≥ 0.
  The paper's values (λ = 1/2, c = 0.4·(2, −2, −3)) give five states, m ∈ {−3..1}.
- ``"enumerate"`` (exact to ``tol``): the reachable Ψ (or x) values with their probabilities,
  equal values merged.
- ``"grid"``: the mass split multilinearly onto a ``grid_points`` grid spanning the reachable
  box each step; ``"auto"`` falls back to it, with a :class:`DiscretisationWarning`, when the
  enumeration passes ``max_states``.
"""

from __future__ import annotations

import itertools
import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from fractions import Fraction

import numpy as np

from dualpilot.model.dynamics import Array
from dualpilot.supervisor.paper.attention import xi
from dualpilot.supervisor.paper.decision import B_MATRIX, SupervisorParams

METHODS = ("auto", "lattice", "enumerate", "grid")
_DIFF = np.array([1.0, -1.0])  # x = Ψ(1) − Ψ(2): S_t = 1 ⇔ x_t ≥ 0


class DiscretisationWarning(UserWarning):
    """The exact Ψ state space passed ``max_states``: the rest of the chain ran on a grid."""


@dataclass(frozen=True)
class BoundParams:
    """The supervisor whose chain is run, and how.

    ``h_matrix`` (2 × 2) replaces ``supervisor.h``·I and ``b_matrix`` (2 × 2) replaces
    decision.B_MATRIX when given; ``psi_init`` is Ψ_{−1} (zeros, as ``Supervisor``).
    """

    supervisor: SupervisorParams = field(default_factory=SupervisorParams)
    h_matrix: tuple[tuple[float, float], tuple[float, float]] | None = None
    b_matrix: tuple[tuple[float, float], tuple[float, float]] | None = None
    psi_init: tuple[float, float] = (0.0, 0.0)
    method: str = "auto"
    tol: float = 1e-9
    max_states: int = 20_000
    grid_points: int = 2001

    def matrices(self) -> tuple[Array, Array, Array]:
        """(H, increments, Ψ_{−1}): increments[a] = B Q e_a, the Ψ step of attention a (0-based)."""
        h = (
            self.supervisor.h * np.eye(2)
            if self.h_matrix is None
            else np.array(self.h_matrix, dtype=float)
        )
        b = B_MATRIX if self.b_matrix is None else np.array(self.b_matrix, dtype=float)
        q = self.supervisor.q_matrix
        if h.shape != (2, 2) or b.shape != (2, 2) or q.shape != (2, 3):
            raise ValueError(f"need H, B 2x2 and Q 2x3, got {h.shape}, {b.shape}, {q.shape}")
        return h, (b @ q).T, np.array(self.psi_init, dtype=float)


def _as_bound_params(params: SupervisorParams | BoundParams) -> BoundParams:
    bp = params if isinstance(params, BoundParams) else BoundParams(supervisor=params)
    if bp.method not in METHODS:
        raise ValueError(f"method must be one of {METHODS}, got {bp.method!r}")
    return bp


def _check_distances(d_path: float | Sequence[float] | Array) -> Array:
    d = np.atleast_1d(np.asarray(d_path, dtype=float))
    if d.ndim != 1 or d.size == 0:
        raise ValueError(f"distances must be a non-empty 1-D sequence, got shape {d.shape}")
    if np.any(np.isnan(d)) or np.any(d < 0):
        raise ValueError(f"distance to the nearest fire must be >= 0 m (inf: no fire), got {d}")
    return d


def _check_step(t: int) -> int:
    if isinstance(t, bool) or int(t) != t or t < 0:
        raise ValueError(f"step t must be an integer >= 0, got {t}")
    return int(t)


def attention_marginal(t: int, d_m: float, params: SupervisorParams = SupervisorParams()) -> Array:
    """P(A_t = a) = ξ_a / Σξ, a = 1..3: the Dirichlet–categorical marginal (Eqs. KSI, dir, cat).

    ``d_m`` is the distance to the nearest fire in m (inf: none), ``t`` the step.
    """
    x = xi(float(_check_step(t)), float(_check_distances([d_m])[0]), params.attention)
    return np.asarray(x / x.sum())


def _lattice(h: Array, inc: Array, tol: float) -> tuple[int, Array, float] | None:
    """(n, k, u) with λ = 1/n and c = u·k if the finite-state reduction applies, else None."""
    lam_row = _DIFF @ h
    lam = float(lam_row[0])
    if not np.allclose(lam_row, lam * _DIFF, atol=tol, rtol=0) or lam <= 0:
        return None
    n = round(1.0 / lam)
    if abs(n * lam - 1.0) > tol:
        return None
    c = inc @ _DIFF
    if np.allclose(c, 0.0, atol=tol):
        return None
    fracs = [Fraction(float(v)).limit_denominator(10**6) for v in c]
    if any(abs(float(f) - v) > tol * max(1.0, abs(v)) for f, v in zip(fracs, c, strict=True)):
        return None
    den = math.lcm(*(f.denominator for f in fracs))
    nums = [int(f * den) for f in fracs]
    g = math.gcd(*nums)
    u = g / den
    return n, np.array([v // g for v in nums], dtype=np.int64), u


def chain_method(params: SupervisorParams | BoundParams = SupervisorParams()) -> str:
    """The exact method ``"auto"`` starts with: ``"lattice"`` if it applies, else ``"enumerate"``.

    ``"enumerate"`` may still fall back to ``"grid"`` (see :class:`DiscretisationWarning`).
    """
    bp = _as_bound_params(params)
    h, inc, _ = bp.matrices()
    return "lattice" if _lattice(h, inc, bp.tol) is not None else "enumerate"


def _merge(keys: np.ndarray, weights: Array) -> tuple[np.ndarray, Array]:
    """Sum ``weights`` (n, 2) of equal rows of ``keys``; returns (first index per key, sums)."""
    _, first, inverse = np.unique(keys, axis=0, return_index=True, return_inverse=True)
    inverse = inverse.ravel()
    cols = [np.bincount(inverse, weights=weights[:, j], minlength=first.size) for j in range(2)]
    return first, np.stack(cols, axis=1).astype(np.float64)


def _to_grid(points: Array, weights: Array, g: int) -> tuple[Array, Array]:
    """Split each point's mass multilinearly onto a g-per-axis grid over the points' box."""
    lo, hi = points.min(axis=0), points.max(axis=0)
    span = np.where(hi > lo, hi - lo, 1.0)
    u = (points - lo) / span * (g - 1)
    i0 = np.clip(np.floor(u), 0, g - 2).astype(np.int64)
    f = u - i0
    k = points.shape[1]
    flat_all, w_all = [], []
    for corner in itertools.product((0, 1), repeat=k):
        c = np.array(corner)
        share = np.prod(np.where(c == 1, f, 1.0 - f), axis=1)
        idx = i0 + c
        flat_all.append(np.ravel_multi_index(tuple(idx.T), (g,) * k))
        w_all.append(weights * share[:, None])
    flat = np.concatenate(flat_all)
    w = np.concatenate(w_all)
    first, sums = _merge(flat[:, None], w)
    keep = sums[:, 0] > 0
    nodes = np.stack(np.unravel_index(flat[first][keep], (g,) * k), axis=1)
    return lo + nodes / (g - 1) * span, sums[keep]


def _forward(bp: BoundParams, probs: Array, hazards: Array | None) -> tuple[Array, float, str]:
    """Run the chain over the steps of ``probs`` (T, 3).

    Returns (P(S_t = 1) per step, P(no step ended the mission), method used); ``hazards``
    (T, 2) are the per-step hazards of S1 and S2, applied to the step's system.
    """
    h, inc, psi0 = bp.matrices()
    steps = probs.shape[0]
    haz = np.zeros((steps, 2)) if hazards is None else hazards
    lat = _lattice(h, inc, bp.tol) if bp.method in ("auto", "lattice") else None
    if bp.method == "lattice" and lat is None:
        raise ValueError(
            "the lattice reduction needs (1,-1)H = (1/n)(1,-1) and (1,-1)BQ on a grid u·Z"
        )
    if lat is not None:
        return _forward_lattice(bp, lat, psi0, probs, haz)
    return _forward_states(bp, h, inc, psi0, probs, haz)


def _forward_lattice(bp: BoundParams, lat: tuple[int, Array, float], psi0: Array,
                     probs: Array, haz: Array) -> tuple[Array, float, str]:
    """The chain on the lattice m = floor((1,-1)Ψ / u / n): exact, one integer per state."""
    n, k, u = lat
    steps = probs.shape[0]
    p_s1 = np.empty(steps)
    # weights: column 0 the probability, column 1 the same joint with survival
    weights = np.ones((1, 2))
    m = np.array([math.floor(float(_DIFF @ psi0) / u / n + bp.tol)], dtype=np.int64)
    for t in range(steps):
        m_all = np.concatenate([(m + k[a]) // n for a in range(3)])
        w_all = np.concatenate([weights * probs[t, a] for a in range(3)])
        s1 = m_all >= 0
        p_s1[t] = w_all[s1, 0].sum()
        w_all[:, 1] *= np.where(s1, 1.0 - haz[t, 0], 1.0 - haz[t, 1])
        first, weights = _merge(m_all[:, None], w_all)
        m = m_all[first]
    return p_s1, float(weights[:, 1].sum()), "lattice"


def _forward_states(bp: BoundParams, h: Array, inc: Array, psi0: Array, probs: Array,
                    haz: Array) -> tuple[Array, float, str]:
    """The chain on Ψ itself (or x = (1,-1)Ψ alone), enumerated exactly or on a grid."""
    steps = probs.shape[0]
    p_s1 = np.empty(steps)
    weights = np.ones((1, 2))
    # x alone is a Markov state when (1,-1) is a left eigenvector of H
    lam_row = _DIFF @ h
    scalar = np.allclose(lam_row, lam_row[0] * _DIFF, atol=bp.tol, rtol=0)
    if scalar:
        step_h, step_inc = np.array([[lam_row[0]]]), (inc @ _DIFF)[:, None]
        states = np.array([[_DIFF @ psi0]])
    else:
        step_h, step_inc, states = h, inc, psi0[None, :]
    method = "grid" if bp.method == "grid" else "enumerate"
    for t in range(steps):
        pts = np.concatenate([states @ step_h.T + step_inc[a] for a in range(3)])
        w_all = np.concatenate([weights * probs[t, a] for a in range(3)])
        x = pts[:, 0] if scalar else pts @ _DIFF
        s1 = x >= -bp.tol  # a tie in exact arithmetic goes to System 1
        p_s1[t] = w_all[s1, 0].sum()
        w_all[:, 1] *= np.where(s1, 1.0 - haz[t, 0], 1.0 - haz[t, 1])
        if method == "enumerate":
            first, weights = _merge(np.round(pts / bp.tol).astype(np.int64), w_all)
            states = pts[first]
            if states.shape[0] > bp.max_states:
                _too_many_states(bp, t)
                method = "grid"
        else:
            states, weights = _to_grid(pts, w_all, bp.grid_points)
    return p_s1, float(weights[:, 1].sum()), method


def _too_many_states(bp: BoundParams, t: int) -> None:
    """Exact enumeration passed ``max_states``: an error if asked for, else a warning."""
    if bp.method == "enumerate":
        raise ValueError(f"exact enumeration passed max_states={bp.max_states} at t={t}")
    warnings.warn(
        f"exact Ψ state space passed {bp.max_states} states at t={t}: "
        f"discretising on a {bp.grid_points}-point grid per axis from here on",
        DiscretisationWarning,
        stacklevel=5,
    )


def _attention_path(d: Array, sup: SupervisorParams) -> Array:
    return np.array([attention_marginal(t, float(dt), sup) for t, dt in enumerate(d)])


def p_s1_path(
    d_path: Sequence[float] | Array, params: SupervisorParams | BoundParams = SupervisorParams()
) -> Array:
    """P(S_t = 1 | d_0..d_t), t = 0..len(d_path) − 1, for the distances ``d_path`` (m).

    ``d_path[t]`` is d_t of Eq. (KSI) at step t (inf: no fire); step t's attention uses t.
    """
    bp = _as_bound_params(params)
    d = _check_distances(d_path)
    return _forward(bp, _attention_path(d, bp.supervisor), None)[0]


def p_s1(d_m: float, t: int, params: SupervisorParams | BoundParams = SupervisorParams()) -> float:
    """P(S_t = 1) when the nearest fire is ``d_m`` metres away at every step 0..t."""
    t = _check_step(t)
    return float(p_s1_path(np.full(t + 1, float(_check_distances([d_m])[0])), params)[t])


def p_s1_table(
    d_values: Sequence[float] | Array,
    t_max: int,
    params: SupervisorParams | BoundParams = SupervisorParams(),
) -> Array:
    """P(S_t = 1 | d_s = d for s ≤ t) as an array (len(d_values), t_max + 1): rows d, columns t."""
    d = _check_distances(d_values)
    t_max = _check_step(t_max)
    return np.array([p_s1_path(np.full(t_max + 1, dv), params) for dv in d])


def _check_hazards(h: float | Sequence[float] | Array, name: str, steps: int | None) -> Array:
    arr = np.atleast_1d(np.asarray(h, dtype=float))
    if arr.ndim != 1 or np.any(~np.isfinite(arr)) or np.any((arr < 0) | (arr > 1)):
        raise ValueError(f"hazard {name} must be a probability per step in [0, 1], got {h}")
    if steps is not None and arr.size not in (1, steps):
        raise ValueError(f"hazard {name} has {arr.size} values for {steps} steps")
    return arr


def _hazard_pair(
    h1: float | Sequence[float] | Array, h2: float | Sequence[float] | Array, steps: int | None
) -> Array:
    a1, a2 = _check_hazards(h1, "h1", steps), _check_hazards(h2, "h2", steps)
    if steps is None:
        if a1.size == 1 and a2.size == 1:
            raise ValueError("give the mission length `steps` when both hazards are scalars")
        steps = max(a1.size, a2.size)
        if a1.size not in (1, steps) or a2.size not in (1, steps):
            raise ValueError(f"h1 and h2 have different lengths: {a1.size} and {a2.size}")
    _check_step(steps)
    if steps < 1:
        raise ValueError("the mission needs at least one step")
    return np.stack([np.broadcast_to(a1, steps), np.broadcast_to(a2, steps)], axis=1)


def s1_share_needed(
    target: float,
    h1: float | Sequence[float] | Array,
    h2: float | Sequence[float] | Array,
    steps: int | None = None,
) -> float:
    """Smallest share of the steps System 1 must fly for success ``target`` (inf: unreachable).

    Success = Π_t (1 − h_{S_t, t}) with independent per-step hazards; S1 takes the steps
    where it gains most, fractionally. With constant hazards the share is
    (ln target − T ln(1 − h2)) / (T (ln(1 − h1) − ln(1 − h2))).
    """
    if not 0 < target <= 1:
        raise ValueError(f"target success must be in (0, 1], got {target}")
    haz = np.minimum(_hazard_pair(h1, h2, steps), 1.0 - 1e-15)
    log_ok = np.log1p(-haz)
    need = math.log(target) - float(log_ok[:, 1].sum())
    if need <= 0:
        return 0.0
    gains = np.sort(log_ok[:, 0] - log_ok[:, 1])[::-1]
    gains = gains[gains > 0]
    cum = np.cumsum(gains)
    if cum.size == 0 or cum[-1] < need:
        return math.inf
    j = int(np.searchsorted(cum, need))
    before = cum[j - 1] if j > 0 else 0.0
    return float((j + (need - before) / gains[j]) / haz.shape[0])


@dataclass(frozen=True)
class CCBound:
    """Best CC success over ``steps`` steps, with S1-only and S2-only success on the same hazards.

    ``s1_share`` is the expected share of steps CC gives S1; ``share_needed`` the share CC
    would need for ``target`` (inf: even S1 on every step falls short).
    """

    steps: int
    d_m: float
    cc_success: float
    s1_success: float
    s2_success: float
    s1_share: float
    p_s1: Array
    target: float
    share_needed: float
    method: str


def best_cc_success(
    h1: float | Sequence[float] | Array,
    h2: float | Sequence[float] | Array,
    steps: int | None = None,
    params: SupervisorParams | BoundParams = SupervisorParams(),
    *,
    d_m: float | Sequence[float] | Array = 0.0,
    target: float = 0.9,
) -> CCBound:
    """Best mission success of CC with per-step hazards ``h1``, ``h2`` (probabilities per step).

    Assumptions: a step flown by system i ends the mission with probability h_i (scalars or
    one value per step), independently across steps and of the supervisor's draws; the
    nearest fire is ``d_m`` = 0 m at every step (the default), so ξ1 is at its maximum.
    For the paper's supervisor d = 0 is the best case when h1 ≤ h2: a larger ξ1 shifts
    A_t towards attribute 1 (first-order), x ↦ x/2 + c_a is increasing in x and in c_a,
    so under the monotone coupling S1 flies on a superset of steps.
    """
    bp = _as_bound_params(params)
    haz = _hazard_pair(h1, h2, steps)
    n = haz.shape[0]
    d = _check_distances(d_m)
    if d.size not in (1, n):
        raise ValueError(f"d_m has {d.size} values for {n} steps")
    d = np.broadcast_to(d, n)
    p, survival, method = _forward(bp, _attention_path(d, bp.supervisor), haz)
    return CCBound(
        steps=n,
        d_m=float(d[0]) if np.all(d == d[0]) else math.nan,
        cc_success=survival,
        s1_success=float(np.prod(1.0 - haz[:, 0])),
        s2_success=float(np.prod(1.0 - haz[:, 1])),
        s1_share=float(p.mean()),
        p_s1=p,
        target=target,
        share_needed=s1_share_needed(target, haz[:, 0], haz[:, 1]),
        method=method,
    )
