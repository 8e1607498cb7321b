"""Occupancy forecast of the physics fire process: its level set run ahead, and the births.

The fire-behaviour model's counterpart of :mod:`dualpilot.model.front_forecast`, on
the same grid, slices and levels (an :class:`OccupancyForecast`). For the
centre x of a grid cell, k sub-steps (k·T_f seconds) ahead,

    P_k(x) = 1 − (1 − B_k(x)) · (1 − R_k(x)):

* R_k(x) ∈ {0, 1}: x lies inside a region of the process's own level set run
  k sub-steps on from its current state with no births (:class:`RunAhead`). The
  spread is deterministic given fuel, wind and moisture, and the copy makes the
  process's own pyretechnics runs at the same fire clock, so when nothing
  random happens in those k sub-steps it *is* the process's future, cell for
  cell. Regions are the process's: the box of each 8-connected burned area's
  active perimeter, grown by the pad.
* Spotting is bounded, not sampled: firebrands already in flight (the process
  knows when and where each lands) ignite in the copy at their times, and new
  ones are not cast, because a firebrand lands no sooner than
  :func:`spot_flight_s` after it is cast (twice Albini's lofting time at the
  head fire's flame length), 114 s in ``grass-15-spotting``: over any shorter
  horizon the spot fires are exactly those in flight.
* B_k(x), the fires still to be born: at each life event j ≤ k (the paper's
  Bernoulli birth, :func:`dualpilot.model.forecast.life_events`) one cell
  ignites with probability p_b, uniform over the area's cells, and its fire
  grows deterministically, so B_k(x) = 1 − Π_j (1 − p_b F_{k−j}(x)) with
  F_m(x) the fraction of ignition cells whose fire's region m sub-steps after
  its birth covers x. That region is measured once on a lone fire
  (:func:`birth_extents`: its box relative to the ignition cell, age by age),
  so F_m(x) = F^x_m(x₁) F^y_m(x₂), a count of cells per axis: the paper's
  closed form with p_s = 1 (fires do not die) and the lone fire's box for the
  drawn sides. The level set runs every few sub-steps (when the fire clock
  leads it by more than 1 s); the phase of a birth in that cycle shifts its
  growth by up to 1 s, and F_m is the mean over the phases.

What B neglects: births are redrawn off burned cells and off the ignition
keep-out (both unmodelled: births are taken uniform over the whole area, so
the forecast errs low by the burned fraction far from the fires, and high near
the UAV); a newborn that merges with another fire makes one box of both, larger
than the two (errs low); births and the run-ahead are otherwise independent
(both are boxes grown from where they are). Every other factor is exact. k = 0
is the current occupancy. Lengths m, times s.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from functools import lru_cache
from math import sqrt
from typing import Any, cast

import numpy as np
from numba import njit
from numpy.typing import NDArray

from dualpilot.arrays import AnyArray
from dualpilot.model.fire import FireParams
from dualpilot.model.forecast import (
    LEVELS,
    ForecastParams,
    OccupancyForecast,
    grid_shape,
    life_events,
    occupancy,
)
from dualpilot.model.geometry import Rect
from dualpilot.model.physics_fire import RUN_THRESHOLD_S, PhysicsFire
from dualpilot.model.scenarios import PhysicsFireParams

#: Albini (1979) as pyretechnics computes a firebrand's lofting time (spot_fire.albini_t_max):
#: a = 5.963, b = a − 1.4, the firebrand's greatest height z = 117 m.
_ALBINI_A, _ALBINI_B, _ALBINI_Z = 5.963, 4.563, 117.0
#: the connectivity of a burned area (8) and of an unburned neighbour (4), as the process's
_EIGHT = np.ones((3, 3), dtype=bool)
_FOUR = np.array([[False, True, False], [True, True, True], [False, True, False]])


def albini_t_max_s(flame_length_m: float) -> float:
    """Albini's (1979) lofting time (s) of a firebrand from a flame of ``flame_length_m``:
    (2 z_F / w_F)(1.2 + (a/3)(((b + z/z_F)/a)^{3/2} − 1)), w_F = 2.3 √z_F (pyretechnics'
    spot_fire.albini_t_max, eq. D43)."""
    z_f = float(flame_length_m)
    if not z_f > 0:
        raise ValueError(f"flame length must be positive, got {flame_length_m}")
    u = (_ALBINI_B + _ALBINI_Z / z_f) / _ALBINI_A
    return 2.0 * z_f / (2.3 * sqrt(z_f)) * (1.2 + _ALBINI_A / 3.0 * (u * sqrt(u) - 1.0))


def head_flame_length_m(params: PhysicsFireParams) -> float:
    """Byram's flame length (m) of the head fire under the scenario's wind (pyretechnics)."""
    import pyretechnics.fuel_models as fm
    import pyretechnics.surface_fire as sf

    from dualpilot.model.physics_fire import midflame_wind_m_min, upwind_azimuth_deg

    m = params.moisture
    moist = fm.moisturize(fm.get_fuel_model(params.fuel_model), (
        m.dead_1h, m.dead_10h, m.dead_100h, 0.0, m.live_herbaceous, m.live_woody))
    base = sf.calc_surface_fire_behavior_no_wind_no_slope(moist)
    head = sf.calc_surface_fire_behavior_max(
        base, midflame_wind_m_min(params.fuel_model, params.wind_speed_mps),
        upwind_azimuth_deg(params.wind_direction_rad), 0.0, 0.0, True, params.lw_ratio_model)
    return float(head["max_flame_length"])


def spot_flight_s(params: PhysicsFireParams) -> float:
    """The least time (s) from a firebrand's casting to the spot fire it starts: twice the
    lofting time (pyretechnics: arrival at 2 t_max) plus ``SpottingParams.build_up_s``.

    The lofting time falls as the flame lengthens (up to z_F ≈ 110 m), so the head fire's
    flame, the longest a homogeneous scenario has, gives the bound. inf without spotting.
    """
    if params.spotting is None:
        return float("inf")
    return 2.0 * albini_t_max_s(head_flame_length_m(params)) + params.spotting.build_up_s


def regions_of(proc: PhysicsFire, burned: NDArray[np.bool_]) -> list[Rect]:
    """The process's regions for a burned raster: the box of each 8-connected burned area's
    active perimeter (burned cells with an unburned 4-neighbour in the grid), grown by the
    pad and cut to the area (:meth:`PhysicsFire._update_fronts`); burned-out areas have none."""
    if not burned.any():
        return []
    from scipy import ndimage  # 0.2 s to import: where a raster is read

    labels, _ = ndimage.label(burned, structure=_EIGHT)
    active = burned & ndimage.binary_dilation(~burned, structure=_FOUR, border_value=0)
    out = []
    for sl in ndimage.find_objects(np.where(active, labels, 0)):
        if sl is not None:
            out.append(proc._box(sl[0].start, sl[0].stop - 1, sl[1].start, sl[1].stop - 1))
    return out


@dataclass
class _Entry:
    """The copy after one sub-step: its clock, level-set time, φ and firebrands in flight."""

    clock_s: float
    sim_min: float
    phi: NDArray[np.float32]  # shared with the previous entry while no run changed it
    spots: dict[float, frozenset[object]]
    occupied: dict[tuple[float, int], NDArray[np.bool_]] = field(default_factory=dict)


class RunAhead:
    """A copy of a :class:`PhysicsFire`'s level set run ahead with no births, kept and reused.

    :meth:`entries` gives the copy at 0..k sub-steps ahead of the process's
    current state. The copy is kept: while the process follows it (the same
    clock, level-set time, φ and firebrands in flight at a later issue: nothing
    random happened), the next issue reuses the sub-steps already run and runs
    only those beyond them, so the result is the same as a fresh copy's.
    """

    def __init__(self, proc: PhysicsFire):
        self.proc = proc
        self._entries: list[_Entry] = []
        self._tip: Any = None  # the copy's SpreadState after the last entry
        #: issues that reused the kept copy, and those that made a new one
        self.reused = 0
        self.fresh = 0

    def _now(self) -> _Entry:
        p = self.proc
        phi = np.array(p.state.get_full_matrices(["phi"])["phi"])  # type: ignore[attr-defined]
        return _Entry(p.clock_s, float(p.state.get_simulation_time()),  # type: ignore
                      phi, {t: frozenset(c) for t, c in p.spots.items()})

    def _follows(self, now: _Entry) -> int | None:
        """The kept entry the process is at now (None: the process left the copy)."""
        for i, e in enumerate(self._entries):
            if e.clock_s == now.clock_s:
                same = (e.sim_min == now.sim_min and e.spots == now.spots
                        and np.array_equal(e.phi, now.phi))
                return i if same else None
        return None

    def entries(self, substeps: int) -> list[_Entry]:
        """The copy after 0..``substeps`` sub-steps from the process's current state."""
        now = self._now()
        i = self._follows(now) if self._entries else None
        if i is None:
            self.fresh += 1
            self._entries = [now]
            self._tip = self.proc.state.copy()  # type: ignore[attr-defined]
        else:
            self.reused += 1
            self._entries = self._entries[i:]
        while len(self._entries) <= substeps:
            self._entries.append(self._next(self._entries[-1]))
        return self._entries[: substeps + 1]

    def _next(self, last: _Entry) -> _Entry:
        """One sub-step of the copy: the process's :meth:`PhysicsFire._spread`, no births, no
        new firebrands (the ones in flight land)."""
        p, state = self.proc, self._tip
        clock = last.clock_s + p.fire.substep_s
        lag_min = (clock - 60.0 * float(state.get_simulation_time())) / 60.0
        if lag_min * 60.0 <= RUN_THRESHOLD_S + 1e-9:
            return _Entry(clock, last.sim_min, last.phi, last.spots)
        spots = ({t: set(c) for t, c in last.spots.items()}
                 if p.physics.spotting is not None else None)
        out = p.run(state, lag_min, spots)
        sim = float(state.get_simulation_time())
        stop = float(cast(float, out["stop_time"]))
        left = {t: c for t, c in last.spots.items() if t >= stop}
        phi = np.array(state.get_full_matrices(["phi"])["phi"])
        if np.array_equal(phi, last.phi):
            phi = last.phi
        return _Entry(clock, sim, phi, left)

    def occupied(self, entry: _Entry, resolution_m: float,
                 shape: tuple[int, int]) -> NDArray[np.bool_]:
        """Which forecast cell centres lie inside the copy's regions at ``entry`` (kept)."""
        key = (resolution_m, shape[0])
        got = entry.occupied.get(key)
        if got is None:
            for e in self._entries:  # the same φ, the same regions
                if e.phi is entry.phi and key in e.occupied:
                    got = e.occupied[key]
                    break
            else:
                got = occupancy(regions_of(self.proc, entry.phi < 0.0), resolution_m, shape)
                got.flags.writeable = False
            entry.occupied[key] = got
        return got


