"""Run the whole stack locally: a Zenoh router and every service of docker-compose.yml as processes.

``python -m services.launch`` flies the default mission (``make run``;
dualpilot.mission.config.DEFAULT_MISSION), ``--seed 3 --controller cc`` another.

By job: :mod:`.compose` (the compose file onto loopback), :mod:`.processes`
(child processes, free ports), :mod:`.stack` (one stack, one mission),
:mod:`.fleet` (several vehicles, repeated missions), :mod:`.runs` (a mission's report, a
fleet, replicas joining a stack), ``__main__`` (the CLI).
"""

from services.launch.compose import (
                                     COMPOSE,
                                     ENDPOINT_KEYS,
                                     REPO,
                                     ROUTER_IMAGE,
                                     PortMap,
                                     check_compose,
                                     load_compose,
                                     published_ports,
)
from services.launch.fleet import SHARED_SERVICES, VEHICLE_SERVICES, Fleet, Vehicle
from services.launch.processes import (
                                     STOP_GRACE_S,
                                     Proc,
                                     ProcessGroup,
                                     free_port,
                                     free_port_run,
                                     port_is_free,
)
from services.launch.stack import (
                                     Outcome,
                                     Stack,
                                     StackConfig,
                                     client_session,
                                     follow,
                                     next_event,
                                     run_mission,
                                     wait_router,
)

__all__ = [
    "COMPOSE", "ENDPOINT_KEYS", "REPO", "ROUTER_IMAGE", "SHARED_SERVICES", "STOP_GRACE_S",
    "VEHICLE_SERVICES", "Fleet", "Outcome", "PortMap", "Proc", "ProcessGroup", "Stack",
    "StackConfig", "Vehicle", "check_compose", "client_session", "follow", "free_port",
    "free_port_run",
    "load_compose", "next_event", "port_is_free", "published_ports", "run_mission",
    "wait_router",
]
