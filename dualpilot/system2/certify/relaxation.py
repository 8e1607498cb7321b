"""The convex relaxation of (P2) at one node of the branch and bound, with its certified bound.

A node fixes, for some planned positions p_τ and hulls i, the face l that p_τ stays
outside of (α_l·p_τ ≥ β_l + ε, Eq. (P2_3) with b_{τ,i,l} = 0). Every other avoidance
disjunction (P2_3)-(P2_4) is either dropped or, for the clusters of hulls a node
"blocks" at τ, replaced by the *convex hull of the disjunction together with the cost*.
With the convex pieces P_k that cover what the cluster leaves free in the reach box B_τ
(:func:`dualpilot.system2.certify.pieces.cover`, the faces fixed at τ included),

    p_τ = Σ_k Z_k,  Σ_k λ_k = 1,  λ ≥ 0,  Z_k ∈ λ_k P_k,  Z_k ∈ λ_k B_τ,
    t_τ ≥ Σ_k w_k,  w_k λ_k ≥ ‖Z_k − λ_k G_o‖²  (a rotated second-order cone),

and κ1 t_τ takes the place of κ1 ‖p_τ − G_o‖² in Eq. (S2). This is the perspective
formulation of a disjunction (Ceria and Soares 1999), the one Graphs of Convex Sets
(Marcucci et al. 2023) is built on: a trajectory with p_τ in P_k has λ_k = 1, Z_k = p_τ,
t_τ = its own cost, so the relaxation contains (P2); a point inside a hull, or in a gap
between two hulls narrower than 2ε, can only be paid for by splitting it into points
of the pieces, each at its own cost, which the plain relaxation (the disjunction
dropped) does not see. Hulls are convexified together (one cluster) when a point
violates them together, so such gaps close. The program is solved by Clarabel; its
bound comes from :mod:`dualpilot.system2.certify.duality`, so it holds whatever
Clarabel's accuracy. Positions are in units of ``scale`` m and the objective is
divided by κ1 s².
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import clarabel
import numpy as np
import scipy.sparse as sp

from dualpilot.arrays import AnyArray, Array
from dualpilot.model.dynamics import reach_boxes
from dualpilot.system2.certify.duality import Cones, lagrangian_bound, proves_infeasible
from dualpilot.system2.certify.model import Instance, Maps, Offsets, offsets
from dualpilot.system2.certify.pieces import cover
from dualpilot.system2.certify.reach import ReachSets, reach_sets

Pair = tuple[int, int]
"""(τ, hull index) of one avoidance disjunction, τ = 2..T."""

Blocks = Mapping[int, tuple[frozenset[int], ...]]
"""The clusters of hulls convexified at each τ (hulls fixed at τ are left out)."""

#: Most pieces one cluster may have; a larger cluster is convexified hull by hull.
MAX_PIECES = 48


@dataclass(frozen=True)
class NodeResult:
    """One relaxation: its certified bound on (P2) at the node (true units; inf when the
    node holds no feasible point), Clarabel's status, the scaled positions z and, per
    (τ, cluster), the pieces' weights λ (z None when the solve gave no usable point)."""

    bound: float
    status: str
    z: Array | None
    weights: Mapping[tuple[int, frozenset[int]], Array] = field(default_factory=dict)
    pieces: Mapping[tuple[int, frozenset[int]], tuple[Array, ...]] = field(default_factory=dict)

    def rounding(self) -> dict[int, Array]:
        """Per τ, the half-planes (a_x, a_y, c) of each block's heaviest piece (m)."""
        out: dict[int, list[Array]] = {}
        for key, w in self.weights.items():
            if len(w):
                out.setdefault(key[0], []).append(self.pieces[key][int(np.argmax(w))])
        return {tau: np.vstack(rows) for tau, rows in out.items()}


