"""The third dimension's readings (docs/three_d.md): one parameter object for the readings.

Sec. II's UAV moves in 𝓔 ⊂ ℝ³; Sec. IV-A's evaluation flies "a top-down view (i.e.,
2-dimensional settings)", "assuming a fixed altitude". A 3-D mission (``dim = 3`` of
:class:`~dualpilot.model.dynamics.DynamicsParams`) needs what the paper leaves open, each a
named reading with its source in the module that defines it:

* the altitude band, the start and G_o's altitudes (:class:`AltitudeBand`,
  dualpilot/model/altitude.py) and the goal box's vertical extent (``goal_vertical``);
* the fronts' heights (:class:`FireHeightParams`, dualpilot/model/fire_height.py) and, on
  a fire-behaviour scenario, the air the UAV must not enter above a fire
  (:class:`PlumeParams`, dualpilot/model/plume.py).
* where System 1 flies (``s1_altitude``, :data:`S1Altitude`,
  dualpilot/system1/altitude.py).
* how tall the forecast's risk zones are (``risk_zone_height``,
  :data:`~dualpilot.model.zone_heights.ZoneReading`, dualpilot/model/zone_heights.py): as
  tall as every altitude (``"band"``) or as the fires they forecast (``"fire"``).

:mod:`dualpilot.readings` addresses every field of the three by its bare name
(``--set ceiling_m=100 --set fire_height=uniform``); a 2-D mission reads none of them.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cache
from typing import Literal, get_args

from dualpilot.model.altitude import AltitudeBand, GoalVertical
from dualpilot.model.fire_height import FireHeightParams, FireHeights
from dualpilot.model.plume import PlumeParams, fire_top_m
from dualpilot.model.zone_heights import BAND, ZoneHeights, ZoneReading, check_reading
from dualpilot.spec import MissionSpec, Stream

#: Where System 1 plans in 3-D (dualpilot/system1/altitude.py): "slice-first" (in the
#: horizontal slice at the UAV's altitude, with the planar Alg. 1; the 3-D tree only when
#: the slice has no path) or "volume" (the 3-D tree at once). The paper's System 1 is "the
#: human process of creating a safe path" (Sec. III-A) and its evaluation flies "assuming a
#: fixed altitude" (Sec. IV): a pilot keeps their altitude until a fire is in the way.
S1Altitude = Literal["slice-first", "volume"]


@dataclass(frozen=True)
class VerticalParams:
    """The band, the goal's vertical reading, the fronts' heights, the plume and where System 1
    plans (3-D only)."""

    band: AltitudeBand = field(default_factory=AltitudeBand)
    goal_vertical: GoalVertical = "band"
    heights: FireHeightParams = field(default_factory=FireHeightParams)
    plume: PlumeParams = field(default_factory=PlumeParams)
    s1_altitude: S1Altitude = "slice-first"
    risk_zone_height: ZoneReading = "band"

    def __post_init__(self) -> None:
        check_reading(self.risk_zone_height)
        if self.goal_vertical not in get_args(GoalVertical):
            raise ValueError(f"goal_vertical must be one of {get_args(GoalVertical)}, "
                             f"not {self.goal_vertical!r}")
        if self.s1_altitude not in get_args(S1Altitude):
            raise ValueError(f"s1_altitude must be one of {get_args(S1Altitude)}, "
                             f"not {self.s1_altitude!r}")

    def fire_heights(self, spec: MissionSpec, scenario: str) -> FireHeights | None:
        """The fire process's heights for the mission of ``spec`` on ``scenario`` (None in
        2-D: its fronts have no heights); the height stream is the spec's seed's."""
        if spec.dim != 3:
            return None
        return FireHeights(self.heights, spec.band, spec.clearance_m,
                           spec.rng(Stream.FIRE_HEIGHT), self.heights.resolved(scenario),
                           self.plume)

    def zone_heights(self, spec: MissionSpec, scenario: str) -> ZoneHeights:
        """The forecast's risk zones' heights for the mission of ``spec`` on ``scenario``
        (dualpilot/model/zone_heights.py): :data:`BAND` in 2-D and under ``"band"``; under
        ``"fire"`` the fronts' own reading's: above the ceiling (ceiling + ε), the uniform
        law, or a scenario's head fire's top (m)."""
        if spec.dim != 3 or self.risk_zone_height == "band":
            return BAND
        reading = self.heights.resolved(scenario)
        if reading == "uniform":
            h = self.heights
            return ZoneHeights(uniform=(h.fire_height_min_m, h.fire_height_max_m))
        if reading == "plume":
            intensity_kw_m, wind_mps = head_fire(scenario)
            return ZoneHeights(top_m=fire_top_m(intensity_kw_m, wind_mps, self.plume))
        return ZoneHeights(top_m=spec.above_ceiling_m)


@cache
def head_fire(scenario: str) -> tuple[float, float]:
    """(head fireline intensity kW/m, midflame wind m/s) of the fire-behaviour scenario
    ``scenario`` on flat ground (pyretechnics' Rothermel surface fire)."""
    from dualpilot.model.physics_fire import (  # pyretechnics: only for a scenario's zones
        fireline_intensities_kw_m,
        midflame_wind_m_min,
    )
    from dualpilot.model.scenarios import get_scenario
    physics = get_scenario(scenario).params
    _, head = fireline_intensities_kw_m(physics)
    return head, midflame_wind_m_min(physics.fuel_model, physics.wind_speed_mps) / 60.0
