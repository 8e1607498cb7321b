"""Zenoh key expressions of the stack, all namespaced by vehicle id.

``dualpilot/<uav>/…``: every key of one vehicle's mission lives under its
namespace, so several vehicles can share a router (and one vehicle's keys
never match another's).

======================  ==========  =====================================
key                     kind        payload (dualpilot.v1)
======================  ==========  =====================================
ews/fires               pub/sub     FireState, every T_f of simulated time
ews/forecast            pub/sub     FireForecast
ews/command             queryable   FireCommand → FireUpdate
ews/forecasts           queryable   FireCommand (a forecast query with its digest) →
                                    FireUpdate: a forecast the EWS already answered its
                                    supervisor (a planner's forecast by reference)
plan/system1, …/system2 queryable   PlanRequest → Plan (errors: Error), any replica
plan/system<k>/<zid>    queryable   the same, answered by the replica whose session is <zid>
supervisor/decision     pub/sub     Decision, every step
supervisor/plans        pub/sub     StepPlans, every step (the live view, services/viewer)
vehicle/state           pub/sub     VehicleState read over MAVLink
mission/event           pub/sub     MissionEvent (started, step, ended)
uavsim/mission          queryable   MissionConfig → MissionConfig: what the simulated vehicle
                                    flies (Eq. (1), the area), from its supervisor
operator/waypoints      pub/sub     OperatorWaypoints for System 1
clock                   pub/sub     Clock, the simulated clock's anchor
alive/<service>         liveliness  token while the service runs
alive/<service>/<zid>   liveliness  the same, naming the holder's Zenoh session id
======================  ==========  =====================================
"""

from __future__ import annotations

import re
from collections.abc import Callable

ROOT = "dualpilot"
SERVICES = ("ews", "system1", "system2", "supervisor", "uavsim")
#: services that may run as several replicas (a planner pool): each holder of the service's
#: token is a replica, asked on its own key (:func:`plan_replica`); the others have one holder
REPLICATED = frozenset({"system1", "system2"})
_ID = re.compile(r"^[A-Za-z0-9_\-]{1,64}$")
_ANY = "any"  # a stand-in id that every_vehicle replaces by "*"


def check_id(uav: str) -> str:
    """A vehicle id is 1–64 characters of [A-Za-z0-9_-] (no key-expression syntax)."""
    if not _ID.match(uav):
        raise ValueError(f"vehicle id must match {_ID.pattern}, got {uav!r}")
    return uav


def ns(uav: str) -> str:
    return f"{ROOT}/{check_id(uav)}"


def fires(uav: str) -> str:
    return f"{ns(uav)}/ews/fires"


def forecast(uav: str) -> str:
    return f"{ns(uav)}/ews/forecast"


def fire_command(uav: str) -> str:
    return f"{ns(uav)}/ews/command"


def forecasts(uav: str) -> str:
    """Queryable of the forecasts the EWS answered, by digest (a planner's, by reference)."""
    return f"{ns(uav)}/ews/forecasts"


def plan(uav: str, system: int) -> str:
    if system not in (1, 2):
        raise ValueError(f"system must be 1 or 2, got {system}")
    return f"{ns(uav)}/plan/system{system}"


def plan_replica(uav: str, system: int, zid: str) -> str:
    """The plan queryable of one replica of ``system`` (the session ``zid`` that holds it)."""
    if not _ID.match(zid):
        raise ValueError(f"bad session id {zid!r}")
    return f"{plan(uav, system)}/{zid}"


def decision(uav: str) -> str:
    return f"{ns(uav)}/supervisor/decision"


def step_plans(uav: str) -> str:
    return f"{ns(uav)}/supervisor/plans"


def every_vehicle(key: Callable[[str], str]) -> str:
    """``key``'s expression for every vehicle: ``every_vehicle(fires)`` is
    ``dualpilot/*/ews/fires`` (a viewer of a whole fleet)."""
    return f"{ROOT}/*" + key(_ANY).removeprefix(ns(_ANY))


def vehicle_of(key: str) -> str:
    """The vehicle id of a key under ``dualpilot/<uav>/…``; raises ValueError for another key."""
    parts = str(key).split("/")
    if len(parts) < 3 or parts[0] != ROOT:
        raise ValueError(f"not a vehicle's key: {str(key)[:200]!r}")
    return check_id(parts[1])


def vehicle_state(uav: str) -> str:
    return f"{ns(uav)}/vehicle/state"


def mission_event(uav: str) -> str:
    return f"{ns(uav)}/mission/event"


def sim_mission(uav: str) -> str:
    """Queryable of the simulated vehicle's mission configuration (services/uavsim)."""
    return f"{ns(uav)}/uavsim/mission"


def sim_flight(uav: str) -> str:
    """Queryable of the simulated plant's ground truth (services/uavsim/truth.py)."""
    return f"{ns(uav)}/uavsim/flight"


def waypoints(uav: str) -> str:
    return f"{ns(uav)}/operator/waypoints"


def clock(uav: str) -> str:
    return f"{ns(uav)}/clock"


def alive(uav: str, service: str) -> str:
    """Liveliness token of ``service`` (one of :data:`SERVICES` or a test's own name)."""
    if not _ID.match(service):
        raise ValueError(f"bad service name {service!r}")
    return f"{ns(uav)}/alive/{service}"


def alive_all(uav: str) -> str:
    return f"{ns(uav)}/alive/*"


def holder(uav: str, service: str, zid: str) -> str:
    """Liveliness token naming the session (Zenoh id ``zid``) that holds ``service``'s token.

    Liveliness samples do not say who declared them, so the holder declares
    this second token; replies are trusted only from that session
    (services/common/bus.py).
    """
    if not _ID.match(zid):
        raise ValueError(f"bad session id {zid!r}")
    return f"{alive(uav, service)}/{zid}"


def alive_tree(uav: str) -> str:
    """Every liveliness token of one vehicle: ``alive/<service>`` and ``alive/<service>/<zid>``."""
    return f"{ns(uav)}/alive/**"


def holder_of(alive_key: str) -> tuple[str, str] | None:
    """(service, zid) of a holder token; None for a plain ``alive/<service>`` token."""
    head, _, tail = str(alive_key).partition("/alive/")
    parts = tail.split("/")
    return (parts[0], parts[1]) if len(parts) == 2 else None


def service_of(alive_key: str) -> str:
    """The service name at the end of a liveliness key."""
    return str(alive_key).rsplit("/", 1)[-1]


def status(uav: str, service: str) -> str:
    """Queryable of ``service``'s status (JSON: rejected inputs per key and reason, uptime)."""
    if not _ID.match(service):
        raise ValueError(f"bad service name {service!r}")
    return f"{ns(uav)}/status/{service}"