@dataclass
class _Rows:
    """Rows A x (≤, = or in a cone) b in triplet form, appended section by section."""

    rows: list[AnyArray] = field(default_factory=list)
    cols: list[AnyArray] = field(default_factory=list)
    vals: list[AnyArray] = field(default_factory=list)
    rhs: list[AnyArray] = field(default_factory=list)
    count: int = 0

    def add(self, r: AnyArray, c: AnyArray, v: AnyArray, b: AnyArray) -> None:
        """Append rows whose local indices ``r`` start at 0."""
        self.rows.append(np.asarray(r, dtype=np.int64) + self.count)
        self.cols.append(np.asarray(c, dtype=np.int64))
        self.vals.append(np.asarray(v, dtype=float))
        self.rhs.append(np.asarray(b, dtype=float))
        self.count += len(b)

    def add_matrix(self, m: sp.spmatrix, b: AnyArray) -> None:
        coo = sp.coo_matrix(m)
        self.add(coo.row, coo.col, coo.data, b)

    def stacked(self, offset: int) -> tuple[AnyArray, AnyArray, AnyArray, AnyArray]:
        if not self.rows:
            z = np.zeros(0)
            return z.astype(np.int64), z.astype(np.int64), z, z
        return (np.concatenate(self.rows) + offset, np.concatenate(self.cols),
                np.concatenate(self.vals), np.concatenate(self.rhs))


