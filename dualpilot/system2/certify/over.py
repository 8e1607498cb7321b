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
  and whose interval reaches z_hi + ε; likewise by the bottom (z_τ ≤ z_lo − ε);
* with U, X and the band dropped instead, the z part under Eq. (1) is a quadratic in u_z,
  whose least is J* and whose least with z_τ ≥ h is J* + δ² / (2 m_τᵀ H⁻¹ m_τ) in closed
  form (:class:`_Free`): per τ the larger of the two bounds holds (the κ2 terms count
  here: they dominate under the energy objective).

:func:`altitude_costs` gives Z_0 and, per prism and τ, the least such bound over the
faces it may use (inf: it can be kept by its base's faces only at that τ). These
are what the certified method's branches over "around" and "over" add to the planar bound
(:mod:`dualpilot.system2.certify.planner3`). Lengths m, costs in Eq. (S2)'s units.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import scipy.linalg

from dualpilot.arrays import AnyArray, Array
from dualpilot.model.dynamics import reach_boxes, rollout
from dualpilot.model.prism import Prism
from dualpilot.spec import MissionSpec

#: the relative and absolute slack taken off every bound (the rounding of the sums and of
#: the Cholesky solves of :class:`_Free`, far below it at the Hessians' conditioning)
SLACK = 1e-6


def altitude_costs(spec: MissionSpec, x0: Array, u_prev_z: float, prisms: Sequence[Prism],
                   kappa: tuple[float, float], horizon: int) -> tuple[float, Array]:
    """(Z_0, per prism and τ = 1..T (an (n, T) array) the least z part of a trajectory that
    keeps the prism by its top or bottom at τ; inf where none can), lower bounds (module
    docstring)."""
    band, dyn, eps = spec.band, spec.dynamics, spec.clearance_m
    x0 = np.asarray(x0, dtype=float)
    lo, hi = reach_boxes(x0, horizon, dyn)
    z_lo, z_hi = np.maximum(lo[:, 2], band.floor_m), np.minimum(hi[:, 2], band.ceiling_m)
    g, k1 = float(spec.goal_center[2]), kappa[0]
    free = _Free(spec, x0, u_prev_z, kappa, horizon)
    z0 = max(k1 * float(np.sum(_dist2(g, z_lo, z_hi))), free.least)
    steps = np.arange(horizon)
    reach = dyn.v_max_mps * dyn.dt_s * np.abs(steps[:, None] - steps[None, :])  # [τ, σ]
    costs = np.full((len(prisms), horizon), math.inf)
    for k, prism in enumerate(prisms):
        faces = prism.escape_faces(band, eps)
        n = prism.base.n_faces
        taus = _over_footprint(prism, eps, lo[:, :2], hi[:, :2])
        if n in faces:  # the top: z_τ ≥ z_hi + ε
            need = prism.z_hi + eps
            floor = np.maximum(z_lo[None, :], need - reach)
            per = np.maximum(k1 * _per_tau(g, floor, np.broadcast_to(z_hi, floor.shape)),
                             free.above(need))
            costs[k] = np.minimum(costs[k], np.where(taus, per, math.inf))
        if n + 1 in faces:  # the bottom: z_τ ≤ z_lo − ε
            need = prism.z_lo - eps
            roof = np.minimum(z_hi[None, :], need + reach)
            per = np.maximum(k1 * _per_tau(g, np.broadcast_to(z_lo, roof.shape), roof),
                             free.below(need))
            costs[k] = np.minimum(costs[k], np.where(taus, per, math.inf))
    return _safe(z0), _safe_all(costs)


class _Free:
    """The z part of Eq. (S2) under Eq. (1) alone (U, X and the band dropped: a
    relaxation), κ1 ‖a + M u − g‖² + κ2 ‖D u − d‖² over u_z (d = (u_{t|t,z}, 0, …)): its
    least J* and, per τ, its least with z_τ ≥ h (or ≤ h), J* + δ² / (2 m_τᵀ H⁻¹ m_τ), δ how
    far z*_τ is short of h, H the Hessian (a quadratic under one linear constraint)."""

    def __init__(self, spec: MissionSpec, x0: Array, u_prev_z: float,
                 kappa: tuple[float, float], horizon: int) -> None:
        dyn, T = spec.dynamics, horizon
        k1, k2 = kappa
        a = rollout(x0, np.zeros((T, 3)), dyn)[1:, 2]
        unit = np.zeros((T, 3))
        unit[0, 2] = 1.0
        col = rollout(np.zeros(6), unit, dyn)[1:, 2]  # z_k's response to u_1
        m = np.zeros((T, T))
        for j in range(T):  # u_j's is u_1's j steps later (Eq. (1) is time-invariant)
            m[j:, j] = col[:T - j]
        d = np.eye(T) - np.eye(T, k=-1)
        dv = np.zeros(T)
        dv[0] = u_prev_z
        g = float(spec.goal_center[2])
        if k2 <= 0.0:  # H singular (u_T moves no position): the bound of X alone
            self.z, self.least, self.s = np.full(T, g), 0.0, np.full(T, math.inf)
            return
        factor = scipy.linalg.cho_factor(2.0 * (k1 * m.T @ m + k2 * d.T @ d))
        u = scipy.linalg.cho_solve(factor, -2.0 * (k1 * m.T @ (a - g) - k2 * d.T @ dv))
        self.z = a + m @ u
        self.least = float(k1 * np.sum((self.z - g) ** 2) + k2 * np.sum((d @ u - dv) ** 2))
        self.s = np.einsum("ij,ji->i", m, scipy.linalg.cho_solve(factor, m.T))

    def above(self, h: float) -> Array:
        """Per τ, the least with z_τ ≥ h (inf where z_τ does not depend on u and is short)."""
        return self._with(np.maximum(h - self.z, 0.0))

    def below(self, h: float) -> Array:
        """Per τ, the least with z_τ ≤ h."""
        return self._with(np.maximum(self.z - h, 0.0))

    def _with(self, short: Array) -> Array:
        out = np.full(len(short), math.inf)
        ok = self.s > 0.0
        out[ok] = self.least + short[ok] ** 2 / (2.0 * self.s[ok])
        out[~ok & (short <= 0.0)] = self.least
        return out


def _per_tau(g: float, lo: Array, hi: Array) -> Array:
    """Per row τ, Σ_σ dist(g, [lo[τ, σ], hi[τ, σ]])² (inf where an interval is empty)."""
    out = np.sum(_dist2(g, lo, hi), axis=1)
    out[~np.all(lo <= hi, axis=1)] = math.inf
    return np.asarray(out)


def _dist2(g: float, lo: Array, hi: Array) -> Array:
    """dist(g, [lo, hi])², elementwise (lo > hi: no altitude, handled by the caller)."""
    return np.asarray(np.maximum(np.maximum(lo - g, g - hi), 0.0) ** 2)


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


def _safe_all(c: Array) -> Array:
    """:func:`_safe` elementwise."""
    out = np.maximum(c * (1.0 - SLACK) - SLACK, 0.0)
    return np.asarray(np.where(np.isfinite(c), out, c))
