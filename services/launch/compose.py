"""docker-compose.yml, the one description of the services: load and check it, its published
ports, and :class:`PortMap`, which puts the services on loopback.

For each service the launcher runs its ``command`` (``python`` → this
interpreter) with its ``environment``. Compose host names (``zenoh``,
``uavsim``, ``0.0.0.0``) become 127.0.0.1, and every port in ``ZENOH_CONNECT``,
``MAVLINK_URL``, ``GCS_URL``, ``VIEWER_LISTEN`` and ``WEB_LISTEN`` is mapped to a local one: the
published port (7447, 14550, 8765, 8766) when it is free, else a free one (``--free-ports``:
always a free one). The ``eclipse/zenoh`` router is replaced by ``python -m services.router``
(a zenoh-python session in router mode).

A host's part of a split deployment (``--role air|ground``, services/launch/roles.py) is the
file with its role's override merged in (``docker-compose.<role>.yml``), by compose's own
rules (:func:`merge`).
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from services.launch.processes import REPO, free_port, port_is_free

COMPOSE = REPO / "docker-compose.yml"
ROUTER_IMAGE = "eclipse/zenoh"
ENDPOINT_KEYS = ("ZENOH_CONNECT", "ZENOH_LISTEN", "MAVLINK_URL", "GCS_URL", "VIEWER_LISTEN",
                 "WEB_LISTEN")
#: endpoints other hosts reach (a ground station, a browser): a host's part of a split
#: deployment (``--role``) keeps their ``0.0.0.0``, the whole stack on one host maps it to
#: loopback
EXPOSED_KEYS = ("GCS_URL", "VIEWER_LISTEN", "WEB_LISTEN")
#: ``udpin:host:port`` (pymavlink) or ``tcp/host:port`` (Zenoh endpoint)
_ENDPOINT = re.compile(r"^(?P<scheme>[a-z]+[:/])(?P<host>[^:/,]+|\[[^\]]+\]):(?P<port>\d{1,5})$")


#: compose's variable forms ``${NAME}`` and ``${NAME:-default}`` (default when unset or empty)
_VARIABLE = re.compile(r"\$\{(?P<name>[A-Za-z_][A-Za-z0-9_]*)(?::-(?P<default>[^}]*))?\}")


# -- the compose file -----------------------------------------------------------------------------
def load_compose(path: Path = COMPOSE, env: Mapping[str, str] | None = None,
                 overrides: Sequence[Path] = ()) -> dict[str, Any]:
    """Parse the compose file and its ``overrides`` (``docker compose -f path -f …``, merged
    by :func:`merge`), fill in their variables from ``env`` (default: this process's
    environment) as ``docker compose`` does, and check the result (:func:`check_compose`)."""
    import os

    import yaml

    values = os.environ if env is None else env
    doc = interpolate(yaml.safe_load(Path(path).read_text()), values)
    for extra in overrides:
        doc = merge(doc, interpolate(yaml.safe_load(Path(extra).read_text()), values))
    check_compose(doc)
    return doc  # type: ignore[no-any-return]


#: service keys an override replaces instead of appending to (compose's merge rules)
REPLACED = ("command", "entrypoint")


def merge(base: Any, override: Any, key: str = "") -> Any:
    """``override`` merged into ``base`` as ``docker compose -f base -f override`` does:
    mappings merge key by key, ``command`` and ``entrypoint`` are replaced, other sequences
    are appended to (an item already there is not repeated), scalars are replaced."""
    if isinstance(base, dict) and isinstance(override, dict):
        out = dict(base)
        for k, v in override.items():
            out[k] = merge(base[k], v, k) if k in base else v
        return out
    if isinstance(base, list) and isinstance(override, list) and key not in REPLACED:
        return base + [v for v in override if v not in base]
    return override


def interpolate(node: Any, env: Mapping[str, str]) -> Any:
    """``node`` with each ``${NAME}`` / ``${NAME:-default}`` in its strings replaced from
    ``env`` (an unset ``${NAME}`` becomes "", as compose does); ``$$`` is a literal ``$``."""
    if isinstance(node, dict):
        return {k: interpolate(v, env) for k, v in node.items()}
    if isinstance(node, list):
        return [interpolate(v, env) for v in node]
    if not isinstance(node, str) or "$" not in node:
        return node

    def value(m: re.Match[str]) -> str:
        got = env.get(m["name"], "")
        return got if got or m["default"] is None else m["default"]

    return "$".join(_VARIABLE.sub(value, part) for part in node.split("$$"))


def check_compose(doc: Any) -> None:
    """The subset of the compose spec the stack relies on; raises ValueError with every problem.

    Checks: a ``services`` mapping; exactly one router service from the
    ``eclipse/zenoh`` image at a pinned tag (not ``latest``); every other
    service has an ``image`` and a ``build``, a list-form ``command`` running
    ``python -m services.<name>`` for an existing module, a string-valued
    ``environment`` mapping that connects to the router by its service name,
    and ``depends_on`` the router; ports are ``"host:container[/proto]"``.
    """
    if not isinstance(doc, dict) or not isinstance(doc.get("services"), dict):
        raise ValueError("compose file needs a 'services' mapping")
    services: dict[str, Any] = doc["services"]
    routers, problems = _routers(services)
    router = routers[0] if len(routers) == 1 else "zenoh"
    images = set()
    for name, svc in services.items():
        if name in routers:
            continue
        if not isinstance(svc, dict):
            problems.append(f"{name}: not a mapping")
            continue
        images.add(svc.get("image"))
        problems += _service_problems(name, svc, services, router)
    for name, svc in services.items():
        for port in (svc.get("ports", []) if isinstance(svc, dict) else []):
            if not re.fullmatch(r"\d{1,5}:\d{1,5}(/(tcp|udp))?", str(port)):
                problems.append(f"{name}: port {port!r} is not 'host:container[/proto]'")
    if len(images) > 1:
        problems.append(f"every service should use one image, got {sorted(map(str, images))}")
    if problems:
        raise ValueError("docker-compose.yml: " + "; ".join(problems))


def _routers(services: dict[str, Any]) -> tuple[list[str], list[str]]:
    """The router services (``eclipse/zenoh:<tag>``) and what is wrong with them."""
    problems: list[str] = []
    routers = [n for n, s in services.items()
               if isinstance(s, dict) and str(s.get("image", "")).startswith(ROUTER_IMAGE + ":")]
    if len(routers) != 1:
        problems.append(f"exactly one {ROUTER_IMAGE}:<tag> router service needed, got {routers}")
    for name in routers:
        tag = str(services[name]["image"]).split(":", 1)[1]
        if not re.fullmatch(r"\d+\.\d+\.\d+", tag):
            problems.append(f"router image tag must be pinned (x.y.z), got {tag!r}")
    return routers, problems


def _service_problems(name: str, svc: dict[str, Any], services: dict[str, Any],
                      router: str) -> list[str]:
    """What is wrong with one dualpilot service: keys, command, environment, dependencies."""
    problems = [f"{name}: missing {key}" for key in ("image", "build", "command", "environment")
                if key not in svc]
    cmd = svc.get("command")
    if not (isinstance(cmd, list) and len(cmd) >= 3 and cmd[:2] == ["python", "-m"]
            and all(isinstance(c, str) for c in cmd)):
        problems.append(f"{name}: command must be a list ['python', '-m', 'services.<x>', ...]")
    else:
        module = cmd[2]
        mod_path = REPO / Path(*module.split("."))
        if not module.startswith("services.") or not (
                (mod_path / "__main__.py").is_file() or mod_path.with_suffix(".py").is_file()):
            problems.append(f"{name}: {module} is not a service module")
    env = svc.get("environment", {})
    if not isinstance(env, dict) or not all(isinstance(v, str) for v in env.values()):
        problems.append(f"{name}: environment must map names to strings (quote numbers)")
    elif not re.fullmatch(rf"tcp/{re.escape(router)}:\d+", env.get("ZENOH_CONNECT", "")):
        problems.append(f"{name}: ZENOH_CONNECT must be tcp/{router}:<port>")
    deps = svc.get("depends_on", [])
    dep_names = list(deps) if isinstance(deps, (list, dict)) else []
    if router not in dep_names:
        problems.append(f"{name}: must depend_on {router}")
    problems += [f"{name}: depends_on unknown service {dep}" for dep in dep_names
                 if dep not in services]
    return problems


def published_ports(doc: Mapping[str, Any]) -> dict[int, str]:
    """Container ports published by any service → protocol."""
    out: dict[int, str] = {}
    for svc in doc["services"].values():
        for port in svc.get("ports", []):
            spec, _, proto = str(port).partition("/")
            out[int(spec.split(":")[1])] = proto or "tcp"
    return out


def _proto_of(key: str, value: str) -> str:
    return "tcp" if key == "ZENOH_CONNECT" or value.startswith("tcp") else "udp"


@dataclass
class PortMap:
    """Container port → local port, decided once per stack."""

    published: dict[int, str]
    free_ports: bool
    ports: dict[int, int] = field(default_factory=dict)

    def local(self, port: int, proto: str) -> int:
        if port not in self.ports:
            keep = (not self.free_ports and port in self.published and port_is_free(port, proto))
            self.ports[port] = port if keep else free_port(proto)
        return self.ports[port]

    def rewrite(self, key: str, value: str, exposed: bool = False) -> str:
        """``scheme:host:port`` / ``proto/host:port`` → loopback and a local port (or a list);
        with ``exposed``, an endpoint of :data:`EXPOSED_KEYS` on ``0.0.0.0`` stays on every
        address (its port mapped as the others)."""
        proto = _proto_of(key, value)
        out = []
        for item in filter(None, (v.strip() for v in value.split(","))):
            m = _ENDPOINT.match(item)
            if m is None:
                raise ValueError(f"{key}: cannot map endpoint {item!r} to loopback")
            port = int(m.group("port"))  # 0: the system picks one (each process its own)
            keep = exposed and key in EXPOSED_KEYS and m.group("host") == "0.0.0.0"
            host = "0.0.0.0" if keep else "127.0.0.1"
            out.append(f"{m.group('scheme')}{host}:{self.local(port, proto) if port else 0}")
        return ",".join(out)
