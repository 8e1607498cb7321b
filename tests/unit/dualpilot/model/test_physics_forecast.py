"""The occupancy forecast of the physics fire process: its level set run ahead, and the births."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from dualpilot.mission.local import LocalFires
from dualpilot.model.field_forecast import field_forecast
from dualpilot.model.fire import FireParams
from dualpilot.model.fire_field import FireField
from dualpilot.model.forecast import LEVELS, ForecastParams, occupancy
from dualpilot.model.physics_forecast import (
    RunAhead,
    albini_t_max_s,
    birth_extents,
    birth_levels,
    physics_forecast,
    regions_of,
    run_ahead,
    spot_flight_s,
)
from dualpilot.model.scenarios import get_scenario
from dualpilot.spec import MissionSpec, Stream, stream_rng

pytestmark = pytest.mark.timeout(180)

PARAMS = ForecastParams()  # 10 m cells, 40 s, a slice a second


def _burning(name: str, p_birth: float = 0.1, substeps: int = 60, seed: int = 3,
             centres: tuple[tuple[float, float], ...] = ((300.0, 300.0), (600.0, 450.0))
             ) -> tuple[FireField, np.random.Generator]:
    """A field of scenario ``name`` with fires at ``centres`` run ``substeps`` sub-steps."""
    field = FireField(params=FireParams(scenario=name, p_birth=p_birth))
    rng = stream_rng(seed, Stream.FIRE)
    for c in centres:
        field.spawn(rng, 0, center=c)
    for s in range(substeps):
        field.substep(rng, s // 10)
    return field, rng


def _quiet(field: FireField) -> None:
    """No more births in the process from now on (the forecast already issued keeps its own)."""
    assert field.physics is not None
    field.params = replace(field.params, p_birth=0.0)
    field.physics.fire = field.params


def _truth(field: FireField) -> np.ndarray:
    return occupancy([f.region for f in field.fronts], PARAMS.resolution_m,
                     (100, 100))


@pytest.mark.parametrize("name", ["grass-15", "shrub"])
def test_the_run_ahead_is_the_process_future_when_nothing_random_happens(name: str) -> None:
    """No births in the process after the issue: every slice is its future regions exactly
    (255 inside them), the births' levels elsewhere, and the copy's burned cells are its own."""
    field, rng = _burning(name)
    assert field.physics is not None
    fc = field_forecast(field, PARAMS, seed=3)
    births = birth_levels(field.physics.physics, field.params, 1000.0, 10.0, fc.horizons, 1)
    entries = run_ahead(field.physics).entries(fc.max_substeps)
    _quiet(field)
    for k in range(1, fc.max_substeps + 1):
        field.substep(rng, 100)
        assert np.array_equal(entries[k].phi < 0.0, field.physics.burned()), k
        if k in fc.horizons:
            i = fc.horizons.index(k)
            truth = _truth(field)
            assert np.array_equal(fc.level(i) == LEVELS, truth), k
            assert np.array_equal(fc.level(i)[~truth], births[i][~truth])
    grown = (fc.level(len(fc.horizons) - 1) == LEVELS).sum() - (fc.level(0) == LEVELS).sum()
    assert grown > 200, "the fires should grow over the horizon"


def test_without_births_the_forecast_is_the_future_occupancy_itself() -> None:
    field, rng = _burning("grass-15", p_birth=0.0)
    fc = field_forecast(field, PARAMS, seed=3)
    assert set(np.unique(fc.levels)) <= {0, LEVELS}
    for k in range(1, fc.max_substeps + 1):
        field.substep(rng, 100)
        if k in fc.horizons:
            assert np.array_equal(fc.level(fc.horizons.index(k)) == LEVELS, _truth(field))


def test_horizon_zero_is_the_current_occupancy() -> None:
    field, _ = _burning("shrub", substeps=30)
    fc = field_forecast(field, PARAMS, seed=3)
    assert fc.horizons[0] == 0 and fc.issued_substep == field.substeps_done == 30
    assert np.array_equal(fc.probability(0), _truth(field).astype(float))
    assert field.physics is not None
    # the same regions as the process's fronts (in raster order, not by front id)
    key = lambda r: (r.center_x, r.center_y)  # noqa: E731
    assert sorted(regions_of(field.physics, field.physics.burned()), key=key) == sorted(
        (f.region for f in field.fronts), key=key)


def test_probabilities_in_range_and_a_reused_copy_is_a_fresh_one() -> None:
    """Along a fire with births, each forecast (the kept copy reused when the process followed
    it) equals the one a new copy gives; probabilities in [0, 1]."""
    field, rng = _burning("grass-15", substeps=20)
    assert field.physics is not None
    steps = [2, 2, 11, 2, 11, 11, 2, 2, 2, 11, 2, 2]
    for t, n in enumerate(steps):
        fc = field_forecast(field, PARAMS, seed=3)
        kept = field.physics.run_ahead
        field.physics.run_ahead = RunAhead(field.physics)
        fresh = field_forecast(field, PARAMS, seed=3)
        field.physics.run_ahead = kept
        assert np.array_equal(fc.levels, fresh.levels), t
        p = np.stack([fc.probability(i) for i in range(len(fc.horizons))])
        assert p.min() >= 0.0 and p.max() <= 1.0
        for _ in range(n):
            field.substep(rng, 10 + t)
    ahead = field.physics.run_ahead
    assert isinstance(ahead, RunAhead) and ahead.reused >= 3 and ahead.fresh >= 3


def test_the_forecast_moves_no_fire_stream_and_no_fire() -> None:
    a, rng_a = _burning("grass-15", substeps=20)
    b, rng_b = _burning("grass-15", substeps=20)
    for t in range(20):
        field_forecast(a, PARAMS, seed=3)
        a.substep(rng_a, 50 + t)
        b.substep(rng_b, 50 + t)
        sa, sb = a.snapshot(), b.snapshot()
        assert sa.regions == sb.regions and sa.front_ids == sb.front_ids
    assert a.physics is not None and b.physics is not None
    assert np.array_equal(a.physics.burned(), b.physics.burned())
    assert rng_a.random() == rng_b.random()


def test_births_of_one_life_event_by_hand() -> None:
    """One sub-step ahead, only the birth of that sub-step can add fire: a one-cell box grown by
    the pad, so P = p_b · c_x c_y / n², c the ignition cells (1 or 2 an axis) whose box covers x."""
    fire = FireParams(scenario="grass-15", p_birth=0.3)
    physics = get_scenario("grass-15").params
    lv = birth_levels(physics, fire, 1000.0, 10.0, (0, 1), 1)
    assert not lv[0].any()
    pad = FireField(params=fire).physics.pad_m  # type: ignore[union-attr]
    assert pad == pytest.approx(10.0 + 2.4948, abs=1e-3)

    def cells(u: float) -> int:  # ignition cells i with 20 i − pad <= u <= 20 (i + 1) + pad
        return sum(20 * i - pad <= u <= 20 * (i + 1) + pad for i in range(50))

    for row, col in ((0, 0), (10, 10), (31, 57), (50, 51), (99, 99)):
        x, y = col * 10 + 5.0, row * 10 + 5.0
        want = 0.3 * cells(x) * cells(y) / 2500
        assert lv[1][row, col] == int(np.floor(want * LEVELS + 0.5)), (row, col)


def test_a_lone_fire_grows_downwind_in_every_phase() -> None:
    physics = get_scenario("grass-15").params
    fire = FireParams(scenario="grass-15")
    ext = birth_extents(physics, fire, 1000.0, 80)
    assert ext.shape == (3, 81, 4)  # the level set runs every third sub-step of 0.5 s
    pad = 10.0 + 2.4948
    assert np.allclose(ext[:, 0], [-pad, 20 + pad, -pad, 20 + pad], atol=1e-3)
    for q in range(3):
        x0, x1, y0, y1 = ext[q].T
        assert (np.diff(x1) >= 0).all() and (np.diff(x0) <= 0).all()
        # towards the north-east the head runs 2.495 m/s (docs/physics_fires.md): 70.6 m an
        # axis in 40 s, within a 20 m cell on the grid; the back barely moves
        axis = 2.495 * np.cos(np.pi / 4) * 40.0
        for grown in (x1[-1] - x1[0], y1[-1] - y1[0]):
            assert axis - 20.0 <= grown <= axis + 20.0
        assert x0[0] - x0[-1] < 25 and y0[0] - y0[-1] < 25


def test_the_births_term_matches_the_process_from_an_empty_area() -> None:
    """Fires born in an empty area of 400 m over 10 s, 300 runs of the process itself against
    the births-only forecast. Neglected by the forecast: births redrawn off burned cells and
    newborns that merge (both rare here)."""
    fire = FireParams(scenario="grass-15", p_birth=0.2)
    params = ForecastParams(horizon_s=10.0)
    field = FireField(params=fire, area_size_m=400.0)
    assert field.physics is not None
    fc = physics_forecast(field.physics, params, 1, 0)
    runs = 300
    hits = np.zeros((len(fc.horizons), 40, 40))
    for r in range(runs):
        f = FireField(params=fire, area_size_m=400.0)
        rng = np.random.default_rng(r)
        for k in range(1, fc.max_substeps + 1):
            f.substep(rng, 0)
            if k in fc.horizons:
                hits[fc.horizons.index(k)] += occupancy([x.region for x in f.fronts], 10.0,
                                                        (40, 40))
    freq = hits / runs
    p = np.stack([fc.probability(i) for i in range(len(fc.horizons))])
    assert p[-1].mean() > 0.03, "the test needs fire to count"
    assert np.abs(p.mean(axis=(1, 2)) - freq.mean(axis=(1, 2))).max() < 0.01
    se = np.sqrt(np.maximum(p * (1 - p), 1e-4) / runs)
    assert np.abs(p - freq).max() < 5 * se.max()


def test_spotting_is_bounded_by_the_firebrands_flight() -> None:
    """Albini's lofting time by hand, and the bound of each scenario: no firebrand cast within
    a 40 s horizon can land within it."""
    u = (4.563 + 117.0) / 5.963
    assert albini_t_max_s(1.0) == pytest.approx(2 / 2.3 * (1.2 + 5.963 / 3 * (u ** 1.5 - 1)))
    assert albini_t_max_s(10.0) < albini_t_max_s(3.0) < albini_t_max_s(1.0)
    with pytest.raises(ValueError, match="flame length must be positive"):
        albini_t_max_s(0.0)
    assert spot_flight_s(get_scenario("grass-15").params) == float("inf")
    flight = spot_flight_s(get_scenario("grass-15-spotting").params)
    assert 100.0 < flight < 130.0  # a 3.0 m head flame
    assert flight > PARAMS.horizon_s


def test_spot_fires_within_the_horizon_are_the_firebrands_in_flight() -> None:
    """With spotting on, the process casts new firebrands after the issue; none lands within the
    horizon, so the run-ahead (the ones in flight landing, no new ones) is still its future.
    Every firebrand the process casts lands no sooner than the bound."""
    field, rng = _burning("grass-15-spotting", p_birth=0.0, substeps=400,
                          centres=((150.0, 150.0), (200.0, 500.0), (500.0, 200.0)))
    proc = field.physics
    assert proc is not None
    cast: dict[float, float] = {}  # ignition time (min) → the fire clock when first seen (s)
    flight = spot_flight_s(proc.physics)
    in_flight = set(proc.spots)  # cast before we watch: their casting time is unknown
    for _ in range(120):
        field.substep(rng, 50)
        for when in proc.spots:
            if when not in in_flight:
                cast.setdefault(when, proc.clock_s)
    assert cast, "the scenario should cast firebrands"
    assert min(60.0 * w - c for w, c in cast.items()) >= flight - 1.5 - 1e-6
    landing = [w for w in proc.spots if 60.0 * w - proc.clock_s < PARAMS.horizon_s]
    fc = field_forecast(field, PARAMS, seed=3)
    for k in range(1, fc.max_substeps + 1):
        field.substep(rng, 60)
        if k in fc.horizons:
            assert np.array_equal(fc.level(fc.horizons.index(k)) == LEVELS, _truth(field)), k
    assert landing or proc.spots, "firebrands should be in flight at the issue"


def test_the_fire_port_gives_the_physics_forecast() -> None:
    fires = LocalFires(MissionSpec(seed=5), FireParams(scenario="grass-15"))
    fires.field.spawn(fires.rng, 0, center=(500.0, 500.0))
    fires.advance(0, 11, None)
    fc = fires.forecast(11)
    assert fc is not None and fc.shape == (100, 100) and fc.horizons[-1] == 80
    assert fires.forecast(2) is fc  # time-steps do not matter with births every sub-step
    assert fc.issued_substep == 11 and (fc.level(fc.horizons.index(80)) == LEVELS).sum() > (
        fc.level(0) == LEVELS).sum()
