"""What every fast-method QP of one shape shares: Eq. (1)'s maps, fixed rows and memo tables.

A shape is (T, dynamics, area, margins, scale, K, axes, floor)
(:class:`dualpilot.system2.fast.qp.P2Qp`): ``axes`` = 2 is the plane's QP (n = 2T, bandwidth
6), ``axes`` = 1 the altitude's of a 3-D plan (n = T, bandwidth 3; its bounds the band).
Its sparse maps write v, u and Δu of Eq. (1) in the scaled positions z; its fixed rows
(U, X and the area, padded to three or four entries a row) are those of the banded
interior-point solver (:mod:`dualpilot.system2.fast.ipm`); its memo tables keep the
Hessians of Eq. (S2), their bands and the interior-point structures. Built once a process
(:func:`qp_shape`); only the memo tables change after.
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from functools import lru_cache
from typing import NamedTuple

import numpy as np
import scipy.sparse as sp

from dualpilot.arrays import AnyArray
from dualpilot.model.dynamics import DynamicsParams, speed_polygon
from dualpilot.system2.fast.ipm import BandedQp, Rows, band_pairs


class Margins(NamedTuple):
    """How much the QP tightens Eq. (1)'s bounds: speed (m/s), force (N), area (m)."""

    v: float
    u: float
    area: float


class QpShape:
    """The matrices and memo tables of one shape (see the module docstring).

    ``T`` is the horizon, ``area`` the upper bound of every coordinate (m: the area's
    side; the ceiling for the altitude; None: no bounds) and ``floor`` the lower (m: 0 in
    the plane), ``scale`` the unit of z (m); ``vmax``, ``umax`` and ``area_margin`` the
    bounds tightened by the margins (m/s, N, m); ``speed_sides`` K of the speed polygon
    (``"norm"``, planar only); ``axes`` the coordinates a position has here (2 or 1).
    """

    def __init__(self, T: int, dynamics: DynamicsParams, area_size_m: float | None,
                 margins: Margins, s: float, speed_sides: int, axes: int = 2,
                 floor: float = 0.0) -> None:
        v_margin, u_margin, area_margin = margins
        if axes not in (1, 2):
            raise ValueError(f"a QP shape has 1 or 2 axes, got {axes}")
        self.T, self.dyn, self.area, self.scale, self.n = T, dynamics, area_size_m, s, axes * T
        self.axes, self.floor = axes, float(floor)
        n = self.n
        self.bw = 3 * axes
        self.vmax = dynamics.v_max_mps - v_margin
        self.umax = dynamics.u_max_n - u_margin
        self.area_margin = area_margin
        dt, a, mass = dynamics.dt_s, 1.0 - dynamics.zeta, dynamics.mass_kg
        eye = sp.identity(axes, format="csr")
        # P = [p_1; p_2..p_{T+1}] = M z + e, e = [p_1; 0]
        m_pos = sp.vstack([sp.csr_matrix((axes, n)), s * sp.identity(n, format="csr")]).tocsr()
        d_v = sp.kron(sp.diags([-np.ones(T), np.ones(T)], [0, 1], shape=(T, T + 1)), eye) / dt
        self.V = (d_v @ m_pos).tocsr()  # v_1..v_T (without the p_1 offset)
        self.dv = d_v.tocsr()
        self.shift = sp.kron(sp.diags([np.ones(T - 1)], [-1], shape=(T, T)), eye).tocsr()
        self.U = ((mass / dt) * (self.V - a * (self.shift @ self.V))).tocsr()
        self.diff = sp.kron(sp.diags([np.ones(T), -np.ones(T - 1)], [0, -1], shape=(T, T)),
                            eye).tocsr()
        self.dU = (self.diff @ self.U).tocsr()
        self.dUT = self.dU.T.tocsr()
        # costed positions p_1..p_T: p_1 constant, p_2..p_T = s z[:2(T-1)]
        k = axes * (T - 1)
        sel = sp.hstack([s * sp.identity(k), sp.csr_matrix((k, axes))]).tocsr()
        self.selT = sel.T.tocsr()
        self.H_pos = (sel.T @ sel).tocsc()
        self.H_du = (self.dU.T @ self.dU).tocsc()
        self.norm = dynamics.speed_limit == "norm"
        if self.norm and axes != 2:
            raise ValueError("the speed polygon (speed_limit = 'norm') couples the plane's axes")
        if self.norm:  # n_k·v_τ ≤ v_max cos(π/K): one row per (τ, k), τ-major
            normals, cos_k = speed_polygon(speed_sides)
            self.vpoly = dynamics.v_max_mps * cos_k - v_margin
            self.N = sp.kron(sp.identity(T, format="csr"), sp.csr_matrix(normals)).tocsr()
            self.P = (self.N @ self.V).tocsr()
            self.box = sp.vstack([self.U, -self.U, self.P]).tocsr()
        else:
            self.box = sp.vstack([self.U, -self.U, self.V, -self.V]).tocsr()
        self._fixed_rows(area_size_m)
        self.H_cache: dict[tuple[float, float], sp.csc_matrix] = {}
        self.band_cache: dict[tuple[float, float], AnyArray] = {}
        self.struct_cache: OrderedDict[tuple[float, float, bytes, bytes], BandedQp] = (
            OrderedDict())
        self.struct_lock = threading.Lock()  # a fleet's planners share it from their threads

    def _fixed_rows(self, area_size_m: float | None) -> None:
        """Padded rows of the banded interior-point solver: U, V (two-sided) and the area
        (the speed polygon's rows have four entries: then every fixed row has four)."""
        T, n, s = self.T, self.n, self.scale
        width = 4 if self.norm else 3
        fixed_rows = [_padded(self.U, width), _padded(self.P if self.norm else self.V, width)]
        if area_size_m is not None:
            j = np.arange(self.axes * (T - 1))
            cols = np.column_stack([j] * width)
            vals = np.column_stack([np.full(len(j), s)] + [np.zeros(len(j))] * (width - 1))
            fixed_rows.append((cols, vals))
        self.fixed_norm = [np.linalg.norm(v, axis=1) for _, v in fixed_rows]
        self.fixed = Rows(np.vstack([c for c, _ in fixed_rows]),
                          np.vstack([v / nr[:, None] for (_, v), nr in
                                     zip(fixed_rows, self.fixed_norm, strict=True)]),
                          np.zeros(0), np.zeros(0))
        self.fixed_pairs = band_pairs(self.fixed, n)

    def hessian(self, kappa: tuple[float, float]) -> sp.csc_matrix:
        """The upper triangle of the QP's Hessian (Eq. (S2) in z) for κ, kept."""
        key = (float(kappa[0]), float(kappa[1]))
        h = self.H_cache.get(key)
        if h is None:
            h = sp.triu(2.0 * key[0] * self.H_pos + 2.0 * key[1] * self.H_du).tocsc()
            self.H_cache[key] = h
        return h

    def hessian_band(self, kappa: tuple[float, float]) -> AnyArray:
        """H of the QP in lower band form (bw+1, n), kept."""
        key = (float(kappa[0]), float(kappa[1]))
        band = self.band_cache.get(key)
        if band is None:
            h = (2.0 * key[0] * self.H_pos + 2.0 * key[1] * self.H_du).tocsr()
            n, bw = self.n, self.bw
            band = np.zeros((bw + 1, n))
            for d in range(bw + 1):
                band[d, : n - d] = h.diagonal(-d)
            coo = h.tocoo()
            if np.any(np.abs(coo.row - coo.col) > bw):
                raise AssertionError("QP Hessian is not within the band")  # pragma: no cover
            self.band_cache[key] = band
        return band


