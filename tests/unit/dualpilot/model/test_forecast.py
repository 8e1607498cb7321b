"""The probabilistic fire forecast (dualpilot/model/forecast.py): values worked out by hand,
and the forecast against the fire process itself (FireField) run many times."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from dualpilot.model.fire import FireFront, FireParams, LifeBase
from dualpilot.model.fire_field import FireField
from dualpilot.model.forecast import (
    LEVELS,
    ForecastParams,
    OccupancyForecast,
    life_events,
    occupancy,
)
from dualpilot.model.front_forecast import (
    area_cover,
    front_forecast,
    mean_displacement,
    side_cover,
)
from dualpilot.model.geometry import Rect
from dualpilot.spec import forecast_rng

pytestmark = pytest.mark.timeout(120)

#: no noise, no births, every front survives, fronts at rest
STILL = FireParams(p_birth=0.0, p_survive=1.0, speed_mean_mps=0.0, speed_sigma_mps=0.0,
                   direction_sigma_rad=0.0)
SHORT = ForecastParams(horizon_s=5.0, interval_s=1.0)


def front(region: Rect, speed: float = 0.0, direction: float = 0.0, fid: int = 0) -> FireFront:
    return FireFront(fid, 0, speed, direction, region, region.polytope())


def level_at(fc: OccupancyForecast, i: int, x: float, y: float) -> int:
    rows, cols, inside = fc.cells(np.array([[x, y]]))
    assert inside[0]
    return int(fc.levels[i, rows[0], cols[0]])


def test_side_cover_by_hand() -> None:
    """W ~ U[100, 250]: P(W >= 2|u|) is 1 to |u| = 50, (250 - 2|u|)/150 on the ramp, 0 past 125."""
    u = np.array([0.0, 50.0, -75.0, 100.0, 125.0, 300.0])
    assert side_cover(u, 100.0, 250.0) == pytest.approx([1, 1, 2 / 3, 1 / 3, 0, 0])
    assert side_cover(np.array([49.0, 51.0]), 100.0, 100.0).tolist() == [1.0, 0.0]


def test_area_cover_by_hand() -> None:
    """A side whose centre is uniform in [0, 1000] covers an interior point with E[W]/A = 0.175,
    the area's edge with half that, and agrees with the integral of f done numerically."""
    assert area_cover(np.array([500.0]), 100.0, 250.0, 1000.0)[0] == pytest.approx(0.175)
    assert area_cover(np.array([0.0]), 100.0, 250.0, 1000.0)[0] == pytest.approx(0.0875)
    s = np.linspace(0.0, 1000.0, 200_001)
    for u in (-60.0, 30.0, 110.0, 940.0):
        num = np.trapezoid(side_cover(u - s, 100.0, 250.0), s) / 1000.0
        assert area_cover(np.array([u]), 100.0, 250.0, 1000.0)[0] == pytest.approx(num, abs=1e-6)


def test_life_events_by_base() -> None:
    assert life_events(5, FireParams(), 4).tolist() == [0, 1, 2, 3, 4, 5]
    # a time-step of 4 sub-steps, the first forecast sub-step starting one: draws at 1 and 5
    assert life_events(6, FireParams(life_base="step"), 4).tolist() == [0, 1, 1, 1, 1, 2, 2]


def test_mean_displacement_without_direction_noise() -> None:
    fire = FireParams(direction_sigma_rad=0.0, direction_mean_rad=0.0)
    d = mean_displacement(4, fire)
    assert d[:, 0] == pytest.approx([0.0, 1.5, 3.0, 4.5, 6.0])  # 3 m/s · 0.5 s a sub-step
    assert d[:, 1] == pytest.approx(0.0, abs=1e-12)


def test_horizon_zero_is_the_current_occupancy() -> None:
    rng = np.random.default_rng(4)
    field = FireField()
    for _ in range(3):
        field.spawn(rng, 0)
    fc = front_forecast(field.fronts, field.params, 1000.0, forecast_rng(1, 0))
    now = occupancy([f.region for f in field.fronts], fc.resolution_m, fc.shape)
    assert fc.horizons[0] == 0
    assert np.array_equal(fc.levels[0], np.where(now, LEVELS, 0))


def test_no_noise_no_births_kept_sides_is_the_propagated_region() -> None:
    """p_b = 0, p_s = 1, zero noise, sides kept (extent = birth): every slice is the region the
    fire process itself moves the front to (probability exactly 0 or 1)."""
    fire = FireParams(p_birth=0.0, p_survive=1.0, speed_sigma_mps=0.0, direction_sigma_rad=0.0,
                      extent="birth")
    field = FireField(params=fire)
    field.fronts.append(front(Rect(312.3, 287.9, 163.1, 121.7), speed=4.0, direction=0.3))
    fc = front_forecast(field.fronts, fire, 1000.0, np.random.default_rng(0), SHORT)
    rng = np.random.default_rng(9)
    for k in range(fc.max_substeps + 1):
        if k in fc.horizons:
            i = fc.horizons.index(k)
            truth = occupancy([f.region for f in field.fronts], fc.resolution_m, fc.shape)
            assert np.array_equal(fc.levels[i], np.where(truth, LEVELS, 0)), k
        field.substep(rng, 0)


