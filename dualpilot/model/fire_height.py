"""The height of a front's cuboid C_t on the paper's fire process (Sec. II-B): a reading.

Sec. II-B: "a firefront Y_t occupies a distinct volume within the environment 𝓔 …
represented as a time-varying rectangular cuboid C_t, characterized by its
dynamically changing dimensions"; Sec. IV-A draws only two of them: "the extend
(i.e., size) of each firefront at each time-step is represented as a rectangle with
dimensions uniformly sampled from the range [100,250]m". The paper gives no height,
so it is a named reading (:class:`FireHeightParams`):

* ``"above-ceiling"`` (the default): every cuboid is taller than the altitude band's
  ceiling (:meth:`dualpilot.model.altitude.AltitudeBand.above_ceiling_m`), so it blocks
  every altitude over its rectangle: the top-down evaluation of Sec. IV, whose numbers
  a 3-D mission then reproduces. It draws nothing.
* ``"uniform"``: the third dimension drawn like the other two, U[``min_m``,
  ``max_m``], by default the paper's [100, 250] m. Against a 120 m ceiling and
  d_safe = 20 m such a cuboid can never be crossed above (100 + 20 ≥ 120): altitude
  then buys nothing on the paper's process; lower bounds explore what it would.

A height is drawn whenever the rectangle is (``FireParams.extent``), from a stream of
its own, so a 3-D mission's rectangles are the 2-D mission's, seed for seed. On a
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
    """How tall the paper's cuboids are: ``reading`` and the uniform law's range (m)."""

    reading: HeightReading = "above-ceiling"
    min_m: float = 100.0
    max_m: float = 250.0

    def __post_init__(self) -> None:
        if self.reading not in get_args(HeightReading):
            raise ValueError(f"reading must be one of {get_args(HeightReading)}, "
                             f"not {self.reading!r}")
        if not (math.isfinite(self.min_m) and math.isfinite(self.max_m)
                and 0.0 < self.min_m <= self.max_m):
            raise ValueError(f"need 0 < min_m <= max_m, got {self.min_m}, {self.max_m}")

    @property
    def draws(self) -> bool:
        """Whether a height is drawn (False: every cuboid is taller than the ceiling)."""
        return self.reading == "uniform"


def cuboid_top_m(params: FireHeightParams, band: AltitudeBand, margin_m: float,
                 rng: np.random.Generator | None = None) -> float:
    """The top (m above ground) of one cuboid: drawn from ``rng`` under "uniform", else the
    band's ceiling + ``margin_m`` (``margin_m`` > 0: the planners' clearance ε, so no face
    above the band can satisfy Eq. (P2_3))."""
    if not params.draws:
        return band.above_ceiling_m(margin_m)
    if rng is None:
        raise ValueError("a uniform height needs a generator")
    return float(rng.uniform(params.min_m, params.max_m))
