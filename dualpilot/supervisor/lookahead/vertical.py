"""The lookahead supervisor in 3-D (docs/three_d.md, 8): the known future over the fronts'
footprints, and its planar space-time plans flown at the UAV's altitude.

The known future and the lattice search are planar (:mod:`dualpilot.spacetime`). In 3-D:

* **The search** runs on every front's footprint, as if each prism were taller than the band
  (a UAV at any altitude is at least as far from a prism as from its footprint in the plane,
  so a plan that keeps d in the plane keeps d in 3-D), from the UAV's planar state; its plan
  is flown at the UAV's altitude (:func:`lift_plan`: the planar controls, the vertical axis
  braking the climb the UAV has, under the per-axis limit).
* **Soundness** of a plan (the concurrent choice, or the space-time plan kept): its ground
  track on the known future of the prisms that span the band (and the forecast's cells, as
  tall as every altitude), and its exact 3-D distance from the low prisms of now over the
  same flights (:func:`low_clear`): a plan over a low front is sound when it keeps d above it.

With every prism spanning the band both are the 2-D rule's, on the same boxes, and a plan
from a UAV that does not climb is the 2-D plan at its altitude, bit for bit.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np

from dualpilot.mission.braking import brake_control
from dualpilot.model.altitude import AltitudeBand, lift_controls, lift_state
from dualpilot.model.dynamics import Array, DynamicsParams, step
from dualpilot.model.geometry import Polytope
from dualpilot.model.prism import Prism
from dualpilot.model.segment3 import prism_path_clearance
from dualpilot.plan import Plan
from dualpilot.spec import MissionSpec
from dualpilot.supervisor.concurrent.rule import Obstacles


def footprints(obstacles: Obstacles) -> tuple[Polytope, ...]:
    """Every obstacle in the plane: a prism's base, a polygon as it is."""
    return tuple(o.base if isinstance(o, Prism) else o for o in obstacles)


def spanning(obstacles: Obstacles, band: AltitudeBand) -> tuple[Polytope, ...]:
    """The footprints of the obstacles that block every altitude of ``band`` over their base
    (every polygon of a 2-D mission)."""
    return tuple(o.base if isinstance(o, Prism) else o for o in obstacles
                 if not isinstance(o, Prism) or o.spans(band))


def low(obstacles: Obstacles, band: AltitudeBand) -> tuple[Prism, ...]:
    """The prisms a UAV in ``band`` may pass over (none in 2-D)."""
    return tuple(o for o in obstacles if isinstance(o, Prism) and not o.spans(band))


def low_clear(plan: Plan, prisms: Sequence[Prism], d: float, steps: int) -> bool:
    """Whether the plan's first ``steps`` flights keep ``d`` (m) from ``prisms`` in 3-D."""
    if not prisms:
        return True
    last = min(steps, len(plan.states) - 1)
    return prism_path_clearance(plan.states[: last + 1, :3], list(prisms)) >= d


def planar_spec(spec: MissionSpec) -> MissionSpec:
    """The 2-D mission of a 3-D one (its plane: the same area, goal, ε, d_safe, Eq. (1))."""
    return dataclasses.replace(spec, dynamics=dataclasses.replace(spec.dynamics, dim=2))


def planar(state: Array) -> Array:
    """A state's planar part [p_x, p_y, v_x, v_y] (a 2-D state as it is)."""
    x = np.asarray(state, dtype=float)
    return x if len(x) == 4 else x[[0, 1, 3, 4]]


def lift_plan(plan: Plan, state: Array, dynamics: DynamicsParams) -> Plan | None:
    """The planar ``plan`` flown from the 3-D ``state``: its controls in the plane and, when
    the UAV climbs, the vertical axis braking (:func:`~dualpilot.mission.braking.brake_control`
    on z alone); None under ``speed_limit = "norm"`` with a climb (the axes couple there, and
    the ground track would not be the plan's)."""
    x0 = np.asarray(state, dtype=float)
    if x0[5] == 0.0:  # level: the plane's states at the UAV's altitude (Eq. (1) lifted)
        z = float(x0[2])
        return dataclasses.replace(plan, states=np.array([lift_state(s, z) for s in plan.states]),
                                   controls=lift_controls(plan.controls))
    if dynamics.speed_limit == "norm":
        return None
    states, controls = [x0], []
    for u_xy in plan.controls:
        u = np.array([u_xy[0], u_xy[1], brake_control(states[-1], dynamics)[2]])
        controls.append(u)
        states.append(step(states[-1], u, dynamics))
    return dataclasses.replace(plan, states=np.array(states), controls=np.array(controls))
