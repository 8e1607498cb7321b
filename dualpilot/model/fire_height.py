"""The height of a front's cuboid C_t on the paper's fire process (Sec. II-B): a reading.

Sec. II-B: "a firefront Y_t occupies a distinct volume within the environment 𝓔 …
represented as a time-varying rectangular cuboid C_t, characterized by its
dynamically changing dimensions"; Sec. IV-A draws only two of them: "the extend
(i.e., size) of each firefront at each time-step is represented as a rectangle with
dimensions uniformly sampled from the range [100,250]m". The paper gives no height,
so it is a named reading (:attr:`FireHeightParams.fire_height`; the fields' names are
unique among the readings' fields, which dualpilot/readings.py addresses by bare name):

* ``"auto"`` (the default): ``"above-ceiling"`` on the paper's process, ``"plume"`` on a
  fire-behaviour scenario (:meth:`FireHeightParams.resolved`).
* ``"above-ceiling"``: every cuboid is taller than the altitude band's
  ceiling (:meth:`dualpilot.model.altitude.AltitudeBand.above_ceiling_m`), so it blocks
  every altitude over its rectangle: the top-down evaluation of Sec. IV, whose numbers
  a 3-D mission then reproduces. It draws nothing.
* ``"uniform"``: the third dimension drawn like the other two, U[``fire_height_min_m``,
  ``fire_height_max_m``], by default the paper's [100, 250] m. Against a 120 m ceiling and
  d_safe = 20 m such a cuboid can never be crossed above (100 + 20 ≥ 120): altitude
  then buys nothing on the paper's process; lower bounds explore what it would.
* ``"plume"`` (a fire-behaviour scenario only): the height follows the fire's intensity
  (dualpilot/model/plume.py), per front (``plume_intensity = "front"``: the largest
  fireline intensity of its burning perimeter) or every front as tall as the scenario's
  head fire (``"head"``).

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
from dualpilot.model.plume import DEFAULT_PLUME, PlumeParams
from dualpilot.model.scenarios import PAPER

#: Readings of a cuboid's height (module docstring).
HeightReading = Literal["auto", "above-ceiling", "uniform", "plume"]
#: Readings of a front's fireline intensity under "plume": its own, or the head fire's.
PlumeIntensity = Literal["front", "head"]


@dataclass(frozen=True)
class FireHeightParams:
    """How tall the cuboids are: the reading, the uniform law's range (m) and, on a scenario,
    whose fireline intensity sets a front's plume."""

    fire_height: HeightReading = "auto"
    fire_height_min_m: float = 100.0
    fire_height_max_m: float = 250.0
    plume_intensity: PlumeIntensity = "front"

    def __post_init__(self) -> None:
        if self.fire_height not in get_args(HeightReading):
            raise ValueError(f"fire_height must be one of {get_args(HeightReading)}, "
                             f"not {self.fire_height!r}")
        if self.plume_intensity not in get_args(PlumeIntensity):
            raise ValueError(f"plume_intensity must be one of {get_args(PlumeIntensity)}, "
                             f"not {self.plume_intensity!r}")
        lo, hi = self.fire_height_min_m, self.fire_height_max_m
        if not (math.isfinite(lo) and math.isfinite(hi) and 0.0 < lo <= hi):
            raise ValueError(f"need 0 < fire_height_min_m <= fire_height_max_m, got {lo}, {hi}")

    @property
    def draws(self) -> bool:
        """Whether a height is drawn (False: every cuboid is taller than the ceiling)."""
        return self.fire_height == "uniform"

    def resolved(self, scenario: str) -> HeightReading:
        """The reading on the fire process ``scenario`` ("auto" made "above-ceiling" on the
        paper's, "plume" on a fire-behaviour scenario); ValueError for "plume" on the paper's
        process (its rectangles burn with no intensity) and "uniform" on a scenario (its
        fronts' heights follow their fire)."""
        paper = scenario == PAPER
        if self.fire_height == "auto":
            return "above-ceiling" if paper else "plume"
        if self.fire_height == "plume" and paper:
            raise ValueError("fire_height=plume follows a fire-behaviour scenario's intensity; "
                             "the paper's process has none (set scenario, or above-ceiling / "
                             "uniform)")
        if self.fire_height == "uniform" and not paper:
            raise ValueError(f"fire_height=uniform draws the paper's cuboids; scenario "
                             f"{scenario!r} gives its fronts the heights of their fire "
                             f"(plume, or above-ceiling)")
        return self.fire_height


def cuboid_top_m(params: FireHeightParams, band: AltitudeBand, margin_m: float,
                 rng: np.random.Generator | None = None) -> float:
    """The top (m above ground) of one of the paper's cuboids: drawn from ``rng`` under
    "uniform", else ("auto", "above-ceiling") the band's ceiling + ``margin_m`` (``margin_m``
    > 0: the planners' clearance ε, so no face above the band can satisfy Eq. (P2_3))."""
    if params.fire_height == "plume":
        raise ValueError("a plume's top follows the fire's intensity (plume.fire_top_m)")
    if not params.draws:
        return band.above_ceiling_m(margin_m)
    if rng is None:
        raise ValueError("a uniform height needs a generator")
    return float(rng.uniform(params.fire_height_min_m, params.fire_height_max_m))


@dataclass
class FireHeights:
    """Where a 3-D fire process takes its fronts' tops from (m above ground).

    ``reading`` is :meth:`FireHeightParams.resolved` for the process; ``margin_m`` the
    planners' clearance ε (an above-ceiling top is the ceiling + ε); ``rng`` the heights'
    own stream (:attr:`dualpilot.spec.Stream.FIRE_HEIGHT`), drawn only under "uniform";
    ``plume`` the UAV's limit and the air under "plume".
    """

    params: FireHeightParams
    band: AltitudeBand
    margin_m: float
    rng: np.random.Generator
    reading: HeightReading = "above-ceiling"
    plume: PlumeParams = DEFAULT_PLUME

    def draw(self) -> float:
        """A new cuboid's top on the paper's process (the height stream under "uniform")."""
        if self.reading == "uniform":
            return cuboid_top_m(self.params, self.band, self.margin_m, self.rng)
        if self.reading == "above-ceiling":
            return self.above_ceiling_m
        raise ValueError(f"fire_height={self.reading} draws no cuboid's top")

    @property
    def above_ceiling_m(self) -> float:
        """The top of a cuboid taller than the band (m)."""
        return self.band.above_ceiling_m(self.margin_m)
