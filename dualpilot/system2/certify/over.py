"""Lower bounds on the altitude's part of Eq. (S2) in 3-D, over or around each front.

Eq. (S2) is a sum over the axes, κ1 Σ_τ ‖p_τ − G_o‖² + κ2 Σ_τ ‖u_τ − u_{τ−1}‖², so the cost
of a 3-D trajectory is its (x, y) part plus its z part, κ1 Σ_τ (z_τ − g_z)² + κ2 Σ_τ
(u_{τ,z} − u_{τ−1,z})², and the z part is at least Z = κ1 Σ_τ (z_τ − g_z)². Under Eq. (1), X
and the band, each z_τ (τ = 1..T, the rows x_{t+1|t}..x_{t+T|t}) lies in its reach interval
[l_τ, h_τ] (:func:`~dualpilot.model.dynamics.reach_boxes` cut to the band), so

* every feasible trajectory has Z ≥ Z_0 = κ1 Σ_τ dist(g_z, [l_τ, h_τ])²;
* a trajectory that keeps a prism by its top at τ (z_τ ≥ z_hi + ε, the top row of
  Eq. (P2_3)) has z_σ ≥ z_hi + ε − v_max ΔT |σ − τ| at every σ (z_σ − z_τ is ΔT times a sum
  of |σ − τ| vertical velocities, each at most v_max by X, both readings), so
  Z ≥ κ1 Σ_σ dist(g_z, [max(l_σ, z_hi + ε − v_max ΔT |σ − τ|), h_σ])², and τ is one whose
  planar reach box meets {α_l·p ≤ β_l + ε, every base face l} (no base face holds there)
  and whose interval reaches z_hi + ε; likewise by the bottom (z_τ ≤ z_lo − ε).

:func:`altitude_costs` gives Z_0 and, per prism, the least such bound over the τ and the
faces it may use (inf: it can be kept by its base's faces only within the horizon). These
are what the certified method's branches over "around" and "over" add to the planar bound
(:mod:`dualpilot.system2.certify.planner3`). Lengths m, costs in Eq. (S2)'s units.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from dualpilot.arrays import AnyArray, Array
from dualpilot.model.dynamics import reach_boxes
from dualpilot.model.prism import Prism
from dualpilot.spec import MissionSpec

#: the relative and absolute slack taken off every bound (rounding of the sums)
SLACK = 1e-9


def altitude_costs(spec: MissionSpec, x0: Array, prisms: Sequence[Prism], kappa1: float,
                   horizon: int) -> tuple[float, Array]:
    """(Z_0, per prism the least Z of a trajectory that keeps it by its top or bottom at some
    τ; inf where none can), both lower bounds (module docstring)."""
    band, dyn, eps = spec.band, spec.dynamics, spec.clearance_m
    lo, hi = reach_boxes(np.asarray(x0, dtype=float), horizon, dyn)
    z_lo, z_hi = np.maximum(lo[:, 2], band.floor_m), np.minimum(hi[:, 2], band.ceiling_m)
    g = float(spec.goal_center[2])
    z0 = kappa1 * float(np.sum(_dist2(g, z_lo, z_hi)))
    steps = np.arange(horizon)
    reach = dyn.v_max_mps * dyn.dt_s * np.abs(steps[:, None] - steps[None, :])  # [τ, σ]
    costs = np.full(len(prisms), math.inf)
    for k, prism in enumerate(prisms):
        faces = prism.escape_faces(band, eps)
        n = prism.base.n_faces
        taus = _over_footprint(prism, eps, lo[:, :2], hi[:, :2])
        best = math.inf
        if n in faces:  # the top: z_τ ≥ z_hi + ε
            need = prism.z_hi + eps
            floor = np.maximum(z_lo[None, :], need - reach)
            best = min(best, _least(g, floor, np.broadcast_to(z_hi, floor.shape),
                                    taus & (z_hi >= need)))
        if n + 1 in faces:  # the bottom: z_τ ≤ z_lo − ε
            need = prism.z_lo - eps
            roof = np.minimum(z_hi[None, :], need + reach)
            best = min(best, _least(g, np.broadcast_to(z_lo, roof.shape), roof,
                                    taus & (z_lo <= need)))
        costs[k] = kappa1 * best
    return _safe(z0), np.array([_safe(c) for c in costs])


def _dist2(g: float, lo: Array, hi: Array) -> Array:
    """dist(g, [lo, hi])², elementwise (lo > hi: no altitude, handled by the caller)."""
    return np.asarray(np.maximum(np.maximum(lo - g, g - hi), 0.0) ** 2)


def _least(g: float, lo: Array, hi: Array, allowed: AnyArray) -> float:
    """The least over the allowed rows τ (with every σ's interval non-empty) of
    Σ_σ dist(g, [lo[τ, σ], hi[τ, σ]])²."""
    ok = allowed & np.all(lo <= hi, axis=1)
    if not np.any(ok):
        return math.inf
    return float(np.min(np.sum(_dist2(g, lo[ok], hi[ok]), axis=1)))


def _over_footprint(prism: Prism, eps: float, lo: Array, hi: Array) -> AnyArray:
    """Per τ, whether the planar reach box [lo_τ, hi_τ] meets the bounding box of
    {p : α_l·p ≤ β_l + ε for every base face l} (a superset: where no base face holds)."""
    a, b = prism.base.A, prism.base.b + eps
    n = len(b)
    i, j = np.triu_indices(n, 1)
    det = a[i, 0] * a[j, 1] - a[i, 1] * a[j, 0]
    keep = np.abs(det) > 1e-12
    i, j, det = i[keep], j[keep], det[keep]
    px = (b[i] * a[j, 1] - b[j] * a[i, 1]) / det
    py = (a[i, 0] * b[j] - a[j, 0] * b[i]) / det
    pts = np.column_stack([px, py])
    pts = pts[np.all(pts @ a.T <= b + 1e-6 * (1.0 + np.abs(b)), axis=1)]
    if not len(pts):
        return np.ones(len(lo), dtype=bool)  # no vertex found: every τ (a superset)
    slack = 1e-6 * (1.0 + np.abs(pts).max())
    box_lo, box_hi = pts.min(axis=0) - slack, pts.max(axis=0) + slack
    return np.asarray(np.all((lo <= box_hi) & (hi >= box_lo), axis=1))


def _safe(c: float) -> float:
    """``c`` less its rounding slack (a lower bound stays one)."""
    return c if not math.isfinite(c) else max(0.0, c * (1.0 - SLACK) - SLACK)
