"""Branch and bound over the avoidance disjunctions of (P2), with certified node bounds.

A node fixes faces of some disjunctions (τ, i) (:mod:`dualpilot.system2.certify.relaxation`);
its bound comes from the relaxation with the convex hulls ("blocks") of the disjunctions
its own solution violates, added over a few rounds. Branching takes the disjunction
whose block is split most (the largest share of weight off its heaviest face, times how
deep p_τ lies inside Q_i) and makes one child per face whose half-plane meets the reach
box of p_τ (the others hold no trajectory). Children inherit their parent's blocks and
bound, and are solved when popped (best bound first). A node is closed when its bound
reaches the incumbent's cost / (1 + tolerance); the certified bound of the search is the
least bound over the open and closed leaves, so it stays valid whenever the search
stops. A node whose relaxation solution flies (Eq. (1), U, X, the disjunctions: checked
by :func:`dualpilot.system2.problem.verify_p2_plan`) offers a new incumbent.
"""

from __future__ import annotations

import heapq
import itertools
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from dualpilot.arrays import Array
from dualpilot.plan import certified_gap
from dualpilot.system2.certify.relaxation import NodeResult, Pair, Relaxation

#: The hulls convexified together at each τ (one cluster per τ here).
_Blocks = dict[int, tuple[frozenset[int], ...]]


@dataclass(frozen=True)
class CertifyParams:
    """Knobs of the exact method.

    ``tolerance``: stop once the certified gap (cost − bound) / bound is at most this;
    ``time_budget_s`` (wall clock) and ``max_nodes`` stop the search earlier, the bound
    still valid; ``block_rounds`` relaxations a node may solve while adding blocks;
    ``neighbours``: a violated (τ, i) also blocks (τ ± k, i) for k ≤ this;
    ``plain_root_s``: the root is first solved without the reach sets for at most this
    long; most requests end there.
    """

    tolerance: float = 0.01
    time_budget_s: float = 1.0
    max_nodes: int = 10_000
    block_rounds: int = 3
    neighbours: int = 1
    plain_root_s: float = 0.1

    def __post_init__(self) -> None:
        if not (self.tolerance >= 0 and self.time_budget_s > 0 and self.max_nodes >= 1
                and self.block_rounds >= 1 and self.neighbours >= 0 and self.plain_root_s > 0):
            raise ValueError(f"invalid CertifyParams: {self}")


@dataclass
class _Node:
    bound: float
    fixed: dict[Pair, int]
    blocks: _Blocks
    depth: int = 0
    result: NodeResult | None = None


@dataclass
class Outcome:
    """What a search proved: the bound (m² N² units of Eq. (S2)), the incumbent's cost and
    controls (None if it did not change), and the work done."""

    bound: float
    cost: float
    controls: Array | None
    nodes: int = 0
    relaxations: int = 0
    root_bound: float = -math.inf
    time_s: float = 0.0
    stop: str = ""
    trace: list[tuple[float, float, float]] = field(default_factory=list)
    root_blocks: set[Pair] = field(default_factory=set)

    @property
    def gap(self) -> float:
        return certified_gap(self.cost, self.bound)


#: A relaxation's solution made into a plan: its cost and controls if (P2) holds, else None.
Candidate = Callable[[NodeResult], "tuple[float, Array] | None"]


