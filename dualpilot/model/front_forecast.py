"""The forecast of the paper's rectangles (Sec. II-B): P(inside a region) k sub-steps ahead.

From the current fronts of :mod:`dualpilot.model.fire`, the probability that
the centre x of a grid cell lies inside an active region after k sub-steps
(k·T_f seconds ahead) is

    P_k(x) = 1 − (1 − B_k(x)) · Π_i (1 − S_i(k) C_ik(x)),

exact in everything but the fronts' motion:

* fronts survive, move and are redrawn with independent draws, and births
  are independent of them: occupancy by distinct fronts are independent events;
* S_i(k) = p_s^{L_k}, L_k the life events (Bernoulli birth/survival draws) in
  sub-steps 1..k: every sub-step, or (``life_base = "step"``) the first
  sub-step of each time-step, the forecast's first sub-step starting one and
  a time-step lasting ``substeps_per_step`` sub-steps;
* C_ik(x) = E[c(x − y_ik)]: the mean over ``members`` Monte-Carlo paths of the
  Gauss–Markov speed and direction of the cover c of the region centred at
  y_ik. The sides are integrated exactly: a side redrawn from U[a, b] covers
  an offset u with f(u) = P(U ≥ 2|u|) = clip((b − 2|u|)/(b − a), 0, 1), a
  kept side w (``extent = "birth"``, or k = 0) with 1{|u| ≤ w/2};
* B_k(x) = 1 − Π_j (1 − p_b p_s^{L_k − L_j} F(x₁ − D̄₁) F(x₂ − D̄₂)) over the
  life events j ≤ k: a front born at j (centre uniform in [0, A]², sides
  U[a, b]) covers x with F(u) = (1/A)∫₀^A f(u − s) ds per axis once moved by
  D̄ = D̄(k − j), its exact mean displacement (the spread of the displacement,
  under 15 m in 40 s, is neglected for births only).

The ignition keep-out (``MissionParams.ignition_clearance_m``) and redraw
clearance are not modelled: the UAV's future positions are not known, so the
forecast errs high near the UAV. The result is an
:class:`dualpilot.model.forecast.OccupancyForecast` (levels of 1/255); a front whose
survival to a slice is below half a level is left out of it (a level changes by one at
most).
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import lru_cache
from math import ceil, cos, exp, floor, sin, sqrt

import numpy as np
from numba import njit
from numpy.typing import NDArray

from dualpilot.arrays import AnyArray, Array
from dualpilot.model.fire import FireFront, FireParams
from dualpilot.model.forecast import (
    LEVELS,
    ForecastParams,
    OccupancyForecast,
    grid_shape,
    life_events,
)

#: A front whose chance to survive until a slice is below half a level is left out of that
#: slice: it changes P by less than that, a level by at most one.
MIN_SURVIVAL = 0.5 / LEVELS


def side_cover(u: Array, a: float, b: float) -> Array:
    """f(u) = P(W ≥ 2|u|) for a side W ~ U[a, b] (m): the chance a redrawn side covers offset u."""
    d = 2.0 * np.abs(np.asarray(u, dtype=float))
    if b - a <= 1e-12:
        return (d <= a).astype(float)
    return np.asarray(np.clip((b - d) / (b - a), 0.0, 1.0))


def area_cover(u: Array, a: float, b: float, area_m: float) -> Array:
    """F(u) = (1/A)∫₀^A f(u − s) ds: chance that a side U[a, b] whose centre is uniform in
    [0, A] covers u (m) (:func:`side_cover` integrated in closed form)."""
    u = np.asarray(u, dtype=float)
    return np.asarray((_cover_integral(u, a, b) - _cover_integral(u - area_m, a, b)) / area_m)


def _cover_integral(t: Array, a: float, b: float) -> Array:
    """Φ(t) = ∫_{−∞}^t f(s) ds for :func:`side_cover`'s f."""
    al, be = a / 2, b / 2
    mean = (a + b) / 2

    def left(s: Array) -> Array:  # Φ on s <= 0
        if b - a <= 1e-12:
            return np.clip(s + al, 0.0, None)
        ramp = np.where(s <= -be, 0.0, (s + be) ** 2 / (b - a))
        return np.asarray(np.where(s <= -al, ramp, (b - a) / 4 + (s + al)))

    return np.asarray(np.where(t <= 0, left(np.minimum(t, 0.0)),
                               mean - left(np.minimum(-t, 0.0))))


