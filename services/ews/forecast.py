"""A deterministic forecast of each front's region: the mean of the Gauss–Markov model (Sec. II-B).

With the noise at its mean (zero), speed and direction relax towards their
means, y_k = γ y_{k-1} + (1 − γ) ȳ, and the centre moves y^ν·T_f along y^d per
sub-step; each forecast region is the largest rectangle the process can draw
(side_max × side_max), so it covers the drawn rectangle whenever the centre
forecast is right. It is a forecast, not a bound: planners avoid the hulls.
"""

from __future__ import annotations

from math import cos, sin

import numpy as np
from scipy.spatial import ConvexHull

from dualpilot.model.fire import FireFront, FireParams
from dualpilot.model.geometry import Polytope, Rect


def forecast_regions(front: FireFront, params: FireParams, substeps: int) -> list[Rect]:
    """The front's expected region after each of the next ``substeps`` sub-steps."""
    if substeps < 0:
        raise ValueError(f"substeps must be >= 0, got {substeps}")
    g = params.gamma
    speed, direction = front.speed_mps, front.direction_rad
    cx, cy = front.region.center_x, front.region.center_y
    side = params.side_max_m
    out = []
    for _ in range(substeps):
        speed = g * speed + (1 - g) * params.speed_mean_mps
        direction = g * direction + (1 - g) * params.direction_mean_rad
        cx += speed * params.substep_s * cos(direction)
        cy += speed * params.substep_s * sin(direction)
        out.append(Rect(cx, cy, side, side))
    return out


def envelope(front: FireFront, regions: list[Rect]) -> Polytope:
    """Convex hull of the front's path hull and its forecast regions.

    Qhull first picks the extreme points among the hundreds of corners, so
    the (pure Python) hull of :class:`Polytope` runs on a dozen points.
    """
    pts = np.vstack([front.hull.vertices] + [r.corners() for r in regions])
    if len(pts) > 16:
        pts = pts[ConvexHull(pts).vertices]
    return Polytope.from_vertices(pts)
