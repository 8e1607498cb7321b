"""The run-time safety monitor of the one step (simplex style): no plan is flown unchecked.

Whoever computed a plan (a planner in this process, a planner service over
the network, an impostor on the bus), the step checks it itself before a
setpoint leaves (:func:`check_plan`). A plan is accepted only if

1. its shapes are (T+1, 2·dim) states and (T, dim) controls, T ≥ 1, all finite;
2. it **starts at the measured state**: ‖x_{t|t} − x_t‖_∞ ≤ ``start_tol`` plus the
   spec's ``measurement_tol`` (what the plant's measurement noise lets two measurements
   of one state differ by, :func:`dualpilot.plant.reading.measurement_tol`; 0 for exact
   measurements);
3. it **follows Eq. (1)** step by step: ‖x_{k+1} − (Φ x_k + Γ u_k)‖_∞ ≤
   ``dynamics_tol`` for every k (no clipping: a plan that needs the
   autopilot's clip is not the plan that will be flown);
4. it keeps **|u| ≤ u_max** per axis and **|v| ≤ v_max** per axis, or ‖v‖ ≤ v_max
   under ``DynamicsParams.speed_limit = "norm"`` (+ ``limit_tol``);
5. every planned position lies **in the area** [0, area]² (± ``area_tol_m``), and in 3-D
   every planned altitude **in the band** [floor, ceiling] (± ``area_tol_m``);
6. **every segment** of the planned polyline keeps at least d_safe from each
   obstacle the step itself sent (the fire regions and hulls △(C^i_{1:t}) of
   :meth:`dualpilot.model.fire.FireSnapshot.obstacles_for`: polygons in 2-D, prisms in
   3-D, :class:`~dualpilot.model.segment3.SegmentChecker3`), checked exactly.

A risk-aware plan that says it met the fire forecast's chance constraint
(``info["risk"] == "met"``, dualpilot/model/risk.py) is also checked against the
zones of the forecast the step sent with its request (:func:`check_risk`): System
2's positions p_τ (τ ≥ 2) keep ε from the zones of their steps, and System 1's
trajectory keeps from the zones of its steps the distance it reports. In 3-D the zones
are as tall as the spec's ``zone_heights`` says (dualpilot/model/zone_heights.py): under
the default ``risk_zone_height = "band"`` they are footprints checked against the plan's
planar positions (zones taller than any altitude, the stricter check); with heights they
are prisms and the distances are the exact 3-D ones, as the planners measure them.

The honest planners verify their own plans with stricter checks (the
planners' clearance, dualpilot/verify.py), so the monitor rejects none of
theirs: it is the independent second check against a planner that is wrong,
compromised or impersonated. A rejected plan is a failed plan (status UNSAFE
with the monitor's reason): the step asks the fallback system, then brakes.
Tolerances are in m and m/s (states) and N (controls).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from dualpilot.mission.answers import MONITOR_TAG, Answer, SystemStatus
from dualpilot.model.dynamics import Array, DynamicsParams, transition_matrices
from dualpilot.model.geometry import Polytope, path_clearance
from dualpilot.model.prism import Prism
from dualpilot.model.risk import ForecastView, RiskParams, path_risk_clearance, risk_map
from dualpilot.model.segment3 import prism_path_clearance
from dualpilot.plan import Plan
from dualpilot.spec import MissionSpec

#: prefix of every plan status and message the monitor writes ("s2:unsafe[monitor: …]")
TAG = MONITOR_TAG


@dataclass(frozen=True)
class MonitorParams:
    """The monitor's tolerances (stated, not hidden)."""

    #: how far (m, m/s, ∞-norm) the plan's first state may be from the measured one
    start_tol: float = 1e-3
    #: one-step residual of Eq. (1) allowed (m, m/s, ∞-norm): float round-off only
    dynamics_tol: float = 1e-3
    #: allowance on |u| ≤ u_max (N) and |v| ≤ v_max (m/s)
    limit_tol: float = 1e-3
    #: allowance on the area bounds (m)
    area_tol_m: float = 1e-3
    #: allowance on the d_safe clearance (m)
    clearance_tol_m: float = 1e-6


@dataclass(frozen=True)
class MonitorVerdict:
    ok: bool
    reason: str
    clearance_m: float = float("nan")


def one_step_residual(states: Array, controls: Array, dyn: DynamicsParams) -> float:
    """max_k ‖x_{k+1} − (Φ x_k + Γ u_k)‖_∞ (Eq. (1) without clipping)."""
    phi, gamma = transition_matrices(dyn)
    predicted = states[:-1] @ phi.T + controls @ gamma.T
    return float(np.abs(predicted - states[1:]).max())


