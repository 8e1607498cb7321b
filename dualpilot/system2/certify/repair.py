"""A relaxation's trajectory made to fly: convex restrictions around its points.

The branch and bound's relaxations often pass where the fast method's homotopies do not
(between two hulls whose ε-inflations overlap only between two planned positions, since
(P2) constrains the positions, not the segments). :func:`repair` takes such a trajectory
as the reference of the fast method's convex-feasible-set iteration: each position p_τ
within ``near_m`` of an inflated hull Q_i keeps to the supporting half-plane of Q_i at
its projection (the face it is least inside of, when inside), the QP of
:class:`dualpilot.system2.fast.qp.P2Qp` is solved, and the supports are taken again at
the solution until it violates nothing and its cost stalls. Lengths in m.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from dualpilot.arrays import Array
from dualpilot.system2.fast.geometry import FaceStack, HullStack, Inflated
from dualpilot.system2.fast.qp import P2Qp


@dataclass(frozen=True)
class Repaired:
    """A trajectory that keeps every (P2_3)-(P2_4): positions p_1..p_{T+1}, controls, cost."""

    positions: Array
    controls: Array
    cost: float


def repair(qp: P2Qp, x0: Array, u_prev: Array, goal: Array, kappa: tuple[float, float],
           polys: Sequence[Inflated], reference: Array, *, near_m: float = 60.0,
           margin_m: float = 0.01, iterations: int = 4, area: float | None = None,
           rounding: Mapping[int, Array] | None = None) -> Repaired | None:
    """The best violation-free QP solution met from ``reference`` (p_1..p_{T+1}), or None.

    ``rounding`` gives, for some τ, half-planes (a_x, a_y, c) that p_τ keeps in the
    first QP instead of the supports (the relaxation's heaviest convex piece at τ).
    """
    if not polys:
        return None
    T = len(reference) - 1
    faces, stack = FaceStack.of(list(polys)), HullStack.of(list(polys))
    ref = np.asarray(reference, dtype=float)
    best: Repaired | None = None
    first = dict(rounding or {})
    for _ in range(iterations):
        pts = ref[1:T]  # p_2..p_T
        near = faces.margins(pts) < near_m  # (T-1, H)
        near[[t - 2 for t in first if 2 <= t <= T], :] = False
        tt, hid = np.nonzero(near)
        if not len(tt) and not first:
            return best
        nrm, off, _ = stack.support(hid, pts[tt])
        tau, rhs = tt + 2, off + margin_m
        if first:
            taus = np.array(sorted(first))
            extra = [first[t] for t in taus]
            tau = np.r_[tau, np.repeat(taus, [len(e) for e in extra])]
            rows = np.vstack(extra)
            nrm, rhs = np.vstack([nrm, rows[:, :2]]), np.r_[rhs, rows[:, 2] + margin_m]
            first = {}
        res = qp.solve(x0, u_prev, goal, kappa, tau, nrm, rhs, z0=ref[1:], confirm=False)
        if not res.ok:
            return best
        pos = res.positions
        inside = faces.margins(pos[1:T]) < 0.0
        in_area = area is None or bool(np.all((pos[1:T] >= -1e-6) & (pos[1:T] <= area + 1e-6)))
        if not np.any(inside) and in_area:
            if best is not None and res.objective >= best.cost * (1.0 - 1e-6):
                return best
            best = Repaired(pos, res.controls, float(res.objective))
        ref = pos
    return best
