"""Named fire-behaviour scenarios of the physics fire process (dualpilot/model/physics_fire.py).

A scenario fixes the physics of Rothermel surface spread: a fuel model, the
10-m open wind (speed m/s, the direction it blows towards in rad from +x, as
the paper's ȳ^d), the fuel moistures (kg water / kg oven-dry fuel), the grid
cell (m) and spotting. ``FireParams.scenario`` names one; "paper" is the
rectangles of Sec. II-B. Everything here is plain data: pyretechnics is
imported only by the process itself.

Fuel models are pyretechnics' numbers: 1–13 are Anderson (1982), "Aids to
determining fuel models for estimating fire behavior", USDA FS GTR INT-122;
101–204 are Scott & Burgan (2005), "Standard fire behavior fuel models",
USDA FS RMRS-GTR-153. The moisture scenario D1L1 (very low dead fuel moisture,
fully cured herbaceous) is Scott & Burgan's (2005).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal, get_args

#: ``FireParams.scenario`` of the paper's fire process (Sec. II-B rectangles).
PAPER = "paper"

#: pyretechnics' surface length-to-width ratio models.
LwRatioModel = Literal["behave", "rothermel"]


@dataclass(frozen=True)
class FuelMoisture:
    """Fuel moistures (kg moisture / kg oven-dry fuel); defaults: Scott & Burgan's D1L1."""

    dead_1h: float = 0.03
    dead_10h: float = 0.04
    dead_100h: float = 0.05
    live_herbaceous: float = 0.30
    live_woody: float = 0.60

    def __post_init__(self) -> None:
        for name in ("dead_1h", "dead_10h", "dead_100h", "live_herbaceous", "live_woody"):
            v = getattr(self, name)
            if not (math.isfinite(v) and 0.0 <= v <= 5.0):
                raise ValueError(f"{name} must be a moisture fraction in [0, 5], got {v}")


@dataclass(frozen=True)
class SpottingParams:
    """Firebrand casting and spot ignition (pyretechnics.spot_fire).

    The casting values are pyretechnics' own spotting example ("How to Spread a
    Fire from a Point Ignition with Spotting Enabled"). pyretechnics ignites a
    spot at the firebrand's arrival (Albini 1979) plus 20 min for the spot fire
    to build up to steady state (Perryman 2012); a mission's fires run for
    minutes, so ``build_up_s`` replaces those 20 min: 0 counts a spot fire from
    its ignition (it then spreads at once at the steady rate, which is faster
    than a real spot fire's start).
    """

    firebrands_per_unit_heat: float = 1e-6  # firebrands / kJ
    downwind_distance_mean_m: float = 10.0
    fireline_intensity_exponent: float = 0.3
    wind_speed_exponent: float = 0.55
    downwind_variance_mean_ratio_m: float = 425.0  # Var(X) / E(X), m² / m
    crosswind_distance_stdev_m: float = 100.0
    decay_distance_m: float = 200.0
    temperature_c: float = 30.0
    build_up_s: float = 0.0

    def __post_init__(self) -> None:
        if not (self.firebrands_per_unit_heat >= 0 and self.build_up_s >= 0):
            raise ValueError("firebrands_per_unit_heat and build_up_s must be >= 0")
        if min(self.downwind_distance_mean_m, self.decay_distance_m,
               self.crosswind_distance_stdev_m, self.downwind_variance_mean_ratio_m) <= 0:
            raise ValueError("spotting distances must be positive")


