"""Where each service runs: the deployment's placements (``--role air|ground``).

A real deployment splits the stack over hosts (docs/deployment.md):

=========  ==========================================================================
role       what runs there
=========  ==========================================================================
``air``    the UAV's companion computer: the vehicle (uavsim, or the real autopilot on
           the same MAVLink link), the supervisor and its setpoint stream, System 1,
           and a Zenoh router that joins the ground's across the radio link
``ground`` a ground server or edge cloud: the Zenoh router, the EWS, the System 2
           pool and the viewer
``gcs``    a ground station (MAVProxy, QGroundControl) on its own telemetry link to
           the vehicle; no service of ours
=========  ==========================================================================

Each role is ``docker-compose.yml`` with ``docker-compose.<role>.yml`` merged in
(services/launch/compose.py): the other host's services get a profile named after that
host, so they do not start here, and every service becomes a client of its own host's
router, so only the routers' one session crosses the link.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

from services.launch.compose import COMPOSE

#: the placements a launcher can run (``gcs`` runs a ground station, not a service of ours)
ROLES = ("air", "ground")
PLACEMENTS = (*ROLES, "gcs")
#: the air host's concurrent supervisor (``--concurrent`` items, before the mission's own):
#: while System 2 is behind a dead link, System 1 plans every step onboard
#: (docs/deployment.md; docker-compose.air.yml says the same in CONCURRENT_PARAMS)
AIR_CONCURRENT = ("s2_unavailable=system1",)


def role_file(role: str, compose: Path = COMPOSE) -> Path:
    """The override that makes ``compose`` the ``role`` host's part (ValueError: no role)."""
    if role not in ROLES:
        raise ValueError(f"--role must be one of {ROLES}, got {role!r}")
    return compose.with_name(f"docker-compose.{role}.yml")


def router_connect(doc: Mapping[str, Any], router: str) -> list[str]:
    """The endpoints the ``router`` service's command joins (``--connect E``; [] none)."""
    cmd = [str(c) for c in doc["services"][router].get("command", [])]
    out = []
    for i, item in enumerate(cmd):
        if item in ("--connect", "-e") and i + 1 < len(cmd):
            out.append(cmd[i + 1])
        elif item.startswith("--connect="):
            out.append(item.split("=", 1)[1])
    return out


def router_env(doc: Mapping[str, Any], router: str) -> dict[str, str]:
    """The router service's environment in the file (its lease: ``ZENOH_LEASE_MS``)."""
    return {k: str(v) for k, v in doc["services"][router].get("environment", {}).items()}
