"""Run the whole stack locally: a Zenoh router and every service of docker-compose.yml as processes.

``python -m services.launch --seed 7 --speed-factor 20 --controller cc --timing paper``

``docker-compose.yml`` is the one description of the services: for each
service the launcher runs its ``command`` (``python`` → this interpreter) with
its ``environment``, on loopback. Compose host names (``zenoh``, ``uavsim``,
``0.0.0.0``) become 127.0.0.1, and every port in ``ZENOH_CONNECT``,
``MAVLINK_URL`` and ``GCS_URL`` is mapped to a local one: the published port
(7447, 14550) when it is free, else a free one (``--free-ports``: always a free
one). The ``eclipse/zenoh`` router is replaced by ``python -m services.router``
(a zenoh-python session in router mode).

The launcher follows the mission on ``mission/event``, prints progress and a
summary, stops every process (SIGINT, then SIGKILL after 2 s) and leaves
``runs/<id>/`` with ``summary.json``, ``steps.csv``, ``trace.json``,
``latency.csv``, ``vehicle.tlog`` (the vehicle's MAVLink traffic), the figures
and ``logs/<service>.log``.

:class:`Fleet` runs several vehicles against one EWS and one pair of planner
services (benchmarks/load_vehicles.py) and mission after mission on the same
shared services (benchmarks/soak.py).
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
from services.launch.processes import STOP_GRACE_S, Proc, ProcessGroup, free_port, port_is_free
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
    "load_compose", "next_event", "port_is_free", "published_ports", "run_mission",
    "wait_router",
]
