"""System 1 service: operator waypoints or RRT (Alg. 1) tracked by LQR, as a Zenoh queryable.

Answers PlanRequests on ``<ns>/plan/system1`` (services/common/planning.py)
with :class:`dualpilot.system1.planner.System1`, one instance per mission,
built from the mission's spec and configuration (its System 1 method and
risk) by :func:`dualpilot.planners.build_planner` as in-process (its RNG is
the spec's System 1 stream). Operator waypoints come
on ``<ns>/operator/waypoints``. Rejected inputs are counted per key and
reason in the status served on ``<ns>/status/system1``. ``--uav-ids`` serves
a fleet (services/common/fleet.py): one planner loop per vehicle id.
"""

from __future__ import annotations

from dualpilot.mission.config import MissionConfig
from dualpilot.plan import Planner
from dualpilot.planners import build_planner
from dualpilot.spec import MissionSpec
from services.common import bus, fleet, planning
from services.common import cli as common_cli


def make(spec: MissionSpec, config: MissionConfig) -> Planner:
    """The mission's System 1, as the in-process mission builds it."""
    return build_planner(1, spec, config.methods()[1], config.system1_params(), risk=config.risk)


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
