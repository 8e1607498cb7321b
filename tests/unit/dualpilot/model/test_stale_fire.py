"""Growth of stale fire data (dualpilot.model.stale_fire), values worked out by hand."""

from __future__ import annotations

import numpy as np
import pytest

from dualpilot.model.fire import FireParams
from dualpilot.model.geometry import Rect
from dualpilot.model.stale_fire import (
    StaleFireParams,
    credible_margin_m,
    credible_speed_mps,
    grow_polygon,
)

FIRE = FireParams()


def test_credible_speed_and_margin() -> None:
    # ȳ = 3 m/s, σ = 0.8 m/s, k = 4: 6.2 m/s; sides in [100, 250] m: 75 m of redraw growth
    assert credible_speed_mps(FIRE) == pytest.approx(6.2)
    assert credible_margin_m(0.0, FIRE) == 0.0
    assert credible_margin_m(0.5, FIRE) == pytest.approx(3.1 + 75.0)
    assert credible_margin_m(2.0, FIRE, StaleFireParams(sigma_bound=0.0)) == pytest.approx(81.0)
    with pytest.raises(ValueError, match="finite"):
        credible_margin_m(float("nan"), FIRE)


def test_grow_polygon_is_the_square_minkowski_sum() -> None:
    grown = grow_polygon(Rect(100.0, 200.0, 40.0, 20.0).polytope(), 5.0)
    lo, hi = grown.vertices.min(axis=0), grown.vertices.max(axis=0)
    np.testing.assert_allclose([lo, hi], [[75.0, 185.0], [125.0, 215.0]])
    assert len(grown.vertices) == 4
