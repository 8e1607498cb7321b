"""The fast method's QP in Clarabel's native form, A z ≤ b: the decider and the elastic QP.

The banded interior point (:mod:`dualpilot.system2.fast.ipm`) solves most QPs; Clarabel
decides when it fails on a QP known to be feasible, and solves the elastic QPs (each
half-plane softened by a slack σ ≥ 0 that costs ``elastic`` a metre) and every QP of
the ``"clarabel"`` backend. Rows: U and X (:class:`dualpilot.system2.fast.qp_shape.QpShape`),
the half-planes n·p_τ ≥ c and the area's sides; z in units of ``scale`` m.
"""

from __future__ import annotations

import clarabel
import numpy as np
import scipy.sparse as sp

from dualpilot.arrays import AnyArray
from dualpilot.system2.fast.qp_shape import QpShape


class ClarabelQp:
    """Clarabel's problem (P, q, A, b) of one shape, solved at tolerance ``tol``."""

    def __init__(self, shape: QpShape, tol: float) -> None:
        self.shape = shape
        self.settings = clarabel.DefaultSettings()
        self.settings.verbose = False
        self.settings.tol_gap_abs = tol
        self.settings.tol_gap_rel = tol
        self.settings.tol_feas = tol
        self.settings.max_threads = 1
        self.settings.max_iter = 60
        self.settings.equilibrate_enable = False

    def solve(self, kappa: tuple[float, float], q: AnyArray, vc: AnyArray, uc: AnyArray,
              half_planes: tuple[AnyArray, AnyArray, AnyArray], area_rows: AnyArray | None,
              elastic: float | None) -> clarabel.DefaultSolution:
        """Clarabel's solution of :meth:`problem`."""
        h, q, A, b = self.problem(kappa, q, vc, uc, half_planes, area_rows, elastic)
        solver = clarabel.DefaultSolver(h, q, A, b, [clarabel.NonnegativeConeT(A.shape[0])],
                                        self.settings)
        return solver.solve()

    def problem(self, kappa: tuple[float, float], q: AnyArray, vc: AnyArray, uc: AnyArray,
                half_planes: tuple[AnyArray, AnyArray, AnyArray], area_rows: AnyArray | None,
                elastic: float | None
                ) -> tuple[sp.csc_matrix, AnyArray, sp.csc_matrix, AnyArray]:
        """Clarabel's (P, q, A, b), A z ≤ b: U, X, the half-planes (τ, normals, rhs) and the
        area rows, with the offsets ``vc``, ``uc`` of v and u; with ``elastic`` one slack
        column per half-plane, costing ``elastic`` a metre."""
        sh = self.shape
        tau, normals, rhs = half_planes
        m = len(tau)
        n_sl = m if elastic is not None else 0
        n = sh.n + n_sl
        h = sh.hessian(kappa)
        box = sh.box
        if n_sl:
            h = sp.block_diag([h, sp.csc_matrix((n_sl, n_sl))], format="csc")
            q = np.concatenate([q, np.full(n_sl, float(elastic or 0.0))])
            box = sp.hstack([box, sp.csr_matrix((box.shape[0], n_sl))], format="csr")
        blocks: list[sp.spmatrix] = [box]
        bs = [sh.umax - uc, sh.umax + uc]
        bs += ([sh.vpoly - sh.N @ vc] if sh.norm
               else [sh.vmax - vc, sh.vmax + vc])
        if m:
            hp_blocks, hp_bs = self._half_plane_rows(tau, normals, rhs, n_sl)
            blocks.extend(hp_blocks)
            bs.extend(hp_bs)
        if sh.area is not None:
            ar = self._area_rows(area_rows)
            if len(ar):
                col = sh.axes * (ar[:, 0] - 2) + ar[:, 1]
                sign = np.where(ar[:, 2] == 0, -1.0, 1.0)
                blocks.append(sp.csr_matrix((sign * sh.scale, (np.arange(len(ar)), col)),
                                            shape=(len(ar), n)))
                # the area's lower side is 0 (−(0 + margin) = −margin exactly)
                bs.append(np.where(ar[:, 2] == 0, -(sh.floor + sh.area_margin),
                                   sh.area - sh.area_margin))
        A = sp.vstack(blocks, format="csc")
        b = np.concatenate(bs)
        return h, q, A, b

    def _half_plane_rows(self, tau: AnyArray, normals: AnyArray, rhs: AnyArray, n_sl: int
                         ) -> tuple[list[sp.spmatrix], list[AnyArray]]:
        """Rows −s·n_k·z ≤ −rhs_k of the half-planes (with ``n_sl`` slacks: −σ_k added, and
        −σ_k ≤ 0), and their right-hand sides."""
        sh = self.shape
        m, n, s = len(tau), sh.n + n_sl, sh.scale
        tau = np.asarray(tau, dtype=int)
        if np.any(tau < 2) or np.any(tau > sh.T):
            raise ValueError("half-planes apply to p_2..p_T")
        k = sh.axes
        cols = (k * (tau - 2)[:, None] + np.arange(k)[None, :]).ravel()
        rows = np.repeat(np.arange(m), k)
        vals = (-s * np.asarray(normals, dtype=float).reshape(m, k)).ravel()
        if n_sl:
            cols = np.concatenate([cols, sh.n + np.arange(m)])
            rows = np.concatenate([rows, np.arange(m)])
            vals = np.concatenate([vals, -np.ones(m)])
            slack = sp.csr_matrix((-np.ones(m), (np.arange(m), sh.n + np.arange(m))),
                                  shape=(m, n))
            return ([sp.csr_matrix((vals, (rows, cols)), shape=(m, n)), slack],
                    [-np.asarray(rhs, dtype=float), np.zeros(m)])
        return [sp.csr_matrix((vals, (rows, cols)), shape=(m, n))], [-np.asarray(rhs, dtype=float)]

    def _area_rows(self, area_rows: AnyArray | None) -> AnyArray:
        """(τ, axis, side) rows of the area (None: every side of every p_2..p_T)."""
        if area_rows is None:
            tau = np.arange(2, self.shape.T + 1)
            axes = list(range(self.shape.axes))
            grid = np.array(np.meshgrid(tau, axes, [0, 1], indexing="ij")).reshape(3, -1).T
            return grid.astype(int)
        return np.asarray(area_rows, dtype=int).reshape(-1, 3)