def check_plan(
    states: Array,
    controls: Array,
    measured: Array,
    obstacles: Sequence[Polytope] | Sequence[Prism],
    spec: MissionSpec,
    params: MonitorParams = MonitorParams(),
) -> MonitorVerdict:
    """Accept or reject a plan before it is flown (module docstring); pure."""
    dyn = spec.dynamics
    n = dyn.dim
    states = np.asarray(states, dtype=float)
    controls = np.asarray(controls, dtype=float)
    measured = np.asarray(measured, dtype=float)
    if (states.ndim != 2 or states.shape[1] != 2 * n or controls.ndim != 2
            or controls.shape[1] != n or len(controls) < 1 or len(states) != len(controls) + 1):
        return MonitorVerdict(False, f"bad shapes {states.shape} / {controls.shape}")
    if not (np.isfinite(states).all() and np.isfinite(controls).all()):
        return MonitorVerdict(False, "non-finite values")
    off = float(np.abs(states[0] - measured).max())
    if off > params.start_tol + spec.measurement_tol:
        return MonitorVerdict(False, f"starts {off:.3g} from the measured state")
    u = float(np.abs(controls).max())
    if u > dyn.u_max_n + params.limit_tol:
        return MonitorVerdict(False, f"|u| {u:.4g} N exceeds {dyn.u_max_n:g} N")
    v = float(dyn.speeds(states[1:, n:]).max())  # max |v_i|, or ‖v‖ under "norm"
    if v > dyn.v_max_mps + params.limit_tol:
        return MonitorVerdict(False, f"|v| {v:.4g} m/s exceeds {dyn.v_max_mps:g} m/s")
    resid = one_step_residual(states, controls, dyn)
    if resid > params.dynamics_tol:
        return MonitorVerdict(False, f"violates Eq. (1) by {resid:.3g}")
    pos = states[:, :n]
    lo, hi = -params.area_tol_m, spec.area_size_m + params.area_tol_m
    if (pos[1:, :2] < lo).any() or (pos[1:, :2] > hi).any():
        return MonitorVerdict(False, "leaves the area")
    if n == 3:
        verdict = _in_band(pos[1:, 2], spec, params)
        if verdict is not None:
            return verdict
        if not all(isinstance(o, Prism) for o in obstacles):
            return MonitorVerdict(False, "a 3-D plan checked against planar obstacles")
        clearance = prism_path_clearance(pos, list(obstacles))  # type: ignore[arg-type]
    else:
        clearance = path_clearance(pos[:, :2], list(obstacles))  # type: ignore[arg-type]
    if clearance < spec.d_safe_m - params.clearance_tol_m:
        return MonitorVerdict(False, f"passes {clearance:.2f} m from a fire region or hull "
                                     f"(d_safe {spec.d_safe_m:g} m)", clearance)
    return MonitorVerdict(True, "ok", clearance)


def _in_band(z: Array, spec: MissionSpec, params: MonitorParams) -> MonitorVerdict | None:
    """None when every planned altitude ``z`` (m) lies in the spec's band (± the area's
    allowance), else the refusal."""
    band, tol = spec.band, params.area_tol_m
    if len(z) and float(z.min()) < band.floor_m - tol:
        return MonitorVerdict(False, f"leaves the altitude band: {float(z.min()):.2f} m below "
                                     f"the floor {band.floor_m:g} m")
    if len(z) and float(z.max()) > band.ceiling_m + tol:
        return MonitorVerdict(False, f"leaves the altitude band: {float(z.max()):.2f} m above "
                                     f"the ceiling {band.ceiling_m:g} m")
    return None


def check(plan: Plan, measured: Array, obstacles: Sequence[Polytope] | Sequence[Prism],
          spec: MissionSpec, params: MonitorParams = MonitorParams()) -> MonitorVerdict:
    """:func:`check_plan` of an OK plan's states and controls."""
    return check_plan(plan.states, plan.controls, measured, obstacles, spec, params)


#: the risk-aware planners' chance constraint (dualpilot.planners builds them with it)
PLANNER_RISK = RiskParams()


def check_risk(plan: Plan, view: ForecastView | None, spec: MissionSpec,
               risk: RiskParams = PLANNER_RISK,
               params: MonitorParams = MonitorParams()) -> MonitorVerdict:
    """Accept a plan unless it says it met the chance constraint on ``view`` and does not;
    pure.

    System 2 ("fast+risk") promises that p_τ (τ = 2..T) keeps ε from every zone of step τ:
    checked exactly. System 1 ("rrt+risk") promises it of its reference path timed at the
    reference speed, which a plan does not carry (the path is shortcut after the check);
    what is checked is the distance its trajectory keeps from the zones of its steps, which
    it reports (``info["risk_clearance_m"]``): a plan that misstates it is refused.
    """
    if view is None or plan.info.get("risk") != "met":
        return MonitorVerdict(True, "ok")
    zones = risk_map(view, risk, spec)
    pos = np.asarray(plan.states, dtype=float)[:, :2 if zones.planar else 3]
    if plan.system == 1:
        worst = path_risk_clearance(zones, pos)
        said = plan.info.get("risk_clearance_m")
        if not isinstance(said, (int, float)) or not (
                abs(float(said) - worst) <= params.clearance_tol_m or said == worst):
            return MonitorVerdict(False, f"says its trajectory keeps {said} m from the "
                                         f"forecast risk zones, it keeps {worst:.3f} m", worst)
        return MonitorVerdict(True, "ok", worst)
    eps = spec.clearance_m
    worst = float("inf")
    for tau in range(2, min(len(pos) - 1, view.last_step) + 1):
        for zone in zones.zones(tau):
            worst = min(worst, zone.distance(pos[tau]))
    if worst < eps - params.clearance_tol_m:
        return MonitorVerdict(False, f"p_tau passes {worst:.2f} m from a forecast risk zone "
                                     f"of its step (alpha {risk.alpha:g}, eps {eps:g} m)", worst)
    return MonitorVerdict(True, "ok", worst)


def status_note(verdict: MonitorVerdict) -> str:
    """The rejection as it goes into a plan status (no ';', the status separator)."""
    return f"[{TAG}: {verdict.reason.replace(';', ',')}]"


def refusal(system: int, verdict: MonitorVerdict) -> Answer:
    """System ``system``'s plan as the monitor refused it: UNSAFE, with the reason."""
    return Answer(system, SystemStatus.UNSAFE, status_note(verdict))
