"""What the UAV flies without an OK plan: braking, or an escape from a fire too near to plan.

Braking is the force that stops the UAV in one ΔT (Eq. 1): with v_{t+1} = (1 − ζ) v_t +
(ΔT / m) u_t, u = −m (1 − ζ) v_t / ΔT gives v_{t+1} = 0; it is clipped to U (|u_i| ≤ u_max, N).

An escape (``MissionParams.no_plan = "escape"``, :func:`no_plan_control`) is for the case
braking cannot mend: the UAV is so near a hull that the planners refuse its start
(``invalid_input``: "no safe plan can start here"), so every next step brakes again while the
fire spreads towards it. When braking would leave the UAV within the planners' clearance of
a hull, the step flies instead the force that puts it farthest from the hulls once it has
braked after it: among braking and :data:`ESCAPE_HEADINGS` horizontal headings at the
largest force U and the speed limit allow, the one whose position two steps of Eq. (1) on
(this control, then braking) is farthest from every hull and inside the area. A heading is
flown only when it lands strictly farther than braking; in 3-D its vertical force is
braking's, so an escape never climbs or sinks out of the band.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from dualpilot.model.dynamics import Array, DynamicsParams, step
from dualpilot.model.geometry import Rect
from dualpilot.plan import Plan, PlanStatus

#: the horizontal headings an escape tries, evenly spaced from east (22.5° apart)
ESCAPE_HEADINGS = 16
#: bisection steps for the largest force along a heading that keeps the speed limit
_BISECTIONS = 30


def brake_control(state: Array, dyn: DynamicsParams) -> Array:
    """The force (N) that brings the velocity to zero in one ΔT, clipped to U."""
    v = state[dyn.dim :]
    u = -dyn.mass_kg * (1.0 - dyn.zeta) * v / dyn.dt_s
    return np.asarray(np.clip(u, -dyn.u_max_n, dyn.u_max_n))


def braking_overshoot_m(dynamics: DynamicsParams, max_steps: int = 1000) -> float:
    """How far (m) the UAV travels along one axis while braking (:func:`brake_control`, Eq. (1))
    from that axis's speed limit v_max until at rest: how far past a bound a braking plan
    started on it may carry the vehicle (19.86 m at the paper's values: 15 m, then 4.86 m)."""
    state = np.zeros(2 * dynamics.dim)
    state[-1] = dynamics.v_max_mps
    for _ in range(max_steps):
        if abs(state[-1]) < 1e-9:
            break
        state = step(state, brake_control(state, dynamics), dynamics)
    return float(state[dynamics.dim - 1])


def braking_plan(state: Array, steps: int, dynamics: DynamicsParams) -> Plan:
    """The UAV braking for ``steps`` steps (system 0: no planner's)."""
    states, controls = [np.asarray(state, dtype=float)], []
    for _ in range(steps):
        u = brake_control(states[-1], dynamics)
        controls.append(u)
        states.append(step(states[-1], u, dynamics))
    return Plan(0, PlanStatus.OK, np.array(states), np.array(controls), 0.0)


def _largest_force(state: Array, direction: Array, base: Array, dyn: DynamicsParams
                   ) -> Array | None:
    """``base + s·direction`` (N) with the largest s in [0, u_max] whose next velocity keeps
    the speed limit (None when not even s = 0 does); ``direction`` has |d_i| ≤ 1, so the
    force stays in U."""
    decay, gain = 1.0 - dyn.zeta, dyn.dt_s / dyn.mass_kg
    v = state[dyn.dim:]

    def keeps(s: float) -> bool:
        return bool(dyn.speeds(decay * v + gain * (base + s * direction)) <= dyn.v_max_mps + 1e-9)

    if keeps(dyn.u_max_n):
        return base + dyn.u_max_n * direction
    if not keeps(0.0):
        return None
    lo, hi = 0.0, dyn.u_max_n  # the next speed is convex in s: the feasible s are [0, s*]
    for _ in range(_BISECTIONS):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if keeps(mid) else (lo, mid)
    return base + lo * direction


def escape_candidates(state: Array, dyn: DynamicsParams) -> list[Array]:
    """The forces (N) an escape weighs: braking first, then each of :data:`ESCAPE_HEADINGS`
    horizontal headings at the largest force U and the speed limit allow (in 3-D with
    braking's vertical force)."""
    brake = brake_control(state, dyn)
    base = np.zeros(dyn.dim)
    if dyn.dim == 3:
        base[2] = brake[2]
    out = [brake]
    for angle in np.arange(ESCAPE_HEADINGS) * (2.0 * np.pi / ESCAPE_HEADINGS):
        direction = np.zeros(dyn.dim)
        direction[:2] = np.cos(angle), np.sin(angle)
        force = _largest_force(state, direction, base, dyn)
        if force is not None:
            out.append(force)
    return out


def braked_landing(state: Array, control: Array, dyn: DynamicsParams) -> Array:
    """Where the UAV is (m) after one ΔT of ``control`` and one of braking (Eq. 1)."""
    after = step(state, control, dyn)
    return np.asarray(step(after, brake_control(after, dyn), dyn)[:dyn.dim])


def no_plan_control(state: Array, dyn: DynamicsParams, distance: Callable[[Array], float],
                    clearance_m: float, area: Rect) -> tuple[Array, bool]:
    """The force (N) to fly with no OK plan under ``no_plan = "escape"``, and whether it is an
    escape (module docstring): braking unless braking lands within ``clearance_m`` (m) of a
    hull by ``distance`` (position → m to the nearest hull) and a heading lands strictly
    farther, inside ``area``."""
    brake = brake_control(state, dyn)
    best, best_m = brake, distance(braked_landing(state, brake, dyn))
    if best_m >= clearance_m:
        return brake, False
    for force in escape_candidates(state, dyn)[1:]:
        landing = braked_landing(state, force, dyn)
        if not area.contains(landing[:2]):
            continue
        d = distance(landing)
        if d > best_m + 1e-9:
            best, best_m = force, d
    return best, best is not brake
