"""Compile (or load from the disk cache) every Numba kernel before the first timed plan.

The kernels (the fast QP's iterations, the hull, the reach boxes, the LQR
trackers) compile on their first call, seconds on a fresh checkout and about
a tenth of a second from the cache. :func:`warm_up` flies one plan of each
system under both speed limits, so neither a planner service's first answer
nor a measured planning time includes it; :func:`warm_up_3d` does the same for the
3-D kernels (the prisms' distances, the 3-D segment test) where a 3-D planner is made.
``python -m dualpilot.warmup`` fills the cache for both (``make setup`` runs it). It is
thread-safe: a second thread waits until the first has finished.
"""

from __future__ import annotations

import threading
import time

import numpy as np

_done = False
_lock = threading.RLock()  # a second thread waits for the first


def warm_up() -> float:
    """Run each kernel once in this process (a no-op after the first call); seconds taken."""
    global _done
    with _lock:
        if _done:
            return 0.0
        _done = True
        return _warm()


def _warm() -> float:
    t0 = time.perf_counter()
    from dataclasses import replace

    from dualpilot.model.dynamics import DynamicsParams, hover_state
    from dualpilot.model.fire import FireParams
    from dualpilot.model.fire_field import FireField
    from dualpilot.model.geometry import Rect
    from dualpilot.plan import Objective
    from dualpilot.spec import MissionSpec
    from dualpilot.system1.planner import System1, System1Params
    from dualpilot.system2.fast.planner import FastSystem2
    from dualpilot.system2.problem import System2Params

    fire = FireField(FireParams(p_birth=1.0))
    rng = np.random.default_rng(0)
    for k in range(3):
        fire.substep(rng, k)
    hull = Rect(300.0, 300.0, 80.0, 60.0).polytope()
    for limit in ("axis", "norm"):
        dyn = DynamicsParams(speed_limit=limit)
        spec = MissionSpec(dynamics=dyn)
        state = hover_state(np.array(spec.start), dyn)
        for tracker in ("lqr", "lqr_du"):  # the registry's "rrt" and "rrt+du"
            s1 = System1(spec, replace(System1Params(), tracker=tracker))
            s1.plan(state, (hull,), Objective.MISSION_TIME)
        FastSystem2(spec, System2Params()).plan(state, (hull,), Objective.ENERGY)  # "fast"
    return time.perf_counter() - t0


_3d_done = False


def warm_up_3d() -> float:
    """The 3-D kernels once a process (a no-op after the first call), after :func:`warm_up`;
    seconds taken. Without it a 3-D mission's first plan would compile them inside System 1's
    CPU cap (``RrtParams.max_cpu_s``) and could end early on a slow machine."""
    global _3d_done
    with _lock:
        if _3d_done:
            return 0.0
        _3d_done = True
        t0 = time.perf_counter()
        warm_up()
        _warm_3d()
        return time.perf_counter() - t0


def _warm_3d() -> None:
    from dualpilot.model.dynamics import DynamicsParams, hover_state
    from dualpilot.model.geometry import Rect
    from dualpilot.model.prism import Prism
    from dualpilot.plan import Objective
    from dualpilot.spec import MissionSpec
    from dualpilot.system1.planner import System1, System1Params
    from dualpilot.system2.fast.planner import FastSystem2
    from dualpilot.system2.problem import System2Params

    wall = Prism.cuboid(Rect(500.0, 450.0, 1000.0, 100.0), 0.0, 40.0)  # under the start's 50 m
    for limit in ("axis", "norm"):
        spec = MissionSpec(dynamics=DynamicsParams(dim=3, speed_limit=limit))
        state = hover_state(spec.start_position, spec.dynamics)
        for altitude in ("slice-first", "volume"):
            System1(spec, System1Params(altitude=altitude)).plan(state, (wall,),
                                                                 Objective.MISSION_TIME)
        if limit == "axis":  # the fast method's 3-D QP splits under "axis" only
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
