"""EWS service: the fire process of Sec. II-B behind a Zenoh command queryable.

* ``<ns>/ews/command`` (queryable, FireCommand → FireUpdate): ``reset`` starts
  a mission's fire process from its seed and area (the spec's fire stream, as
  the in-process mission), with the fire process of the reset's mission
  configuration (its reading's FireParams: T_f, life_base, extent, the
  scenario, …; dualpilot/mission/config.py; a reset without one: the default
  configuration's: the EWS has no reading of its own); ``advance`` propagates
  n sub-steps for mission step t, no front igniting within the command's
  keep-out radius of the UAV; ``forecast`` answers with the occupancy forecast
  of the current fire state (the mission configuration's grid and ensemble,
  time-steps of the query's length), made only when asked and refused when the
  query names another revision of the fire state (sub-steps done) than the EWS
  holds. Sub-step k is published on ``<ns>/ews/fires`` when the stack's clock
  (carried in the command) reaches ``τ_t + k·T_f``: the fires propagate while
  the plan is computed (see services/common/clock.py). The reply carries every
  sub-step's state.
* ``<ns>/ews/forecast``: while anyone subscribes, after each command's sub-steps
  and before its reply, the occupancy forecast (P(a point is inside a fire
  region) on a grid, the mission configuration's; dualpilot/model/forecast.py)
  and the mean-motion forecast of each front over ``--forecast-horizon-s``
  (services/ews/forecast.py). The mean motion is the paper model's, so a
  scenario's fronts get none (horizon 0); the occupancy grid is the scenario's
  level set run ahead (dualpilot/model/physics_forecast.py).

Bad commands get an error reply (dualpilot.v1.Error), never a crash; each is
counted per key and reason in the status served on ``<ns>/status/ews``
(services/common/bus/status.py), with each mission's effective configuration.
The fire process is services/ews/fireprocess.py, the loop services/ews/service.py.
``--uav-ids`` serves a fleet (services/common/fleet.py): one fire process per
vehicle id, each seeded by its own supervisor's reset, so every vehicle's fires
are those of its in-process mission. An advance whose clock would keep the EWS
pacing for more than ``MAX_PACED_WAIT_S`` is refused, so no command can stall it.
"""

from __future__ import annotations

import math

from services.common import bus, fleet
from services.common import cli as common_cli

from .service import body
from .warm import Warmer


def main(argv: list[str] | None = None) -> int:
    p = common_cli.parser("ews", "EWS fire forecaster (Sec. II-B) over Zenoh.")
    p.add_argument("--forecast-horizon-s", type=float,
                   default=common_cli.env("FORECAST_HORIZON_S", "80"),
                   help="the live view's mean-motion forecast of each front: its horizon in "
                        "simulated s (what the EWS publishes on ews/forecast, not what a "
                        "mission plans on) [FORECAST_HORIZON_S]")
    fleet.add_argument(p)
    args = p.parse_args(argv)
    try:
        settings = common_cli.settings("ews", args)
        uavs = fleet.uav_ids(args.uav_ids, settings.uav_id)
        if not (math.isfinite(args.forecast_horizon_s) and args.forecast_horizon_s >= 0):
            raise ValueError("--forecast-horizon-s must be finite and >= 0")
    except ValueError as err:
        p.error(str(err))

    def serve(ctx: bus.Context) -> None:
        warmer = Warmer()  # one for every vehicle's fire process: a fire process warms once
        fleet.for_each(ctx, uavs, lambda sub: body(sub, args.forecast_horizon_s, warmer))

    return bus.run_service(settings, serve)


if __name__ == "__main__":
    bus.leave(main())
