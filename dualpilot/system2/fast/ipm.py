"""A small primal-dual interior-point QP solver for banded problems (Mehrotra predictor-corrector).

Solves  min ½ zᵀHz + qᵀz  s.t.  lo ≤ L z ≤ hi  (row-wise, ±inf allowed),
where H is symmetric positive definite with lower bandwidth ``bw`` and every
row of L has a few nonzeros (three, or four for a speed polygon) within ``bw``
of each other. Then the
Newton matrix H + Lᵀ D L is banded too, and each iteration costs one banded
Cholesky factorisation (LAPACK ``dpbtrf``) and two solves — O(n·bw²) — which
is what makes the convex restrictions of Problem (P2) cheap: n = 2T = 160.

Rows are kept in a padded form: ``cols`` and ``vals`` of shape (R, k).
"""

from __future__ import annotations

import copy
from dataclasses import dataclass

import numpy as np

from dualpilot.arrays import AnyArray
from dualpilot.system2.fast.mehrotra import (
    DIVERGED,
    FACTORIZATION,
    MAX_ITER,
    SOLVED,
    STALLED,
    mehrotra,
)

#: the status of each code :func:`mehrotra` returns
_STATUS = {SOLVED: "solved", MAX_ITER: "max_iter", DIVERGED: "diverged",
           STALLED: "stalled (likely infeasible)"}


@dataclass(frozen=True)
class Rows:
    """Rows lo ≤ Σ_k vals[r,k]·z[cols[r,k]] ≤ hi, each row scaled to unit norm."""

    cols: AnyArray  # (R, k) int
    vals: AnyArray  # (R, k)
    lo: AnyArray
    hi: AnyArray

    @staticmethod
    def make(cols: AnyArray, vals: AnyArray, lo: AnyArray, hi: AnyArray) -> Rows:
        cols = np.asarray(cols, dtype=np.int64)
        vals = np.asarray(vals, dtype=float)
        norm = np.linalg.norm(vals, axis=1)
        norm = np.where(norm > 0, norm, 1.0)
        return Rows(cols, vals / norm[:, None], np.asarray(lo, dtype=float) / norm,
                    np.asarray(hi, dtype=float) / norm)

    @staticmethod
    def stack(parts: list[Rows]) -> Rows:
        k = max(p.width for p in parts)
        parts = [p.widen(k) for p in parts]
        return Rows(np.vstack([p.cols for p in parts]), np.vstack([p.vals for p in parts]),
                    np.concatenate([p.lo for p in parts]), np.concatenate([p.hi for p in parts]))

    @property
    def width(self) -> int:
        return int(self.cols.shape[1])

    def widen(self, k: int) -> Rows:
        """The same rows with ``k`` entries each (padding repeats column 0 with value 0)."""
        return Rows(*widen(self.cols, self.vals, k), self.lo, self.hi)

    def __len__(self) -> int:
        return len(self.lo)


@dataclass(frozen=True)
class IpmResult:
    ok: bool
    status: str
    z: AnyArray
    iterations: int


def widen(cols: AnyArray, vals: AnyArray, k: int) -> tuple[AnyArray, AnyArray]:
    """Padded rows with ``k`` entries each: extra entries repeat column 0 with value 0."""
    w = cols.shape[1]
    if w == k:
        return cols, vals
    if w > k:
        raise ValueError(f"cannot narrow rows of width {w} to {k}")
    pad = k - w
    return (np.hstack([cols, np.repeat(cols[:, :1], pad, axis=1)]),
            np.hstack([vals, np.zeros((len(vals), pad))]))


def pairs_of(k: int) -> list[tuple[int, int]]:
    """The entry pairs (p, q) of a width-k row's LᵀDL terms: the k squares, then p < q."""
    return [(p, p) for p in range(k)] + [(p, q) for p in range(k) for q in range(p + 1, k)]


def band_pairs(rows: Rows, n: int) -> tuple[AnyArray, AnyArray, AnyArray]:
    """Flat band indices d·n + min(i, j), coefficients and row ids of every LᵀDL term.

    Row-major: the P = k(k+1)/2 terms of row r are entries P·r … P·r + P − 1, so
    the terms of stacked row sets (of one width) are the concatenation of their terms.
    """
    pairs = pairs_of(rows.width)
    i = rows.cols[:, [p for p, _ in pairs]]
    j = rows.cols[:, [q for _, q in pairs]]
    c = rows.vals[:, [p for p, _ in pairs]] * rows.vals[:, [q for _, q in pairs]]
    idx = np.abs(i - j) * n + np.minimum(i, j)
    rid = np.repeat(np.arange(len(rows.cols)), len(pairs))
    return idx.ravel(), c.ravel(), rid


