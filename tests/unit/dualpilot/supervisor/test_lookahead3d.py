"""The lookahead supervisor's known future and search over the band (docs/three_d.md, 8).

A hand-made known future: a still wall 35 m tall across the whole area between the start
and G. In the plane (the footprints, as tall as every altitude) no plan gets past it; over
the band the search from the UAV's 3-D state climbs over it, d = d_safe + 0.5 m = 20.5 m
above its top: 55.5 m, 60 m on the lattice (δ = 5 m/s, ΔT = 1 s: altitudes 50 + 5·k m).
"""

from __future__ import annotations

import numpy as np

from dualpilot.mission.config import MissionConfig
from dualpilot.model.dynamics import hover_state
from dualpilot.model.geometry import Rect
from dualpilot.model.prism import Cuboid
from dualpilot.model.zone_heights import ZoneHeights
from dualpilot.spacetime.known import TALL_M, known_future3
from dualpilot.spacetime.plan import FutureBoxes, lattice_plan
from dualpilot.spacetime.plan3 import lattice_plan3, plan_clear3
from dualpilot.supervisor.lookahead.rule import LookaheadParams
from dualpilot.supervisor.lookahead.vertical import planar, planar_spec

#: the wall: x over the whole area, y in [440, 460], 35 m tall
WALL = (0.0, 440.0, 1000.0, 460.0, 35.0)
D = 20.5  # d_safe + the lookahead's margin


def _spec():  # type: ignore[no-untyped-def]
    return MissionConfig.named("lookahead", seed=0, profile="today-3d").spec()


def _future(rows: np.ndarray, substeps: int = 151) -> FutureBoxes:
    return FutureBoxes.of([rows] * (substeps + 1), 1)


def test_the_search_over_the_band_climbs_over_a_low_wall_the_plane_cannot_pass() -> None:
    spec = _spec()
    assert spec.start == (50.0, 50.0) and spec.band.start_altitude_m == 50.0
    state = hover_state(spec.start_position, spec.dynamics)
    p = LookaheadParams()
    flat = _future(np.array([WALL[:4]]))
    for stage in p.stages:
        found, _ = lattice_plan(planar(state), flat, planar_spec(spec), stage, 150, D)
        assert found is None  # the footprint closes the plane
    plan, spent = lattice_plan3(state, _future(np.array([WALL])), spec, p.stages3, 150, D)
    assert plan is not None and spent > 0
    assert spec.in_goal(plan.states[-1, :3])
    wall = Cuboid(Rect(500.0, 450.0, 1000.0, 20.0), 35.0)  # centre, sides
    assert min(wall.distance(x[:3]) for x in plan.states) >= D - 1e-9
    over = plan.states[(plan.states[:, 1] >= 440.0) & (plan.states[:, 1] <= 460.0)]
    assert len(over) and np.allclose(over[:, 2], 60.0)  # 55.5 m rounded up on the lattice
    assert plan.states[:, 2].max() == 60.0
    assert plan_clear3(plan, _future(np.array([WALL])), D)
    # the same wall as tall as the band: no plan over it either
    tall = np.array([[*WALL[:4], TALL_M]])
    assert lattice_plan3(state, _future(tall), spec, p.stages3, 150, D)[0] is None


def test_the_known_future_keeps_each_front_s_top() -> None:
    from dualpilot.model.prism import Prism

    low = Prism.cuboid(Rect(300.0, 300.0, 50.0, 40.0), 0.0, 30.8)
    flat = Rect(600.0, 300.0, 10.0, 10.0).polytope()
    future = known_future3([low, flat], None, 3, 0.1, ZoneHeights())
    assert future.steps == 3 and len(future.offsets) == 5
    for s in range(4):
        rows = future.boxes[future.offsets[s]:future.offsets[s + 1]]
        np.testing.assert_array_equal(rows, [[275.0, 280.0, 325.0, 320.0, 30.8],
                                             [595.0, 295.0, 605.0, 305.0, TALL_M]])