def mean_displacement(substeps: int, fire: FireParams) -> Array:
    """D̄(m), m = 0..substeps: the mean move (m) of a front born at the means after m sub-steps.

    θ_m is Gaussian with the mean ȳ^d and variance σ_d²(1 − γ^{2m}), so
    E[ν_m cos θ_m] = ν̄ cos ȳ^d · exp(−Var θ_m / 2) (speed and direction independent).
    """
    g, dt = fire.gamma, fire.substep_s
    out = np.zeros((substeps + 1, 2))
    for m in range(1, substeps + 1):
        shrink = exp(-0.5 * fire.direction_sigma_rad ** 2 * (1.0 - g ** (2 * m)))
        step = fire.speed_mean_mps * dt * shrink
        out[m, 0] = out[m - 1, 0] + step * cos(fire.direction_mean_rad)
        out[m, 1] = out[m - 1, 1] + step * sin(fire.direction_mean_rad)
    return out


@njit(cache=True)
def _paths(v0: float, th0: float, x0: float, y0: float, z: AnyArray, gamma: float,
           v_mean: float, th_mean: float, v_sigma: float, th_sigma: float,
           dt: float) -> tuple[AnyArray, AnyArray]:
    """Centres (members, K+1) of a front's Gauss–Markov paths; z (members, K, 2) N(0, 1).

    The arithmetic of :meth:`dualpilot.model.fire.FireFront.advance_clear`.
    """
    m_count, k_count = z.shape[0], z.shape[1]
    xs = np.empty((m_count, k_count + 1))
    ys = np.empty((m_count, k_count + 1))
    noise = sqrt(1.0 - gamma * gamma)
    for m in range(m_count):
        v, th, x, y = v0, th0, x0, y0
        xs[m, 0] = x
        ys[m, 0] = y
        for j in range(k_count):
            v = gamma * v + (1 - gamma) * v_mean + noise * (v_sigma * z[m, j, 0])
            th = gamma * th + (1 - gamma) * th_mean + noise * (th_sigma * z[m, j, 1])
            dist = v * dt
            x = x + dist * cos(th)
            y = y + dist * sin(th)
            xs[m, j + 1] = x
            ys[m, j + 1] = y
    return xs, ys


@njit(cache=True)
def _cover(c: float, centre: float, half: float, a: float, b: float, kept: bool) -> float:
    """Chance that a side centred at ``centre`` covers coordinate c: kept (half-side ``half``,
    the bounds of :class:`dualpilot.model.geometry.Rect`) or redrawn from U[a, b]."""
    if kept:
        return 1.0 if centre - half <= c <= centre + half else 0.0
    d = 2.0 * abs(c - centre)
    if b - a <= 1e-12:
        return 1.0 if d <= a else 0.0
    v = (b - d) / (b - a)
    return 1.0 if v >= 1.0 else (v if v > 0.0 else 0.0)


@njit(cache=True)
def _level(p: float) -> np.uint8:
    """P as the nearest level (1/255 steps), clipped to [0, 1]."""
    p = 0.0 if p < 0.0 else (1.0 if p > 1.0 else p)
    return np.uint8(floor(p * LEVELS + 0.5))


@njit(cache=True, fastmath=True)
def _dot(x: AnyArray, y: AnyArray, n: int) -> float:
    """Σ_{m<n} x_m y_m, vectorised (the order of the sum is the compiler's)."""
    acc = 0.0
    for m in range(n):
        acc += x[m] * y[m]
    return acc


@njit(cache=True)
def _window(lo: float, hi: float, half: float, res: float, origin: float,
            n: int) -> tuple[int, int]:
    """The cells whose centres lie in [lo − half, hi + half] (first, last; last < first: none)."""
    first = max(0, int(ceil((lo - half - origin) / res - 0.5)))
    last = min(n - 1, int(floor((hi + half - origin) / res - 0.5)))
    return first, last


