"""Load the compiled kernels the supervisor's own step runs, before its first mission.

The supervisor plans nothing itself: its step checks plans and fire data
against the hulls (segment distances), turns forecasts into risk zones (cell
hulls) and, as the lookahead supervisor, searches its space-time lattice
(moves checked against the known fires). Each of those Numba kernels costs a
load from the disk cache on its first call, which the step that first met a
fire used to wait for (0.5–0.65 s; docs/load.md). :func:`warm_kernels` calls
each once on a tiny input of the types the step passes, and nothing else: the
planners' kernels (System 1's trackers, System 2's QP) run in the planner
services, which warm their own (services/common/planning.py).
"""

from __future__ import annotations

import threading
import time

import numpy as np

_lock = threading.Lock()
_done = False


def warm_kernels() -> float:
    """Call each kernel of the supervisor's step once in this process (a no-op after the
    first call); the seconds it took."""
    global _done
    with _lock:
        if _done:
            return 0.0
        _done = True
        t0 = time.perf_counter()
        from dualpilot.model.geometry import Rect, path_clearance
        from dualpilot.model.risk import cell_hulls
        from dualpilot.spacetime.lattice import move_clear

        hull = Rect(300.0, 300.0, 80.0, 60.0).polytope()
        path_clearance(np.array([[0.0, 0.0], [100.0, 100.0], [200.0, 50.0]]), (hull,))
        cell_hulls(np.eye(4, dtype=np.bool_), 10.0)
        boxes = np.array([[290.0, 290.0, 310.0, 310.0]])  # one fire box, at every sub-step
        offsets = np.array([0, 1, 1, 1], dtype=np.int64)
        move_clear(0.0, 0.0, 10.0, 10.0, 0, 1, boxes, offsets, 5.0)
        return time.perf_counter() - t0
