"""The compiled shaping filters of the Dryden turbulence (dualpilot.plant.wind).

A module of its own so that importing the wind model (the mission's configuration, every
service through it) does not import Numba; only a vehicle flying in turbulence loads it.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from dualpilot.arrays import Array

#: output row: y = √3 z₁ + (1 − √3) z₂ realises (1 + √3 T s)/(1 + T s)²
C2 = np.array([math.sqrt(3.0), 1.0 - math.sqrt(3.0)])


@njit(cache=True)
def shape(pu: Array, gu: Array, pv: Array, gv: Array, pw: Array, gw: Array, u: Array,
          v: Array, w: Array, noise: Array, out: Array) -> None:
    """Run the three shaping filters over ``noise`` (n, 5); states updated in place."""
    c0, c1 = C2[0], C2[1]
    for k in range(noise.shape[0]):
        u[0] = pu[0, 0] * u[0] + gu[0, 0] * noise[k, 0]
        for z, p, g, j in ((v, pv, gv, 1), (w, pw, gw, 3)):
            z0 = p[0, 0] * z[0] + p[0, 1] * z[1] + g[0, 0] * noise[k, j] + g[0, 1] * noise[k, j + 1]
            z1 = p[1, 0] * z[0] + p[1, 1] * z[1] + g[1, 0] * noise[k, j] + g[1, 1] * noise[k, j + 1]
            z[0], z[1] = z0, z1
        out[k, 0] = u[0]
        out[k, 1] = c0 * v[0] + c1 * v[1]
        out[k, 2] = c0 * w[0] + c1 * w[1]
