"""A lattice plan smoothed inside a tube around it: the same path, the least change of control.

A lattice plan (:func:`dualpilot.spacetime.plan.lattice_plan`) changes its velocity in
steps of δ, so a path off the lattice's directions zig-zags between two velocities and
Σ‖u_t − u_{t−1}‖² (the energy of Eq. S2) grows with every step. The smoothed plan solves
the QP

    min_u Σ_t ‖u_t − u_{t−1}‖²  (u_{−1} the control applied last)
    s.t.  Eq. (1) from the current state,  |u_i| ≤ u_max,  the speed limit,
          |p_τ − p̂_τ|_∞ ≤ r (the tube around the lattice plan's positions p̂),
          p_T ∈ G (its last position, where the lattice plan lands),

with Clarabel (through cvxpy). If the lattice plan keeps d + √2·r from every box, a
flight whose two ends lie in the tube keeps d (each point of it lies within √2·r of the
lattice flight's point): the smoothed plan is as safe, a fact :func:`smooth` still checks
rather than assumes. Lengths m, forces N.
"""

from __future__ import annotations

import numpy as np

from dualpilot.arrays import Array
from dualpilot.model.dynamics import rollout
from dualpilot.plan import Plan, PlanStatus
from dualpilot.spec import MissionSpec


def smooth(plan: Plan, spec: MissionSpec, prev_control: Array, tube_m: float) -> Plan | None:
    """``plan`` smoothed in a tube of half-side ``tube_m`` (module docstring); None when the QP
    fails or its plan breaks a limit."""
    import cvxpy as cp

    dyn = spec.dynamics
    x0 = np.asarray(plan.states[0], dtype=float)
    horizon = len(plan.controls)
    vel_v0, vel_u, pos_v0, pos_u = _rollout_matrices(dyn.zeta, dyn.dt_s, dyn.mass_kg, horizon)
    u = cp.Variable((horizon, 2))
    v = vel_v0[:, None] * x0[None, 2:] + vel_u @ u  # v_1..v_T
    p = x0[None, :2] + pos_v0[:, None] * x0[None, 2:] + pos_u @ u  # p_1..p_T
    lo, hi = np.array(spec.goal.bounds[:2]) + 1e-3, np.array(spec.goal.bounds[2:]) - 1e-3
    cons = [cp.abs(u) <= dyn.u_max_n - 1e-6, cp.abs(p - plan.states[1:, :2]) <= tube_m,
            p[horizon - 1] >= lo, p[horizon - 1] <= hi]
    if dyn.speed_limit == "norm":
        cons.append(cp.norm(v, 2, axis=1) <= dyn.v_max_mps - 1e-6)
    else:
        cons.append(cp.abs(v) <= dyn.v_max_mps - 1e-6)
    du = cp.vstack([u[:1] - np.asarray(prev_control, dtype=float)[None, :], u[1:] - u[:-1]])
    problem = cp.Problem(cp.Minimize(cp.sum_squares(du)), cons)
    try:
        problem.solve(solver="CLARABEL")
    except cp.error.SolverError:
        return None
    if u.value is None or problem.status != "optimal":
        return None
    controls = np.clip(np.asarray(u.value, dtype=float), -dyn.u_max_n, dyn.u_max_n)
    states = rollout(x0, controls, dyn)
    if (dyn.speeds(states[1:, 2:]) > dyn.v_max_mps + 1e-6).any():
        return None
    return Plan(plan.system, PlanStatus.OK, states, controls, plan.compute_time_s,
                info={**plan.info, "smoothed": True})


def _rollout_matrices(zeta: float, dt: float, mass: float, horizon: int
                      ) -> tuple[Array, Array, Array, Array]:
    """Eq. (1) over ``horizon`` steps as v_k = a_k v_0 + (B u)_k and p_k = p_0 + c_k v_0 +
    (D u)_k, k = 1..T: (a, B, c, D)."""
    keep, gain = 1.0 - zeta, dt / mass
    k = np.arange(1, horizon + 1)
    a = np.asarray(keep ** k, dtype=float)
    expo = k[:, None] - 1 - np.arange(horizon)[None, :]
    b = np.where(expo >= 0, keep ** np.maximum(expo, 0), 0.0) * gain
    before = np.tril(np.ones((horizon, horizon)), -1)  # p_k sums v_1..v_{k−1}, and v_0
    c = dt * (1.0 + before @ a)
    d = dt * (before @ b)
    return a, b, c, d