class BranchAndBound:
    """One search; :meth:`run` returns its :class:`Outcome`.

    ``rel`` is the instance's relaxation, ``cost`` the incumbent's Eq. (S2) cost (inf
    without one) and ``candidate`` the check of a relaxation solution as a plan.
    """

    def __init__(self, rel: Relaxation, params: CertifyParams, cost: float,
                 candidate: Candidate, initial_blocks: set[Pair] | None = None) -> None:
        self.rel, self.p, self.candidate = rel, params, candidate
        self.cost = float(cost)
        self.controls: Array | None = None
        self.initial = _merged({}, {b for b in (initial_blocks or set()) if rel.pair_needed(b)})
        self.closed_min = math.inf  # least bound of the closed leaves
        self.heap: list[tuple[float, int, _Node]] = []
        self.count = itertools.count()
        self.out = Outcome(-math.inf, self.cost, None)

    # ------------------------------------------------------------------ search
    def run(self) -> Outcome:
        t0 = time.perf_counter()
        self.t0 = t0
        root = _Node(-math.inf, {}, self.initial)
        self._push(root)
        first = True
        while self.heap:
            if self._done():
                break
            if time.perf_counter() - t0 > self.p.time_budget_s:
                self.out.stop = "time budget"
                break
            if self.out.nodes >= self.p.max_nodes:
                self.out.stop = "node limit"
                break
            _, _, node = heapq.heappop(self.heap)
            if node.bound * (1.0 + self.p.tolerance) >= self.cost:
                self._close(node.bound)
                continue
            self._evaluate(node)
            if first:
                self.out.root_bound = node.bound
                self.out.root_blocks = {(tau, i) for tau, clusters in node.blocks.items()
                                        for c in clusters for i in c}
                first = False
            self._record(node.bound)  # the node is out of the heap until closed or branched
            if node.bound * (1.0 + self.p.tolerance) >= self.cost:
                self._close(node.bound)
                continue
            self._branch(node)
        else:
            self.out.stop = "search complete"
        self.out.bound = self._bound()
        self.out.cost = self.cost
        self.out.time_s = time.perf_counter() - t0
        self._record()
        return self.out

    def _done(self) -> bool:
        if certified_gap(self.cost, self._bound()) <= self.p.tolerance:
            self.out.stop = "tolerance"
            return True
        return False

    def _bound(self) -> float:
        open_min = self.heap[0][0] if self.heap else math.inf
        return min(open_min, self.closed_min, self.cost)

    def _record(self, current: float = math.inf) -> None:
        """(time, bound, cost) now; ``current`` is the bound of a node being worked on."""
        bound = min(self._bound(), current)
        self.out.trace.append((time.perf_counter() - self.t0, bound, self.cost))

    def _push(self, node: _Node) -> None:
        heapq.heappush(self.heap, (node.bound, next(self.count), node))

    def _close(self, bound: float) -> None:
        self.closed_min = min(self.closed_min, bound)

    # ------------------------------------------------------------------ nodes
    def _evaluate(self, node: _Node) -> None:
        """Solve the node's relaxation, convexifying what its solution violates."""
        self.out.nodes += 1
        blocks = dict(node.blocks)
        best: NodeResult | None = None
        for _ in range(self.p.block_rounds):
            left = self.p.time_budget_s - (time.perf_counter() - self.t0)
            if left <= 0.0:
                break
            res = self.rel.solve(node.fixed, blocks, left)
            self.out.relaxations += 1
            if res.bound > node.bound:
                node.bound = res.bound
                self._record(node.bound)
            if res.z is None:
                break
            best = res
            if node.bound * (1.0 + self.p.tolerance) >= self.cost:
                break
            self._offer(res)
            if node.bound * (1.0 + self.p.tolerance) >= self.cost:
                break
            new = {p for p in self._violated(res.z, node.fixed)
                   if p[1] not in _hulls_at(blocks, p[0])}
            if not new:
                break
            blocks = _merged(blocks, self._with_neighbours(new, node.fixed))
        node.blocks = blocks
        node.result = best

    def _violated(self, z: Array, fixed: dict[Pair, int]) -> set[Pair]:
        """Disjunctions (τ, i) that the scaled positions z violate (not fixed)."""
        out: set[Pair] = set()
        pos = z.reshape(-1, 2) * self.rel.maps.scale  # p_2..p_{T+1}
        T, eps = self.rel.maps.horizon, self.rel.eps
        for i, h in enumerate(self.rel.hulls):
            margin = np.max(pos[:T - 1] @ h.A.T - h.b, axis=1) - eps
            for k in np.flatnonzero(margin < -1e-6):
                pair = (int(k) + 2, i)
                if pair not in fixed and self.rel.pair_needed(pair):
                    out.add(pair)
        return out

    def _with_neighbours(self, pairs: set[Pair], fixed: dict[Pair, int]) -> set[Pair]:
        out = set(pairs)
        for tau, i in pairs:
            for d in range(1, self.p.neighbours + 1):
                for nb in ((tau - d, i), (tau + d, i)):
                    if nb not in fixed and self.rel.pair_needed(nb):
                        out.add(nb)
        return out

    def _offer(self, res: NodeResult) -> None:
        """A relaxation solution, as it is or repaired: try it as the incumbent."""
        self.consider(self.candidate(res))

    def consider(self, got: tuple[float, Array] | None) -> None:
        """A verified plan (Eq. (S2) cost, controls), or None: the incumbent if cheaper."""
        if got is not None and got[0] < self.cost:
            self.cost, self.controls = got
            self.out.controls = got[1]

    # --------------------------------------------------------------- branching
    def _branch(self, node: _Node) -> None:
        res = node.result
        if res is None or res.z is None:
            self._close(node.bound)  # nothing to branch on: closed at the bound it has
            return
        pair = self._choose(node, res)
        if pair is None:
            self._close(node.bound)
            return
        for face in self.rel.faces[pair]:
            fixed = dict(node.fixed)
            fixed[pair] = int(face)
            self._push(_Node(node.bound, fixed, node.blocks, node.depth + 1))

    def _choose(self, node: _Node, res: NodeResult) -> Pair | None:
        """The violated disjunction whose block is split most, weighted by depth."""
        assert res.z is not None
        pos = res.z.reshape(-1, 2) * self.rel.maps.scale
        split_at: dict[Pair, float] = {}
        for (tau, part), w in res.weights.items():
            share = 1.0 - float(np.max(w)) if len(w) else 1.0
            for i in part:
                split_at[(tau, i)] = share
        best, best_score = None, 0.0
        for pair in self._violated(res.z, node.fixed):
            tau, i = pair
            h = self.rel.hulls[i]
            depth = -(float(np.max(h.A @ pos[tau - 2] - h.b)) - self.rel.eps)
            score = depth * (0.05 + split_at.get(pair, 1.0))
            if score > best_score:
                best, best_score = pair, score
        return best


def _hulls_at(blocks: _Blocks, tau: int) -> frozenset[int]:
    out: frozenset[int] = frozenset()
    for cluster in blocks.get(tau, ()):
        out |= cluster
    return out


def _merged(blocks: _Blocks, pairs: set[Pair]) -> _Blocks:
    """``blocks`` with the hulls of ``pairs`` joined to the cluster at their τ."""
    out = dict(blocks)
    for tau in {t for t, _ in pairs}:
        add = frozenset(i for t, i in pairs if t == tau)
        out[tau] = (_hulls_at(out, tau) | add,)
    return out