@njit(cache=True)
def _covers(g: AnyArray, sums: AnyArray, same: AnyArray, first: int, last: int,
            centres: AnyArray, members: int, half: float, a: float, b: float, kept: bool,
            res: float, origin: float) -> None:
    """g[c, m]: member m's cover of cell c's coordinate; sums over members; same: all equal.

    A cell every member covers wholly, or none at all (the members' centres all
    within, or all beyond, the flat part of the cover), is set without the members.
    """
    lo, hi = centres[0], centres[0]
    for m in range(1, members):
        lo, hi = min(lo, centres[m]), max(hi, centres[m])
    full = half if kept else a / 2  # |x − centre| within this: covered for sure
    none = half if kept else b / 2  # beyond this (kept: strictly): never covered
    for c in range(first, last + 1):
        x = origin + (c + 0.5) * res
        if hi - full <= x <= lo + full and (kept or b - a > 1e-12):
            v = 1.0
        elif (x < lo - none or x > hi + none) if kept else (x <= lo - none or x >= hi + none):
            v = 0.0
        else:
            v = -1.0
        if v >= 0.0:
            for m in range(members):
                g[c, m] = v
            sums[c] = v * members
            same[c] = True
            continue
        tot = 0.0
        eq = True
        for m in range(members):
            v = _cover(x, centres[m], half, a, b, kept)
            g[c, m] = v
            tot += v
            eq = eq and v == g[c, 0]
        sums[c] = tot
        same[c] = eq


@njit(cache=True)
def _fronts(levels: AnyArray, base: AnyArray, horizons: AnyArray, survive: AnyArray,
            xs: AnyArray, ys: AnyArray, kept_after: bool, widths: AnyArray, heights: AnyArray,
            a: float, b: float, res: float, ox: float, oy: float) -> None:
    """levels[i] = level of 1 − base[i]·Π_f (1 − S(k_i)·C_f(k_i)) where some front f can be.

    xs, ys (fronts, members, K+1): the fronts' centre paths. Per slice, a cell's
    product starts from ``base`` when a front's window first reaches it.
    """
    n_h, ny, nx = levels.shape
    n_f, m_count = xs.shape[0], xs.shape[1]
    gx = np.empty((nx, m_count))
    gy = np.empty((ny, m_count))
    sx, sy = np.empty(nx), np.empty(ny)
    cx_same, cy_same = np.empty(nx, dtype=np.bool_), np.empty(ny, dtype=np.bool_)
    buf = np.empty((ny, nx))
    stamp = np.zeros((ny, nx), dtype=np.int32)
    boxes = np.empty((n_f, 4), dtype=np.int64)
    for i in range(n_h):
        k = horizons[i]
        s = survive[i]
        mark = i + 1
        kept = kept_after or k == 0
        members = 1 if k == 0 else m_count  # k = 0: the current region, no draw yet
        scale = s / members
        for f in range(n_f):
            boxes[f, 0], boxes[f, 1] = 0, -1
            if s < MIN_SURVIVAL:
                continue
            hx = widths[f] / 2 if kept else b / 2
            hy = heights[f] / 2 if kept else b / 2
            lo_x, hi_x = xs[f, 0, k], xs[f, 0, k]
            lo_y, hi_y = ys[f, 0, k], ys[f, 0, k]
            for m in range(1, members):
                lo_x, hi_x = min(lo_x, xs[f, m, k]), max(hi_x, xs[f, m, k])
                lo_y, hi_y = min(lo_y, ys[f, m, k]), max(hi_y, ys[f, m, k])
            j0, j1 = _window(lo_x, hi_x, hx, res, ox, nx)
            l0, l1 = _window(lo_y, hi_y, hy, res, oy, ny)
            if j1 < j0 or l1 < l0:
                continue
            boxes[f, 0], boxes[f, 1], boxes[f, 2], boxes[f, 3] = j0, j1, l0, l1
            _covers(gx, sx, cx_same, j0, j1, xs[f, :, k], members, hx, a, b, kept, res, ox)
            _covers(gy, sy, cy_same, l0, l1, ys[f, :, k], members, hy, a, b, kept, res, oy)
            for r in range(l0, l1 + 1):
                for j in range(j0, j1 + 1):
                    if stamp[r, j] != mark:
                        stamp[r, j] = mark
                        buf[r, j] = base[i, r, j]
                    if cx_same[j]:  # every member covers column j alike
                        acc = gx[j, 0] * sy[r]
                    elif cy_same[r]:
                        acc = gy[r, 0] * sx[j]
                    else:
                        acc = _dot(gx[j], gy[r], members)
                    if acc > 0.0:
                        buf[r, j] *= 1.0 - scale * acc
        for f in range(n_f):
            j0, j1, l0, l1 = boxes[f, 0], boxes[f, 1], boxes[f, 2], boxes[f, 3]
            for r in range(l0, l1 + 1):
                for j in range(j0, j1 + 1):
                    levels[i, r, j] = _level(1.0 - buf[r, j])


