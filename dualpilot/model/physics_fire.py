"""Fires from Rothermel surface spread on pyretechnics' Eulerian level set (a named scenario).

The fire process a scenario (:mod:`dualpilot.model.scenarios`) names in place
of the rectangles of Sec. II-B, behind the same fire port: pyretechnics
spreads the burned area over a grid of the area [0, A]² (rows northwards,
columns eastwards), and each sub-step of T_f

* advances the level set to the fire clock (sub-steps × T_f);
* draws the paper's birth: with probability p_b (``FireParams.p_birth``, on
  the ``life_base`` time base) one cell ignites, uniform in the area and
  redrawn until its region keeps clear of the keep-out (the ignition
  clearance) and it has not burned yet;
* turns the burned raster into fronts: each 8-connected burned area is one
  front, its region the box of its active perimeter (burned cells with an
  unburned 4-neighbour in the grid) and its hull △ the convex hull of all it
  has burned and every region it had, both grown by :attr:`PhysicsFire.pad_m`
  and cut to the area. An area whose perimeter has no unburned fuel left is
  extinct; a burned area with no ignition of its own (a spot fire) is born.

Boxes, because the mission step's regions are axis-aligned rectangles (the
failure rule, the records, the wire format); the hull contains the region, so
a plan that clears the hulls by the planners' clearance clears the regions by
d_safe. Speeds m/s, lengths m, times s (pyretechnics' own: m/min and min).
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from typing import cast

import numpy as np

from dualpilot.model.fire import MAX_DRAWS, FireFront, FireParams
from dualpilot.model.fire_height import FireHeights
from dualpilot.model.geometry import Polytope, Rect
from dualpilot.model.physics_heights import PhysicsTops
from dualpilot.model.scenarios import (
    FuelMoisture,
    LwRatioModel,
    PhysicsFireParams,
    get_scenario,
)

#: pyretechnics ends a run with less than this much simulated time left (s): the level set
#: lags the fire clock by at most this much (eulerian_level_set.spread_fire_with_phi_field).
RUN_THRESHOLD_S = 1.0
#: pyretechnics ignites a spot fire this long after the firebrand lands, the time it takes to
#: build up to steady state (spot_fire.spot_ignition_time, Perryman 2012) (s).
SPOT_STEADY_STATE_S = 1200.0
#: Duration of the input cubes (min): longer than any mission's fire clock.
CUBE_DURATION_MIN = 7 * 24 * 60.0

_EIGHT = np.ones((3, 3), dtype=bool)
_FOUR = np.array([[False, True, False], [True, True, True], [False, True, False]])


def upwind_azimuth_deg(direction_rad: float) -> float:
    """pyretechnics' upwind direction (° clockwise from north) of a wind blowing towards
    ``direction_rad`` (rad from +x, counter-clockwise)."""
    return (90.0 - math.degrees(direction_rad) + 180.0) % 360.0


def midflame_wind_m_min(fuel_model: int, wind_speed_10m_mps: float) -> float:
    """The midflame wind (m/min) of a 10-m open wind over an unsheltered fuel bed, as the level
    set computes it (10 m → 20 ft: ÷ 1.15; the fuel bed's wind adjustment factor)."""
    import pyretechnics.conversion as conv
    import pyretechnics.fuel_models as fm
    import pyretechnics.surface_fire as sf

    wind_20ft = conv.wind_speed_10m_to_wind_speed_20ft(wind_speed_10m_mps * 3.6)  # km/h
    delta = fm.get_fuel_model(fuel_model)["delta"]  # ft
    return float(sf.calc_midflame_wind_speed(conv.km_hr_to_m_min(wind_20ft), delta, 0.0, 0.0))


def _surface_fire(fuel_model: int, moisture: FuelMoisture, midflame_wind_m_min: float,
                  upwind_deg: float, slope: float, aspect_deg: float,
                  lw_ratio_model: LwRatioModel,
                  use_wind_limit: bool) -> tuple[dict[str, float], dict[str, float]]:
    """pyretechnics' no-wind-no-slope and maximum surface fire behaviour of the fuel bed."""
    import pyretechnics.fuel_models as fm
    import pyretechnics.surface_fire as sf

    m = moisture
    moist = fm.moisturize(fm.get_fuel_model(fuel_model), (
        m.dead_1h, m.dead_10h, m.dead_100h, 0.0, m.live_herbaceous, m.live_woody))
    base = sf.calc_surface_fire_behavior_no_wind_no_slope(moist)
    head = sf.calc_surface_fire_behavior_max(base, midflame_wind_m_min, upwind_deg, slope,
                                             aspect_deg, use_wind_limit, lw_ratio_model)
    return base, head


def rothermel_spread(fuel_model: int, moisture: FuelMoisture, midflame_wind_m_min: float = 0.0,
                     upwind_deg: float = 0.0, slope: float = 0.0, aspect_deg: float = 0.0,
                     lw_ratio_model: LwRatioModel = "behave",
                     use_wind_limit: bool = True) -> tuple[float, float]:
    """(no-wind-no-slope, head) Rothermel surface spread rates (m/min) of pyretechnics.

    ``slope`` is rise/run, ``aspect_deg`` and ``upwind_deg`` ° clockwise from north; the head
    rate is in the direction of maximum spread, the effective wind speed limited unless
    ``use_wind_limit`` is False.
    """
    base, head = _surface_fire(fuel_model, moisture, midflame_wind_m_min, upwind_deg, slope,
                               aspect_deg, lw_ratio_model, use_wind_limit)
    return float(base["base_spread_rate"]), float(head["max_spread_rate"])


def _flat_fire(params: PhysicsFireParams) -> tuple[dict[str, float], dict[str, float]]:
    """The scenario's surface fire on flat ground under its wind (no-wind-no-slope, head)."""
    return _surface_fire(
        params.fuel_model, params.moisture,
        midflame_wind_m_min(params.fuel_model, params.wind_speed_mps),
        upwind_azimuth_deg(params.wind_direction_rad), 0.0, 0.0, params.lw_ratio_model, True)


def head_spread_rate_mps(params: PhysicsFireParams) -> float:
    """The head fire's Rothermel spread rate (m/s) on flat ground under the scenario's wind."""
    return float(_flat_fire(params)[1]["max_spread_rate"]) / 60.0


def fireline_intensities_kw_m(params: PhysicsFireParams) -> tuple[float, float]:
    """(no-wind-no-slope, head) Byram fireline intensities (kW/m) of the scenario's fuel bed
    on flat ground under its wind."""
    base, head = _flat_fire(params)
    return float(base["base_fireline_intensity"]), float(head["max_fireline_intensity"])


def scenario_tops(physics: PhysicsFireParams, heights: FireHeights) -> PhysicsTops:
    """The tops of the scenario's fronts (3-D): its intensities and midflame wind."""
    base, head = fireline_intensities_kw_m(physics)
    wind = midflame_wind_m_min(physics.fuel_model, physics.wind_speed_mps) / 60.0
    return PhysicsTops(heights, base, head, wind)


def clip_to_box(vertices: np.ndarray, lo: float, hi: float) -> np.ndarray:
    """A convex polygon (counter-clockwise vertices) cut to the square [lo, hi]²
    (Sutherland–Hodgman, one half-plane per side)."""
    pts = [tuple(v) for v in np.asarray(vertices, dtype=float)]
    for axis, bound, keep_below in ((0, lo, False), (0, hi, True), (1, lo, False),
                                    (1, hi, True)):
        def inside(p: tuple[float, ...], axis: int = axis, bound: float = bound,
                   keep_below: bool = keep_below) -> bool:
            return p[axis] <= bound if keep_below else p[axis] >= bound

        out: list[tuple[float, ...]] = []
        for i, cur in enumerate(pts):
            prev = pts[i - 1]
            if inside(cur) != inside(prev):
                t = (bound - prev[axis]) / (cur[axis] - prev[axis])
                cut = [prev[0] + t * (cur[0] - prev[0]), prev[1] + t * (cur[1] - prev[1])]
                cut[axis] = bound
                out.append((cut[0], cut[1]))
            if inside(cur):
                out.append(cur)
        pts = out
    return np.array(pts, dtype=float).reshape(-1, 2)


class PhysicsFire:
    """The burned area on the grid, its fronts and their hulls (the EWS's ground truth).

    ``fire`` gives T_f, p_b, the birth time base and whether extinct hulls are
    kept; ``physics`` everything else; ``heights`` (3-D) the fronts' tops
    (dualpilot/model/physics_heights.py). The keep-out of a birth is kept in the plane
    (a cell's top is not known before it burns; the planar test is the stricter one).
    """

    def __init__(self, physics: PhysicsFireParams, fire: FireParams, area_size_m: float,
                 heights: FireHeights | None = None):
        import pyretechnics.eulerian_level_set as els
        import pyretechnics.fuel_models as fm
        from pyretechnics.space_time_cube import SpaceTimeCube

        if not fm.fuel_model_exists(physics.fuel_model):
            raise ValueError(f"pyretechnics has no fuel model {physics.fuel_model}")
        if not fm.get_fuel_model(physics.fuel_model)["burnable"]:
            raise ValueError(f"fuel model {physics.fuel_model} does not burn")
        self.physics = physics
        self.fire = fire
        self.area_size_m = float(area_size_m)
        self.n = max(1, round(self.area_size_m / physics.cell_m))
        self.cell_m = self.area_size_m / self.n
        self.head_rate_mps = head_spread_rate_mps(physics)
        #: growth of the burned cells: the level-set front lies within half a cell of a burned
        #: cell's edge, and lags the fire clock by at most RUN_THRESHOLD_S
        self.pad_m = self.cell_m / 2 + self.head_rate_mps * RUN_THRESHOLD_S
        self._els = els
        self._shape = (1, self.n, self.n)
        self._res = (CUBE_DURATION_MIN, self.cell_m, self.cell_m)
        m, p = physics.moisture, physics
        values: dict[str, float] = {
            "slope": 0.0, "aspect": 0.0, "fuel_model": p.fuel_model, "canopy_cover": 0.0,
            "canopy_height": 0.0, "canopy_base_height": 0.0, "canopy_bulk_density": 0.0,
            "wind_speed_10m": p.wind_speed_mps * 3.6,
            "upwind_direction": upwind_azimuth_deg(p.wind_direction_rad),
            "fuel_moisture_dead_1hr": m.dead_1h, "fuel_moisture_dead_10hr": m.dead_10h,
            "fuel_moisture_dead_100hr": m.dead_100h,
            "fuel_moisture_live_herbaceous": m.live_herbaceous,
            "fuel_moisture_live_woody": m.live_woody, "foliar_moisture": 0.9}
        if p.spotting is not None:
            values["temperature"] = p.spotting.temperature_c
        self._cubes = {k: SpaceTimeCube(self._shape, v) for k, v in values.items()}
        self.state = self._new_state(0.0)
        self.clock_s = 0.0
        #: firebrands in flight: ignition time (min) → cells, re-timed by build_up_s
        self.spots: dict[float, set[object]] = {}
        # ignitions: (front id, row, col, born step); a retired id never names a front again
        self._ignitions: list[tuple[int, int, int, int]] = []
        self._retired: set[int] = set()
        self._hulls: dict[int, np.ndarray] = {}  # front id → hull vertices △ so far
        #: front id → (cells, ignitions, front) of the last update, reused while unchanged
        self._cache: dict[int, tuple[int, tuple[int, ...], FireFront]] = {}
        self._owner: dict[int, int] = {}  # ignition id → the front it burns in
        self._burned_seen = -1
        self.next_id = 0
        self.fronts: list[FireFront] = []
        self.extinct_hulls: list[Polytope] = []
        self.extinct_tops: list[float] = []  # their tops (3-D)
        self.tops = None if heights is None else scenario_tops(physics, heights)
        self.births_skipped = 0
        #: the forecast's copy of the level set run ahead, kept between issues
        #: (dualpilot/model/physics_forecast.py); it never touches this process
        self.run_ahead: object | None = None

    # -- the level set --------------------------------------------------------------------------
    def _new_state(self, start_min: float) -> object:
        state = self._els.SpreadState(self._shape)
        state.set_resolution(self._res)
        state.set_start_time(start_min)
        return state

    def burned(self) -> np.ndarray:
        """Burned cells (rows northwards, columns eastwards): the level set's φ < 0."""
        phi = self.state.get_full_matrices(["phi"])["phi"]  # type: ignore[attr-defined]
        return np.asarray(phi) < 0.0

    def _lag_s(self) -> float:
        return self.clock_s - 60.0 * float(self.state.get_simulation_time())  # type: ignore

    def _spread(self, rng: np.random.Generator) -> None:
        """Run the level set up to the fire clock (to within RUN_THRESHOLD_S)."""
        lag_min = self._lag_s() / 60.0
        if lag_min * 60.0 <= RUN_THRESHOLD_S + 1e-9:
            return
        p = self.physics
        if p.spotting is None:
            self.run(self.state, lag_min)
            return
        s = p.spotting
        out = self.run(self.state, lag_min, self.spots, {
            "random_seed": int(rng.integers(2**63)),
            "firebrands_per_unit_heat": s.firebrands_per_unit_heat,
            "downwind_distance_mean": s.downwind_distance_mean_m,
            "fireline_intensity_exponent": s.fireline_intensity_exponent,
            "wind_speed_exponent": s.wind_speed_exponent,
            "downwind_variance_mean_ratio": s.downwind_variance_mean_ratio_m,
            "crosswind_distance_stdev": s.crosswind_distance_stdev_m,
            "decay_distance": s.decay_distance_m})
        self.spots = self._retimed(cast(dict[float, set[object]], out["spot_ignitions"]),
                                   s.build_up_s)

    def run(self, state: object, lag_min: float, spots: dict[float, set[object]] | None = None,
            spot_config: dict[str, object] | None = None) -> dict[str, object]:
        """One pyretechnics run of ``state`` for ``lag_min`` minutes from its own time (the
        firebrands ``spots`` in flight ignite when due; ``spot_config`` casts new ones)."""
        p = self.physics
        extra: dict[str, object] = {}
        if spots is not None:
            extra["spot_ignitions"] = dict(spots)
        if spot_config is not None:
            extra["spot_config"] = spot_config
        out: dict[str, object] = self._els.spread_fire_with_phi_field(
            self._cubes, state, self._res, float(state.get_simulation_time()),  # type: ignore
            lag_min, max_cells_per_timestep=p.max_cells_per_timestep,
            surface_lw_ratio_model=p.lw_ratio_model, **extra)
        return out

    def _retimed(self, pending: dict[float, set[object]],
                 build_up_s: float) -> dict[float, set[object]]:
        """The firebrands in flight, the ones cast during the last run moved from
        pyretechnics' steady-state ignition to ``build_up_s`` after landing."""
        shift_min = (build_up_s - SPOT_STEADY_STATE_S) / 60.0
        out: dict[float, set[object]] = {}
        for when, cells in pending.items():
            known = self.spots.get(when, set())
            if known:
                out.setdefault(when, set()).update(cells & known)
            new = set(cells) - known
            if new:
                out.setdefault(float(when) + shift_min, set()).update(new)
        return out

    # -- births ---------------------------------------------------------------------------------
    def _cell_box(self, row: int, col: int) -> Rect:
        return self._box(row, row, col, col)

    def _box(self, r0: int, r1: int, c0: int, c1: int) -> Rect:
        """Rows r0..r1 × columns c0..c1 grown by pad_m, cut to the area."""
        d, a = self.cell_m, self.area_size_m
        x0, x1 = max(0.0, c0 * d - self.pad_m), min(a, (c1 + 1) * d + self.pad_m)
        y0, y1 = max(0.0, r0 * d - self.pad_m), min(a, (r1 + 1) * d + self.pad_m)
        return Rect((x0 + x1) / 2, (y0 + y1) / 2, x1 - x0, y1 - y0)

    def _cell_of(self, x: float, y: float) -> tuple[int, int]:
        n = self.n
        return (min(n - 1, max(0, int(y // self.cell_m))),
                min(n - 1, max(0, int(x // self.cell_m))))

    def _draw_cell(self, rng: np.random.Generator, center: tuple[float, float] | None,
                   keep_out: tuple[np.ndarray, float] | None) -> tuple[int, int] | None:
        """b_t: a cell uniform in the area, not burned and clear of ``keep_out``; None if
        :data:`MAX_DRAWS` draws find none (one try when ``center`` is given)."""
        burned = self.burned()
        for _ in range(1 if center is not None else MAX_DRAWS):
            if center is None:
                x, y = (float(v) for v in rng.uniform(0.0, self.area_size_m, size=2))
            else:
                x, y = center
            row, col = self._cell_of(x, y)
            if burned[row, col]:
                continue
            if keep_out is not None and (
                    self._cell_box(row, col).distance(keep_out[0]) < keep_out[1]):
                continue
            return row, col
        return None

    def _ignite(self, row: int, col: int, step: int) -> None:
        if self._lag_s() > RUN_THRESHOLD_S + 1e-9:  # idle level set: restart it at the clock
            old = self.state.get_full_matrices(["phi"])["phi"]  # type: ignore[attr-defined]
            burned = np.asarray(old) < 0.0
            self.state = self._new_state(self.clock_s / 60.0)
            if burned.any():
                self.state.ignite_cells(  # type: ignore[attr-defined]
                    (0, 0), np.ascontiguousarray(np.where(burned, old, 1.0), dtype=np.float32))
        self.state.ignite_cell((row, col))  # type: ignore[attr-defined]
        self._ignitions.append((self.next_id, row, col, step))
        self.next_id += 1

    def spawn(self, rng: np.random.Generator, step: int, center: tuple[float, float] | None = None,
              keep_out: tuple[np.ndarray, float] | None = None) -> FireFront:
        """Ignite one cell now (at ``center``, else drawn as a birth); its new front."""
        cell = self._draw_cell(rng, center, keep_out)
        if cell is None:
            raise ValueError("no unburned cell clear of the keep-out to ignite")
        self._ignite(*cell, step)
        new_id = self.next_id - 1
        self._update_fronts(step)
        owner = self._owner[new_id]  # the ignition's own front, or the one it merged into
        return next(f for f in self.fronts if f.front_id == owner)

    # -- one sub-step ---------------------------------------------------------------------------
    def substep(self, rng: np.random.Generator, step: int, life: bool,
                keep_out: tuple[np.ndarray, float] | None) -> list[FireFront]:
        """One sub-step of T_f during mission step ``step``: spread, birth (when ``life``), fronts.

        Returns the fronts born in it: its birth and any spot fires.
        """
        first_new = self.next_id
        self.clock_s += self.fire.substep_s
        self._spread(rng)
        if life and rng.random() < self.fire.p_birth:
            cell = self._draw_cell(rng, None, keep_out)
            if cell is None:
                self.births_skipped += 1
            else:
                self._ignite(*cell, step)
        self._update_fronts(step)
        return [f for f in self.fronts if f.front_id >= first_new]

    def _update_fronts(self, step: int) -> None:
        """The fronts of the burned raster (see the module docstring)."""
        burned = self.burned()
        count = int(burned.sum())
        if count == self._burned_seen:
            return  # cells never unburn: the same set, the same fronts
        self._burned_seen = count
        from scipy import ndimage  # 0.2 s to import: where a raster is read

        labels, _ = ndimage.label(burned, structure=_EIGHT)
        active = burned & ndimage.binary_dilation(~burned, structure=_FOUR, border_value=0)
        owners: dict[int, list[int]] = {}
        for fid, row, col, _ in self._ignitions:
            if fid not in self._retired and labels[row, col]:
                owners.setdefault(int(labels[row, col]), []).append(fid)
        born_at = {fid: b for fid, _, _, b in self._ignitions}
        sizes = np.bincount(labels.ravel())
        fronts: list[FireFront] = []
        cache: dict[int, tuple[int, tuple[int, ...], FireFront]] = {}
        for k, sl in enumerate(ndimage.find_objects(labels), start=1):
            if sl is None:
                continue
            ids = sorted(owners.get(k, []))
            if ids:  # cells only ever join an area: the same size and ignitions, the same cells
                seen = self._cache.get(ids[0])
                if seen is not None and seen[:2] == (int(sizes[k]), tuple(ids)):
                    cache[ids[0]] = seen
                    fronts.append(seen[2])
                    continue
            mine = labels[sl] == k
            act = mine & active[sl]
            if not act.any():  # burned out: extinct, never a front again
                for fid in ids:
                    self._retire(fid)
                continue
            if not ids:  # a spot fire (or fire reaching an extinct area): a new front
                r, c = (int(v) for v in np.argwhere(act)[0])
                self._ignitions.append((self.next_id, sl[0].start + r, sl[1].start + c, step))
                born_at[self.next_id] = step
                ids = [self.next_id]
                self.next_id += 1
            fid = ids[0]
            self._owner.update((i, fid) for i in ids)
            region, hull = _front_shape(self, mine, act, sl, ids)
            self._hulls[fid] = hull.vertices
            for merged in ids[1:]:  # merged into the oldest: its hull lives on in this one
                self._retired.add(merged)
                self._hulls.pop(merged, None)
            top, hull_top = _front_tops(self.tops, self.state, sl, act, fid, ids[1:])
            front = FireFront(fid, born_at[fid], self.head_rate_mps,
                              self.physics.wind_direction_rad, region, hull, top, hull_top)
            cache[fid] = (int(sizes[k]), tuple(ids), front)
            fronts.append(front)
        self._cache = cache
        self.fronts = sorted(fronts, key=lambda f: f.front_id)

    def _retire(self, fid: int) -> None:
        self._retired.add(fid)
        hull = self._hulls.pop(fid, None)
        top = None if self.tops is None else self.tops.retire(fid)
        if hull is not None and self.fire.keep_extinct_hulls:
            self.extinct_hulls.append(Polytope.from_vertices(hull))
            if top is not None:
                self.extinct_tops.append(top)

    def _cell_corners(self, mine: np.ndarray, row0: int, col0: int) -> np.ndarray:
        """Corners of each row's first and last cell of a burned area, grown by pad_m (m)."""
        has = mine.any(axis=1)
        first = mine.argmax(axis=1)[has]
        last = mine.shape[1] - 1 - mine[:, ::-1].argmax(axis=1)[has]
        rows = np.nonzero(has)[0] + row0
        d, g = self.cell_m, self.pad_m
        xl, xr = (first + col0) * d - g, (last + col0 + 1) * d + g
        yb, yt = rows * d - g, (rows + 1) * d + g
        return np.column_stack([np.concatenate([xl, xl, xr, xr]),
                                np.concatenate([yb, yt, yb, yt])])



def _front_tops(tops: PhysicsTops | None, state: object, window: tuple[slice, ...],
                active: np.ndarray, fid: int,
                merged: list[int]) -> tuple[float | None, float | None]:
    """(top, hull top) (m) of front ``fid``, whose burning cells are ``active`` within
    ``window`` of the grid; (None, None) in 2-D."""
    if tops is None:
        return None, None
    return tops.of_front(tops.layer(state)[window], active, fid, merged)


def covered_area_m2(fire: PhysicsFire, resolution_m: float = 2.5) -> tuple[float, float]:
    """(burned area, area inside the union of the fronts' hulls) in m², the union counted on
    a lattice of ``resolution_m``: what the planners avoid against what has burned."""
    a = fire.area_size_m
    ticks = np.arange(resolution_m / 2, a, resolution_m)
    xs, ys = np.meshgrid(ticks, ticks)
    pts = np.column_stack([xs.ravel(), ys.ravel()])
    inside = np.zeros(len(pts), dtype=bool)
    for front in fire.fronts:
        h = front.hull
        inside |= (pts @ h.A.T <= h.b).all(axis=1)
    return (float(fire.burned().sum()) * fire.cell_m**2,
            float(inside.sum()) * resolution_m**2)


def measure(name: str, seeds: Sequence[int], checkpoints: Sequence[int],
            fire: FireParams = FireParams()) -> list[dict[str, float]]:
    """Each checkpoint (sub-steps) of scenario ``name`` from each seed's fire stream, births
    anywhere: fronts, burned area and hull union (m²), hull vertices, level-set cost (ms a
    sub-step), averaged over the seeds."""
    from dualpilot.spec import Stream, stream_rng

    rows: dict[int, list[dict[str, float]]] = {c: [] for c in checkpoints}
    warm = PhysicsFire(get_scenario(name).params, fire, 1000.0)  # pyretechnics' first-use cost
    warm.spawn(np.random.default_rng(0), 0, center=(500.0, 500.0))
    for _ in range(4):
        warm.substep(np.random.default_rng(0), 0, False, None)
    for seed in seeds:
        proc = PhysicsFire(get_scenario(name).params, fire, 1000.0)
        rng = stream_rng(seed, Stream.FIRE)
        spent, done = 0.0, 0
        for c in sorted(checkpoints):
            t0 = time.perf_counter()
            while done < c:
                proc.substep(rng, done // 10, True, None)
                done += 1
            spent += time.perf_counter() - t0
            burned, hulls = covered_area_m2(proc)
            vertices = [len(f.hull.vertices) for f in proc.fronts]
            rows[c].append({"fronts": len(proc.fronts), "burned_m2": burned,
                            "hull_union_m2": hulls,
                            "hull_vertices": float(np.mean(vertices)) if vertices else 0.0,
                            "ms_per_substep": spent / max(done, 1) * 1e3})
    return [{"substeps": float(c), **{k: float(np.mean([r[k] for r in rows[c]]))
                                       for k in rows[c][0]}} for c in sorted(checkpoints)]


def _front_shape(fire: PhysicsFire, mine: np.ndarray, act: np.ndarray,
                 sl: tuple[slice, slice], ids: list[int]) -> tuple[Rect, Polytope]:
    """The box of an area's burning cells ``act`` and the hull of its burned cells ``mine``
    (within the slices ``sl``) with the hulls its fronts ``ids`` had, clipped to the area."""
    rows, cols = np.nonzero(act)
    region = fire._box(sl[0].start + int(rows.min()), sl[0].start + int(rows.max()),
                       sl[1].start + int(cols.min()), sl[1].start + int(cols.max()))
    pts = [fire._cell_corners(mine, sl[0].start, sl[1].start), region.corners()]
    pts += [fire._hulls[i] for i in ids if i in fire._hulls]
    hull = Polytope.from_vertices(np.vstack(pts))
    if hull.vertices.min() < 0.0 or hull.vertices.max() > fire.area_size_m:
        hull = Polytope.from_vertices(clip_to_box(hull.vertices, 0.0, fire.area_size_m))
    return region, hull
