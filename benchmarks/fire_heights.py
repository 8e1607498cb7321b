"""How tall each fire-behaviour scenario's fronts are to a small UAV, and whether one can cross.

    .venv/bin/python benchmarks/fire_heights.py

For each scenario of dualpilot/model/scenarios.py: the head fire's fireline intensity and
midflame wind on flat ground (pyretechnics' Rothermel surface fire, as the scenario's
level set spreads it), Byram's flame length, the height at which the plume's excess over
the ambient air falls to the UAV's limit's (Van Wagner), the cuboid's top (the larger),
and whether a UAV can pass over it keeping d_safe below the altitude band's ceiling
(dualpilot/model/plume.py, dualpilot/model/altitude.py). Prints a Markdown table.
"""

from __future__ import annotations

import harness  # noqa: F401  (the repository on the path: before its packages)
import pyretechnics.fuel_models as fm
import pyretechnics.surface_fire as sf

from dualpilot.model.altitude import AltitudeBand
from dualpilot.model.physics_fire import midflame_wind_m_min, upwind_azimuth_deg
from dualpilot.model.plume import (
    DEFAULT_PLUME,
    crossable,
    fire_top_m,
    flame_length_m,
    plume_height_m,
)
from dualpilot.model.scenarios import SCENARIOS
from dualpilot.spec import D_SAFE_M


def head_fire(name: str) -> tuple[float, float]:
    """(head fireline intensity kW/m, midflame wind m/s) of scenario ``name``."""
    p = SCENARIOS[name].params
    m = p.moisture
    moist = fm.moisturize(fm.get_fuel_model(p.fuel_model), (
        m.dead_1h, m.dead_10h, m.dead_100h, 0.0, m.live_herbaceous, m.live_woody))
    base = sf.calc_surface_fire_behavior_no_wind_no_slope(moist)
    wind = midflame_wind_m_min(p.fuel_model, p.wind_speed_mps)
    head = sf.calc_surface_fire_behavior_max(base, wind, upwind_azimuth_deg(
        p.wind_direction_rad), 0.0, 0.0, True, p.lw_ratio_model)
    return float(head["max_fireline_intensity"]), wind / 60.0


def main() -> None:
    band = AltitudeBand()
    print(f"UAV limit {DEFAULT_PLUME.uav_limit_c:g} °C, air {DEFAULT_PLUME.ambient_c:g} °C, "
          f"ceiling {band.ceiling_m:g} m, d_safe {D_SAFE_M:g} m\n")
    print("| scenario | head intensity (kW/m) | midflame wind (m/s) | flame (m) | plume (m) "
          "| top (m) | crossable |")
    print("|---|---|---|---|---|---|---|")
    for name in SCENARIOS:
        i, u = head_fire(name)
        top = fire_top_m(i, u)
        print(f"| {name} | {i:,.0f} | {u:.2f} | {flame_length_m(i):.2f} | "
              f"{plume_height_m(i, u, DEFAULT_PLUME.excess_c):.1f} | {top:.1f} | "
              f"{'yes' if crossable(top, band.ceiling_m, D_SAFE_M) else 'no'} |")


if __name__ == "__main__":
    main()
