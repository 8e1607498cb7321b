"""System 2 service: Problem (P2), the mixed-integer MPC, as a Zenoh queryable.

Answers PlanRequests on ``<ns>/plan/system2`` (services/common/planning.py)
with :func:`dualpilot.planners.build_planner`, built once per mission from its
spec and configuration (its System 2 method, one of
``dualpilot.planners.METHODS[2]``, and risk) and re-solved each request.
Rejected inputs are counted per key and reason in the status served on
``<ns>/status/system2``. ``--uav-ids`` serves a fleet
(services/common/fleet.py): one planner loop per vehicle id.
"""

from __future__ import annotations

from dataclasses import replace

from dualpilot.mission.config import MissionConfig
from dualpilot.plan import Planner
from dualpilot.planners import build_planner
from dualpilot.spec import MissionSpec
from dualpilot.system2.problem import System2Params
from services.common import bus, fleet, planning
from services.common import cli as common_cli


def main(argv: list[str] | None = None) -> int:
    p = common_cli.parser("system2", __doc__.splitlines()[0])
    p.add_argument("--time-limit-s", type=float,
                   default=common_cli.env("S2_TIME_LIMIT_S", str(System2Params().time_limit_s)),
                   help="solver time limit per plan [S2_TIME_LIMIT_S]")
    fleet.add_argument(p)
    args = p.parse_args(argv)
    try:
        settings = common_cli.settings("system2", args)
        uavs = fleet.uav_ids(args.uav_ids, settings.uav_id)
        params = replace(System2Params(), time_limit_s=args.time_limit_s)
    except ValueError as err:
        p.error(str(err))

    def make(spec: MissionSpec, config: MissionConfig) -> Planner:
        return build_planner(2, spec, config.system2_method, params, risk=config.risk)

    return bus.run_service(settings, lambda ctx: fleet.for_each(
        ctx, uavs, lambda sub: planning.run(sub, 2, make)))


if __name__ == "__main__":
    bus.leave(main())