_HESSIANS: dict[bytes, tuple[float, AnyArray, AnyArray]] = {}


def _scaled_hessian(h_band: AnyArray) -> tuple[float, AnyArray, AnyArray]:
    """(c, H/c in band form, H/c dense) with c = max diag H (1 if not positive), cached."""
    key = h_band.tobytes() + str(h_band.shape).encode()
    hit = _HESSIANS.get(key)
    if hit is not None:
        return hit
    c_obj = float(np.max(h_band[0]))
    c_obj = c_obj if c_obj > 0 else 1.0
    band = h_band / c_obj
    n = band.shape[1]
    dense = np.diag(band[0])
    for d in range(1, band.shape[0]):
        off = np.diag(band[d, : n - d], -d)
        dense += off + off.T
    band.setflags(write=False)
    dense.setflags(write=False)
    if len(_HESSIANS) >= 16:
        _HESSIANS.clear()
    _HESSIANS[key] = (c_obj, band, dense)
    return c_obj, band, dense


class BandedQp:
    """The fixed part of a banded QP (objective and fixed rows), ready for many solves.

    Every :meth:`solve` appends one-sided rows ``extra`` (lo ≤ L z) — the
    half-planes of Problem (P2) — to the fixed rows and runs
    :func:`solve_qp`'s Mehrotra iterations; the fixed rows' sparse matrices
    and Newton-matrix terms are built once.
    """

    def __init__(self, h_band: AnyArray, q: AnyArray, rows: Rows,
                 pairs: tuple[AnyArray, AnyArray, AnyArray]) -> None:
        self.bw1, self.n = h_band.shape
        self.c_obj, self.h_band, self.h_dense = _scaled_hessian(h_band)
        self.q = q / self.c_obj
        il = np.flatnonzero(np.isfinite(rows.lo))
        iu = np.flatnonzero(np.isfinite(rows.hi))
        self.il, self.iu = il, iu
        ridx = np.concatenate([il, iu])
        sg = np.concatenate([-np.ones(len(il)), np.ones(len(iu))])
        self.h = np.concatenate([-rows.lo[il], rows.hi[iu]])
        self.m = m = len(self.h)
        # G in the padded row form (≤ 3 entries a row); each solve reads it as CSR arrays
        self.g_cols = rows.cols[ridx]
        self.g_vals = rows.vals[ridx] * sg[:, None]
        p_idx, p_coef, _ = pairs
        self.width = rows.width
        n_pairs = len(pairs_of(self.width))
        g_pair = (ridx[:, None] * n_pairs + np.arange(n_pairs)[None, :]).ravel()
        rowid = np.repeat(np.arange(m), n_pairs)
        coef = p_coef[g_pair]
        nz = coef != 0.0  # padding terms add nothing
        self.p_idx, self.p_coef, self.p_row = p_idx[g_pair][nz], coef[nz], rowid[nz]
        self._arrays: tuple[AnyArray, ...] | None = None  # made by the first solve

    def rebound(self, q: AnyArray, lo: AnyArray, hi: AnyArray) -> BandedQp:
        """The same QP with a new linear term and new row bounds (same finite pattern)."""
        if not (np.array_equal(np.flatnonzero(np.isfinite(lo)), self.il)
                and np.array_equal(np.flatnonzero(np.isfinite(hi)), self.iu)):
            raise ValueError("rebound needs the same finite bounds")
        return self.rebound_unchecked(q, lo, hi)

    def rebound_unchecked(self, q: AnyArray, lo: AnyArray, hi: AnyArray) -> BandedQp:
        """:meth:`rebound` for bounds the caller knows to have this QP's finite pattern."""
        out = copy.copy(self)
        out.q = q / self.c_obj
        out.h = np.concatenate([-lo[self.il], hi[self.iu]])
        return out

    def solve(self, extra: Rows | None = None, *, max_iter: int = 40, tol: float = 1e-9,
              z0: AnyArray | None = None, slack0: float = 1.0,
              detect_infeasible: bool = True) -> IpmResult:
        """Mehrotra predictor-corrector with the fixed rows plus ``extra`` (lower bounds).

        G (CSR arrays; read as CSC they are Gᵀ) and the map w ↦ band(GᵀWG) (CSC,
        one column per row of G) are set up once per solve; the iterations run
        compiled (:func:`dualpilot.system2.fast.mehrotra.mehrotra`).
        """
        n = self.n
        if extra is not None and len(extra.cols):
            # lo ≤ L z  ⇔  −L z ≤ −lo (the fixed rows are at least as wide as the extra ones)
            e_cols, e_vals = widen(extra.cols, extra.vals, self.width)
            g_cols = np.vstack([self.g_cols, e_cols])
            g_vals = np.vstack([self.g_vals, -e_vals])
            h = np.concatenate([self.h, -extra.lo])
            ep = band_pairs(Rows(e_cols, e_vals, extra.lo, extra.hi), n)
            nz = ep[1] != 0.0
            p_idx = np.concatenate([self.p_idx, ep[0][nz]])
            p_coef = np.concatenate([self.p_coef, ep[1][nz]])
            p_row = np.concatenate([self.p_row, ep[2][nz] + self.m])
            arrays = _solver_arrays(g_cols, g_vals, p_idx, p_coef, p_row)
        else:
            h = self.h
            if self._arrays is None:  # the fixed rows alone: the same arrays every solve
                self._arrays = _solver_arrays(self.g_cols, self.g_vals, self.p_idx,
                                              self.p_coef, self.p_row)
            arrays = self._arrays
        g_ptr, g_idx, g_dat, b_ptr, b_idx, b_dat = arrays
        z_start = np.zeros(n) if z0 is None else np.array(z0, dtype=float)
        code, z, it, info = mehrotra(
            self.h_dense, self.h_band, self.q, np.ascontiguousarray(h, dtype=float), g_ptr,
            g_idx, g_dat, b_ptr, b_idx, b_dat, z_start, float(slack0), int(max_iter),
            float(tol), bool(detect_infeasible))
        status = _STATUS[code] if code != FACTORIZATION else f"factorization failed ({info})"
        return IpmResult(status == "solved", status, z, it)


