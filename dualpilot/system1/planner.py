"""System 1, Sec. III-A: the fast, human-like planner (operator waypoints or Alg. 1, then LQR).

Each call of :meth:`System1.plan` picks a reference path from the UAV's
position into the goal region G and tracks it with the LQR of
:mod:`dualpilot.system1.lqr` over the horizon T, giving a predicted trajectory.
Where the reference path comes from, in order:

1. **Operator waypoints** (:meth:`System1.set_waypoints`), the paper's
   first responder, when every segment of current position → remaining
   waypoints keeps the spec's ``clearance_m`` from every hull (exact checks).
2. **The previous RRT path**, from the point nearest the UAV onward, while
   it stays free and the UAV is within ``reuse_max_offset_m`` of it
   (``reuse_path``): an operator keeps a path while it is safe.
3. **A fresh RRT path** (Alg. 1, :func:`dualpilot.system1.rrt.plan_path`).

The predicted trajectory is verified independently
(:func:`dualpilot.verify.verify_trajectory` at the spec's d_safe): a trajectory
that cuts a corner too close is retried at a lower reference speed, then
with a fresh RRT path; a plan that never verifies is returned as UNSAFE,
never as OK. The attention's objective does not change System 1 (it
optimises response time only). ``prev_control`` (u_{t|t}) is unused by the
paper's tracker; ``tracker="lqr_du"`` starts its Δu-penalising LQR from it
(:func:`dualpilot.system1.lqr.lqr_du_gain`).

In 3-D (``spec.dim == 3``, docs/three_d.md) the hulls are prisms, positions and paths
carry the altitude, a fresh path comes from :func:`dualpilot.system1.altitude.plan_in_band`
by the reading ``altitude`` (``s1_altitude``: the slice at the UAV's altitude first, or
the 3-D tree at once), the LQR runs per axis with the planar DARE's scalars
(:func:`dualpilot.system1.lqr.tracker_gain`) and the check keeps the altitude band.
Operator waypoints keep their altitude; a planar list is flown at the UAV's altitude.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace
from typing import Literal

import numpy as np

from dualpilot.arrays import Array
from dualpilot.model.dynamics import check_state
from dualpilot.model.prism import Prism
from dualpilot.model.risk import ArcRisk, ForecastView, RiskParams, path_risk_clearance, risk_map
from dualpilot.model.segment3 import SegmentChecker3
from dualpilot.model.vertical import S1Altitude
from dualpilot.plan import Objective, Obstacles, Plan, PlanStatus
from dualpilot.spec import MissionSpec, Stream
from dualpilot.system1.altitude import plan_in_band
from dualpilot.system1.lqr import R_DELTA_U, LqrParams, reference_states, track, tracker_gain
from dualpilot.system1.rrt import RrtParams, RrtResult, SegmentChecker, plan_path
from dualpilot.verify import verify_trajectory


@dataclass(frozen=True)
class System1Params:
    """Sec. IV-A values (step 15 m, Q = 2·I, R = 0.1·I, T = 80) and our readings.

    ``max_iterations`` is 2000 instead of the paper's 500 (see
    :class:`dualpilot.system1.rrt.RrtParams`); ``max_cpu_s`` bounds the RRT's CPU time (s).
    ``ref_speed_mps`` is the speed along the path (≤ 15 m/s per axis holds
    for any heading); ``speed_retries`` halvings are tried when the tracked
    trajectory fails verification at the spec's d_safe. The clearance of
    the paths and d_safe come from the :class:`dualpilot.spec.MissionSpec`.
    ``reach_check`` lets the RRT answer "no path" at once when a grid proves
    G unreachable (:mod:`dualpilot.system1.reach`).
    ``tracker`` is "lqr" (the paper's, u = u_ff − K(x − x̂)) or "lqr_du" (ours,
    for a smooth handover: the LQR on x augmented with the previous control,
    weight ``r_delta_u`` on Δu, started from ``prev_control``; see
    :func:`dualpilot.system1.lqr.lqr_du_gain`); ``r_delta_u`` is unused by "lqr".
    ``altitude`` is the reading ``s1_altitude`` of a 3-D mission
    (:mod:`dualpilot.system1.altitude`).
    """

    step_size_m: float = 15.0
    max_iterations: int = 2000
    horizon: int = 80
    ref_speed_mps: float = 12.0
    q_lqr: float = 2.0
    r_lqr: float = 0.1
    goal_bias: float = 0.05
    max_cpu_s: float = 2.0
    speed_retries: int = 2
    feedforward: bool = True
    accel_mps2: float = 3.0
    decel_mps2: float = 2.0
    reuse_path: bool = True
    reuse_max_offset_m: float = 50.0
    shortcut: bool = True
    aim_goal_center: bool = True
    reach_check: bool = True
    tracker: Literal["lqr", "lqr_du"] = "lqr"
    r_delta_u: float = R_DELTA_U
    altitude: S1Altitude = "slice-first"

    def __post_init__(self) -> None:
        if self.horizon < 1:
            raise ValueError(f"horizon must be >= 1, got {self.horizon}")
        if not (self.ref_speed_mps > 0 and self.speed_retries >= 0):
            raise ValueError("ref_speed_mps > 0 and speed_retries >= 0 are required")
        if self.reuse_max_offset_m < 0:
            raise ValueError("reuse_max_offset_m must be >= 0")
        if self.tracker not in ("lqr", "lqr_du"):
            raise ValueError(f"tracker must be 'lqr' or 'lqr_du', got {self.tracker!r}")
        if not (self.r_delta_u >= 0 and np.isfinite(self.r_delta_u)):
            raise ValueError(f"r_delta_u must be finite and >= 0, got {self.r_delta_u}")
        if self.altitude not in ("slice-first", "volume"):
            raise ValueError(f"altitude must be 'slice-first' or 'volume', not {self.altitude!r}")
        self.rrt_params()  # validates the RRT fields
        self.lqr_params()

    def rrt_params(self) -> RrtParams:
        return RrtParams(
            step_size_m=self.step_size_m, max_iterations=self.max_iterations,
            goal_bias=self.goal_bias, max_cpu_s=self.max_cpu_s,
            shortcut=self.shortcut, aim_goal_center=self.aim_goal_center,
            reach_check=self.reach_check,
        )

    def lqr_params(self) -> LqrParams:
        return LqrParams(q=self.q_lqr, r=self.r_lqr, feedforward=self.feedforward,
                         accel_mps2=self.accel_mps2, decel_mps2=self.decel_mps2)


class _TrackedPath:
    """A stored polyline and the UAV's progress along it (monotone segment index)."""

    def __init__(self, points: Array, dim: int = 2):
        self.points = np.asarray(points, dtype=float).reshape(-1, dim)
        self.segment = 0

    def remaining(self, pos: Array) -> tuple[Array, float]:
        """Reference pos → nearest path point (at/after the progress) → rest, and the offset (m)."""
        pts = self.points
        if len(pts) == 1:
            return _dedup(np.vstack([pos, pts])), _hypot(pts[0] - pos)
        a, c = pts[self.segment:-1], pts[self.segment + 1:]
        ac = c - a
        len2 = np.einsum("ij,ij->i", ac, ac)
        t = np.clip(np.einsum("ij,ij->i", pos - a, ac) / np.where(len2 > 0, len2, 1.0), 0, 1)
        proj = a + t[:, None] * ac
        dist = np.linalg.norm(proj - pos, axis=1)
        j = int(len(dist) - 1 - np.argmin(dist[::-1]))  # ties: the later segment
        self.segment += j
        ref = np.vstack([pos, proj[j], pts[self.segment + 1:]])
        return _dedup(ref), float(dist[j])


