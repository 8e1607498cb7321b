"""The shared instance generator: seeded, the asked hull count, a free UAV state."""

from __future__ import annotations

import numpy as np

from dualpilot.evaluation.instances import SPEC, make_instance


def test_instances_are_seeded_and_free() -> None:
    a, b = make_instance(3, 1, 4), make_instance(3, 1, 4)
    assert a.n_hulls == 4 and np.array_equal(a.state, b.state)
    assert all(np.array_equal(h.vertices, g.vertices) for h, g in zip(a.hulls, b.hulls,
                                                                        strict=True))
    # the UAV keeps the planners' clearance + 10 m, and lies inside the area
    assert min(h.distance(a.state[:2]) for h in a.hulls) >= SPEC.clearance_m + 10.0
    assert SPEC.area.contains(a.state[:2])