@njit(cache=True)
def _levels_of(free: AnyArray) -> AnyArray:
    """:func:`_level` of 1 − free, cell by cell."""
    out = np.empty(free.shape, dtype=np.uint8)
    flat, res = free.ravel(), out.ravel()
    for c in range(len(flat)):
        res[c] = _level(1.0 - flat[c])
    return out


@njit(cache=True)
def _birth_free(horizons: AnyArray, events: AnyArray, life: AnyArray, disp: AnyArray,
                xc: AnyArray, yc: AnyArray, p_b: float, p_s: float, a: float, b: float,
                area: float) -> AnyArray:
    """Π_j (1 − p_b p_s^{L_k − L_j} F(x − D̄)) per slice (see the module docstring)."""
    n_h = len(horizons)
    out = np.ones((n_h, len(yc), len(xc)))
    u = np.empty(len(xc))
    v = np.empty(len(yc))
    for i in range(n_h):
        k = horizons[i]
        for j in range(1, k + 1):
            if not events[j]:
                continue
            wgt = p_b * p_s ** (life[k] - life[j])
            if wgt <= 0.0:
                continue
            dx, dy = disp[k - j, 0], disp[k - j, 1]
            for c in range(len(xc)):
                u[c] = _area_cover_1(xc[c] - dx, a, b, area)
            for r in range(len(yc)):
                v[r] = _area_cover_1(yc[r] - dy, a, b, area)
            for r in range(len(yc)):
                if v[r] == 0.0:
                    continue
                for c in range(len(xc)):
                    out[i, r, c] *= 1.0 - wgt * v[r] * u[c]
    return out


@njit(cache=True)
def _phi_left(s: float, a: float, b: float) -> float:
    al, be = a / 2, b / 2
    if b - a <= 1e-12:
        return max(s + al, 0.0)
    if s <= -be:
        return 0.0
    if s <= -al:
        return (s + be) ** 2 / (b - a)
    return (b - a) / 4 + (s + al)


@njit(cache=True)
def _phi(t: float, a: float, b: float) -> float:
    if t <= 0.0:
        return _phi_left(t, a, b)
    return (a + b) / 2 - _phi_left(-t, a, b)


@njit(cache=True)
def _area_cover_1(u: float, a: float, b: float, area: float) -> float:
    return (_phi(u, a, b) - _phi(u - area, a, b)) / area


@lru_cache(maxsize=16)
def _births(fire: FireParams, area_m: float, res: float, shape: tuple[int, int],
            horizons: tuple[int, ...], substeps_per_step: int) -> AnyArray:
    """The births' factor 1 − B_k per slice; it depends on no front, so it is kept."""
    k_max = horizons[-1] if horizons else 0
    life = life_events(k_max, fire, substeps_per_step)
    events = np.zeros(k_max + 1, dtype=np.bool_)
    events[1:] = np.diff(life) > 0
    xc = (np.arange(shape[1]) + 0.5) * res
    yc = (np.arange(shape[0]) + 0.5) * res
    free = _birth_free(np.asarray(horizons, dtype=np.int64), events, life.astype(np.int64),
                       mean_displacement(k_max, fire), xc, yc, fire.p_birth, fire.p_survive,
                       fire.side_min_m, fire.side_max_m, area_m)
    out = free.astype(np.float32)  # half the memory a forecast reads; 1/255 steps need less
    out.flags.writeable = False
    return out