@lru_cache(maxsize=8)
def qp_shape(T: int, dynamics: DynamicsParams, area_size_m: float | None, v_margin: float,
             u_margin: float, area_margin: float, s: float, speed_sides: int, axes: int = 2,
             floor: float = 0.0) -> QpShape:
    """The one :class:`QpShape` of these arguments in this process."""
    return QpShape(T, dynamics, area_size_m, Margins(v_margin, u_margin, area_margin), s,
                   speed_sides, axes, floor)


def _padded(mat: sp.csr_matrix, width: int = 3) -> tuple[AnyArray, AnyArray]:
    """(cols, vals) of shape (rows, width) for a CSR matrix with ≤ width nonzeros a row."""
    mat = mat.tocsr(copy=True)
    mat.eliminate_zeros()
    mat.sort_indices()
    nnz = np.diff(mat.indptr)
    if np.any(nnz > width):
        raise ValueError(f"rows with more than {width} nonzeros")
    rows = mat.shape[0]
    cols = np.zeros((rows, width), dtype=np.int64)
    vals = np.zeros((rows, width))
    for k in range(width):
        has = nnz > k
        pos = mat.indptr[:-1][has] + k
        cols[has, k] = mat.indices[pos]
        vals[has, k] = mat.data[pos]
    # padding repeats the first column with value 0 (keeps band offsets small)
    for k in range(1, width):
        pad = nnz <= k
        cols[pad, k] = cols[pad, 0]
    return cols, vals
