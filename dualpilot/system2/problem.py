"""Problem (P2), System 2's MPC: parameters, the objective Eq. (S2) and the independent check.

J(X, U) = κ1 Σ_{τ=1..T} ‖p_{t+τ|t} − G_o‖² + κ2 Σ_{τ=1..T} ‖u_{t+τ|t} − u_{t+τ−1|t}‖²,

with u_{t|t} the control applied at the previous step, subject to Eq. (1)
(P2_1)-(P2_2), U and X, and the avoidance disjunction (P2_3)-(P2_4) with ε =
``MissionSpec.clearance_m``. Every System 2 method is scored with
:func:`p2_cost` and checked with :func:`verify_p2_plan`. Lengths in m.

In 3-D (docs/three_d.md) the obstacles are prisms (:class:`~dualpilot.model.prism.Prism`:
a cuboid's six faces, as Sec. II-B writes them, or a swept hull's k + 2), positions
[x, y, z], and the check adds the altitude band.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal, overload

import numpy as np

from dualpilot.arrays import Array
from dualpilot.model.altitude import AltitudeBand
from dualpilot.model.dynamics import DynamicsParams
from dualpilot.model.geometry import Polytope, hull_boxes
from dualpilot.model.prism import Prism
from dualpilot.plan import Objective
from dualpilot.verify import Verdict, verify_trajectory

#: An obstacle of (P2): a planar polygon (2-D) or a prism (3-D), {p : α_l·p ≤ β_l}.
Obstacle = Polytope | Prism


@dataclass(frozen=True)
class System2Params:
    """Sec. IV-A: T = 80, M = 1e5, κ per objective; ε, d_safe and the area come from the spec.

    ``keep_in_area`` keeps every planned position in the area; ``max_hulls``
    and ``max_faces`` size the exact method's compiled problem. Under
    ``DynamicsParams.speed_limit = "norm"`` both methods bound v_τ by the regular
    K-gon inside the disc, n_k·v_τ ≤ v_max·cos(π/K), K = ``speed_polygon_sides``,
    so (P2) stays a mixed-integer QP.
    """

    horizon: int = 80
    big_m: float = 1e5
    kappa_time: tuple[float, float] = (1.0, 0.001)
    kappa_energy: tuple[float, float] = (0.001, 1.0)
    keep_in_area: bool = True
    time_limit_s: float = 60.0
    max_hulls: int = 10
    max_faces: int = 12
    speed_polygon_sides: int = 16

    def __post_init__(self) -> None:
        if self.horizon < 1:
            raise ValueError(f"horizon must be >= 1, got {self.horizon}")
        if self.speed_polygon_sides < 3:
            raise ValueError(f"speed_polygon_sides must be >= 3, got {self.speed_polygon_sides}")
        if self.big_m <= 0 or self.time_limit_s <= 0:
            raise ValueError("big_m > 0 and time_limit_s > 0 are required")

    def kappa(self, objective: Objective) -> tuple[float, float]:
        """(κ1, κ2) for the attention's objective."""
        return self.kappa_time if objective is Objective.MISSION_TIME else self.kappa_energy


def p2_cost(
    states: Array,
    controls: Array,
    goal_center: Array,
    kappa: tuple[float, float],
    prev_control: Array | None = None,
) -> float:
    """Eq. (S2) for a plan; ``states`` (T+1, 2·dim) includes x_{t|t} at row 0 (not costed)."""
    states = np.asarray(states, dtype=float)
    controls = np.asarray(controls, dtype=float)
    dim = controls.shape[1]
    g = np.asarray(goal_center, dtype=float)[:dim]
    u_prev = np.zeros(dim) if prev_control is None else np.asarray(prev_control, dtype=float)
    pos = states[1:, :dim]
    du = np.diff(np.vstack([u_prev, controls]), axis=0)
    return float(kappa[0] * np.sum((pos - g) ** 2) + kappa[1] * np.sum(du**2))


@overload
def check_request(state: Array, hulls: Sequence[Polytope], objective: Objective,
                  prev_control: Array | None,
                  dim: Literal[2] = 2) -> tuple[Array, Array, tuple[Polytope, ...]] | str: ...


@overload
def check_request(state: Array, hulls: Sequence[Prism], objective: Objective,
                  prev_control: Array | None,
                  dim: Literal[3]) -> tuple[Array, Array, tuple[Prism, ...]] | str: ...


def check_request(state: Array, hulls: Sequence[Obstacle], objective: Objective,
                  prev_control: Array | None,
                  dim: int = 2) -> tuple[Array, Array, tuple[Obstacle, ...]] | str:
    """(x_t, u_{t|t}, hulls) as arrays and a tuple, or why the request is invalid: x_t of
    2·``dim`` numbers, u_{t|t} of ``dim``, polygons in 2-D and prisms in 3-D."""
    x0 = np.asarray(state, dtype=float)
    if x0.shape != (2 * dim,) or not np.all(np.isfinite(x0)):
        return f"state must be {2 * dim} finite numbers, got {state}"
    u_prev = np.zeros(dim) if prev_control is None else np.asarray(prev_control, dtype=float)
    if u_prev.shape != (dim,) or not np.all(np.isfinite(u_prev)):
        return f"prev_control must be {dim} finite numbers, got {prev_control}"
    if not isinstance(objective, Objective):
        return f"unknown objective {objective!r}"
    hull_t = tuple(hulls)
    kind = Polytope if dim == 2 else Prism
    if not all(isinstance(h, kind) for h in hull_t):
        return f"hulls must be {kind.__name__} instances"
    return x0, u_prev, hull_t