def test_no_noise_redrawn_sides_by_hand() -> None:
    """A still front whose sides are redrawn from U[100, 250]: a cell at offset (dx, dy) is
    covered with f(dx)·f(dy)."""
    fc = front_forecast([front(Rect(505.0, 505.0, 120.0, 120.0))], STILL, 1000.0,
                        np.random.default_rng(0), SHORT)
    i = fc.horizons.index(4)
    for (dx, dy), p in {(0, 0): 1.0, (50, 50): 1.0, (100, 0): 1 / 3, (80, 40): 0.6,
                        (-100, 100): 1 / 9, (200, 0): 0.0}.items():
        assert level_at(fc, i, 505.0 + dx, 505.0 + dy) == round(LEVELS * p), (dx, dy)
    # at k = 0 the current 120 m square: (80, 40) is outside it
    assert level_at(fc, 0, 585.0, 545.0) == 0 and level_at(fc, 0, 555.0, 555.0) == LEVELS


def test_far_cell_without_births_is_zero() -> None:
    fire = replace(FireParams(), p_birth=0.0)
    fc = front_forecast([front(Rect(200.0, 200.0, 150.0, 150.0), speed=3.0, direction=np.pi / 4)],
                        fire, 1000.0, np.random.default_rng(1))
    assert np.all(fc.levels[:, 90:, 90:] == 0)  # cells around (950, 950), every horizon
    assert fc.levels.max() == LEVELS


def test_survival_by_hand() -> None:
    """Kept sides, p_s = 0.5: the front's centre is covered with 0.5^L_k (L_k draws so far)."""
    cases: tuple[tuple[LifeBase, int, dict[int, float]], ...] = (
        ("substep", 1, {2: 0.25, 4: 0.0625}), ("step", 4, {2: 0.5, 4: 0.5, 6: 0.25}))
    for life_base, n, expect in cases:
        fire = replace(STILL, p_survive=0.5, extent="birth", life_base=life_base)
        fc = front_forecast([front(Rect(505.0, 505.0, 100.0, 100.0))], fire, 1000.0,
                            np.random.default_rng(0), SHORT, substeps_per_step=n)
        for k, p in expect.items():
            assert level_at(fc, fc.horizons.index(k), 505.0, 505.0) == round(LEVELS * p)


def test_births_only_in_the_interior_by_hand() -> None:
    """No fronts: an interior cell is covered by a front born j sub-steps ago with
    p_b·p_s^j·0.175², so B_k = 1 − Π_{j<k} (1 − p_b p_s^j 0.030625)."""
    fire = FireParams()
    fc = front_forecast([], fire, 1000.0, np.random.default_rng(0), SHORT)
    for k in fc.horizons:
        b = 1.0 - np.prod([1.0 - 0.1 * 0.75 ** j * 0.175 ** 2 for j in range(k)])
        assert level_at(fc, fc.horizons.index(k), 505.0, 505.0) == round(LEVELS * b), k
    # fewer births reach a corner: the centre must lie in the area
    assert level_at(fc, len(fc.horizons) - 1, 5.0, 5.0) < level_at(fc, len(fc.horizons) - 1,
                                                                   505.0, 505.0)


def test_probabilities_are_deterministic_and_in_range() -> None:
    rng = np.random.default_rng(3)
    field = FireField()
    for _ in range(4):
        field.spawn(rng, 0)
    a = front_forecast(field.fronts, field.params, 1000.0, forecast_rng(5, 12))
    b = front_forecast(field.fronts, field.params, 1000.0, forecast_rng(5, 12))
    assert np.array_equal(a.levels, b.levels)
    p = np.stack([a.probability(i) for i in range(len(a.horizons))])
    assert p.min() >= 0.0 and p.max() <= 1.0
    assert a.horizons == ForecastParams().horizons(0.5) and a.horizons[-1] == 80


def _empirical(fronts: list[FireFront], fire: FireParams, horizons: tuple[int, ...], runs: int,
               res: float, substeps_per_step: int) -> np.ndarray:
    """Frequency of each cell centre inside a region at each horizon, over ``runs`` runs of the
    fire process from ``fronts`` (a new time-step every ``substeps_per_step`` sub-steps)."""
    shape = (int(1000 / res), int(1000 / res))
    freq = np.zeros((len(horizons), *shape))
    rng = np.random.default_rng(2024)
    for _ in range(runs):
        field = FireField(params=fire, fronts=list(fronts), next_id=len(fronts), last_step=-1)
        for k in range(horizons[-1] + 1):
            if k in horizons:
                freq[horizons.index(k)] += occupancy([f.region for f in field.fronts], res,
                                                     shape)
            field.substep(rng, k // substeps_per_step)
    return freq / runs


@pytest.mark.parametrize("fire, n", [
    (FireParams(), 1),                                  # the paper's process (today)
    (FireParams(life_base="step", extent="birth"), 4),  # fig-r5's, 4 sub-steps a step
])
def test_forecast_matches_the_fire_process(fire: FireParams, n: int) -> None:
    """The forecast against 3000 runs of FireField itself from the same fronts: the largest
    difference of any cell is within the runs' own sampling error (4σ at P = ½: 0.037) plus
    the forecast's (its motion paths and 1/255 steps), and the mean difference is small."""
    fronts = [front(Rect(420.0, 380.0, 210.0, 140.0), 3.4, 0.9, 0),
              front(Rect(560.0, 470.0, 120.0, 180.0), 2.2, 0.6, 1)]
    params = ForecastParams(resolution_m=20.0, horizon_s=6.0, interval_s=2.0, members=64)
    fc = front_forecast(fronts, fire, 1000.0, np.random.default_rng(11), params,
                        substeps_per_step=n)
    freq = _empirical(fronts, fire, fc.horizons, 3000, 20.0, n)
    p = np.stack([fc.probability(i) for i in range(len(fc.horizons))])
    assert np.abs(p - freq).max() < 0.05
    assert np.abs(p - freq).mean() < 0.004
    assert p[1:].max() > 0.3  # the fronts are in the slices, not only the births