class Relaxation:
    """The relaxations of one (P2) instance: the state, u_{t|t}, κ, the hulls, ε and area.

    Parameters
    ----------
    maps : Maps
        Eq. (1) in the positions (:func:`dualpilot.system2.certify.model.maps`).
    instance : Instance
        x_t, u_{t|t}, G_o, κ, the hulls, ε and the area
        (:class:`dualpilot.system2.certify.model.Instance`).
    reach : bool
        Also bound each position by the reach sets of the hulls
        (:mod:`dualpilot.system2.certify.reach`): its box, its floor ‖p_τ − G_o‖ ≥ d_τ and
        the prefix costs Σ_{σ=2..τ} ‖p_σ − G_o‖² ≥ F_τ, each summand an epigraph t_σ.
    """

    def __init__(self, maps: Maps, instance: Instance, reach: bool = True) -> None:
        kappa, area_size_m = instance.kappa, instance.area_size_m
        self.maps, self.kappa, self.hulls = maps, kappa, tuple(instance.hulls)
        self.eps, self.area = float(instance.epsilon_m), area_size_m
        self.x0 = np.asarray(instance.x0, dtype=float)
        self.u_prev = np.asarray(instance.u_prev, dtype=float)
        self.off: Offsets = offsets(maps, self.x0, instance.u_prev)
        T, s = maps.horizon, maps.scale
        self.g = np.asarray(instance.goal, dtype=float)[:2] / s
        self.c = float(kappa[0]) * s * s  # the objective's scale
        lo, hi = reach_boxes(self.x0, T + 1, maps.dynamics)  # p_1..p_{T+1}
        if area_size_m is not None:
            lo[:T], hi[:T] = np.maximum(lo[:T], 0.0), np.minimum(hi[:T], area_size_m)
        self.infeasible = bool(np.any(lo > hi + 1e-9))  # p_{t+1|t} (fixed) outside the area
        self.floor = np.zeros(T + 1)  # per p_1..p_{T+1}: least ‖p_τ/s − g‖² (units s)
        self.prefix = np.zeros(T + 1)  # per p_1..p_{T+1}: least Σ_{σ=2..τ} of those
        self.suffix = np.zeros(T + 1)  # per p_1..p_{T+1}: least Σ_{σ=τ..T} of those
        self.reach: ReachSets | None = None
        if reach and not self.infeasible:
            sets = reach_sets(self.off.p1, lo[:T], hi[:T], self.hulls, self.eps,
                              self.g * s, maps.dynamics.dt_s * maps.dynamics.v_max_mps)
            self.infeasible, self.reach = sets.empty, sets
            if not sets.empty:
                lo[:T], hi[:T] = sets.lo, sets.hi
                self.floor[:T] = (sets.floor_m / s) ** 2
                self.prefix[:T] = sets.prefix_m2 / (s * s)
                self.suffix[1:T] = sets.suffix_m2[1:] / (s * s)
        self.box_lo, self.box_hi = lo, hi  # (T+1, 2), m; row k is p_{k+1}
        self.faces: dict[Pair, AnyArray] = {}  # reachable faces of each disjunction
        self.always: set[Pair] = set()  # disjunctions that hold in the whole reach box
        self._classify()
        self._base = self._base_rows()
        self._dtd = (maps.D.T @ maps.D).tocsr()
        self._covers: dict[tuple[bytes, bytes, tuple[tuple[int, int], ...], tuple[int, ...],
                                 int], list[Array] | None] = {}
        self._templates: dict[tuple[int, frozenset[int], tuple[tuple[int, int], ...]],
                              list[tuple[frozenset[int], _Template]]] = {}

    # ------------------------------------------------------------------ setup
    def _classify(self) -> None:
        """Which faces of each (τ, i) the reach box B_τ meets; τ = 1 is fixed by the state."""
        T, eps = self.maps.horizon, self.eps
        lo, hi = self.box_lo, self.box_hi
        for i, h in enumerate(self.hulls):
            rhs = h.b + eps
            if float(np.max(h.A @ self.off.p1 - h.b)) < eps - 1e-9:
                self.infeasible = True  # p_{t+1|t} is fixed and violates (P2_3)
            for tau in range(2, T + 1):
                k = tau - 1
                lo_dot = np.minimum(h.A * lo[k], h.A * hi[k]).sum(axis=1)
                hi_dot = np.maximum(h.A * lo[k], h.A * hi[k]).sum(axis=1)
                if np.any(lo_dot >= rhs):
                    self.always.add((tau, i))
                    continue
                reach = np.flatnonzero(hi_dot >= rhs - 1e-9)  # touching counts
                if not len(reach):
                    self.infeasible = True  # no face can hold: every trajectory violates
                self.faces[(tau, i)] = reach

    def _base_rows(self) -> _Rows:
        """U, X and the area as rows A z ≤ b (the area only where the reach box meets it)."""
        mp, off = self.maps, self.off
        dyn, T, s = mp.dynamics, mp.horizon, mp.scale
        rows = _Rows()
        rows.add_matrix(mp.U, dyn.u_max_n - off.u)
        rows.add_matrix(-mp.U, dyn.u_max_n + off.u)
        rows.add_matrix(mp.speed, mp.speed_max - mp.speed_v @ off.v)
        # p_2..p_T in the boxes of their reach sets (inside the area: they are clipped to it)
        j = np.arange(2 * (T - 1))
        rows.add(j, j, np.full(len(j), -s), -self.box_lo[1:T].ravel())
        rows.add(j, j, np.full(len(j), s), self.box_hi[1:T].ravel())
        return rows

    def pair_needed(self, pair: Pair) -> bool:
        """True if the disjunction of ``pair`` can fail inside the reach box."""
        return pair in self.faces

    # ------------------------------------------------------------------ solve
    def solve(self, fixed: Mapping[Pair, int], blocks: Blocks,
              time_limit_s: float = math.inf) -> NodeResult:
        """The relaxation with the faces ``fixed`` and the clusters ``blocks`` convexified.

        Clarabel stops after ``time_limit_s``; the bound of its last iterate still holds.
        Clusters whose pieces are not yet made when the time is up are left out (any
        subset of the blocks is a relaxation too); a later call makes them.
        """
        if self.infeasible:
            return NodeResult(math.inf, "infeasible (reach)", None)
        deadline = time.perf_counter() + time_limit_s
        groups: list[tuple[int, frozenset[int], _Template]] = []
        for tau, clusters in sorted(blocks.items()):
            fixed_here = tuple(sorted((i, f) for (t, i), f in fixed.items() if t == tau))
            done = {i for i, _ in fixed_here}
            for cluster in clusters:
                hulls = frozenset(i for i in cluster if (tau, i) in self.faces) - done
                if not hulls:
                    continue
                if (tau, hulls, fixed_here) not in self._templates \
                        and time.perf_counter() > deadline:
                    continue
                for part, tpl in self.templates(tau, hulls, fixed_here):
                    if tpl.n_pieces == 0:
                        return NodeResult(math.inf, "infeasible (pieces)", None)
                    groups.append((tau, part, tpl))
        return _Program(self, fixed, groups).solve(max(deadline - time.perf_counter(), 1e-3))

    def templates(self, tau: int, hulls: frozenset[int], fixed_here: tuple[tuple[int, int], ...]
                  ) -> list[tuple[frozenset[int], _Template]]:
        """The blocks of a cluster at τ: one, or one per hull past :data:`MAX_PIECES`."""
        key = (tau, hulls, fixed_here)
        hit = self._templates.get(key)
        if hit is not None:
            return hit
        s = self.maps.scale
        fixed_hp = np.array([[*self.hulls[i].A[f], self.hulls[i].b[f] + self.eps]
                             for i, f in fixed_here]).reshape(-1, 3)
        lo, hi = self.box_lo[tau - 1], self.box_hi[tau - 1]
        order = sorted(hulls)
        found = self._cover(lo, hi, fixed_here, fixed_hp, tuple(order), MAX_PIECES)
        if found is not None:
            out = [(hulls, _Template.make(found, lo / s, hi / s, self.g, s, self.t_max(tau)))]
        else:
            out = []
            for i in order:
                one = self._cover(lo, hi, fixed_here, fixed_hp, (i,), 10**6) or []
                out.append((frozenset([i]),
                            _Template.make(one, lo / s, hi / s, self.g, s, self.t_max(tau))))
        self._templates[key] = out
        return out

    def _cover(self, lo: Array, hi: Array, fixed_here: tuple[tuple[int, int], ...],
               fixed_hp: Array, hulls: tuple[int, ...], max_pieces: int
               ) -> list[Array] | None:
        """:func:`cover` of the box, once per (box, fixed faces, hulls): positions whose
        reach sets have filled the area share their boxes, and so their pieces."""
        key = (lo.tobytes(), hi.tobytes(), fixed_here, hulls, max_pieces)
        if key not in self._covers:
            self._covers[key] = cover(lo, hi, fixed_hp, [self.hulls[i] for i in hulls],
                                      self.eps, max_pieces)
        return self._covers[key]

    def t_max(self, tau: int) -> float:
        """The largest ‖p_τ/s − g‖² over the reach box of p_τ."""
        s = self.maps.scale
        lo, hi = self.box_lo[tau - 1] / s, self.box_hi[tau - 1] / s
        far = np.maximum(np.abs(lo - self.g), np.abs(hi - self.g))
        return float(far @ far)


