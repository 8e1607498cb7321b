"""A front's height from its fireline intensity: Byram's flame, Van Wagner's plume, by hand."""

import math

import numpy as np
import pytest

from dualpilot.model.plume import (
    BTU_FT_S_KW_M,
    DEFAULT_PLUME,
    MPH_MPS,
    PlumeParams,
    crossable,
    fire_top_m,
    flame_length_m,
    front_intensity_kw_m,
    plume_height_m,
)


def test_byram_flame_length_by_hand():
    # 1000^0.46 = 10^1.38 = 23.98833; × 0.0775 = 1.859096 m
    assert flame_length_m(1000.0) == pytest.approx(1.859096, rel=1e-6)
    # 100^0.46 = 10^0.92 = 8.317638; × 0.0775 = 0.644617 m
    assert flame_length_m(100.0) == pytest.approx(0.644617, rel=1e-6)
    assert flame_length_m(0.0) == 0.0


def test_van_wagner_matches_behaveplus_published_value():
    """BehavePlus's test of its scorch height: 80 °F air, 5 mph wind, 50 Btu/ft/s give
    7.617325 ft (the needles' lethal 60 °C, i.e. an excess of 140 − 80 = 60 °F).

    BehavePlus writes the exponent 7/6 as 1.166667, which raises its value by 1.3e-6 of
    itself: 63/60 · 50^(7/6) / √175 = 7.6173155 ft by hand."""
    ambient_c = (80.0 - 32.0) / 1.8
    h = plume_height_m(50.0 * BTU_FT_S_KW_M, 5.0 * MPH_MPS, 60.0 - ambient_c)
    assert h == pytest.approx(7.617325 * 0.3048, rel=2e-6)
    assert h == pytest.approx(7.6173155 * 0.3048, rel=1e-7)


def test_van_wagner_calm_by_hand():
    # calm: h = 63/ΔT_F · I^(2/3); I = 1000 Btu/ft/s → 100; ΔT 20 °C = 36 °F: 175 ft
    h = plume_height_m(1000.0 * BTU_FT_S_KW_M, 0.0, 20.0)
    assert h == pytest.approx(175.0 * 0.3048, rel=1e-12)
    # the height falls as 1/ΔT: twice the excess, half the height
    assert plume_height_m(1000.0 * BTU_FT_S_KW_M, 0.0, 40.0) == pytest.approx(h / 2, rel=1e-12)
    # wind bends the plume: lower at the same intensity
    assert plume_height_m(1000.0 * BTU_FT_S_KW_M, 10.0, 20.0) < h
    assert plume_height_m(0.0, 3.0, 20.0) == 0.0


def test_the_top_is_the_flame_or_the_plume_whichever_is_higher():
    assert DEFAULT_PLUME.excess_c == 20.0  # 50 °C limit over 30 °C air
    i = 1000.0
    assert fire_top_m(i, 0.0) == plume_height_m(i, 0.0, 20.0) > flame_length_m(i)
    # a vehicle that bore 1000 °C air would meet only the flame: the plume's 970 °C
    # excess lies at 63/1746 · (1000/3.4615)^(2/3) ft ≈ 0.48 m, below the 1.86 m flame
    hardy = PlumeParams(uav_limit_c=1000.0)
    assert plume_height_m(i, 0.0, hardy.excess_c) == pytest.approx(0.4804, abs=1e-3)
    assert fire_top_m(i, 0.0, hardy) == flame_length_m(i)
    assert fire_top_m(0.0, 5.0) == 0.0


@pytest.mark.parametrize("args, match", [
    ((-1.0, 0.0, 20.0), "intensity"),
    ((math.nan, 0.0, 20.0), "intensity"),
    ((10.0, -1.0, 20.0), "wind"),
    ((10.0, 0.0, 0.0), "excess"),
])
def test_bad_inputs_are_refused(args, match):
    with pytest.raises(ValueError, match=match):
        plume_height_m(*args)


def test_a_limit_at_or_below_the_air_is_refused():
    with pytest.raises(ValueError, match="must exceed the ambient"):
        PlumeParams(uav_limit_c=30.0, ambient_c=30.0)


def test_front_intensity_is_the_largest_over_its_burning_cells():
    grid = np.array([[5.0, 400.0], [900.0, 0.0]])
    assert front_intensity_kw_m(grid, [[True, True], [False, False]]) == 400.0
    assert front_intensity_kw_m(grid, np.zeros((2, 2), dtype=bool)) == 0.0
    with pytest.raises(ValueError, match="differ in shape"):
        front_intensity_kw_m(grid, [True, False])
    with pytest.raises(ValueError, match=">= 0"):
        front_intensity_kw_m(-grid, np.ones((2, 2), dtype=bool))


def _head(name):
    """A scenario's head fireline intensity (kW/m) and midflame wind (m/s) from pyretechnics."""
    import pyretechnics.fuel_models as fm
    import pyretechnics.surface_fire as sf

    from dualpilot.model.physics_fire import midflame_wind_m_min, upwind_azimuth_deg
    from dualpilot.model.scenarios import get_scenario

    p = get_scenario(name).params
    m = p.moisture
    moist = fm.moisturize(fm.get_fuel_model(p.fuel_model), (
        m.dead_1h, m.dead_10h, m.dead_100h, 0.0, m.live_herbaceous, m.live_woody))
    base = sf.calc_surface_fire_behavior_no_wind_no_slope(moist)
    wind = midflame_wind_m_min(p.fuel_model, p.wind_speed_mps)
    head = sf.calc_surface_fire_behavior_max(base, wind, upwind_azimuth_deg(
        p.wind_direction_rad), 0.0, 0.0, True, p.lw_ratio_model)
    return float(head["max_fireline_intensity"]), wind / 60.0


def test_a_uav_may_cross_above_a_grass_fire_but_never_above_the_shrub_front():
    tops = {name: fire_top_m(*_head(name)) for name in ("grass-5", "grass-15", "shrub")}
    assert 5.0 < tops["grass-5"] < 15.0
    assert 20.0 < tops["grass-15"] < 40.0
    assert tops["shrub"] > 150.0
    for name in ("grass-5", "grass-15"):
        assert crossable(tops[name], 120.0, 20.0), name
    assert not crossable(tops["shrub"], 120.0, 20.0)
