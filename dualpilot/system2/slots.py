"""The hulls of a request fitted to the exact MIQP's slots (:mod:`dualpilot.system2.miqp`).

The compiled problem has ``max_hulls`` slots of ``max_faces`` faces each: the hulls
within reach of the horizon are kept, nearest first; a hull with more faces is
replaced by a containing polygon with ``max_faces`` faces (:func:`outer_simplify`),
and big-M must relax Eq. (P2_3) everywhere a planned position can be (:func:`big_m_ok`).
In 3-D a hull is a prism: its base is simplified, its top and bottom kept. Lengths m.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from dualpilot.arrays import Array
from dualpilot.model.altitude import AltitudeBand
from dualpilot.model.dynamics import DynamicsParams, reach_radius
from dualpilot.model.geometry import Polytope
from dualpilot.model.prism import Prism
from dualpilot.system2.fast.geometry import Inflated
from dualpilot.system2.problem import Obstacle, System2Params


def face_inflated(poly: Polytope, eps: float) -> Polytope:
    """{p : α_l·p ≤ β_l + ε ∀l}: the region Eq. (P2_3)-(P2_4) forbid, faces pushed out by ε (m).

    It extends beyond the ε-distance offset at sharp vertices; the vertices
    are those of :class:`dualpilot.system2.fast.geometry.Inflated`.
    """
    return poly if eps <= 0 else Polytope.from_vertices(Inflated.make(poly, eps).W)


def outer_simplify(poly: Polytope, max_faces: int) -> Polytope:
    """A polygon with at most ``max_faces`` faces that contains ``poly``.

    Greedily removes the edge whose removal (extending its two neighbours to
    their intersection) adds the least area; only edges whose neighbours
    meet on the outside (turn < π) are removable, so the result stays bounded.
    """
    if max_faces < 4:
        raise ValueError(f"max_faces must be >= 4, got {max_faces}")
    verts = [np.asarray(p, dtype=float) for p in poly.vertices]
    while len(verts) > max_faces:
        k = len(verts)
        best: tuple[float, int, Array] | None = None
        for i in range(k):
            # edge i runs verts[i] -> verts[i+1]; its neighbours are a0->a1 and b0->b1
            a0, a1 = verts[i - 1], verts[i]
            b0, b1 = verts[(i + 1) % k], verts[(i + 2) % k]
            da, db = a1 - a0, b1 - b0
            den = da[0] * db[1] - da[1] * db[0]
            if den <= 1e-12 * np.linalg.norm(da) * np.linalg.norm(db):
                continue  # neighbours parallel or diverging: removal would be unbounded
            s = ((b0 - a0)[0] * db[1] - (b0 - a0)[1] * db[0]) / den
            r = ((b0 - a0)[0] * da[1] - (b0 - a0)[1] * da[0]) / den
            if s < 1.0 - 1e-12 or r > 1e-12:
                continue  # the extended neighbours would not meet outside edge i
            apex = a0 + s * da
            area = 0.5 * abs((b0 - a1)[0] * (apex - a1)[1] - (b0 - a1)[1] * (apex - a1)[0])
            if best is None or area < best[0]:
                best = (area, i, apex)
        if best is None:  # cannot happen for a convex polygon with > 4 edges
            raise ValueError("cannot simplify polygon conservatively")
        _, i, apex = best
        j = (i + 1) % k
        # replace verts[i] and verts[j] by the apex
        verts = [apex] + verts[1:i] if j == 0 else verts[:i] + [apex] + verts[j + 1 :]
    return Polytope.from_vertices(np.array(verts))


def _fitted(hull: Obstacle, max_faces: int) -> Obstacle:
    """``hull`` with at most ``max_faces`` faces (a prism's base), containing it."""
    if isinstance(hull, Prism):
        if hull.base.n_faces <= max_faces:
            return hull
        return Prism(outer_simplify(hull.base, max_faces), hull.z_lo, hull.z_hi)
    return hull if hull.n_faces <= max_faces else outer_simplify(hull, max_faces)


def _inflated_distance(hull: Obstacle, eps: float, position: Array) -> float:
    """The distance (m) from ``position`` to the region Eq. (P2_3)-(P2_4) forbid around
    ``hull``: its faces pushed out by ε (a prism's base, top and bottom)."""
    if isinstance(hull, Prism):
        grown = Prism(face_inflated(hull.base, eps), hull.z_lo - eps, hull.z_hi + eps)
        return grown.distance(position[:3])
    return face_inflated(hull, eps).distance(position[:2])


def select_hulls(state: Array, hulls: Sequence[Obstacle], params: System2Params,
                 dynamics: DynamicsParams, epsilon_m: float
                 ) -> tuple[list[tuple[int, Obstacle]], list[int]]:
    """Reachable hulls (index, polygon or prism whose base has ≤ max_faces faces) sorted by
    distance; simplified indices. ``state`` is x_t of 2·dim numbers."""
    n = dynamics.dim
    reach = reach_radius(state[n:], params.horizon, dynamics)
    kept: list[tuple[float, int, Obstacle]] = []
    simplified: list[int] = []
    for i, hull in enumerate(hulls):
        poly = _fitted(hull, params.max_faces)
        if poly is not hull:
            simplified.append(i)
        dist = _inflated_distance(poly, epsilon_m, state)
        if dist <= reach + 1e-6:
            kept.append((dist, i, poly))
    kept.sort(key=lambda item: item[0])
    return [(i, poly) for _, i, poly in kept], simplified


def big_m_ok(state: Array, polys: Sequence[Obstacle], params: System2Params,
             dynamics: DynamicsParams, epsilon_m: float, area_size_m: float,
             band: AltitudeBand | None = None) -> bool:
    """M must relax Eq. (P2_3) everywhere a planned position can be (the area, or the reach;
    in 3-D over the ``band``'s altitudes)."""
    n = dynamics.dim
    if params.keep_in_area:
        lo, hi = np.zeros(2), np.full(2, area_size_m)
    else:
        r = reach_radius(state[n:], params.horizon, dynamics)
        lo, hi = state[:2] - r, state[:2] + r
    corners = np.array([[lo[0], lo[1]], [hi[0], lo[1]], [hi[0], hi[1]], [lo[0], hi[1]]])
    if n == 3:
        zs = (AltitudeBand() if band is None else band)
        corners = np.vstack([np.column_stack([corners, np.full(4, z)])
                             for z in (zs.floor_m, zs.ceiling_m)])
    for poly in polys:
        need = np.max(poly.b[:, None] + epsilon_m - poly.A @ corners.T)
        if need > params.big_m:
            return False
    return True