@dataclass(frozen=True)
class _Template:
    """One block's rows, its own variables numbered from 0 (Z_x, Z_y, λ, w per piece); the
    position it splits has columns −2, −1 and its t_τ column −3, placed by the program.

    ``lo``, ``hi`` bound the variables at the (P2) optimum (for the certified bound).
    """

    zero: _Rows
    nonneg: _Rows
    soc: _Rows
    n_pieces: int
    lo: Array
    hi: Array
    pieces: tuple[Array, ...] = ()

    @property
    def n_var(self) -> int:
        return 4 * self.n_pieces

    @staticmethod
    def make(pieces: Sequence[Array], lo: Array, hi: Array, g: Array, s: float,
             t_max: float) -> _Template:
        """The perspective rows of ``pieces`` (half-planes in m) in a box [lo, hi] (units s)."""
        n = len(pieces)
        zx, zy, lam, w = (4 * np.arange(n) + j for j in range(4))
        ones, zeros = np.ones(n), np.zeros(n)
        zero, nonneg, soc = _Rows(), _Rows(), _Rows()
        zero.add(np.r_[0, 1, zeros, ones, 2 * ones], np.r_[-2, -1, zx, zy, lam],
                 np.r_[1.0, 1.0, -ones, -ones, ones], np.array([0.0, 0.0, 1.0]))
        # box and sign: lo λ − Z ≤ 0, Z − hi λ ≤ 0, −λ ≤ 0 (five rows a piece)
        r5 = 5 * np.arange(n)
        nonneg.add(np.concatenate([r5, r5, r5 + 1, r5 + 1, r5 + 2, r5 + 2, r5 + 3, r5 + 3,
                                   r5 + 4]),
                   np.concatenate([zx, lam, zy, lam, zx, lam, zy, lam, lam]),
                   np.concatenate([-ones, lo[0] * ones, -ones, lo[1] * ones, ones,
                                   -hi[0] * ones, ones, -hi[1] * ones, -ones]),
                   np.zeros(5 * n))
        # each half-plane a·p ≥ c of piece k: −a·Z_k + (c/s) λ_k ≤ 0
        k_of = np.concatenate([np.full(len(p), k) for k, p in enumerate(pieces)] or [zeros])
        hp = np.vstack(list(pieces) or [np.zeros((0, 3))]).reshape(-1, 3)
        k_of = k_of.astype(np.int64)[:len(hp)]
        rr = np.arange(len(hp))
        nonneg.add(np.r_[rr, rr, rr], np.r_[zx[k_of], zy[k_of], lam[k_of]],
                   np.r_[-hp[:, 0], -hp[:, 1], hp[:, 2] / s], np.zeros(len(hp)))
        # Σ w_k − t_τ ≤ 0
        nonneg.add(np.zeros(n + 1), np.r_[w, -3], np.r_[ones, -1.0], np.zeros(1))
        # (w + λ, 2(Z − λ g), w − λ) ∈ SOC(4): rows −(…) with b = 0
        r4 = 4 * np.arange(n)
        soc.add(np.concatenate([r4, r4, r4 + 1, r4 + 1, r4 + 2, r4 + 2, r4 + 3, r4 + 3]),
                np.concatenate([w, lam, zx, lam, zy, lam, w, lam]),
                np.concatenate([-ones, -ones, -2.0 * ones, 2.0 * g[0] * ones, -2.0 * ones,
                                2.0 * g[1] * ones, -ones, ones]),
                np.zeros(4 * n))
        one_lo = np.r_[min(lo[0], 0.0), min(lo[1], 0.0), 0.0, 0.0]
        one_hi = np.r_[max(hi[0], 0.0), max(hi[1], 0.0), 1.0, t_max]
        return _Template(zero, nonneg, soc, n, np.tile(one_lo, n), np.tile(one_hi, n),
                         tuple(pieces))