def run_ahead(proc: PhysicsFire) -> RunAhead:
    """The process's kept :class:`RunAhead` (made on first use)."""
    got = proc.run_ahead
    if not isinstance(got, RunAhead):
        got = RunAhead(proc)
        proc.run_ahead = got
    return got


@lru_cache(maxsize=16)
def birth_extents(physics: PhysicsFireParams, fire: FireParams, area_size_m: float,
                  substeps: int) -> AnyArray:
    """A lone fire's region relative to its ignition cell's lower-left corner, age by age.

    Shape (phases, substeps + 1, 4): (x₀, x₁, y₀, y₁) in m, m sub-steps after the
    birth's sub-step, for each phase of the birth in the level set's run cycle
    (the fire clock leading the level set by q·T_f at the ignition, q = 0, 1, …
    while that stays within 1 s). Measured on the process itself with the fire
    ignited at the centre of the area (it does not reach the edge in the horizon).
    """
    quiet = replace(fire, p_birth=0.0)
    phases = int(RUN_THRESHOLD_S // fire.substep_s + 1e-9) + 1
    out = np.zeros((phases, substeps + 1, 4))
    rng = np.random.default_rng(0)  # draws nothing: no births, no spotting casts matter
    for q in range(phases):
        proc = PhysicsFire(replace(physics, spotting=None), quiet, area_size_m)
        for _ in range(q):  # an idle level set: the clock leads it by q·T_f
            proc.clock_s += fire.substep_s
        row, col = proc.n // 2, proc.n // 2
        proc._ignite(row, col, 0)
        proc._update_fronts(0)
        x0, y0 = col * proc.cell_m, row * proc.cell_m
        for m in range(substeps + 1):
            if m:
                proc.substep(rng, 0, False, None)
            regions = regions_of(proc, proc.burned())
            if len(regions) != 1:
                raise ValueError("a lone fire should have one region")
            bx0, by0, bx1, by1 = regions[0].bounds
            out[q, m] = (bx0 - x0, bx1 - x0, by0 - y0, by1 - y0)
    out.flags.writeable = False
    return out


@njit(cache=True)
def _axis_cover(centres: AnyArray, lo: float, hi: float, cell: float, n: int,
                out: AnyArray) -> None:
    """out[c] = (1/n)·#{ignition cells i: i·cell + lo ≤ centres[c] ≤ i·cell + hi}."""
    for c in range(len(centres)):
        u = centres[c]
        first = max(0, int(np.ceil((u - hi) / cell - 1e-9)))
        last = min(n - 1, int(np.floor((u - lo) / cell + 1e-9)))
        out[c] = max(0, last - first + 1) / n


@njit(cache=True)
def _birth_free(horizons: AnyArray, events: AnyArray, ext: AnyArray, xc: AnyArray,
                yc: AnyArray, cell: float, n: int, p_b: float) -> AnyArray:
    """Π_j (1 − p_b F_{k−j}(x)) per slice, F the mean over the phases (module docstring)."""
    n_h, phases = len(horizons), ext.shape[0]
    out = np.ones((n_h, len(yc), len(xc)))
    fx = np.empty((phases, len(xc)))
    fy = np.empty((phases, len(yc)))
    for i in range(n_h):
        k = horizons[i]
        for j in range(1, k + 1):
            if not events[j]:
                continue
            m = k - j
            for q in range(phases):
                _axis_cover(xc, ext[q, m, 0], ext[q, m, 1], cell, n, fx[q])
                _axis_cover(yc, ext[q, m, 2], ext[q, m, 3], cell, n, fy[q])
            for r in range(len(yc)):
                for c in range(len(xc)):
                    f = 0.0
                    for q in range(phases):
                        f += fx[q, c] * fy[q, r]
                    if f > 0.0:
                        out[i, r, c] *= 1.0 - p_b * f / phases
    return out


@lru_cache(maxsize=16)
def birth_levels(physics: PhysicsFireParams, fire: FireParams, area_size_m: float,
                 resolution_m: float, horizons: tuple[int, ...],
                 substeps_per_step: int) -> tuple[NDArray[np.uint8], ...]:
    """B_k per slice in 1/255 (read-only): the forecast of an area with no fire burning."""
    shape = grid_shape(area_size_m, resolution_m)
    k_max = horizons[-1] if horizons else 0
    life = life_events(k_max, fire, substeps_per_step)
    events = np.zeros(k_max + 1, dtype=np.bool_)
    events[1:] = np.diff(life) > 0
    ext = birth_extents(physics, fire, area_size_m, k_max)
    n = max(1, round(area_size_m / physics.cell_m))
    xc = (np.arange(shape[1]) + 0.5) * resolution_m
    yc = (np.arange(shape[0]) + 0.5) * resolution_m
    free = _birth_free(np.asarray(horizons, dtype=np.int64), events, np.ascontiguousarray(ext),
                       xc, yc, area_size_m / n, n, fire.p_birth)
    out = []
    for sl in free:
        lv = np.floor(np.clip(1.0 - sl, 0.0, 1.0) * LEVELS + 0.5).astype(np.uint8)
        lv.flags.writeable = False
        out.append(lv)
    return tuple(out)


def physics_forecast(proc: PhysicsFire, params: ForecastParams,
                     substeps_per_step: int = 1, issued_substep: int = 0) -> OccupancyForecast:
    """P_k on the grid for the slices of ``params`` from the process's current state (module
    docstring); ``substeps_per_step`` is the time-step length when ``life_base == "step"``."""
    if substeps_per_step < 1:
        raise ValueError(f"substeps_per_step must be >= 1, got {substeps_per_step}")
    fire = proc.fire
    n = substeps_per_step if fire.life_base == "step" else 1
    horizons = params.horizons(fire.substep_s)
    shape = grid_shape(proc.area_size_m, params.resolution_m)
    births = birth_levels(proc.physics, fire, proc.area_size_m, params.resolution_m, horizons, n)
    ahead = run_ahead(proc)
    entries = ahead.entries(horizons[-1] if horizons else 0)
    layers: list[NDArray[np.uint8]] = []
    for i, k in enumerate(horizons):
        occ = ahead.occupied(entries[k], params.resolution_m, shape)
        if not occ.any():
            layers.append(births[i])
            continue
        lv = births[i].copy()
        lv[occ] = LEVELS
        lv.flags.writeable = False
        layers.append(lv)
    return OccupancyForecast._made(params.resolution_m, fire.substep_s, horizons, tuple(layers),
                                   issued_substep, n)