def _hypot(d: Array) -> float:
    """‖d‖ (m) of a 2- or 3-vector: np.hypot, nested in 3-D (so a level 3-vector's is the
    planar number bit for bit)."""
    h = np.hypot(d[0], d[1])
    return float(h if len(d) == 2 else np.hypot(h, d[2]))


def _dedup(points: Array, tol: float = 1e-6) -> Array:
    keep = np.concatenate([[True], np.linalg.norm(np.diff(points, axis=0), axis=1) > tol])
    return np.asarray(points[keep])


class System1:
    """The fast planner: operator waypoints or an RRT path, tracked by LQR.

    Parameters
    ----------
    spec : MissionSpec
        Goal G, area, the paths' clearance, d_safe and Eq. (1).
    params : System1Params
        Sec. IV-A values and our readings.
    rng : numpy.random.Generator, optional
        Drives every RRT sample (default: ``spec.rng(Stream.SYSTEM1)``); the
        same seed reproduces the same plans.
    """

    system = 1
    method = "rrt"

    def __init__(self, spec: MissionSpec, params: System1Params = System1Params(),
                 rng: np.random.Generator | None = None):
        dynamics = spec.dynamics
        self.spec = spec
        self.area = spec.area
        self.goal = spec.goal
        self.rng = spec.rng(Stream.SYSTEM1) if rng is None else rng
        self.params = params
        self.dyn = dynamics
        self.area_size_m = spec.area_size_m
        self.clearance_m = spec.clearance_m  # PathFree's margin (Alg. 1)
        self.d_safe_m = spec.d_safe_m  # what every returned trajectory keeps
        if params.tracker == "lqr":
            self.gain = tracker_gain(dynamics, params.q_lqr, params.r_lqr)
        else:
            self.gain = tracker_gain(dynamics, params.q_lqr, params.r_lqr, params.r_delta_u)
            self.method = "rrt+du"
        self._rrt_params = params.rrt_params()
        self._lqr_params = params.lqr_params()
        self._waypoints: Array | None = None
        self._operator: _TrackedPath | None = None
        self._rrt_path: _TrackedPath | None = None
        #: the forecast's risk along paths (:class:`RiskSystem1`; None: the paper's planner)
        self._arc: ArcRisk | None = None

    # -- operator input -------------------------------------------------------------
    def set_waypoints(self, waypoints: Array | None) -> None:
        """Operator waypoints (k, 2) in the local frame (m); None clears them.

        In 3-D a waypoint may carry its altitude (k, 3) (m above ground, the relative
        frame of the mission items), within the band; a planar list (k, 2) is flown at
        the UAV's altitude when it is anchored (the next :meth:`plan`).
        Raises ValueError for an empty list, a wrong shape, non-finite values
        or a waypoint outside the area (or the band). Whether they are safe is judged at
        each :meth:`plan` against the hulls of the moment.
        """
        if waypoints is None:
            self._waypoints = None
            self._operator = None
            return
        wps = np.asarray(waypoints, dtype=float)
        widths = (2,) if self.dyn.dim == 2 else (2, 3)
        if wps.ndim != 2 or wps.shape[1] not in widths or len(wps) == 0:
            raise ValueError(f"waypoints must have shape (k >= 1, "
                             f"{' or '.join(map(str, widths))}), got {wps.shape}")
        if not np.all(np.isfinite(wps)):
            raise ValueError("waypoints must be finite")
        if not all(self.area.contains(w) for w in wps):
            raise ValueError(f"waypoints must lie inside the {self.area_size_m} m area")
        band = self.spec.band
        if wps.shape[1] == 3 and not all(band.contains(z) for z in wps[:, 2]):
            raise ValueError(f"waypoints' altitudes must lie in the band "
                             f"[{band.floor_m:g}, {band.ceiling_m:g}] m")
        self._waypoints = wps.copy()
        self._operator = None  # anchored at the UAV's position at the next plan()

    @property
    def waypoints(self) -> Array | None:
        return None if self._waypoints is None else self._waypoints.copy()

    # -- planning -------------------------------------------------------------------
    def plan(
        self,
        state: Array,
        hulls: Obstacles,
        objective: Objective = Objective.MISSION_TIME,
        prev_control: Array | None = None,
    ) -> Plan:
        """Plan from ``state`` [p, v] avoiding ``hulls`` (see the module docstring): planar
        hulls and [px, py, vx, vy] in 2-D, prisms and [px, py, pz, vx, vy, vz] in 3-D.

        Raises ValueError for a malformed or non-finite state, a position
        outside the area, or one nearer than d_safe to a hull.
        Status NO_PATH when Alg. 1 finds no path within its caps, UNSAFE when
        no tracked trajectory passes verification.
        """
        t0 = time.perf_counter()
        x = check_state(state, self.dyn)
        u_prev = self._prev_control(prev_control)
        pos = x[:self.dyn.dim].copy()
        checker = self._checker(hulls)
        first_need = self._first_need(pos, checker)
        info: dict[str, object] = {"rrt_iterations": 0, "reused": False}
        candidates = self._stored_candidates(pos, checker, first_need, info)
        attempts: list[str] = []
        fresh_tried = False
        while True:
            if not candidates:
                if fresh_tried:
                    break
                fresh_tried = True
                result = self._run_rrt(pos, hulls, checker)
                info.update(rrt_iterations=result.iterations, rrt_status=result.status,
                            rrt_time_s=result.time_s)
                if result.path is None:
                    self._rrt_path = None
                    return self._failed(PlanStatus.NO_PATH, t0, info,
                                        f"RRT found no path ({result.status}, "
                                        f"{result.iterations} iterations)")
                candidates.append(("rrt", result.path))
            source, ref = candidates.pop(0)
            traj = self._track(x, ref, hulls, attempts, source, checker, u_prev)
            if traj is not None:
                return self._tracked_plan(source, ref, traj, info, attempts, t0)
        self._rrt_path = None
        info["attempts"] = attempts
        return self._failed(PlanStatus.UNSAFE, t0, info,
                            "no tracked trajectory kept d_safe: " + "; ".join(attempts))

    # -- planning stages ------------------------------------------------------------
    def _prev_control(self, prev_control: Array | None) -> Array | None:
        """u₋₁ (N) of the Δu tracker (zeros when not given); None for the paper's tracker."""
        if self.params.tracker != "lqr_du":
            return None
        u_prev = np.zeros(self.dyn.dim) if prev_control is None else np.asarray(
            prev_control, dtype=float)
        if u_prev.shape != (self.dyn.dim,) or not np.all(np.isfinite(u_prev)):
            raise ValueError(f"prev_control must be finite with shape "
                             f"({self.dyn.dim},), got {prev_control}")
        return u_prev

    def _first_need(self, pos: Array, checker: SegmentChecker | SegmentChecker3) -> float:
        """The clearance (m) the first reference segment keeps: ``clearance_m`` or the start's.

        Raises ValueError for a position outside the area or nearer than d_safe to a hull.
        """
        if not self.area.contains(pos):
            raise ValueError(f"position {pos} lies outside the {self.area_size_m} m area")
        d_start = checker.point_distance(pos)
        if d_start < self.d_safe_m:
            raise ValueError(
                f"position {pos} lies {d_start:.1f} m from a fire hull "
                f"(System 1 needs {self.d_safe_m} m)"
            )
        return min(self.clearance_m, d_start)

    def _stored_candidates(self, pos: Array, checker: SegmentChecker | SegmentChecker3,
                           first_need: float,
                           info: dict[str, object]) -> list[tuple[str, Array]]:
        """The operator's waypoints, else the previous RRT path, while free (sources 1-2).

        A rejected operator path is noted in ``info``; a reused path that is no
        longer free or too far (``reuse_max_offset_m``) is dropped.
        """
        p = self.params
        candidates: list[tuple[str, Array]] = []
        if self._waypoints is not None:
            if self._operator is None:
                wps = self._waypoints
                if wps.shape[1] < len(pos):  # a planar list, at the UAV's altitude
                    wps = np.column_stack([wps, np.full(len(wps), pos[2])])
                self._operator = _TrackedPath(np.vstack([pos, wps]), len(pos))
            ref, _ = self._operator.remaining(pos)
            if self._path_free(ref, checker, first_need):
                candidates.append(("operator", ref))
            else:
                info["operator_rejected"] = "a segment comes within clearance_m of a hull"
        if not candidates and p.reuse_path and self._rrt_path is not None:
            ref, offset = self._rrt_path.remaining(pos)
            if offset <= p.reuse_max_offset_m and self._path_free(ref, checker, first_need):
                candidates.append(("reuse", ref))
            else:
                self._rrt_path = None
        return candidates

    def _tracked_plan(self, source: str, ref: Array, traj: tuple[Array, Array, float, float],
                      info: dict[str, object], attempts: list[str], t0: float) -> Plan:
        """The OK plan of the verified LQR trajectory ``traj`` along ``ref`` from ``source``."""
        states, controls, speed, clearance = traj
        if source == "rrt":
            self._rrt_path = _TrackedPath(ref, self.dyn.dim)
        info.update(source="operator" if source == "operator" else "rrt",
                    reused=source == "reuse", ref_speed_mps=speed,
                    clearance_m=clearance, attempts=attempts)
        return Plan(
            system=self.system, status=PlanStatus.OK, states=states, controls=controls,
            compute_time_s=time.perf_counter() - t0, path=ref,
            message=f"{info['source']} path tracked at {speed:g} m/s", info=info,
        )

    # -- helpers --------------------------------------------------------------------
    def _checker(self, hulls: Obstacles) -> SegmentChecker | SegmentChecker3:
        """The exact checker of ``hulls``: planar hulls in 2-D, prisms in 3-D (ValueError for
        another kind)."""
        if self.dyn.dim == 2:
            return SegmentChecker(hulls)  # type: ignore[arg-type]
        if not all(isinstance(h, Prism) for h in hulls):
            raise ValueError("a 3-D System 1 avoids prisms, not planar hulls")
        return SegmentChecker3(hulls)  # type: ignore[arg-type]

    def _path_free(self, ref: Array, checker: SegmentChecker | SegmentChecker3,
                   first_need: float) -> bool:
        if len(ref) < 2:
            return checker.point_distance(ref[0]) >= first_need
        need = np.full(len(ref) - 1, self.clearance_m)
        need[0] = first_need
        if not np.all(checker.distances(ref[:-1], ref[1:]) >= need):
            return False
        if self._arc is None:
            return True
        if ref.shape[1] == 3:  # the zones, timed along level paths only
            return bool(np.all(ref[:, 2] == ref[0, 2])) and self._arc.at(
                float(ref[0, 2])).path_clear(ref[:, :2])
        return self._arc.path_clear(ref)

    def _run_rrt(self, pos: Array, hulls: Obstacles,
                 checker: SegmentChecker | SegmentChecker3) -> RrtResult:
        if isinstance(checker, SegmentChecker3):
            return plan_in_band(pos, hulls, self.rng, self.spec,  # type: ignore[arg-type]
                                self._rrt_params, self.params.altitude, checker, self._arc)
        return plan_path(pos, self.goal, hulls, self.rng,  # type: ignore[arg-type]
                         self.clearance_m, self.area_size_m, self._rrt_params,
                         start_clearance_m=self.d_safe_m, checker=checker, risk=self._arc)

    def _along_speed(self, x: Array, ref: Array) -> float:
        """The UAV's speed (m/s) along ``ref``, towards the point 15 m ahead on it (the first
        segment can be a short hop back onto a reused path); in 3-D the planar numbers
        bit for bit on a level path."""
        seg_len = np.linalg.norm(np.diff(ref, axis=0), axis=1)
        cum = np.concatenate([[0.0], np.cumsum(seg_len)])
        s_ahead = min(float(cum[-1]), 15.0)
        n = self.dyn.dim
        ahead = np.array([np.interp(s_ahead, cum, ref[:, d]) for d in range(n)])
        direction = ahead - ref[0]
        if n == 2:
            norm = float(np.hypot(*direction))
            return float(x[2:] @ direction / norm) if norm > 0 else 0.0
        norm = _hypot(direction)
        along = x[3:5] @ direction[:2] + x[5] * direction[2]
        return float(along / norm) if norm > 0 else 0.0

    def _track(self, x: Array, ref: Array, hulls: Obstacles, attempts: list[str],
               source: str, checker: SegmentChecker | SegmentChecker3,
               u_prev: Array | None = None) -> tuple[Array, Array, float, float] | None:
        """LQR-track ``ref`` at the reference speed, halving it on failed verification.

        ``u_prev`` (the Δu tracker's u₋₁) is None for the paper's tracker.
        """
        p = self.params
        v0 = self._along_speed(x, ref)
        band = self.spec.band if self.dyn.dim == 3 else None
        speed = p.ref_speed_mps
        for _ in range(p.speed_retries + 1):
            reference = reference_states(ref, p.horizon, speed, self.dyn, v0, self._lqr_params)
            if u_prev is None:
                states, controls = track(x, reference, self.gain, self.dyn, p.feedforward)
            else:
                states, controls = track(x, reference, self.gain, self.dyn, p.feedforward,
                                         prev_control=u_prev)
            verdict = verify_trajectory(states, controls, hulls, self.dyn, self.d_safe_m,
                                        checker=checker, band=band)
            if verdict.ok:
                return states, controls, speed, verdict.clearance_m
            attempts.append(f"{source}@{speed:g}m/s: {verdict.reason}")
            speed /= 2.0
        return None

    def _failed(self, status: PlanStatus, t0: float, info: dict[str, object],
                message: str) -> Plan:
        plan = Plan.failed(self.system, status, time.perf_counter() - t0, message, self.dyn.dim)
        plan.info.update(info)
        return plan