class _Program:
    """One node's conic program in Clarabel's form and its solve."""

    def __init__(self, rel: Relaxation, fixed: Mapping[Pair, int],
                 groups: Sequence[tuple[int, frozenset[int], _Template]]) -> None:
        self.rel, self.groups = rel, list(groups)
        mp = rel.maps
        n, T = mp.n, mp.horizon
        split = {tau for tau, _, _ in self.groups}
        #: positions whose cost is an epigraph t_τ: the split ones (t_τ ≥ Σ w_k) and those
        #: with a positive floor (t_τ ≥ ‖p_τ − g‖², a rotated cone of their own)
        self.floored = [tau for tau in range(2, T + 1) if tau not in split
                        and (rel.floor[tau - 1] > 0.0 or rel.prefix[T - 1] > 0.0)]
        taus = sorted(split | set(self.floored))
        self.t_col = {tau: n + k for k, tau in enumerate(taus)}
        col = n + len(taus)
        self.group_col: list[int] = []
        for _, _, tpl in self.groups:
            self.group_col.append(col)
            col += tpl.n_var
        self.n_var = col
        self.taus = taus
        self._objective(T)
        self._rows(fixed)
        self._box()

    def _objective(self, T: int) -> None:
        rel, mp = self.rel, self.rel.maps
        n = mp.n
        w2 = float(rel.kappa[1]) / rel.c
        costed = np.ones(T - 1)  # p_2..p_T (p_{T+1} is virtual)
        for tau in self.taus:
            costed[tau - 2] = 0.0
        diag = np.r_[np.repeat(costed, 2), 0.0, 0.0]
        p_z = sp.diags(2.0 * diag) + 2.0 * w2 * rel._dtd
        self.P = sp.block_diag([p_z, sp.csr_matrix((self.n_var - n, self.n_var - n))],
                               format="csc")
        g2 = np.r_[np.tile(rel.g, T - 1), 0.0, 0.0]
        q = np.zeros(self.n_var)
        q[:n] = -2.0 * diag * g2 + 2.0 * w2 * (mp.D.T @ rel.off.du)
        for c in self.t_col.values():
            q[c] = 1.0
        self.q = q
        p1 = rel.off.p1 / mp.scale
        self.const = (float(diag @ (g2 * g2)) + w2 * float(rel.off.du @ rel.off.du)
                      + float((p1 - rel.g) @ (p1 - rel.g)))

    def _rows(self, fixed: Mapping[Pair, int]) -> None:
        rel, mp = self.rel, self.rel.maps
        T = mp.horizon
        zero, nonneg, soc = _Rows(), _Rows(), _Rows()
        base = rel._base
        nonneg.add(*base.stacked(0))
        for (tau, i), face in fixed.items():  # α_l·p_τ ≥ β_l + ε
            h = rel.hulls[i]
            j = 2 * (tau - 2)
            nonneg.add(np.zeros(2), np.r_[j, j + 1], -h.A[face],
                       np.array([-(h.b[face] + rel.eps) / mp.scale]))
        soc_sizes: list[int] = []
        g = rel.g
        for tau in self.floored:  # (t + 1, 2(p − g), t − 1) ∈ SOC(4): t ≥ ‖p − g‖²
            t, j = self.t_col[tau], 2 * (tau - 2)
            soc.add(np.r_[0, 1, 2, 3], np.r_[t, j, j + 1, t], np.r_[-1.0, -2.0, -2.0, -1.0],
                    np.r_[1.0, -2.0 * g[0], -2.0 * g[1], -1.0])
            soc_sizes.append(4)
        for tau, t in self.t_col.items():  # t_τ ≥ the floor of p_τ (reach sets)
            if rel.floor[tau - 1] > 0.0:
                nonneg.add(np.zeros(1), np.r_[t], np.r_[-1.0], np.r_[-rel.floor[tau - 1]])
        for tau in range(2, T + 1):  # Σ_{σ=2..τ} t_σ ≥ the prefix cost of p_τ (reach sets)
            if rel.prefix[tau - 1] > 0.0:
                cols = [self.t_col[sigma] for sigma in range(2, tau + 1)]
                nonneg.add(np.zeros(len(cols)), np.array(cols), -np.ones(len(cols)),
                           np.r_[-rel.prefix[tau - 1]])
            if tau > 2 and rel.suffix[tau - 1] > 0.0:  # and Σ_{σ=τ..T} t_σ ≥ its suffix
                cols = [self.t_col[sigma] for sigma in range(tau, T + 1)]
                nonneg.add(np.zeros(len(cols)), np.array(cols), -np.ones(len(cols)),
                           np.r_[-rel.suffix[tau - 1]])
        for (tau, _, tpl), start in zip(self.groups, self.group_col, strict=True):
            place = {-1: 2 * (tau - 2) + 1, -2: 2 * (tau - 2), -3: self.t_col[tau]}
            for src, dst in ((tpl.zero, zero), (tpl.nonneg, nonneg), (tpl.soc, soc)):
                r, c, v, b = src.stacked(0)
                cc = c + start
                for neg, at in place.items():
                    cc[c == neg] = at
                dst.add(r, cc, v, b)
            soc_sizes += [4] * tpl.n_pieces
        self.cones = Cones(zero.count, nonneg.count, tuple(soc_sizes))
        parts = [zero.stacked(0), nonneg.stacked(zero.count),
                 soc.stacked(zero.count + nonneg.count)]
        r = np.concatenate([p[0] for p in parts])
        c = np.concatenate([p[1] for p in parts])
        v = np.concatenate([p[2] for p in parts])
        self.b = np.concatenate([p[3] for p in parts])
        self.A = sp.csc_matrix((v, (r, c)), shape=(self.cones.rows, self.n_var))

    def _box(self) -> None:
        rel, mp = self.rel, self.rel.maps
        s = mp.scale
        lo = [rel.box_lo[1:].ravel() / s, np.array([rel.floor[tau - 1] for tau in self.taus])]
        hi = [rel.box_hi[1:].ravel() / s, np.array([rel.t_max(tau) for tau in self.taus])]
        for _, _, tpl in self.groups:
            lo.append(tpl.lo)
            hi.append(tpl.hi)
        self.lo, self.hi = np.concatenate(lo), np.concatenate(hi)

    def solve(self, time_limit_s: float) -> NodeResult:
        settings = clarabel.DefaultSettings()
        settings.verbose = False
        settings.max_threads = 1
        settings.max_iter = 100
        if math.isfinite(time_limit_s):
            settings.time_limit = max(1e-3, float(time_limit_s))
        cones: list[object] = []
        if self.cones.zero:
            cones.append(clarabel.ZeroConeT(self.cones.zero))
        cones.append(clarabel.NonnegativeConeT(self.cones.nonneg))
        cones += [clarabel.SecondOrderConeT(k) for k in self.cones.soc]
        solver = clarabel.DefaultSolver(sp.triu(self.P).tocsc(), self.q, self.A, self.b,
                                        cones, settings)
        sol = solver.solve()
        status = str(sol.status)
        x, y = np.asarray(sol.x, dtype=float), np.asarray(sol.z, dtype=float)
        if "Infeasible" in status:
            if proves_infeasible(self.A, self.b, self.cones, y, self.lo, self.hi):
                return NodeResult(math.inf, status, None)
            return NodeResult(-math.inf, status, None)
        if not (np.all(np.isfinite(x)) and np.all(np.isfinite(y))):
            return NodeResult(-math.inf, status, None)
        bound = lagrangian_bound(self.P, self.q, self.const, self.A, self.b, self.cones, x, y,
                                 self.lo, self.hi)
        weights = {(tau, part): x[start + 2:start + tpl.n_var:4].copy()
                   for (tau, part, tpl), start in zip(self.groups, self.group_col, strict=True)}
        pieces = {(tau, part): tpl.pieces for tau, part, tpl in self.groups}
        return NodeResult(self.rel.c * bound, status, x[:self.rel.maps.n].copy(), weights,
                          pieces)