def _solver_arrays(g_cols: AnyArray, g_vals: AnyArray, p_idx: AnyArray, p_coef: AnyArray,
                   p_row: AnyArray) -> tuple[AnyArray, ...]:
    """G in CSR arrays (k entries a row) and the band map's CSC arrays (p_row is
    non-decreasing: the terms of row r are one contiguous run), as :func:`mehrotra` reads them."""
    m, k_g = g_cols.shape
    g_ptr = np.arange(0, k_g * m + 1, k_g, dtype=np.int64)
    g_idx = np.ascontiguousarray(g_cols, dtype=np.int64).ravel()
    g_dat = np.ascontiguousarray(g_vals, dtype=float).ravel()
    b_ptr = np.searchsorted(p_row, np.arange(m + 1)).astype(np.int64)
    b_idx = np.ascontiguousarray(p_idx, dtype=np.int64)
    b_dat = np.ascontiguousarray(p_coef, dtype=float)
    return g_ptr, g_idx, g_dat, b_ptr, b_idx, b_dat


def solve_qp(h_band: AnyArray, q: AnyArray, rows: Rows, pairs: tuple[AnyArray, AnyArray, AnyArray],
             *, max_iter: int = 40, tol: float = 1e-9, z0: AnyArray | None = None,
             slack0: float = 1.0, detect_infeasible: bool = True) -> IpmResult:
    """Solve  min ½ zᵀHz + qᵀz  s.t.  rows  (``h_band`` is (bw+1, n) lower band form).

    Inequalities G z + s = h, s ≥ 0 stack the finite lower bounds (G = −L) and
    upper bounds (G = L). The objective is scaled so that max diag H = 1.
    With ``detect_infeasible`` a primal residual that stops shrinking ends the
    solve early as "stalled (likely infeasible)".
    """
    return BandedQp(h_band, q, rows, pairs).solve(
        max_iter=max_iter, tol=tol, z0=z0, slack0=slack0, detect_infeasible=detect_infeasible)
