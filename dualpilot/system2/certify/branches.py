"""The branches "around" and "over" of the certified method's 3-D bound (docs/three_d.md, 6).

Let S be the prisms that a feasible 3-D trajectory keeps, at some τ, by their top or bottom
(no base face of Eq. (P2_3) holds there). Its (x, y) part then keeps every other prism by
a base face at every τ: it is feasible for the planar (P2) on those footprints, so it
costs at least that problem's certified bound B(footprints). Its z part costs at least
Z_0 if S is empty, and at least max_{j ∈ S} Z_j otherwise (:mod:`over`'s bounds). So with
the prisms' Z_j sorted into levels c_1 < c_2 < …, and O_c = {i : Z_i > c} (prisms that
cannot be passed over within the horizon have Z = inf and are in every O),

    cost ≥ min( B(every prism) + Z_0,  min_c B(O_c) + c ),

each term one branch: S empty, or c the largest Z_j of S (then S ⊆ {Z ≤ c}, and the
planar problem on O_c is a relaxation of the trajectory's). B is monotone (fewer
footprints, a relaxation), so a branch whose set is not searched takes the largest bound
of a searched subset of it, or 0. :class:`Branches` keeps the searched bounds and says
which set to search next: the one of the least branch.
"""

from __future__ import annotations

import math

import numpy as np

from dualpilot.arrays import Array


class Branches:
    """The branches of one request: Z_0 and the prisms' Z (module docstring)."""

    def __init__(self, z0: float, climb: Array) -> None:
        self.z0 = z0
        n = len(climb)
        levels = sorted({float(c) for c in climb if math.isfinite(c)})
        self.every = frozenset(range(n))
        self.branches: list[tuple[frozenset[int], float]] = [(self.every, z0)]
        self.branches += [(frozenset(i for i in range(n) if climb[i] > c), c) for c in levels]
        #: the smallest set: the prisms that cannot be passed over (in every other set)
        self.kept = self.branches[-1][0]
        self.known: dict[frozenset[int], float] = {}

    def add(self, hulls: frozenset[int], bound: float) -> None:
        """The planar certified bound of the search on ``hulls``' footprints."""
        self.known[hulls] = max(bound, self.known.get(hulls, 0.0))

    def planar(self, hulls: frozenset[int]) -> float:
        """The best bound known on the planar (P2) over ``hulls``: a searched subset's, or 0."""
        return max([b for s, b in self.known.items() if s <= hulls], default=0.0)

    def bound(self) -> float:
        """The least over the branches (a lower bound on the 3-D (P2))."""
        return min(self.planar(s) + c for s, c in self.branches)

    def next_set(self, cost: float, tolerance: float) -> frozenset[int] | None:
        """The set to search next: the smallest first, then every prism, then the least
        branch's while it is not searched and the gap to ``cost`` is open; else None."""
        values = [self.planar(s) + c for s, c in self.branches]
        k = int(np.argmin(values))
        lb = values[k]
        if lb >= cost or (lb > 0.0 and (cost - lb) / lb <= tolerance):
            return None
        for first in (self.kept, self.every):
            if first not in self.known:
                return first
        hulls = self.branches[k][0]
        return None if hulls in self.known else hulls