@lru_cache(maxsize=16)
def _birth_layers(fire: FireParams, area_m: float, res: float, shape: tuple[int, int],
                  horizons: tuple[int, ...], substeps_per_step: int
                  ) -> tuple[NDArray[np.uint8], ...]:
    """:func:`_birth_levels` slice by slice (read-only views)."""
    return tuple(_birth_levels(fire, area_m, res, shape, horizons, substeps_per_step))


@lru_cache(maxsize=16)
def _birth_levels(fire: FireParams, area_m: float, res: float, shape: tuple[int, int],
                  horizons: tuple[int, ...], substeps_per_step: int) -> NDArray[np.uint8]:
    """:func:`_births` as levels (the forecast of an area without fronts), read-only."""
    free = _births(fire, area_m, res, shape, horizons, substeps_per_step)
    out = _levels_of(free)
    out.flags.writeable = False
    return out


def front_forecast(
    fronts: Sequence[FireFront],
    fire: FireParams,
    area_size_m: float,
    rng: np.random.Generator | None,
    params: ForecastParams = ForecastParams(),
    substeps_per_step: int = 1,
    issued_substep: int = 0,
) -> OccupancyForecast:
    """P_k on the grid for the slices of ``params`` from ``fronts`` (module docstring).

    ``rng`` draws the motion paths only (never pass a mission's own stream:
    see :func:`dualpilot.spec.forecast_rng`; None will do without fronts);
    ``substeps_per_step`` is the
    time-step length assumed when ``fire.life_base == "step"``.
    """
    if substeps_per_step < 1:
        raise ValueError(f"substeps_per_step must be >= 1, got {substeps_per_step}")
    n = substeps_per_step if fire.life_base == "step" else 1
    key = (fire, float(area_size_m), params.resolution_m,
           grid_shape(area_size_m, params.resolution_m), params.horizons(fire.substep_s), n)
    horizons, hz, survive = _schedule(fire, key[4], n)
    births = _birth_levels(*key)
    reach = int(np.count_nonzero(survive >= MIN_SURVIVAL))  # the slices a front can change
    if not fronts or not reach:  # the births alone: their kept, read-only slices
        layers: tuple[NDArray[np.uint8], ...] = _birth_layers(*key)
    else:
        if rng is None:
            raise ValueError("a forecast of fronts needs a generator for their motion")
        work = np.array(births[:reach])  # survival only falls: the first ``reach`` slices
        k_max = horizons[reach - 1]  # the paths need only reach the last of them
        z = rng.standard_normal((len(fronts), params.members, k_max, 2))
        xs = np.empty((len(fronts), params.members, k_max + 1))
        ys = np.empty_like(xs)
        for i, f in enumerate(fronts):
            xs[i], ys[i] = _paths(f.speed_mps, f.direction_rad, f.region.center_x,
                                  f.region.center_y, z[i], fire.gamma, fire.speed_mean_mps,
                                  fire.direction_mean_rad, fire.speed_sigma_mps,
                                  fire.direction_sigma_rad, fire.substep_s)
        _fronts(work, _births(*key), hz[:reach], survive[:reach], xs, ys,
                fire.extent == "birth", np.array([f.region.width for f in fronts]),
                np.array([f.region.height for f in fronts]),
                fire.side_min_m, fire.side_max_m, params.resolution_m, 0.0, 0.0)
        work.flags.writeable = False
        layers = tuple(work) + _birth_layers(*key)[reach:]
    return OccupancyForecast._made(params.resolution_m, fire.substep_s, horizons, layers,
                                   issued_substep, n)


@lru_cache(maxsize=64)
def _schedule(fire: FireParams, horizons: tuple[int, ...], n: int
              ) -> tuple[tuple[int, ...], AnyArray, AnyArray]:
    """(horizons, as an array, S(k) = p_s^{L_k} at each): the same for every forecast."""
    hz = np.asarray(horizons, dtype=np.int64)
    survive = fire.p_survive ** life_events(horizons[-1], fire, n)[hz].astype(float)
    hz.flags.writeable = False
    survive.flags.writeable = False
    return horizons, hz, survive


