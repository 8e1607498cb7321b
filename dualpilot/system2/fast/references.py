"""The references that start the fast method's CFS runs: one path per homotopy, timed by Eq. (1).

Each reference is a sequence of positions p_1..p_{T+1} (m) that picks a run's
first half-planes (:class:`dualpilot.system2.fast.cfs.Cfs`): the previous plan
shifted by a step, the shortest path of each homotopy class
(:func:`dualpilot.system2.fast.geometry.homotopy_paths`) from p_{t+1|t} to the
target (G_o, or the free point nearest to it) timed along the path at the
relaxation's speed within the limits, and the relaxation itself; braking to a
hover is the last resort (:func:`braking`).
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Callable

import numpy as np

from dualpilot.arrays import Array
from dualpilot.model.dynamics import DynamicsParams
from dualpilot.model.geometry import Rect
from dualpilot.plan import Plan
from dualpilot.system2.fast.cfs import KeepOuts
from dualpilot.system2.fast.geometry import FaceStack, Inflated, homotopy_paths, resample
from dualpilot.system2.fast.params import FastParams
from dualpilot.system2.problem import System2Params

Reference = tuple[str, Array, Callable[[float], Array] | None]
"""(name, positions p_1..p_{T+1}, the same path re-timed slower by a factor, or None)."""


class References:
    """The references of one planner's requests.

    Parameters
    ----------
    fast : FastParams
        Homotopies, their slack and the speed factor of the timing.
    params : System2Params
        T of Eq. (P2) and K of the speed polygon (``speed_limit = "norm"``).
    dynamics : DynamicsParams
        Eq. (1) and its limits.
    goal : Rect
        G, whose centre is G_o of Eq. (S2) (m).
    area : float or None
        The area's side (m; None: no bounds).
    """

    def __init__(self, fast: FastParams, params: System2Params, dynamics: DynamicsParams,
                 goal: Rect, area: float | None) -> None:
        self.fast, self.params = fast, params
        self.dynamics, self.goal, self.area = dynamics, goal, area

    def __call__(self, x0: Array, free_pos: Array, hulls: KeepOuts, kappa: tuple[float, float],
                 last: Plan | None) -> list[Reference]:
        """Reference positions p_1..p_{T+1} (one per homotopy) to pick the first half-planes.

        ``free_pos`` are the relaxation's positions, ``hulls`` what the paths avoid,
        ``last`` the previous plan (None: none). Each comes with a function that
        re-times it slower by a factor (None for the previous plan, whose timing was
        feasible).
        """
        f = self.fast
        T = self.params.horizon
        p1 = free_pos[0]
        speeds = np.linalg.norm(np.diff(free_pos, axis=0), axis=1) / self.dynamics.dt_s
        target = self.target(hulls.polys, hulls.faces)
        refs: list[Reference] = []
        v0 = x0[2:]

        def timed(path: Array) -> tuple[Array, Callable[[float], Array]]:
            return (resample(path, self.timing(path, speeds, v0)),
                    lambda fac: resample(path, self.timing(path, speeds, v0, fac)))

        if f.use_previous and last is not None and last.ok and len(last.states) == T + 1:
            prev_pos = last.states[:, :2]
            if np.linalg.norm(prev_pos[1] - x0[:2]) < 30.0:
                shifted = np.vstack([prev_pos[2:], prev_pos[-1:], prev_pos[-1:]])
                shifted[0] = p1
                refs.append(("previous", shifted, None))
        paths = homotopy_paths(p1, target, hulls.polys, area=self.area, stack=hulls.stack,
                               max_paths=f.max_homotopies,
                               max_signature_hulls=f.max_signature_hulls,
                               length_slack=f.length_slack)
        for k, path in enumerate(paths):
            refs.append((f"path{k}", *timed(path)))
        path_len = (float(np.linalg.norm(np.diff(paths[0], axis=0), axis=1).sum())
                    if paths else 0.0)
        if (paths and kappa[0] < kappa[1]
                and self.timing(paths[0], speeds, v0)[-1] < path_len - 1.0):
            # timed by a slow energy-saving relaxation (κ1 < κ2), the shortest path is not
            # finished within the horizon, which can leave the plan short of the
            # target: also try the path at the speed the limits allow
            fast_speeds = np.full_like(speeds, np.inf)
            path = paths[0]
            refs.append(("path0-brisk", resample(path, self.timing(path, fast_speeds, v0)),
                         lambda fac: resample(path, self.timing(path, fast_speeds, v0, fac))))
        # the relaxation itself: each point leaves Q through its nearest face (dead ends too)
        _, slower = timed(free_pos)
        refs.append(("projected", free_pos, slower))
        return refs

    def timing(self, path: Array, speeds: Array, v0: Array, factor: float = 1.0) -> Array:
        """Arc lengths s(τ), τ = 1..T+1, along ``path``.

        The speed is the relaxation's, capped by a point-mass profile that
        starts from v_t's component along the path and respects Eq. (1)'s drag
        and the per-axis bounds on u and v in each segment's direction
        (times ``speed_factor``), so that the first half-planes are reachable;
        under ``speed_limit = "norm"`` the speed cap is v_max·cos(π/K), the
        inscribed radius of the QP's speed polygon.
        """
        rho = self.fast.speed_factor * factor
        dyn = self.dynamics
        d = np.diff(path, axis=0)
        seg = np.linalg.norm(d, axis=1)
        good = seg > 1e-9
        if not np.any(good):
            return np.zeros(len(speeds) + 1)
        d, seg = d[good], seg[good]
        cum = np.concatenate([[0.0], np.cumsum(seg)])
        axis_factor = seg / np.maximum(np.max(np.abs(d), axis=1), 1e-9)  # 1..√2
        if dyn.speed_limit == "norm":
            v_cap = np.full(len(seg), rho * dyn.v_max_mps
                            * math.cos(math.pi / self.params.speed_polygon_sides))
        else:
            v_cap = rho * dyn.v_max_mps * axis_factor
        a_cap = rho * dyn.u_max_n / dyn.mass_kg * axis_factor
        keep = 1.0 - dyn.zeta
        dt = dyn.dt_s
        sigma = max(0.0, float(v0 @ d[0]) / float(seg[0]))
        # the recursion in plain floats (same IEEE arithmetic as numpy scalars, less overhead)
        cum_l, vc_l, ac_l = cum.tolist(), v_cap.tolist(), a_cap.tolist()
        end, last = cum_l[-1], len(seg) - 1
        s_k = 0.0
        out = [0.0]
        for v in speeds.tolist():
            j = min(max(bisect.bisect_right(cum_l, s_k) - 1, 0), last)
            sigma = min(vc_l[j], keep * sigma + ac_l[j] * dt, factor * max(v, 0.0))
            s_k = min(end, s_k + dt * sigma)
            out.append(s_k)
        return np.array(out)

    def target(self, polys: list[Inflated], faces: FaceStack | None = None) -> Array:
        """G_o, or the free point nearest to it when G_o is covered by inflated hulls.

        Candidates are G_o's projections onto every edge of every Q and the
        vertices of every Q, each pushed 2 m outwards; the nearest that lies
        outside every Q (and in the area) is the target.
        """
        g = self.goal.center
        faces = FaceStack.of(polys) if faces is None else faces
        margin_g = faces.margins(g)[0]
        if np.all(margin_g > 0):
            return g
        # every hull's candidates at once, hull by hull
        all_pts, owner = all_candidates(polys, g)
        bounds = np.searchsorted(owner, np.arange(len(polys) + 1))
        # A candidate of Q lies 2 m outside Q, so it is at least margin_Q(G_o) − 2 m from
        # G_o: visit the hulls nearest first and stop once none can beat the best so far.
        best, best_d = g, math.inf
        for i in np.argsort(margin_g):
            if margin_g[i] - 2.0 >= best_d:
                break
            pts = all_pts[int(bounds[i]):int(bounds[i + 1])]
            free = np.all(faces.margins(pts) > 0, axis=1)
            if self.area is not None:
                free &= np.all((pts >= 0.0) & (pts <= self.area), axis=1)
            if np.any(free):
                pts = pts[free]
                d = np.linalg.norm(pts - g, axis=1)
                j = int(np.argmin(d))
                if d[j] < best_d:
                    best, best_d = pts[j], float(d[j])
        return np.asarray(best)


def all_candidates(polys: list[Inflated], g: Array) -> tuple[Array, Array]:
    """G_o projected onto every edge of every Q and Q's vertices, each pushed 2 m outwards.

    Returns the points hull by hull (its edge projections, then its corners)
    and each point's hull.
    """
    sizes = np.array([len(q.b) for q in polys])
    a = np.vstack([q.W for q in polys])
    nrm = np.vstack([q.A for q in polys])
    e = np.vstack([q.E for q in polys])
    len2 = np.concatenate([q.len2 for q in polys])
    t = np.clip(((g - a) * e).sum(axis=1) / len2, 0.0, 1.0)
    proj = a + t[:, None] * e
    bis = np.vstack([q.nsum for q in polys])  # α_{l−1} + α_l: the corner's bisector
    corners = a + 2.0 * bis / np.maximum(np.linalg.norm(bis, axis=1), 1e-9)[:, None]
    hull = np.repeat(np.arange(len(polys)), sizes)
    k = np.arange(len(a))
    order = np.lexsort((np.concatenate([k, k]), np.repeat([0, 1], len(k)),
                       np.concatenate([hull, hull])))
    pts = np.vstack([proj + 2.0 * nrm, corners])[order]
    return pts, np.concatenate([hull, hull])[order]


def braking(x0: Array, horizon: int, dyn: DynamicsParams) -> Array:
    """Positions p_1..p_{T+1} (m) when braking to a hover as hard as U allows (per axis, in
    the state's dimension; the altitude of a 3-D plan then changes by what v_z carries it)."""
    keep = 1.0 - dyn.zeta
    d = len(x0) // 2
    v = x0[d:].copy()
    p = x0[:d] + dyn.dt_s * v
    out = [p.copy()]
    for _ in range(horizon):
        u = np.clip(-keep * v * dyn.mass_kg / dyn.dt_s, -dyn.u_max_n, dyn.u_max_n)
        v = keep * v + dyn.dt_s / dyn.mass_kg * u
        p = p + dyn.dt_s * v
        out.append(p.copy())
    return np.array(out)
