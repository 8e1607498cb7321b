"""Warm the forecasts before the EWS serves: the first of each fire process costs ~0.2-0.6 s.

The first occupancy forecast a process makes loads its compiled kernels (and,
for a fire-behaviour scenario, builds the fuel model's tables), ~0.4 s for the
paper's process and 0.2-0.8 s for a scenario, against ~10 ms once warm: longer
than the supervisor waits for a forecast (half a step), so a mission's first
step would plan without one (a ``forecast_stale`` fault). The EWS makes one
forecast of each fire process before it announces itself.
"""

from __future__ import annotations

import time
from dataclasses import replace

from dualpilot.model.field_forecast import field_forecast
from dualpilot.model.fire import FireParams
from dualpilot.model.fire_field import FireField
from dualpilot.model.forecast import ForecastParams
from dualpilot.model.scenarios import scenario_names
from dualpilot.spec import Stream, stream_rng

#: sub-steps a warm-up fire process runs at most before its forecast (until a front lives)
MAX_SUBSTEPS = 200


def warm_up(params: FireParams, forecast: ForecastParams) -> dict[str, float]:
    """One forecast of the paper's fire process and of each named scenario with ``params``'
    timing and ``forecast``'s grid; the wall time each took (s)."""
    took = {}
    for scenario in scenario_names():
        t0 = time.perf_counter()
        field = FireField(params=replace(params, scenario=scenario))
        rng = stream_rng(0, Stream.FIRE)
        for _ in range(MAX_SUBSTEPS):
            if field.fronts:
                break
            field.substep(rng, field.substeps_done)
        field_forecast(field, forecast, 0, 1)
        took[scenario] = time.perf_counter() - t0
    return took
