"""The height of a front's cuboid C_t on the paper's fire process (Sec. II-B): a reading.

Sec. II-B: "a firefront Y_t occupies a distinct volume within the environment 𝓔 …
represented as a time-varying rectangular cuboid C_t, characterized by its
dynamically changing dimensions"; Sec. IV-A draws only two of them: "the extend
(i.e., size) of each firefront at each time-step is represented as a rectangle with
dimensions uniformly sampled from the range [100,250]m". The paper gives no height,
so it is a named reading (:attr:`FireHeightParams.fire_height`; the fields' names are
unique among the readings' fields, which dualpilot/readings.py addresses by bare name):

* ``"above-ceiling"`` (the default): every cuboid is taller than the altitude band's
  ceiling (:meth:`dualpilot.model.altitude.AltitudeBand.above_ceiling_m`), so it blocks
  every altitude over its rectangle: the top-down evaluation of Sec. IV, whose numbers
  a 3-D mission then reproduces. It draws nothing.
* ``"uniform"``: the third dimension drawn like the other two, U[``fire_height_min_m``,
  ``fire_height_max_m``], by default the paper's [100, 250] m. Against a 120 m ceiling and
  d_safe = 20 m such a cuboid can never be crossed above (100 + 20 ≥ 120): altitude
  then buys nothing on the paper's process; lower bounds explore what it would.

Where a height is drawn is the fire process's concern (docs/three_d.md): with the
rectangle (``FireParams.extent``) and from a stream of its own, not the fire stream, so
that a 3-D mission's rectangles are the 2-D mission's, seed for seed. On a
fire-behaviour scenario the height follows the fire instead (dualpilot/model/plume.py).
Lengths m.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal, get_args

import numpy as np

from dualpilot.model.altitude import AltitudeBand

#: Readings of a cuboid's height on the paper's process (module docstring).
HeightReading = Literal["above-ceiling", "uniform"]


@dataclass(frozen=True)
class FireHeightParams:
    """How tall the paper's cuboids are: the reading and the uniform law's range (m)."""

    fire_height: HeightReading = "above-ceiling"
    fire_height_min_m: float = 100.0
    fire_height_max_m: float = 250.0

    def __post_init__(self) -> None:
        if self.fire_height not in get_args(HeightReading):
            raise ValueError(f"fire_height must be one of {get_args(HeightReading)}, "
                             f"not {self.fire_height!r}")
        lo, hi = self.fire_height_min_m, self.fire_height_max_m
        if not (math.isfinite(lo) and math.isfinite(hi) and 0.0 < lo <= hi):
            raise ValueError(f"need 0 < fire_height_min_m <= fire_height_max_m, got {lo}, {hi}")

    @property
    def draws(self) -> bool:
        """Whether a height is drawn (False: every cuboid is taller than the ceiling)."""
        return self.fire_height == "uniform"


def cuboid_top_m(params: FireHeightParams, band: AltitudeBand, margin_m: float,
                 rng: np.random.Generator | None = None) -> float:
    """The top (m above ground) of one cuboid: drawn from ``rng`` under "uniform", else the
    band's ceiling + ``margin_m`` (``margin_m`` > 0: the planners' clearance ε, so no face
    above the band can satisfy Eq. (P2_3))."""
    if not params.draws:
        return band.above_ceiling_m(margin_m)
    if rng is None:
        raise ValueError("a uniform height needs a generator")
    return float(rng.uniform(params.fire_height_min_m, params.fire_height_max_m))
