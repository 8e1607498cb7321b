"""Sec. II-B fire process: Gauss–Markov steps, Bernoulli birth/survival, path hulls."""

import numpy as np
import pytest

from dualpilot.model.fire import FireParams, substeps_for
from dualpilot.model.fire_field import FireField


def test_substeps_is_ceil_of_planning_over_tf():
    assert substeps_for(0.155) == 1  # System 1 in the paper
    assert substeps_for(5.0) == 10  # System 2 in the paper
    assert substeps_for(0.5) == 1
    assert substeps_for(0.51) == 2
    assert substeps_for(0.0) == 1
    with pytest.raises(ValueError, match="finite"):
        substeps_for(float("nan"))


def test_noise_free_front_moves_at_mean_speed_and_direction():
    params = FireParams(speed_sigma_mps=0.0, direction_sigma_rad=0.0, p_survive=1.0, p_birth=0.0)
    field = FireField(params=params)
    rng = np.random.default_rng(0)
    front = field.spawn(rng, 0, center=(500.0, 500.0))
    moved = front.advance(rng, params)
    # 3 m/s * 0.5 s along pi/4: 1.5 / sqrt(2) = 1.06066 m on each axis
    assert moved.region.center == pytest.approx([501.06066, 501.06066], abs=1e-5)
    assert moved.speed_mps == pytest.approx(3.0)


def test_gauss_markov_by_hand():
    # y_t = 0.8 * 5 + 0.2 * 3 + sqrt(1 - 0.64) * yhat with yhat the first N(0, 0.8) draw
    params = FireParams(p_survive=1.0, p_birth=0.0)
    field = FireField(params=params)
    front = field.spawn(np.random.default_rng(1), 0, center=(100.0, 100.0))
    from dataclasses import replace

    front = replace(front, speed_mps=5.0)
    rng = np.random.default_rng(42)
    expected_noise = np.random.default_rng(42).normal(0.0, 0.8)
    moved = front.advance(rng, params)
    assert moved.speed_mps == pytest.approx(0.8 * 5 + 0.2 * 3 + 0.6 * expected_noise)


def test_sides_and_hull_cover_the_path():
    field = FireField(params=FireParams(p_survive=1.0, p_birth=0.0))
    rng = np.random.default_rng(3)
    field.spawn(rng, 0, center=(300.0, 300.0))
    corners = [field.fronts[0].region.corners()]
    for k in range(20):
        field.substep(rng, k)
        r = field.fronts[0].region
        assert 100.0 <= r.width <= 250.0 and 100.0 <= r.height <= 250.0
        corners.append(r.corners())
    hull = field.snapshot().hulls[0]
    for c in np.vstack(corners):
        assert hull.contains(c, margin=1e-6)


def test_birth_and_survival_rates():
    field = FireField(params=FireParams(p_birth=0.1, p_survive=0.75))
    rng = np.random.default_rng(5)
    births = sum(len(field.substep(rng, k)) for k in range(20000))
    assert births / 20000 == pytest.approx(0.1, abs=0.01)
    # steady state: mean active fronts = p_b * p_s / (1 - p_s) after survival, + newborn p_b
    counts = []
    for k in range(20000):
        field.substep(rng, k)
        counts.append(len(field.fronts))
    assert np.mean(counts) == pytest.approx(0.1 / (1 - 0.75), rel=0.1)


def test_extinct_hulls_kept_only_when_asked():
    for keep, expect in ((False, 0), (True, 1)):
        field = FireField(params=FireParams(p_survive=0.0, p_birth=0.0, keep_extinct_hulls=keep))
        rng = np.random.default_rng(0)
        field.spawn(rng, 0)
        field.substep(rng, 1)
        assert len(field.snapshot().hulls) == expect and not field.snapshot().regions


def test_bad_fire_parameters():
    with pytest.raises(ValueError, match="p_birth"):
        FireParams(p_birth=1.5)
    with pytest.raises(ValueError, match="side"):
        FireParams(side_min_m=300.0)


def test_keep_out_births_stay_clear_of_the_uav():
    field = FireField(params=FireParams(p_birth=1.0, p_survive=0.0))
    rng = np.random.default_rng(9)
    uav = np.array([500.0, 500.0])
    for k in range(300):
        (born,) = field.substep(rng, k, keep_out=(uav, 20.0))
        assert born.region.polytope().distance(uav) >= 20.0
