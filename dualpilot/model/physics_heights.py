"""How tall a fire-behaviour scenario's fronts are in 3-D: the plume of their fireline intensity.

A scenario's front (dualpilot/model/physics_fire.py) is a cuboid over its region whose top
is :func:`dualpilot.model.plume.fire_top_m` of a fireline intensity (kW/m) and the
scenario's midflame wind (``fire_height = "plume"``, docs/three_d.md):

* ``plume_intensity = "front"``: the largest intensity over the front's burning perimeter
  cells, pyretechnics' ``fireline_intensity`` layer (the intensity at which each cell
  burned, normal to the front); a cell pyretechnics ignited itself carries no intensity,
  so a front is never taken below the fuel's no-wind, no-slope intensity (Rothermel's base
  rate: the fire a cell burns with in calm air on flat ground);
* ``"head"``: every front as tall as the scenario's head fire.

Under ``fire_height = "above-ceiling"`` every front is taller than the band. A front's
hull prism is as tall as the highest top it has had (:class:`PhysicsTops` keeps them).
"""

from __future__ import annotations

import numpy as np

from dualpilot.model.fire_height import FireHeights
from dualpilot.model.plume import fire_top_m, front_intensity_kw_m


class PhysicsTops:
    """The tops (m above ground) of one scenario's fronts and of their hulls.

    ``base_kw_m`` and ``head_kw_m`` are the scenario's no-wind-no-slope and head fireline
    intensities (kW/m), ``wind_mps`` its midflame wind (m/s)
    (:func:`dualpilot.model.physics_fire.fireline_intensities_kw_m`).
    """

    def __init__(self, heights: FireHeights, base_kw_m: float, head_kw_m: float,
                 wind_mps: float):
        self.heights = heights
        self.base_kw_m, self.head_kw_m, self.wind_mps = base_kw_m, head_kw_m, wind_mps
        #: front id → the highest top it has had (m)
        self.hull_tops: dict[int, float] = {}

    def top(self, intensity_kw_m: np.ndarray, active: np.ndarray) -> float:
        """The top (m) of a front whose burning perimeter cells are ``active`` (a mask over
        the grid of pyretechnics' ``fireline_intensity`` layer, ``intensity_kw_m``)."""
        if self.heights.reading != "plume":
            return self.heights.above_ceiling_m
        h = self.heights
        if h.params.plume_intensity == "head":
            return fire_top_m(self.head_kw_m, self.wind_mps, h.plume)
        burning = max(front_intensity_kw_m(intensity_kw_m, active), self.base_kw_m)
        return fire_top_m(burning, self.wind_mps, h.plume)

    @staticmethod
    def layer(state: object) -> np.ndarray:
        """pyretechnics' ``fireline_intensity`` layer (kW/m) of a level-set state."""
        layers = state.get_full_matrices(["fireline_intensity"])  # type: ignore[attr-defined]
        return np.asarray(layers["fireline_intensity"])

    def of_front(self, intensity_kw_m: np.ndarray, active: np.ndarray, fid: int,
                 merged: list[int]) -> tuple[float, float]:
        """(top, hull top) (m) of front ``fid`` (the fronts ``merged`` into it), its burning
        perimeter cells ``active`` over ``intensity_kw_m``."""
        top = self.top(intensity_kw_m, active)
        return top, self.hull_top(fid, merged, top)

    def hull_top(self, fid: int, merged: list[int], top: float) -> float:
        """The highest top (m) of front ``fid`` (and the fronts ``merged`` into it) so far,
        ``top`` its current one; remembered for the next update."""
        best = max([top] + [self.hull_tops[i] for i in [fid, *merged] if i in self.hull_tops])
        for i in merged:
            self.hull_tops.pop(i, None)
        self.hull_tops[fid] = best
        return best

    def retire(self, fid: int) -> float | None:
        """The highest top of front ``fid``, which is extinct (None: it never had one)."""
        return self.hull_tops.pop(fid, None)
