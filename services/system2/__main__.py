"""System 2 service: Problem (P2), the mixed-integer MPC, as a Zenoh queryable.

Answers PlanRequests on ``<ns>/plan/system2`` (services/common/planning.py)
with :func:`dualpilot.planners.build_planner`, built once per mission from its
spec and configuration (its System 2 method, one of
``dualpilot.planners.method_names(2)``, risk and time limit) and re-solved each request.
Rejected inputs are counted per key and reason in the status served on
``<ns>/status/system2``. ``--uav-ids`` serves a fleet
(services/common/fleet.py): one planner loop per vehicle id.
"""

from __future__ import annotations

from dualpilot.mission.config import MissionConfig
from dualpilot.plan import Planner
from dualpilot.planners import build_planner
from dualpilot.spec import MissionSpec
from services.common import bus, fleet, planning
from services.common import cli as common_cli


def make(spec: MissionSpec, config: MissionConfig) -> Planner:
    """The mission's System 2, as the in-process mission builds it."""
    return build_planner(2, spec, config.methods()[2], config.system2_params(), risk=config.risk)


def main(argv: list[str] | None = None) -> int:
    p = common_cli.parser("system2", __doc__.splitlines()[0])
    fleet.add_argument(p)
    args = p.parse_args(argv)
    try:
        settings = common_cli.settings("system2", args)
        uavs = fleet.uav_ids(args.uav_ids, settings.uav_id)
    except ValueError as err:
        p.error(str(err))
    return bus.run_service(settings, lambda ctx: fleet.for_each(
        ctx, uavs, lambda sub: planning.run(sub, 2, make)))


if __name__ == "__main__":
    bus.leave(main())
