"""System 2 service: Problem (P2), the mixed-integer MPC, as a Zenoh queryable.

Answers PlanRequests on ``<ns>/plan/system2`` (services/common/planning.py)
with :func:`dualpilot.planners.make_system2_planner` (``--method`` one of
:data:`dualpilot.system2.fast.planner.METHODS`), built once per mission and re-solved
each request. Rejected inputs are counted per key and reason in the status
served on ``<ns>/status/system2``. ``--uav-ids`` serves a fleet
(services/common/fleet.py): one planner loop per vehicle id.
"""

from __future__ import annotations

from dataclasses import replace

from dualpilot.mission.step import MissionConfig
from dualpilot.plan import Planner
from dualpilot.planners import make_system2_planner
from dualpilot.system2.fast.planner import METHODS
from dualpilot.system2.problem import System2Params
from services.common import bus, codec, fleet, planning
from services.common import cli as common_cli


def main(argv: list[str] | None = None) -> int:
    p = common_cli.parser("system2", __doc__.splitlines()[0])
    p.add_argument("--method", default=common_cli.env("S2_METHOD", "fast"),
                   choices=list(METHODS), help="System 2 solver [S2_METHOD]")
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

    def make(mission: codec.MissionSpec) -> Planner:
        config = MissionConfig(goal=mission.goal, area_size_m=mission.area_size_m)
        return make_system2_planner(config, args.method, replace(params,
                                                                 area_size_m=mission.area_size_m))

    return bus.run_service(settings, lambda ctx: fleet.for_each(
        ctx, uavs, lambda sub: planning.run(sub, 2, make)))


if __name__ == "__main__":
    bus.leave(main())
