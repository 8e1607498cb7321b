"""The occupancy forecast of a fire field's current state, whichever fire process it runs.

The paper's rectangles (Sec. II-B): :func:`dualpilot.model.front_forecast.front_forecast` of the
fronts, their motion paths on the forecast stream of the mission seed and the sub-steps
done (:func:`dualpilot.spec.forecast_rng`). A fire-behaviour scenario: its level set run
ahead (:func:`dualpilot.model.physics_forecast.physics_forecast`). The fire port
(dualpilot/mission/local.py) and the EWS (services/ews) both ask this one function, so
the forecast flown in-process is the one the stack publishes.
"""

from __future__ import annotations

from dualpilot.model.fire import FireParams
from dualpilot.model.fire_field import FireField
from dualpilot.model.forecast import ForecastParams, OccupancyForecast
from dualpilot.model.front_forecast import front_forecast
from dualpilot.model.physics_forecast import physics_forecast
from dualpilot.spec import forecast_rng


def forecast_step_substeps(params: FireParams, substeps_per_step: int) -> int:
    """The time-step length (sub-steps) a forecast of ``params``' fires depends on: births and
    survival draw once a time-step under ``life_base = "step"``, once a sub-step otherwise
    (then every step length gives the same forecast: 1)."""
    return max(1, substeps_per_step) if params.life_base == "step" else 1


def field_forecast(field: FireField, params: ForecastParams, seed: int,
                   substeps_per_step: int = 1) -> OccupancyForecast:
    """The forecast of ``field`` now, for time-steps of ``substeps_per_step`` sub-steps."""
    if field.physics is not None:
        return physics_forecast(field.physics, params, substeps_per_step, field.substeps_done)
    rng = forecast_rng(seed, field.substeps_done) if field.fronts else None
    return front_forecast(field.fronts, field.params, field.area_size_m, rng, params,
                    substeps_per_step=substeps_per_step, issued_substep=field.substeps_done)
