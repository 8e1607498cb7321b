"""The fast method's QP in 3-D: today's planar QP plus a QP in the altitude, solved apart.

A 3-D restriction of (P2) fixes, per (τ, prism), a row that passes the prism *around* (a
half-plane n·(x, y) ≥ c of its ε-inflated footprint, n_z = 0: it excludes the whole prism,
which lies over its footprint) or *over* (z_τ ≥ z_hi + ε, the normal (0, 0, 1)). Eq. (S2)
is a sum over the axes, Eq. (1), U and X (``speed_limit = "axis"``) hold per axis, the
area bounds (x, y) and the band z, an around-row touches (x, y) only and an over-row z
only: the QP is the sum of two independent QPs, and its solution is theirs, exactly. The
plane's is :class:`dualpilot.system2.fast.qp.P2Qp` (n = 2T, bandwidth 6, unchanged); the
altitude's the same class with one axis (n = T, bandwidth 3, the same banded interior
point, :mod:`dualpilot.system2.fast.ipm`). With no over-row, the UAV at G_o's altitude,
v_z = 0 and u_{t|t,z} = 0 the altitude's optimum is z ≡ G_z, u_z ≡ 0 at cost 0 (feasible,
and no cost is below 0): it is written down, not solved. Under ``speed_limit = "norm"``
the axes couple (‖v‖ ≤ v_max) and the QP does not split: refused by name.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from dualpilot.arrays import AnyArray
from dualpilot.model.altitude import AltitudeBand
from dualpilot.model.dynamics import DynamicsParams
from dualpilot.system2.fast.qp import P2Qp, QpParams, QpResult

#: an over-row's normal (a row's last coordinate is 1, the others 0)
OVER = np.array([0.0, 0.0, 1.0])


def planar_dynamics(dyn: DynamicsParams) -> DynamicsParams:
    """The dynamics of the plane of a 3-D mission (the same ΔT, ζ, m and per-axis limits)."""
    return dataclasses.replace(dyn, dim=2)


class SplitQp:
    """The 3-D convex restriction of (P2), solved as a planar and an altitude QP.

    Parameters
    ----------
    horizon : int
        T of Eq. (P2).
    dynamics : DynamicsParams
        Eq. (1) in 3-D (``dim`` 3, ``speed_limit`` "axis").
    area_size_m : float or None
        Keep (x, y) of p_2..p_T in [0, area]² (None: no bounds).
    band : AltitudeBand
        Keep z of p_2..p_T in [floor, ceiling].
    params : QpParams
        The margins (the band's as the area's), the scale and the solver.
    """

    def __init__(self, horizon: int, dynamics: DynamicsParams, area_size_m: float | None,
                 band: AltitudeBand, params: QpParams = QpParams()) -> None:
        if dynamics.dim != 3:
            raise ValueError(f"the split QP is for 3-D plans, got dim={dynamics.dim}")
        if dynamics.speed_limit != "axis":
            raise ValueError("the fast method plans in 3-D under speed_limit = 'axis' only: "
                             "under 'norm' the bound ‖v‖ ≤ v_max couples the three axes and "
                             "its QP does not split into the plane's and the altitude's")
        flat = planar_dynamics(dynamics)
        self.T = int(horizon)
        self.dynamics = dynamics
        self.band = band
        self.plane = P2Qp(horizon, flat, area_size_m, params)
        self.vertical = P2Qp(horizon, flat, band.ceiling_m, params, axes=1,
                             floor_m=band.floor_m)
        self._z_memo: tuple[bytes, QpResult] | None = None

    def at_rest(self, x0: AnyArray, u_prev: AnyArray, goal_z: float) -> bool:
        """The UAV at G_o's altitude, v_z = 0 and u_{t|t,z} = 0: the altitude QP without
        an over-row is z ≡ G_z, u_z ≡ 0 (module docstring)."""
        return bool(x0[2] == goal_z and x0[5] == 0.0 and u_prev[2] == 0.0)

    def solve(self, x0: AnyArray, u_prev: AnyArray, goal: AnyArray, kappa: tuple[float, float],
              tau: AnyArray, normals: AnyArray, rhs: AnyArray,
              area_rows: AnyArray | None = None, elastic: float | None = None, *,
              z0: AnyArray | None = None, confirm: bool = False) -> QpResult:
        """:meth:`P2Qp.solve` in 3-D: rows normals[k]·p_{tau[k]} ≥ rhs[k] with normals
        (m, 3), each an around-row (n_z = 0) or an over-row (0, 0, 1); ``z0`` (T, 3)
        starts both solvers. Positions (T+1, 3), controls (T, 3), the summed cost."""
        if area_rows is not None:
            raise ValueError("the split QP keeps every area and band row")
        x0 = np.asarray(x0, dtype=float)
        u_prev = np.asarray(u_prev, dtype=float)
        nrm = np.asarray(normals, dtype=float).reshape(-1, 3)
        tau = np.asarray(tau, dtype=np.int64)
        rhs = np.asarray(rhs, dtype=float)
        over = nrm[:, 2] != 0.0
        if np.any(over & ~np.all(nrm == OVER, axis=1)) or np.any(~over & (nrm[:, 2] != 0.0)):
            raise ValueError("a row of the fast method is around (n_z = 0) or over (0, 0, 1)")
        xy0 = np.array([x0[0], x0[1], x0[3], x0[4]])
        zs = None if z0 is None else np.asarray(z0, dtype=float).reshape(-1, 3)
        res_xy = self.plane.solve(xy0, u_prev[:2], goal[:2], kappa, tau[~over], nrm[~over, :2],
                                  rhs[~over], None, elastic,
                                  z0=None if zs is None else zs[:, :2], confirm=confirm)
        if not res_xy.ok:
            return _failed(res_xy)
        res_z = self._solve_z(x0, u_prev, float(goal[2]), kappa, tau[over], rhs[over], elastic,
                              None if zs is None else zs[:, 2:], confirm)
        if not res_z.ok:
            return _failed(res_z)
        return QpResult(True, f"{res_xy.status} | z {res_z.status}",
                        np.column_stack([res_xy.positions, res_z.positions]),
                        np.column_stack([res_xy.controls, res_z.controls]),
                        res_xy.objective + res_z.objective,
                        res_xy.iterations + res_z.iterations,
                        res_xy.solve_time_s + res_z.solve_time_s)

    def _solve_z(self, x0: AnyArray, u_prev: AnyArray, goal_z: float,
                 kappa: tuple[float, float], tau: AnyArray, rhs: AnyArray,
                 elastic: float | None, z0: AnyArray | None, confirm: bool) -> QpResult:
        """The altitude's QP (rows z_τ ≥ rhs), written down at rest, else kept per rows: the
        CFS iterations of one plan repeat its rows while they re-choose the plane's."""
        T = self.T
        if not len(tau) and self.at_rest(x0, u_prev, goal_z):
            return QpResult(True, "at rest", np.full((T + 1, 1), goal_z), np.zeros((T, 1)),
                            0.0, 0, 0.0)
        key = b"|".join([x0.tobytes(), u_prev.tobytes(), np.float64(goal_z).tobytes(),
                         np.asarray(kappa, dtype=float).tobytes(), tau.tobytes(),
                         rhs.tobytes(), repr((elastic, confirm)).encode()])
        if self._z_memo is not None and self._z_memo[0] == key:
            return self._z_memo[1]
        res = self.vertical.solve(np.array([x0[2], x0[5]]), u_prev[2:], np.array([goal_z]),
                                  kappa, tau, np.ones((len(tau), 1)), rhs, None, elastic,
                                  z0=z0, confirm=confirm)
        self._z_memo = (key, res)
        return res

    def cost(self, positions: AnyArray, controls: AnyArray, goal: AnyArray,
             kappa: tuple[float, float], u_prev: AnyArray) -> float:
        """Eq. (S2) of 3-D positions p_1..p_T and controls u_1..u_T."""
        return self.plane.cost(positions, controls, goal, kappa, u_prev)


def _failed(res: QpResult) -> QpResult:
    empty = np.empty((0, 3))
    return QpResult(False, res.status, empty, empty, float("inf"), res.iterations,
                    res.solve_time_s)
