"""The occupancy forecast: P(a grid cell's centre lies inside a fire region) k sub-steps ahead.

Every fire process has a forecaster that fills this grid: the paper's rectangles
(Sec. II-B, :mod:`dualpilot.model.front_forecast`) and a fire-behaviour scenario's level
set run ahead (:mod:`dualpilot.model.physics_forecast`); :mod:`dualpilot.model.field_forecast`
asks the one of a field. Readers (the risk zones, the supervisors, the EWS's wire form,
the viewer) read :class:`OccupancyForecast` alone. Probabilities are kept in steps of
1/255 (``levels``, uint8, read-only), the resolution the EWS publishes, so a forecast
received over the bus is the same forecast. k = 0 is the current occupancy
(persistence). Lengths m, times s.
"""

from __future__ import annotations

from bisect import bisect_left, bisect_right
from collections.abc import Sequence
from dataclasses import dataclass
from math import ceil
from typing import Any, cast

import numpy as np
from numpy.typing import NDArray

from dualpilot.arrays import AnyArray, Array
from dualpilot.model.fire import FireParams
from dualpilot.model.geometry import Rect

#: Probability quantum: P = level / LEVELS (uint8).
LEVELS = 255


@dataclass(frozen=True)
class ForecastParams:
    """The forecast's grid and ensemble (lengths m, times s).

    ``resolution_m`` 10 m: half d_safe, so every point of a cell is within 7.1 m
    of its centre. ``horizon_s`` 40 s = T·T_f, the fire time System 2's
    horizon T = 80 spans at one sub-step a step (at the paper's 5 s a plan, its
    first 8 steps). ``interval_s`` 1 s between slices (two sub-steps).
    ``members`` 32 motion paths per front: the centre's spread after 40 s is
    about 10 m. Against 2048 paths, redrawn sides (a 75 m ramp of f) leave an
    error under 2/255; kept sides (``extent = "birth"``, a sharp edge) 0.016 rms
    over the cells with 0.02 < P < 0.98 at 10 s, at most 0.12 at a corner cell
    (tests/unit/dualpilot/model/test_forecast.py checks the forecast against the process itself).
    """

    members: int = 32
    resolution_m: float = 10.0
    horizon_s: float = 40.0
    interval_s: float = 1.0

    def __post_init__(self) -> None:
        if self.members < 1:
            raise ValueError(f"members must be >= 1, got {self.members}")
        if not (self.resolution_m > 0 and np.isfinite(self.resolution_m)):
            raise ValueError(f"resolution_m must be positive, got {self.resolution_m}")
        if not (self.horizon_s >= 0 and self.interval_s > 0 and np.isfinite(self.horizon_s)):
            raise ValueError("horizon_s >= 0 and interval_s > 0 are required")

    def horizons(self, substep_s: float) -> tuple[int, ...]:
        """The slices' sub-steps ahead: 0, i, 2i, … ≤ ⌈H / T_f⌉ with i = round(interval / T_f)."""
        every = max(1, round(self.interval_s / substep_s))
        last = ceil(self.horizon_s / substep_s - 1e-9)
        return tuple(range(0, last + 1, every))


