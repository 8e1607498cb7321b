"""Braking, what the UAV flies without an OK plan: the force that stops it in one ΔT (Eq. 1).

With v_{t+1} = (1 − ζ) v_t + (ΔT / m) u_t, u = −m (1 − ζ) v_t / ΔT gives v_{t+1} = 0;
it is clipped to U (|u_i| ≤ u_max, N).
"""

from __future__ import annotations

import numpy as np

from dualpilot.model.dynamics import Array, DynamicsParams, step
from dualpilot.plan import Plan, PlanStatus


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
