"""The references of the fast method in 3-D: around-classes, over-options, the band.

The around-classes are today's (:class:`dualpilot.system2.fast.references.References`): the
shortest path of each homotopy class around every footprint, timed by Eq. (1). A low prism
(one whose top + ε lies in the band) adds the over-option: the shortest paths around the
footprints of the prisms that cannot be passed over only, which cross the low prisms'
footprints; where such a path is inside a low footprint its run starts with over-rows
(:class:`dualpilot.system2.fast.cfs3.Cfs3`), and the altitude QP finds the fastest climb to
the level (if the climb cannot be made in time the path is re-timed slower, as any
reference whose timing asks too much of Eq. (1)). The cap on homotopies is shared: the
over-paths take at most half of it, the around-classes the rest. A reference's altitude
is the relaxation's (the kind of each row is chosen by the reference's (x, y); its z only
decides which pairs are near). Positions p_1..p_{T+1} (m), (T+1, 3).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import numpy as np

from dualpilot.arrays import Array
from dualpilot.model.altitude import AltitudeBand
from dualpilot.model.dynamics import DynamicsParams
from dualpilot.model.geometry import Rect
from dualpilot.plan import Plan
from dualpilot.system2.fast.cfs import KeepOuts
from dualpilot.system2.fast.cfs3 import KeepOuts3
from dualpilot.system2.fast.params import FastParams
from dualpilot.system2.fast.references import Reference, References, braking
from dualpilot.system2.fast.split import planar_dynamics
from dualpilot.system2.problem import System2Params


class References3:
    """The references of one 3-D planner's requests (module docstring).

    Parameters
    ----------
    fast, params : FastParams, System2Params
        As for :class:`References`.
    dynamics : DynamicsParams
        Eq. (1) in 3-D.
    goal : Rect
        G's rectangle (its centre: G_o's (x, y)).
    area : float or None
        The area's side (m).
    band : AltitudeBand
        The altitudes a plan keeps.
    """

    def __init__(self, fast: FastParams, params: System2Params, dynamics: DynamicsParams,
                 goal: Rect, area: float | None, band: AltitudeBand) -> None:
        self.fast, self.params, self.dynamics, self.band = fast, params, dynamics, band
        self.flat = References(fast, params, planar_dynamics(dynamics), goal, area)
        self.area = area

    def __call__(self, x0: Array, free_pos: Array, keep: KeepOuts3, kappa: tuple[float, float],
                 last: Plan | None) -> list[Reference]:
        """The 3-D references: the previous plan shifted, the over-paths, the around-classes
        (each with its slower re-timing), the relaxation projected."""
        T = self.params.horizon
        z = free_pos[:, 2]
        xy0 = np.array([x0[0], x0[1], x0[3], x0[4]])
        refs: list[Reference] = []
        if self.fast.use_previous and last is not None and last.ok and len(last.states) == T + 1:
            prev = last.states[:, :3]
            if np.linalg.norm(prev[1] - x0[:3]) < 30.0:
                shifted = np.vstack([prev[2:], prev[-1:], prev[-1:]])
                shifted[0] = free_pos[0]
                refs.append(("previous", shifted, None))
        over = self._over_paths(xy0, free_pos, keep, kappa)
        n_around = max(1, self.fast.max_homotopies - len(over))
        around = _planar(keep, np.ones(len(keep.polys), dtype=bool))
        flat = self._flat(max_homotopies=n_around)
        for name, pos, slower in over + flat(xy0, free_pos[:, :2], around, kappa, None):
            refs.append((name, _lift(pos, z), None if slower is None else _lifted(slower, z)))
        return refs

    def _over_paths(self, xy0: Array, free_pos: Array, keep: KeepOuts3,
                    kappa: tuple[float, float]) -> list[Reference]:
        """The shortest paths around the prisms that cannot be passed over, each crossing a
        low prism's footprint (at most half the cap), named ``over0``, ``over1``, …"""
        low = np.isfinite(keep.level)
        if not np.any(low):
            return []
        cap = max(1, self.fast.max_homotopies // 2)
        tall = _planar(keep, ~low)
        flat = self._flat(max_homotopies=cap)
        out: list[Reference] = []
        low_faces = _planar(keep, low).faces
        for name, pos, slower in flat(xy0, free_pos[:, :2], tall, kappa, None):
            if not name.startswith("path"):
                continue  # the brisk and projected references are the around-runs' own
            if not np.any(low_faces.margins(pos) <= 0.0):
                continue  # crosses no low footprint: an around-class
            out.append((f"over{name[4:]}", pos, slower))
        return out

    def _flat(self, max_homotopies: int) -> References:
        """The planar references with at most ``max_homotopies`` classes."""
        if max_homotopies == self.fast.max_homotopies:
            return self.flat
        fast = dataclasses.replace(self.fast, max_homotopies=max_homotopies)
        return References(fast, self.params, self.flat.dynamics, self.flat.goal, self.area)

    def braking(self, x0: Array) -> Array:
        """:func:`braking` in 3-D, its altitudes kept in the band."""
        pos = braking(x0, self.params.horizon, self.dynamics)
        pos[:, 2] = np.clip(pos[:, 2], self.band.floor_m, self.band.ceiling_m)
        return pos


def _planar(keep: KeepOuts3, which: Array) -> KeepOuts:
    """The planar keep-outs of the footprints ``which`` (their homotopies and target)."""
    polys = [q for q, w in zip(keep.polys, which.tolist(), strict=True) if w]
    return KeepOuts.of(polys, keep.horizon, keep.area)


def _lift(pos: Array, z: Array) -> Array:
    return np.column_stack([pos, z])


def _lifted(slower: Callable[[float], Array], z: Array) -> Callable[[float], Array]:
    return lambda fac: _lift(slower(fac), z)