@dataclass(frozen=True)
class PhysicsFireParams:
    """Rothermel surface spread on pyretechnics' Eulerian level set over the area.

    ``cell_m`` is the grid cell (the area is cut into round(area / cell_m)
    cells a side). Flat terrain, no canopy: the midflame wind is the 20-ft wind
    times the unsheltered wind adjustment factor of the fuel bed (Andrews 2012),
    as pyretechnics computes it. ``spotting`` None: no firebrands.
    """

    fuel_model: int = 1
    wind_speed_mps: float = 5.0
    wind_direction_rad: float = math.pi / 4
    moisture: FuelMoisture = field(default_factory=FuelMoisture)
    cell_m: float = 20.0
    spotting: SpottingParams | None = None
    lw_ratio_model: LwRatioModel = "behave"
    #: pyretechnics' CFL number: the front crosses at most this many cells a time-step
    max_cells_per_timestep: float = 0.4

    def __post_init__(self) -> None:
        if not (math.isfinite(self.wind_speed_mps) and 0.0 <= self.wind_speed_mps <= 60.0):
            raise ValueError(f"wind_speed_mps must be in [0, 60], got {self.wind_speed_mps}")
        if not math.isfinite(self.wind_direction_rad):
            raise ValueError("wind_direction_rad must be finite")
        if not (math.isfinite(self.cell_m) and self.cell_m > 0):
            raise ValueError(f"cell_m must be positive, got {self.cell_m}")
        if self.lw_ratio_model not in get_args(LwRatioModel):
            raise ValueError(f"lw_ratio_model must be one of {get_args(LwRatioModel)}")
        if not 0 < self.max_cells_per_timestep <= 1:
            raise ValueError("max_cells_per_timestep must be in (0, 1]")


@dataclass(frozen=True)
class Scenario:
    """A named physics fire: its parameters, a one-line summary and its sources."""

    name: str
    params: PhysicsFireParams
    summary: str
    source: str


_GRASS = "fuel model 1, short grass (Anderson 1982); moisture D1L1 (Scott & Burgan 2005)"
_SPOTTING = "spotting: pyretechnics' example casting values, spot fires counted from ignition"

SCENARIOS: dict[str, Scenario] = {s.name: s for s in (
    Scenario("grass-5", PhysicsFireParams(fuel_model=1, wind_speed_mps=5.0),
             "short grass under a 5 m/s wind towards the north-east", _GRASS),
    Scenario("grass-15", PhysicsFireParams(fuel_model=1, wind_speed_mps=15.0),
             "short grass under a 15 m/s wind towards the north-east (wind-limited spread)",
             _GRASS),
    Scenario("shrub", PhysicsFireParams(fuel_model=145, wind_speed_mps=10.0),
             "high-load dry-climate shrub under a 10 m/s wind towards the north-east",
             "fuel model 145, SH5 (Scott & Burgan 2005); moisture D1L1 (Scott & Burgan 2005)"),
    Scenario("grass-15-spotting",
             PhysicsFireParams(fuel_model=1, wind_speed_mps=15.0, spotting=SpottingParams()),
             "grass-15 with firebrands: spot fires downwind of the burning cells",
             f"{_GRASS}; {_SPOTTING}"),
)}


def scenario_names() -> tuple[str, ...]:
    """Every value ``FireParams.scenario`` takes: "paper", then the named scenarios."""
    return (PAPER, *SCENARIOS)


def get_scenario(name: str) -> Scenario:
    """The scenario called ``name`` (not "paper": that is the rectangles' process)."""
    try:
        return SCENARIOS[name]
    except KeyError:
        raise ValueError(f"unknown fire scenario {name!r}; known: "
                         f"{', '.join(scenario_names())}") from None


def scenario_table() -> str:
    """The scenarios, one block each (text), as ``dualpilot scenarios`` prints them."""
    lines = [f"{PAPER}: the rectangles of Sec. II-B (the default)"]
    for s in SCENARIOS.values():
        p = s.params
        lines += ["", f"{s.name}: {s.summary}",
                  f"  fuel model {p.fuel_model}, 10-m wind {p.wind_speed_mps:g} m/s towards "
                  f"{math.degrees(p.wind_direction_rad):g}° from east, cell {p.cell_m:g} m, "
                  f"spotting {'on' if p.spotting else 'off'}",
                  f"  moisture 1h/10h/100h {p.moisture.dead_1h:g}/{p.moisture.dead_10h:g}/"
                  f"{p.moisture.dead_100h:g}, live herbaceous/woody "
                  f"{p.moisture.live_herbaceous:g}/{p.moisture.live_woody:g}",
                  f"  source: {s.source}"]
    return "\n".join(lines)
