"""Fire data the planners can no longer trust: how stale it is and how far fronts may have spread.

Age: the sub-steps a FireAdvance left unanswered (*owed*) × T_f, in s of
simulated time (0 in normal flight); data at least ``stale_after_s`` old is
stale (:class:`StaleFireParams`; default one sub-step, T_f = 0.5 s). While it
is stale the planners avoid the last known hulls grown (:func:`grow_polygon`)
by :func:`credible_margin_m`, in m:

    r(a) = (ȳ^ν + k σ^ν) · a + (side_max − side_min) / 2

with ȳ, σ the Gauss–Markov speed's mean and deviation (m/s) and k = 4. Fronts
born while the EWS is silent are not bounded.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from dualpilot.model.fire import FireParams, FireSnapshot
from dualpilot.model.geometry import Polytope


@dataclass(frozen=True)
class StaleFireParams:
    """When fire data counts as stale (s of simulated time) and how fast fronts may spread."""

    stale_after_s: float = 0.5
    sigma_bound: float = 4.0  # k in ȳ + k σ

    def __post_init__(self) -> None:
        if not (self.stale_after_s > 0 and self.sigma_bound >= 0):
            raise ValueError("stale_after_s must be > 0 and sigma_bound >= 0")


def credible_speed_mps(fire: FireParams, params: StaleFireParams = StaleFireParams()) -> float:
    """ȳ^ν + k σ^ν: the fastest credible front speed (m/s), 6.2 m/s with the paper's values."""
    return abs(fire.speed_mean_mps) + params.sigma_bound * fire.speed_sigma_mps


def credible_margin_m(age_s: float, fire: FireParams,
                      params: StaleFireParams = StaleFireParams()) -> float:
    """r(a), the margin (m) by which fire data ``age_s`` old is grown (module docstring)."""
    if not (np.isfinite(age_s) and age_s >= 0):
        raise ValueError(f"age must be finite and >= 0, got {age_s}")
    if age_s == 0:
        return 0.0
    return credible_speed_mps(fire, params) * age_s + (fire.side_max_m - fire.side_min_m) / 2


def grow_polygon(poly: Polytope, margin_m: float) -> Polytope:
    """``poly`` ⊕ [−r, r]² (exact: the hull of every vertex moved to the four corners)."""
    if margin_m <= 0:
        return poly
    v = np.asarray(poly.vertices, dtype=float)
    shifts = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]], dtype=float) * margin_m
    return Polytope.from_vertices((v[:, None, :] + shifts[None, :, :]).reshape(-1, 2))


def grown_snapshot(snapshot: FireSnapshot, margin_m: float) -> FireSnapshot:
    """``snapshot`` with every region and hull grown by ``margin_m`` on every side (m), and
    upwards: its tops (3-D) raised by ``margin_m``."""
    if margin_m <= 0:
        return snapshot
    return replace(
        snapshot,
        regions=tuple(replace(r, width=r.width + 2 * margin_m, height=r.height + 2 * margin_m)
                      for r in snapshot.regions),
        hulls=tuple(grow_polygon(h, margin_m) for h in snapshot.hulls),
        tops_m=tuple(t + margin_m for t in snapshot.tops_m),
        hull_tops_m=tuple(t + margin_m for t in snapshot.hull_tops_m))
