"""What a supervisor knows of the fires ahead, as boxes per sub-step: hulls and risky cells.

The known future from step t on (:class:`~dualpilot.spacetime.plan.FutureBoxes`, sub-step s
counted from now) is

* every obstacle of the step (the hulls △(C^i_{1:t}), or a region where a hull grew
  around the UAV: :meth:`~dualpilot.model.fire.FireSnapshot.obstacles_for`), by its
  bounding box, at every sub-step: what the planners and the run-time monitor keep
  from;
* with a fire forecast (:mod:`dualpilot.model.forecast`), the cells whose occupancy
  exceeds α in the slices that stand for sub-step s (past the horizon: the last slice),
  each row's run of them one box, grown by half a cell: a cell counts when its centre
  lies in a region, so a region reaches at most half a cell into the cells around it.

Births are not in it (they are the forecast's background, below α): no causal
controller knows where the next fire ignites. Lengths m.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from dualpilot.arrays import AnyArray, Array
from dualpilot.model.fire import FireParams
from dualpilot.model.forecast import LEVELS, OccupancyForecast
from dualpilot.model.geometry import Polytope
from dualpilot.model.prism import Prism
from dualpilot.model.scenarios import PAPER
from dualpilot.model.zone_heights import ZoneHeights
from dualpilot.spacetime.plan import FutureBoxes


def row_runs(mask: AnyArray, resolution_m: float, origin_m: tuple[float, float],
             grow_m: float = 0.0) -> Array:
    """Boxes (x_lo, y_lo, x_hi, y_hi) of the runs of True cells in each row of ``mask`` (rows
    y, columns x), grown by ``grow_m`` on every side."""
    rows, cols = np.nonzero(np.diff(np.pad(mask.astype(np.int8), ((0, 0), (1, 1))), axis=1))
    if len(rows) == 0:
        return np.empty((0, 4))
    starts, ends = cols[0::2], cols[1::2]  # np.nonzero orders row by row: +1, then −1
    row = rows[0::2]
    ox, oy = origin_m
    out = np.column_stack([ox + starts * resolution_m, oy + row * resolution_m,
                           ox + ends * resolution_m, oy + (row + 1) * resolution_m])
    return out + np.array([-grow_m, -grow_m, grow_m, grow_m])


def hull_boxes(obstacles: Sequence[Polytope]) -> Array:
    """The bounding boxes of ``obstacles``."""
    if not obstacles:
        return np.empty((0, 4))
    return np.array([np.r_[o.vertices.min(axis=0), o.vertices.max(axis=0)] for o in obstacles],
                    dtype=float)


def risky_boxes(forecast: OccupancyForecast, i: int, alpha: float, grow: bool = True) -> Array:
    """Slice i's cells above α as row runs, grown by half a cell unless not ``grow`` (kept on
    the forecast)."""
    key = ("spacetime.risky", i, alpha, grow)
    got = forecast.memo.get(key)
    if got is None:
        threshold = int(np.floor(alpha * LEVELS + 1e-9))
        res = forecast.resolution_m
        got = row_runs(forecast.level(i) > threshold, res, forecast.origin_m,
                       res / 2 if grow else 0.0)
        forecast.memo[key] = got
    return np.asarray(got)


def known_future(obstacles: Sequence[Polytope], forecast: OccupancyForecast | None,
                 substeps: int, alpha: float, per_step: int = 1,
                 grow: bool = True) -> FutureBoxes:
    """The known future over the next ``substeps`` sub-steps (module docstring), steps of
    ``per_step`` sub-steps (the forecast's own assumption); ``grow`` False: the risky cells
    as they are (the cells' centres, not all a region may reach)."""
    return _over_substeps(hull_boxes(obstacles), forecast, substeps, per_step,
                          lambda fc, i: risky_boxes(fc, i, alpha, grow))


def _over_substeps(static: Array, forecast: OccupancyForecast | None, substeps: int,
                   per_step: int,
                   cells: Callable[[OccupancyForecast, int], Array]) -> FutureBoxes:
    """The boxes of each of the next ``substeps`` sub-steps: ``static`` and, with a forecast,
    ``cells`` of each forecast slice that sub-step falls in (its last beyond the horizons)."""
    parts = [static]
    last = len(forecast.horizons) - 1 if forecast is not None else -1
    for s in range(1, substeps + 1):
        if forecast is None:
            parts.append(static)
            continue
        slices = list(forecast.slices(s, s)) or [last]
        parts.append(np.vstack([static, *(cells(forecast, i) for i in slices)]))
    return FutureBoxes.of(parts, per_step)


def growth_per_substep(fire: FireParams) -> float:
    """How far (m) a region's edge can move in one sub-step: a physics scenario's head fire
    (Rothermel, its wind and fuel) runs T_f·rate; a paper front moves T_f·(mean speed + 4σ)
    (its sides redrawn, when they are, are not bounded by this)."""
    if fire.scenario != PAPER:
        from dualpilot.model.physics_fire import head_spread_rate_mps
        from dualpilot.model.scenarios import get_scenario

        return fire.substep_s * head_spread_rate_mps(get_scenario(fire.scenario).params)
    return fire.substep_s * (fire.speed_mean_mps + 4.0 * fire.speed_sigma_mps)


def growing(obstacles: Sequence[Polytope], substeps: int, growth_m: float,
            per_step: int = 1) -> FutureBoxes:
    """The obstacles' boxes, each grown by ``growth_m`` a sub-step, over ``substeps``
    sub-steps: the near future of the fires of now, without a forecast."""
    static = hull_boxes(obstacles)
    grow = np.array([-1.0, -1.0, 1.0, 1.0])
    return FutureBoxes.of([static + grow * growth_m * s for s in range(substeps + 1)], per_step)


#: the top (m) of a cuboid as tall as every altitude: a polygon's, or a forecast cell's under
#: ``risk_zone_height = "band"`` (finite, for the 3-D kernels; far above any band)
TALL_M = 1.0e4


def tops_of(obstacles: Sequence[Polytope | Prism]) -> Array:
    """Each obstacle's top (m): a prism's z_hi (its bottom taken as the ground, conservative),
    a polygon's :data:`TALL_M`."""
    return np.array([o.z_hi if isinstance(o, Prism) else TALL_M for o in obstacles],
                    dtype=float)


def zone_tops(forecast: OccupancyForecast, i: int, alpha: float, runs: Array,
              heights: ZoneHeights) -> Array:
    """The tops (m) of slice i's risky runs ``runs`` (:func:`risky_boxes`, grown): each as
    tall as its highest cell (``heights.top_for`` of the run's largest P_xy), :data:`TALL_M`
    under the ``"band"`` reading (dualpilot/model/zone_heights.py)."""
    if heights.planar or not len(runs):
        return np.full(len(runs), TALL_M)
    res = forecast.resolution_m
    level = forecast.level(i)
    ox, oy = forecast.origin_m
    out = np.empty(len(runs))
    for r, (x0, y0, x1, _) in enumerate(runs):  # a run's cells: one row, its columns
        row = int(round((y0 + res / 2 - oy) / res))
        c0, c1 = int(round((x0 + res / 2 - ox) / res)), int(round((x1 - res / 2 - ox) / res))
        p_xy = float(level[row, c0:c1].max()) / LEVELS
        out[r] = min(TALL_M, heights.top_for(p_xy, alpha))
    return out


def known_future3(obstacles: Sequence[Polytope | Prism], forecast: OccupancyForecast | None,
                  substeps: int, alpha: float, heights: ZoneHeights,
                  per_step: int = 1) -> FutureBoxes:
    """:func:`known_future` with each box's top (rows x_lo, y_lo, x_hi, y_hi, top): a prism's
    over its footprint's box, a risky run's by ``heights`` (docs/three_d.md §8)."""
    static = np.column_stack([hull_boxes([footprint(o) for o in obstacles]), tops_of(obstacles)]) \
        if obstacles else np.empty((0, 5))

    def cells(fc: OccupancyForecast, i: int) -> Array:
        runs = risky_boxes(fc, i, alpha)
        return np.column_stack([runs, zone_tops(fc, i, alpha, runs, heights)])

    return _over_substeps(static, forecast, substeps, per_step, cells)


def footprint(obstacle: Polytope | Prism) -> Polytope:
    """An obstacle in the plane: a prism's base, a polygon as it is."""
    return obstacle.base if isinstance(obstacle, Prism) else obstacle