def disjunction_margin(points: Array, hulls: Sequence[Obstacle], eps: float) -> float:
    """min over points and hulls of max_l (α_l·p − β_l) − ε: ≥ 0 iff Eq. (P2_3)-(P2_4) hold (m);
    every face of each hull, the six of a cuboid in 3-D (points (n, 2) or (n, 3), as the
    hulls' normals)."""
    if not hulls:
        return float("inf")
    pts = np.asarray(points, dtype=float).reshape(-1, hulls[0].A.shape[1])
    if not len(pts):
        return float("inf")
    a = np.vstack([h.A for h in hulls])
    b = np.concatenate([h.b for h in hulls])
    starts = np.cumsum([0] + [h.n_faces for h in hulls[:-1]])
    return float(np.min(np.maximum.reduceat(pts @ a.T - b, starts, axis=1))) - eps


def _boxes(hulls: Sequence[Obstacle], dim: int) -> tuple[Array, Array]:
    """The hulls' bounding boxes (lo, hi), (H, dim) each (m)."""
    if dim == 2:
        return hull_boxes(hulls)  # type: ignore[arg-type]
    boxes = [h.box for h in hulls if isinstance(h, Prism)]
    return (np.array([b[0] for b in boxes]).reshape(-1, 3),
            np.array([b[1] for b in boxes]).reshape(-1, 3))


def verify_p2_plan(states: Array, controls: Array, hulls: Sequence[Obstacle],
                   dynamics: DynamicsParams, epsilon_m: float, d_safe_m: float,
                   area_size_m: float | None, tol: float = 1e-6,
                   rolled_out: bool = False, band: AltitudeBand | None = None) -> Verdict:
    """Every check a System 2 plan must pass before it is returned as OK.

    :func:`dualpilot.verify.verify_trajectory` (Eq. (1), U and X, exact
    segment clearance ≥ ``d_safe_m``; in 3-D the ``band``), then Eq. (P2_3)-(P2_4) at every
    planned position p_{t+1|t}..p_{t+T|t} against the true hull faces
    (max_l α·p − β ≥ ε − tol), then the area bounds (the plane) unless ``area_size_m`` is
    None. Hulls provably clear of every segment (by a bounding-box lower bound) are
    skipped by the segment check only. ``rolled_out``: the caller made ``states`` by
    :func:`dualpilot.model.dynamics.rollout` of ``controls`` (Eq. (1) holds exactly).
    """
    dim = dynamics.dim
    pts = np.asarray(states, dtype=float).reshape(-1, 2 * dim)[:, :dim]
    if len(pts) > 1 and np.all(np.isfinite(pts)):
        # skip hulls that provably keep the clearance: every point of segment k lies
        # within L_k / 2 of an end, so dist(segment, hull) ≥ min(d_k, d_k+1) − L_k / 2
        # with d the (smaller) distance of each sample to the hull's bounding box
        half = 0.5 * np.linalg.norm(np.diff(pts, axis=0), axis=1)
        kept: list[Obstacle] = []
        if hulls:
            lo, hi = _boxes(hulls, dim)  # (H, dim) each
            gap = np.maximum(0.0, np.maximum(lo[:, None, :] - pts[None],
                                             pts[None] - hi[:, None, :]))
            d = (np.hypot(gap[..., 0], gap[..., 1]) if dim == 2
                 else np.sqrt(np.sum(gap * gap, axis=-1)))  # (H, points)
            near = np.min(np.minimum(d[:, :-1], d[:, 1:]) - half, axis=1) < d_safe_m + 1.0
            kept = [h for h, k in zip(hulls, near.tolist(), strict=True) if k]
    else:
        kept = list(hulls)
    verdict = verify_trajectory(states, controls, kept, dynamics,  # type: ignore[arg-type]
                                clearance_m=d_safe_m, rolled_out=rolled_out, band=band)
    if not verdict.ok:
        return verdict
    pos = np.asarray(states, dtype=float)[1:, :dim]
    margin = disjunction_margin(pos, hulls, epsilon_m)
    if margin < -tol:
        return Verdict(False, f"ε-disjunction of (P2) violated by {-margin:.3g} m",
                       verdict.clearance_m)
    flat = pos[:, :2]
    if area_size_m is not None and (np.any(flat < -tol) or np.any(flat > area_size_m + tol)):
        return Verdict(False, "a planned position leaves the area", verdict.clearance_m)
    return verdict
