"""System 1 service: operator waypoints or RRT (Alg. 1) tracked by LQR, as a Zenoh queryable.

Answers PlanRequests on ``<ns>/plan/system1`` (services/common/planning.py)
with :class:`dualpilot.system1.planner.System1`, one instance per mission, seeded as
:func:`dualpilot.planners.make_system1` does in-process. Operator waypoints
come with the mission (PlanRequest.mission) and as live updates on
``<ns>/operator/waypoints``. Rejected inputs are counted per key and reason
in the status served on ``<ns>/status/system1``. ``--uav-ids`` serves a fleet
(services/common/fleet.py): one planner loop per vehicle id.
"""

from __future__ import annotations

from dualpilot.mission.step import MissionConfig
from dualpilot.plan import Planner
from dualpilot.planners import make_system1
from services.common import bus, codec, fleet, planning
from services.common import cli as common_cli


def make(mission: codec.MissionSpec) -> Planner:
    config = MissionConfig(goal=mission.goal, area_size_m=mission.area_size_m)
    return make_system1(config, mission.seed)


def main(argv: list[str] | None = None) -> int:
    p = common_cli.parser("system1", __doc__.splitlines()[0])
    fleet.add_argument(p)
    args = p.parse_args(argv)
    try:
        settings = common_cli.settings("system1", args)
        uavs = fleet.uav_ids(args.uav_ids, settings.uav_id)
    except ValueError as err:
        p.error(str(err))
    return bus.run_service(settings, lambda ctx: fleet.for_each(
        ctx, uavs, lambda sub: planning.run(sub, 1, make)))


if __name__ == "__main__":
    bus.leave(main())
