"""The fires in 3-D (docs/three_d.md, §2): fronts with tops, snapshots with cuboids and prisms."""

from __future__ import annotations

import math

import numpy as np
import pytest

from dualpilot.model.dynamics import DynamicsParams
from dualpilot.model.fire import FireParams, FireSnapshot, clear_of
from dualpilot.model.fire_field import FireField
from dualpilot.model.fire_height import FireHeightParams
from dualpilot.model.geometry import Rect
from dualpilot.model.physics_fire import PhysicsFire, fireline_intensities_kw_m
from dualpilot.model.plume import fire_top_m
from dualpilot.model.prism import Cuboid, Prism
from dualpilot.model.scenarios import get_scenario
from dualpilot.model.stale_fire import grown_snapshot
from dualpilot.model.vertical import VerticalParams
from dualpilot.spec import MissionSpec

D3 = DynamicsParams(dim=3)


def _field(seed: int, reading: str, fire: FireParams, scenario: str = "paper") -> FireField:
    spec = MissionSpec(seed=seed, dynamics=D3)
    heights = VerticalParams(heights=FireHeightParams(reading)).fire_heights(  # type: ignore
        spec, scenario)
    return FireField(fire, heights=heights)


def test_every_cuboid_a_front_occupied_lies_in_its_hull_prism() -> None:
    fire = FireParams(p_birth=0.3, keep_extinct_hulls=True)
    for seed in range(20):
        field = _field(seed, "uniform", fire)
        rng = np.random.default_rng(seed)
        seen: dict[int, list[Cuboid]] = {}
        for k in range(60):
            field.substep(rng, k // 2)
            for f in field.fronts:
                seen.setdefault(f.front_id, []).append(f.cuboid)
            snap = field.snapshot()
            for fid, prism in zip(snap.front_ids, snap.hull_prisms(), strict=False):
                for c in seen[fid]:
                    assert all(prism.contains(v, 1e-9) for v in c.prism.vertices)
                # the hull's top is the highest top so far
                assert prism.z_hi == max(c.top_m for c in seen[fid]) and prism.z_lo == 0.0
        extinct = snap.hull_prisms()[len(snap.regions):]
        assert len(extinct) == len(field.extinct_hulls) == len(field.extinct_tops)


def test_the_snapshot_without_tops_is_taller_than_the_band() -> None:
    rect = Rect(500.0, 500.0, 100.0, 100.0)
    snap = FireSnapshot(regions=(rect,), hulls=(rect.polytope(),), front_ids=(0,),
                        born_steps=(0,))
    assert not snap.has_tops
    with pytest.raises(ValueError, match="give it tops"):
        snap.cuboids()
    tall = snap.with_tops(145.0)
    assert tall.tops_m == (145.0,) and tall.hull_tops_m == (145.0,)
    assert tall.cuboids() == (Cuboid(rect, 145.0),)
    assert tall.with_tops(99.0) is tall  # tops given are kept
    with pytest.raises(ValueError, match="2 tops for 1 regions"):
        FireSnapshot(regions=(rect,), hulls=(rect.polytope(),), tops_m=(1.0, 2.0),
                     hull_tops_m=(1.0,))


def test_obstacles_are_prisms_for_a_3d_position() -> None:
    big = Rect(500.0, 500.0, 200.0, 200.0)
    now = Rect(560.0, 500.0, 80.0, 80.0)
    snap = FireSnapshot(regions=(now,), hulls=(big.polytope(),), front_ids=(0,),
                        born_steps=(0,), tops_m=(10.0,), hull_tops_m=(30.0,))
    # far from the hull: the hull prism, 30 m tall
    assert all(isinstance(o, Prism) for o in snap.obstacles(np.array([1.0, 1.0, 50.0]), 25.0))
    (far,) = snap.prisms_for(np.array([100.0, 100.0, 50.0]), 25.0)
    assert isinstance(far, Prism) and far.z_hi == 30.0 and far.base is big.polytope()
    # inside the hull's footprint but 40 m above it: 3-D distance 10 m < 25 m, so the front is
    # its current cuboid (a UAV is never asked to avoid a region it is in)
    (near,) = snap.prisms_for(np.array([420.0, 500.0, 40.0]), 25.0)
    assert near.z_hi == 10.0 and np.array_equal(near.base.vertices, now.polytope().vertices)
    # 60 m above the hull: clear of it by 30 m, the hull prism again
    (high,) = snap.prisms_for(np.array([420.0, 500.0, 60.0]), 25.0)
    assert high.z_hi == 30.0
    # a planar position: the planar polygons, as before
    assert snap.obstacles(np.array([100.0, 100.0]), 25.0) == (big.polytope(),)
    with pytest.raises(ValueError, match="planar position"):
        snap.obstacles_for(np.array([100.0, 100.0, 50.0]), 25.0)


def test_the_keep_out_is_measured_to_the_cuboid() -> None:
    low = Cuboid(Rect(100.0, 100.0, 20.0, 20.0), 10.0)
    above = (np.array([100.0, 100.0, 45.0]), 30.0)  # 35 m above a 10 m fire
    assert clear_of(low, above)
    assert not clear_of(low, (np.array([100.0, 100.0, 35.0]), 30.0))  # 25 m above it
    assert not clear_of(low.rect, above)  # in the plane it lies under the UAV
    # beside a cuboid, within its altitudes: the planar polygon distance, as in 2-D
    pos = np.array([140.0, 100.0, 5.0])
    assert clear_of(low, (pos, 30.0)) and not clear_of(low, (pos, 30.000001))


def test_stale_fires_grow_upwards_too() -> None:
    rect = Rect(0.0, 0.0, 10.0, 10.0)
    snap = FireSnapshot(regions=(rect,), hulls=(rect.polytope(),), tops_m=(12.0,),
                        hull_tops_m=(20.0,))
    grown = grown_snapshot(snap, 7.0)
    assert grown.tops_m == (19.0,) and grown.hull_tops_m == (27.0,)
    assert grown.regions[0].width == 24.0


def _van_wagner_top(intensity_kw_m: float, wind_mps: float) -> float:
    """Byram's flame or Van Wagner's 50 °C plume height over 30 °C air, written out (m)."""
    i_btu = intensity_kw_m / (1055.05585262 / 0.3048 / 1000.0)
    u_mph = wind_mps / 0.44704
    plume_ft = 63.0 / (1.8 * 20.0) * i_btu ** (7.0 / 6.0) / math.sqrt(i_btu + u_mph**3)
    return max(0.0775 * intensity_kw_m**0.46, plume_ft * 0.3048)


def test_a_one_cell_fire_is_as_tall_as_its_fuel_burns_in_calm_air() -> None:
    """pyretechnics records no intensity for a cell it ignites: the front is as tall as the
    fuel's no-wind, no-slope fire (grass-5: 34.8 kW/m, about 1.08 m)."""
    field = _field(0, "plume", FireParams(scenario="grass-5", p_birth=0.0), "grass-5")
    front = field.spawn(np.random.default_rng(0), 0, center=(500.0, 500.0))
    assert field.physics is not None and field.physics.tops is not None
    base, _ = fireline_intensities_kw_m(get_scenario("grass-5").params)
    assert base == pytest.approx(34.8161, abs=1e-4)
    assert front.top_m == pytest.approx(_van_wagner_top(base, field.physics.tops.wind_mps),
                                        rel=1e-12)
    assert front.top_m == pytest.approx(1.0753, abs=1e-4)


def test_a_spreading_front_is_as_tall_as_its_most_intense_burning_cell() -> None:
    fire = FireParams(scenario="grass-15", p_birth=0.0)
    field = _field(0, "plume", fire, "grass-15")
    field.spawn(np.random.default_rng(0), 0, center=(500.0, 500.0))
    physics = field.physics
    assert isinstance(physics, PhysicsFire) and physics.tops is not None
    rng = np.random.default_rng(1)
    tops: list[float] = []
    for k in range(40):
        field.substep(rng, k // 2)
        layer = np.asarray(physics.state.get_full_matrices(  # type: ignore[attr-defined]
            ["fireline_intensity"])["fireline_intensity"])
        burned = physics.burned()
        # the perimeter: burned cells with an unburned 4-neighbour
        pad = np.pad(burned, 1, constant_values=True)
        edge = burned & ~(pad[:-2, 1:-1] & pad[2:, 1:-1] & pad[1:-1, :-2] & pad[1:-1, 2:])
        want = max(float(layer[edge].max()), physics.tops.base_kw_m)
        (front,) = field.fronts
        assert front.top_m is not None
        assert front.top_m == pytest.approx(fire_top_m(want, physics.tops.wind_mps), rel=1e-12)
        tops.append(front.top_m)
        assert front.hull_top_m == max(tops)
    # grass-15's head fire (2,920 kW/m): the documented 30.8 m
    assert max(tops) == pytest.approx(30.8, abs=0.05)


def test_head_reading_every_front_is_the_head_fires_height() -> None:
    spec = MissionSpec(seed=0, dynamics=D3)
    heights = VerticalParams(heights=FireHeightParams("plume", plume_intensity="head")
                             ).fire_heights(spec, "shrub")
    field = FireField(FireParams(scenario="shrub", p_birth=0.0), heights=heights)
    front = field.spawn(np.random.default_rng(0), 0, center=(300.0, 300.0))
    assert front.top_m == pytest.approx(190.4, abs=0.05)  # above the 120 m ceiling
    assert field.snapshot().tops_m == (front.top_m,)


def test_a_scenario_above_the_ceiling() -> None:
    field = _field(0, "above-ceiling", FireParams(scenario="grass-5", p_birth=0.0), "grass-5")
    front = field.spawn(np.random.default_rng(0), 0, center=(300.0, 300.0))
    assert front.top_m == 145.0 and front.hull_top_m == 145.0


def test_a_2d_scenario_has_no_tops() -> None:
    field = FireField(FireParams(scenario="grass-5", p_birth=0.0))
    front = field.spawn(np.random.default_rng(0), 0, center=(300.0, 300.0))
    assert front.top_m is None and field.snapshot().tops_m == ()
