"""Compile (or load from the disk cache) every Numba kernel before the first timed plan.

The kernels (the fast QP's iterations, the hull, the reach boxes, the LQR
trackers) compile on their first call, seconds on a fresh checkout and about
a tenth of a second from the cache. :func:`warm_up` flies one plan of each
system asked (both by default) under both speed limits, so neither a planner service's
first answer nor a measured planning time includes it; a planner service and
:func:`dualpilot.planners.build_planner` ask for their own system's only (a System 1
process never loads System 2's kernels). :func:`warm_up_3d` does the same for the 3-D
kernels (the prisms' distances, the 3-D segment test) where a 3-D planner is made.
``python -m dualpilot.warmup`` fills the cache for both (``make setup`` runs it). It is
thread-safe: a second thread waits until the first has finished.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Collection
from typing import TYPE_CHECKING

import numpy as np

from dualpilot.arrays import Array

if TYPE_CHECKING:
    from dualpilot.model.geometry import Polytope
    from dualpilot.spec import MissionSpec

#: the planning systems whose kernels a warm-up can load (System 1's, System 2's)
SYSTEMS = (1, 2)
_done: set[int] = set()  # the systems warmed in this process
_lock = threading.RLock()  # a second thread waits for the first


def _todo(systems: Collection[int], done: set[int]) -> tuple[int, ...]:
    """The systems of ``systems`` not in ``done`` (ValueError: a system that is not 1 or 2)."""
    unknown = set(systems) - set(SYSTEMS)
    if unknown:
        raise ValueError(f"no planning system {sorted(unknown)}; choose from {SYSTEMS}")
    return tuple(k for k in SYSTEMS if k in systems and k not in done)


def warm_up(systems: Collection[int] = SYSTEMS) -> float:
    """Run each kernel a plan of ``systems`` calls once in this process (a no-op for a system
    already warmed); seconds taken. A planner service warms its own system's only: a
    System 1 process never plans with System 2."""
    with _lock:
        todo = _todo(systems, _done)
        if not todo:
            return 0.0
        shared = not _done  # the fire's and the hulls' kernels, once a process
        _done.update(todo)
        return _warm(todo, shared)


def _warm(systems: tuple[int, ...], shared: bool) -> float:
    t0 = time.perf_counter()
    from dualpilot.model.dynamics import DynamicsParams, hover_state
    from dualpilot.model.geometry import Rect
    from dualpilot.spec import MissionSpec

    if shared:
        from dualpilot.model.fire import FireParams
        from dualpilot.model.fire_field import FireField

        fire = FireField(FireParams(p_birth=1.0))
        rng = np.random.default_rng(0)
        for k in range(3):
            fire.substep(rng, k)
    hull = Rect(300.0, 300.0, 80.0, 60.0).polytope()
    for limit in ("axis", "norm"):
        dyn = DynamicsParams(speed_limit=limit)
        spec = MissionSpec(dynamics=dyn)
        state = hover_state(np.array(spec.start), dyn)
        if 1 in systems:
            _plan_system1(spec, state, hull)
        if 2 in systems:
            _plan_system2(spec, state, hull)
    return time.perf_counter() - t0


def _plan_system1(spec: MissionSpec, state: Array, hull: Polytope) -> None:
    """One plan of each of System 1's trackers (the registry's "rrt" and "rrt+du")."""
    from dataclasses import replace

    from dualpilot.plan import Objective
    from dualpilot.system1.planner import System1, System1Params

    for tracker in ("lqr", "lqr_du"):
        System1(spec, replace(System1Params(), tracker=tracker)).plan(state, (hull,),
                                                                     Objective.MISSION_TIME)


def _plan_system2(spec: MissionSpec, state: Array, hull: Polytope) -> None:
    """One plan of System 2's fast method (the registry's "fast")."""
    from dualpilot.plan import Objective
    from dualpilot.system2.fast.planner import FastSystem2
    from dualpilot.system2.problem import System2Params

    FastSystem2(spec, System2Params()).plan(state, (hull,), Objective.ENERGY)


_3d_done: set[int] = set()  # the systems whose 3-D kernels are warmed in this process


def warm_up_3d(systems: Collection[int] = SYSTEMS) -> float:
    """The 3-D kernels of ``systems``' plans once a process (a no-op for a system already
    warmed), after :func:`warm_up`; seconds taken. Without it a 3-D mission's first plan would
    compile them inside System 1's CPU cap (``RrtParams.max_cpu_s``) and could end early on a
    slow machine."""
    with _lock:
        todo = _todo(systems, _3d_done)
        if not todo:
            return 0.0
        _3d_done.update(todo)
        t0 = time.perf_counter()
        warm_up(todo)
        _warm_3d(todo)
        return time.perf_counter() - t0


def _warm_3d(systems: tuple[int, ...]) -> None:
    from dualpilot.model.dynamics import DynamicsParams, hover_state
    from dualpilot.model.geometry import Rect
    from dualpilot.model.prism import Prism
    from dualpilot.plan import Objective
    from dualpilot.spec import MissionSpec

    wall = Prism.cuboid(Rect(500.0, 450.0, 1000.0, 100.0), 0.0, 40.0)  # under the start's 50 m
    for limit in ("axis", "norm"):
        spec = MissionSpec(dynamics=DynamicsParams(dim=3, speed_limit=limit))
        state = hover_state(spec.start_position, spec.dynamics)
        if 1 in systems:
            from dualpilot.system1.planner import System1, System1Params

            for altitude in ("slice-first", "volume"):
                System1(spec, System1Params(altitude=altitude)).plan(state, (wall,),
                                                                     Objective.MISSION_TIME)
        if 2 in systems and limit == "axis":  # the fast method's 3-D QP splits under "axis" only
            from dualpilot.system2.fast.planner import FastSystem2
            from dualpilot.system2.problem import System2Params

            FastSystem2(spec, System2Params()).plan(state, (wall,), Objective.ENERGY)


_certificate_done = False


def warm_certificate() -> float:
    """The certified method's kernels (the reach sets, their corridor, the pieces' clipping),
    once a process: only where that method is made, not at every planner's start; seconds."""
    global _certificate_done
    with _lock:
        if _certificate_done:
            return 0.0
        _certificate_done = True
        t0 = time.perf_counter()
        _warm_certificate()
        return time.perf_counter() - t0


def _warm_certificate() -> None:
    from dualpilot.model.geometry import Rect
    from dualpilot.system2.certify.pieces import clip
    from dualpilot.system2.certify.reach import reach_sets

    hull = Rect(40.0, 40.0, 20.0, 20.0).polytope()
    lo, hi = np.zeros((4, 2)), np.full((4, 2), 100.0)
    reach = reach_sets(np.array([10.0, 10.0]), lo, hi, (hull,), 25.0, np.array([90.0, 90.0]),
                       15.0)
    reach.corridor()
    clip(np.zeros(2), np.ones(2), np.array([[1.0, 0.0, 0.5]]))


if __name__ == "__main__":
    print(f"kernels ready in {warm_up() + warm_up_3d() + warm_certificate():.1f} s")