class OccupancyForecast:
    """P_k on a grid of cell centres origin + (j + ½)·resolution, one slice per horizon.

    ``levels[i, row, col]`` is P at ``horizons[i]`` sub-steps ahead, in 1/255,
    for the cell of row y, column x; it may be given as one (horizons, rows,
    cols) array or as one (rows, cols) array a slice (``layers``: slices no front
    reaches are shared between forecasts), read-only either way. ``issued_substep``
    is the fire state's sub-step count the forecast starts from;
    ``substeps_per_step`` the time-step length it assumed (:func:`life_events`).
    """

    def __init__(self, resolution_m: float, substep_s: float, horizons: tuple[int, ...],
                 levels: NDArray[np.uint8] | Sequence[NDArray[np.uint8]],
                 origin_m: tuple[float, float] = (0.0, 0.0), issued_substep: int = 0,
                 substeps_per_step: int = 1):
        layers = tuple(levels)
        shapes = {(lv.dtype, lv.shape) for lv in layers}
        if len(layers) != len(horizons) or len(shapes) != 1 or any(
                d != np.uint8 or len(sh) != 2 for d, sh in shapes):
            raise ValueError(f"levels must be {len(horizons)} uint8 (rows, cols) slices of "
                             f"one shape, got {sorted(map(str, shapes))}")
        if list(horizons) != sorted(set(horizons)) or (horizons and horizons[0] < 0):
            raise ValueError(f"horizons must be increasing sub-step counts >= 0: {horizons}")
        for lv in layers:
            lv.flags.writeable = False
        self._set(resolution_m, substep_s, tuple(horizons), layers, origin_m, issued_substep,
                  substeps_per_step)

    @classmethod
    def _made(cls, resolution_m: float, substep_s: float, horizons: tuple[int, ...],
              layers: tuple[NDArray[np.uint8], ...], issued_substep: int,
              substeps_per_step: int) -> OccupancyForecast:
        """A forecast of a forecaster's own read-only slices (checked there)."""
        out = cls.__new__(cls)
        out._set(resolution_m, substep_s, horizons, layers, (0.0, 0.0), issued_substep,
                 substeps_per_step)
        return out

    def _set(self, resolution_m: float, substep_s: float, horizons: tuple[int, ...],
             layers: tuple[NDArray[np.uint8], ...], origin_m: tuple[float, float],
             issued_substep: int, substeps_per_step: int) -> None:
        self.resolution_m = resolution_m
        self.substep_s = substep_s
        self.horizons = horizons
        self.layers: tuple[NDArray[np.uint8], ...] = layers
        self.origin_m = origin_m
        self.issued_substep = issued_substep
        self.substeps_per_step = substeps_per_step
        #: results derived from the levels, kept by their users (windows, risk zones)
        self.memo: dict[object, Any] = {}

    def __repr__(self) -> str:
        return (f"OccupancyForecast(resolution_m={self.resolution_m}, shape={self.shape}, "
                f"horizons={self.horizons}, substep_s={self.substep_s}, "
                f"issued_substep={self.issued_substep})")

    @property
    def levels(self) -> NDArray[np.uint8]:
        """Every slice as one (horizons, rows, cols) array (made on first use)."""
        got = self.memo.get("levels")
        if got is None:
            got = np.stack(self.layers)
            got.flags.writeable = False
            self.memo["levels"] = got
        return cast(NDArray[np.uint8], got)

    def level(self, i: int) -> NDArray[np.uint8]:
        """Slice i in 1/255 (rows y, columns x)."""
        return self.layers[i]

    @property
    def shape(self) -> tuple[int, int]:
        """(rows, columns) of the grid."""
        rows, cols = self.layers[0].shape
        return int(rows), int(cols)

    @property
    def horizons_s(self) -> Array:
        """The slices' times ahead (s)."""
        return np.asarray(self.horizons, dtype=float) * self.substep_s

    @property
    def max_substeps(self) -> int:
        return self.horizons[-1] if self.horizons else 0

    def probability(self, i: int) -> Array:
        """Slice i as probabilities in [0, 1] (rows y, columns x)."""
        return np.asarray(self.layers[i], dtype=float) / LEVELS

    def cells(self, points: Array) -> tuple[AnyArray, AnyArray, AnyArray]:
        """(rows, cols, inside) of the cells holding ``points`` (n, 2) (m); inside: on the grid."""
        pts = np.asarray(points, dtype=float).reshape(-1, 2)
        col = np.floor((pts[:, 0] - self.origin_m[0]) / self.resolution_m).astype(np.int64)
        row = np.floor((pts[:, 1] - self.origin_m[1]) / self.resolution_m).astype(np.int64)
        ny, nx = self.shape
        inside = (col >= 0) & (col < nx) & (row >= 0) & (row < ny)
        return np.clip(row, 0, ny - 1), np.clip(col, 0, nx - 1), inside

    def slices(self, k_lo: int, k_hi: int) -> range:
        """The slices that stand for sub-steps k_lo..k_hi: those inside, and the nearest one on
        either side when the window falls between slices (empty past the horizon)."""
        if k_lo > self.max_substeps or k_hi < k_lo:
            return range(0)
        hs = self.horizons
        lo = max(bisect_right(hs, k_lo) - 1, 0)
        hi = min(bisect_left(hs, k_hi), len(hs) - 1)
        return range(lo, hi + 1)

    def window(self, k_lo: int, k_hi: int) -> NDArray[np.uint8] | None:
        """The largest level of each cell over :meth:`slices` (None past the horizon)."""
        idx = self.slices(k_lo, k_hi)
        if not idx:
            return None
        key = (idx.start, idx.stop)
        got = self.memo.get(key)
        if got is None:
            got = np.maximum.reduce(self.layers[idx.start:idx.stop])
            self.memo[key] = got
        return got


def life_events(substeps: int, fire: FireParams, substeps_per_step: int) -> AnyArray:
    """L_k for k = 0..substeps: the Bernoulli birth/survival draws in sub-steps 1..k.

    A draw every sub-step, or (``fire.life_base = "step"``) on the first sub-step of each
    time-step of ``substeps_per_step`` sub-steps, the forecast's first sub-step starting one.
    """
    k = np.arange(substeps + 1)
    if fire.life_base == "substep":
        return k
    n = max(1, substeps_per_step)
    return np.where(k >= 1, (k - 1) // n + 1, 0)


def grid_shape(area_m: float, resolution_m: float) -> tuple[int, int]:
    """(rows, columns) of a grid of ``resolution_m`` cells over [0, area_m]²."""
    n = ceil(area_m / resolution_m - 1e-9)
    return n, n


def occupancy(regions: Sequence[Rect], resolution_m: float, shape: tuple[int, int],
              origin_m: tuple[float, float] = (0.0, 0.0)) -> NDArray[np.bool_]:
    """Which cell centres lie inside a region (closed rectangles): the truth, and persistence."""
    ny, nx = shape
    xc = origin_m[0] + (np.arange(nx) + 0.5) * resolution_m
    yc = origin_m[1] + (np.arange(ny) + 0.5) * resolution_m
    out = np.zeros(shape, dtype=bool)
    for r in regions:
        x0, y0, x1, y1 = r.bounds
        cols = (xc >= x0) & (xc <= x1)
        rows = (yc >= y0) & (yc <= y1)
        out |= rows[:, None] & cols[None, :]
    return out

