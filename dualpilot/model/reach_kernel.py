"""The compiled kernel of :func:`dualpilot.model.dynamics.reach_boxes`.

Eq. (1) per axis with the force and the speed at their limits, τ = 1..T (m). A module of
its own so that importing the dynamics (every service, the router included, through the
codecs) does not import Numba; only a process that computes reach boxes (a plan's QP)
loads it.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from dualpilot.arrays import Array


@njit(cache=True)
def reach(x0: Array, horizon: int, dim: int, keep: float, acc: float, vmax: float,
          dt: float) -> tuple[Array, Array]:
    """(lo, hi) bounds on p (m), each (horizon, dim), of x0 = [p, v]: the velocity kept by
    ``keep`` = 1 − ζ and moved by at most ``acc`` = ΔT u_max / m a step, within ±``vmax``."""
    lo, hi = np.empty((horizon, dim)), np.empty((horizon, dim))
    for a in range(dim):
        v_hi = v_lo = x0[dim + a]
        p_hi = p_lo = x0[a] + dt * v_hi
        lo[0, a], hi[0, a] = p_lo, p_hi
        for k in range(1, horizon):
            v_hi = min(keep * v_hi + acc, vmax)
            v_lo = max(keep * v_lo - acc, -vmax)
            p_hi = p_hi + dt * v_hi
            p_lo = p_lo + dt * v_lo
            lo[k, a], hi[k, a] = p_lo, p_hi
    return lo, hi