class RiskSystem1(System1):
    """"rrt+risk" ("rrt+du+risk" with the Δu tracker): System 1 with the fire forecast.

    Operator, reused and RRT paths must also keep ``clearance_m`` from the risk
    zones of the steps in which each piece is flown (:class:`ArcRisk`, timed at
    the reference speed: RRT edges by their tree path length). The tracked
    trajectory is verified against the hulls as by "rrt" (never less); its
    distance from its steps' zones is recorded (``info["risk_clearance_m"]``).
    When no path meets the zones, the "rrt" plan is returned (``info["risk"]``
    says so); without a forecast the method is "rrt".
    """

    uses_forecast = True

    def __init__(self, spec: MissionSpec, params: System1Params = System1Params(),
                 rng: np.random.Generator | None = None, risk: RiskParams | None = None):
        super().__init__(spec, params, rng)
        self.method = f"{self.method}+risk"
        self.risk = risk or RiskParams()

    def plan(self, state: Array, hulls: Obstacles,
             objective: Objective = Objective.MISSION_TIME, prev_control: Array | None = None,
             forecast: ForecastView | None = None) -> Plan:
        if forecast is None:
            return super().plan(state, hulls, objective, prev_control)
        t0 = time.perf_counter()
        risk = risk_map(forecast, self.risk, self.spec)
        self._arc = ArcRisk(risk, self.params.ref_speed_mps, self.dyn.dt_s, self.clearance_m,
                            None if risk.planar else float(state[2]))
        try:
            plan = super().plan(state, hulls, objective, prev_control)
        finally:
            self._arc = None
        note: dict[str, object] = {"risk": "met"}
        if not plan.ok:
            note["risk"] = f"unmet ({plan.status.value})"
            plan = super().plan(state, hulls, objective, prev_control)
        if plan.ok:
            note["risk_clearance_m"] = path_risk_clearance(risk, plan.states[:, :self.dyn.dim])
        return replace(plan, compute_time_s=time.perf_counter() - t0,
                       info={**plan.info, **note})
