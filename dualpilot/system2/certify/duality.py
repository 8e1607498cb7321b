"""A lower bound on a convex conic program that holds whatever the solver's accuracy.

For  min ½xᵀPx + qᵀx + c  s.t.  Ax + s = b, s ∈ K  (P ⪰ 0, K a product of zero,
non-negative and second-order cones) and any y in the dual cone K*, weak duality gives
L(x, y) = ½xᵀPx + qᵀx + c + yᵀ(Ax − b) ≤ the objective at every feasible x (yᵀs ≥ 0).
L is convex in x, so L(x, y) ≥ L(x̄, y) + rᵀ(x − x̄) with r = Px̄ + q + Aᵀy at any x̄;
over a box lo ≤ x ≤ hi that holds at every point that matters (here: the point of the
(P2) optimum) the minimum of the right-hand side is in closed form. So a solver's
approximate primal x̄ and dual y, after y is projected onto K*, give a bound that is
exact up to floating point, for which a relative margin is taken off
(:data:`ROUNDING_MARGIN`). The same construction with the objective dropped proves a
problem infeasible in the box (a Farkas certificate).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from dualpilot.arrays import Array

#: Relative margin taken off every bound for the rounding of its own evaluation.
ROUNDING_MARGIN = 1e-9


@dataclass(frozen=True)
class Cones:
    """The cone of the rows: ``zero`` equalities, then ``nonneg`` rows, then ``soc``
    second-order cones of the given sizes (each (t, y) with ‖y‖ ≤ t)."""

    zero: int
    nonneg: int
    soc: tuple[int, ...]

    @property
    def rows(self) -> int:
        return self.zero + self.nonneg + sum(self.soc)


def project_dual(y: Array, cones: Cones) -> Array:
    """``y`` projected onto K* (zero cone: free; non-negative: clipped; SOC: self-dual)."""
    out = np.array(y, dtype=float)
    k = cones.zero
    out[k:k + cones.nonneg] = np.maximum(out[k:k + cones.nonneg], 0.0)
    k += cones.nonneg
    for size in cones.soc:
        t, v = out[k], out[k + 1:k + size]
        nv = float(np.linalg.norm(v))
        if nv > t:
            if nv <= -t:
                out[k:k + size] = 0.0
            else:
                a = 0.5 * (t + nv)
                out[k] = a
                out[k + 1:k + size] = a * v / nv
        k += size
    return out


def box_minimum(r: Array, base: Array, lo: Array, hi: Array) -> tuple[float, float]:
    """min over lo ≤ x ≤ hi of rᵀ(x − base), and the sum of the terms' magnitudes."""
    a, b = r * (lo - base), r * (hi - base)
    terms = np.minimum(a, b)
    return float(np.sum(terms)), float(np.sum(np.abs(terms)))


def lagrangian_bound(P: sp.spmatrix, q: Array, c: float, A: sp.spmatrix, b: Array,
                     cones: Cones, x: Array, y: Array, lo: Array, hi: Array) -> float:
    """A lower bound on the program's optimum over the box (see the module docstring).

    ``P`` is the full symmetric matrix; ``x``, ``y`` any primal and dual vectors.
    Returns −inf when the numbers are not finite.
    """
    y = project_dual(y, cones)
    px = P @ x
    ax = A @ x
    r = px + q + A.T @ y
    lin, lin_abs = box_minimum(r, x, lo, hi)
    parts = np.array([0.5 * float(x @ px), float(q @ x), c, float(y @ ax), -float(y @ b)])
    value = float(np.sum(parts)) + lin
    scale = float(np.sum(np.abs(parts))) + lin_abs
    bound = value - ROUNDING_MARGIN * scale
    return bound if math.isfinite(bound) else -math.inf


def proves_infeasible(A: sp.spmatrix, b: Array, cones: Cones, y: Array, lo: Array,
                      hi: Array) -> bool:
    """True if ``y`` (projected onto K*) shows that no x in the box satisfies the rows.

    Every feasible x has yᵀ(Ax − b) = −yᵀs ≤ 0; if the least value of yᵀ(Ax − b) over
    the box is positive (beyond the rounding margin) there is none.
    """
    y = project_dual(y, cones)
    aty = A.T @ y
    zero = np.zeros_like(lo)
    lin, lin_abs = box_minimum(aty, zero, lo, hi)
    by = float(y @ b)
    value = lin - by
    return bool(math.isfinite(value)
                and value > ROUNDING_MARGIN * (lin_abs + abs(by)) + 1e-12)
