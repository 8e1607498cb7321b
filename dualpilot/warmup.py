"""Compile (or load from the disk cache) every Numba kernel before the first timed plan.

The kernels (the fast QP's iterations, the hull, the reach boxes, the LQR
trackers) compile on their first call, seconds on a fresh checkout and about
a tenth of a second from the cache. :func:`warm_up` flies one plan of each
system under both speed limits, so neither a planner service's first answer
nor a measured planning time includes it. ``python -m dualpilot.warmup``
fills the cache (``make setup`` runs it). It is thread-safe: a second
thread waits until the first has finished.
"""

from __future__ import annotations

import threading
import time

import numpy as np

_done = False
_lock = threading.RLock()  # re-entered by the planners warm_up builds


def warm_up() -> float:
    """Run each kernel once in this process (a no-op after the first call); seconds taken."""
    global _done
    with _lock:
        if _done:
            return 0.0
        _done = True  # first: the planners built here call warm_up too
        return _warm()


def _warm() -> float:
    t0 = time.perf_counter()
    from dualpilot.model.dynamics import DynamicsParams, hover_state
    from dualpilot.model.fire import FireField, FireParams
    from dualpilot.model.geometry import Rect
    from dualpilot.plan import Objective
    from dualpilot.planners import build_planner
    from dualpilot.spec import MissionSpec

    fire = FireField(FireParams(p_birth=1.0))
    rng = np.random.default_rng(0)
    for k in range(3):
        fire.substep(rng, k)
    hull = Rect(300.0, 300.0, 80.0, 60.0).polytope()
    for limit in ("axis", "norm"):
        dyn = DynamicsParams(speed_limit=limit)
        spec = MissionSpec(dynamics=dyn)
        state = hover_state(np.array(spec.start), dyn)
        for method in ("rrt", "rrt+du"):
            build_planner(1, spec, method).plan(state, (hull,), Objective.MISSION_TIME)
        build_planner(2, spec, "fast").plan(state, (hull,), Objective.ENERGY)
    return time.perf_counter() - t0


if __name__ == "__main__":
    print(f"kernels ready in {warm_up():.1f} s")
