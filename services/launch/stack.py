"""The router and the services of the compose file as local processes (:class:`Stack`), and
following one mission on ``mission/event`` (:func:`follow`, :func:`run_mission`).

:func:`run_mission` prints progress and a summary, stops every process
(SIGINT, then SIGKILL after 2 s) and leaves ``runs/<id>/`` with
``summary.json``, ``steps.csv``, ``trace.json``, ``latency.csv``,
``vehicle.tlog`` (the vehicle's MAVLink traffic), the figures and
``logs/<service>.log``.
"""

from __future__ import annotations

import json
import os
import socket
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from dualpilot.mission.config import MissionConfig
from dualpilot.mission.config_args import config_to_argv
from services.common.mission_env import without_mission_env
from services.launch.compose import (
    COMPOSE,
    ENDPOINT_KEYS,
    REPO,
    ROUTER_IMAGE,
    PortMap,
    load_compose,
    published_ports,
)
from services.launch.processes import ProcessGroup
from services.launch.roles import role_file, router_connect, router_env


def next_event(events: Any, timeout_s: float = 0.2) -> Any:
    """The next readable MissionEvent from the queue ``events`` within ``timeout_s``, else None."""
    import queue

    from services.common import rejections, wire
    from services.msgs import supervisor_pb2

    try:
        raw = events.get(timeout=timeout_s)
    except queue.Empty:
        return None
    try:
        return wire.parse(raw, supervisor_pb2.MissionEvent)
    except rejections.CodecError:
        return None


# -- the stack ------------------------------------------------------------------------------------
@dataclass
class StackConfig:
    """What to run and how (the launcher's flags): the mission, and the processes' settings.

    ``mission`` is handed to the supervisor whole, as its command line's configuration flags
    (dualpilot.mission.config_args.config_to_argv), the only process that reads it; it
    reaches the planners, the EWS and uavsim on the wire. No process inherits a mission
    name of the launcher's environment (services/common/mission_env.py). Its mission id
    defaults to the run directory's name.
    """

    run_dir: Path
    mission: MissionConfig = field(default_factory=lambda: MissionConfig(seed=7))
    speed_factor: float = 20.0
    uav_id: str = "uav1"
    waypoints: str = ""
    free_ports: bool = False
    log_format: str = "json"
    log_level: str = "INFO"
    services: tuple[str, ...] = ()  # empty: every service of the compose file
    extra_env: dict[str, dict[str, str]] = field(default_factory=dict)  # per service
    # mutual TLS and the router's access control (ZENOH_TLS_DIR): a directory of
    # services.certs; with tls and none given, certificates are made in <run_dir>/tls
    tls: bool = False
    tls_dir: Path | None = None
    #: replicas of a service (a planner pool: ``{"system2": 3}``), as ``docker compose --scale``
    scale: dict[str, int] = field(default_factory=dict)
    #: services started only by :meth:`Stack.start_deferred` (a test subscribes first)
    deferred: tuple[str, ...] = ()
    #: compose profiles to run besides the default services (``("viewer",)``: the live view)
    profiles: tuple[str, ...] = ()
    #: join the router at this Zenoh endpoint instead of starting one: a host of more
    #: replicas (``services``) for a stack that runs elsewhere; they share only the router.
    #: With ``role`` "air": the ground's router, which this host's own router joins
    join: str = ""
    #: this host's placement (services/launch/roles.py): "" the whole stack, "air" or
    #: "ground" that host's part of docker-compose.yml (its docker-compose.<role>.yml merged
    #: in), each service a client of this host's router
    role: str = ""
    #: the ground router's endpoint (``role`` "ground"; default tcp/0.0.0.0:<7447 or free>)
    listen: str = ""

    @property
    def mission_id(self) -> str:
        return self.mission.mission_id or self.run_dir.name


class Stack:
    """The router and the services of the compose file as local processes (a context manager)."""

    def __init__(self, cfg: StackConfig, compose: Path = COMPOSE):
        self.cfg = cfg
        values = dict(os.environ)
        if cfg.role == "air" and cfg.join:  # the ground router the air router joins
            values["GROUND_ZENOH"] = cfg.join
        self.doc = load_compose(compose, values,
                                overrides=[role_file(cfg.role, compose)] if cfg.role else [])
        services = self.doc["services"]
        self.router_name = next(n for n, s in services.items()
                                if str(s.get("image", "")).startswith(ROUTER_IMAGE))
        self.ports = PortMap(published_ports(self.doc), cfg.free_ports)
        self.zenoh_port = self.ports.local(7447, "tcp")
        #: where this host's router listens ("" none: ``join`` without a role)
        self.router_listen = f"tcp/127.0.0.1:{self.zenoh_port}"
        if cfg.role == "ground":
            self.router_listen = cfg.listen or f"tcp/0.0.0.0:{self.zenoh_port}"
        elif cfg.join and not cfg.role:
            self.router_listen = ""
        #: where this host's services (and the launcher) connect
        self.endpoint = (cfg.join if not self.router_listen
                         else self.router_listen.replace("/0.0.0.0:", "/127.0.0.1:"))
        self.group = ProcessGroup()
        self.logs = cfg.run_dir / "logs"
        self.tls_dir: Path | None = None
        if cfg.tls or cfg.tls_dir is not None:
            self.tls_dir = (cfg.tls_dir or cfg.run_dir / "tls").resolve()

    def mission_argv(self) -> list[str]:
        """The supervisor's configuration flags: the stack's mission."""
        return config_to_argv(replace(self.cfg.mission, mission_id=self.cfg.mission_id))

    def overrides(self) -> dict[str, str]:
        c = self.cfg
        return {
            "UAV_ID": c.uav_id, "SPEED_FACTOR": str(c.speed_factor), "RUN_DIR": str(c.run_dir),
            "EXIT_AFTER_MISSION": "0", "OPERATOR_WAYPOINTS": c.waypoints,
            "LOG_FORMAT": c.log_format, "TLOG_PATH": str(c.run_dir / "vehicle.tlog"),
            "STREAM_STATS_PATH": str(c.run_dir / "stream.json"),
            "LOG_LEVEL": c.log_level, "PYTHONUNBUFFERED": "1",
            "ZENOH_TLS_DIR": str(self.tls_dir or ""),
        }

    def service_env(self, name: str, mission_flags: bool = False) -> dict[str, str]:
        """``name``'s environment: the launcher's (no mission names), the compose file's (with
        ``mission_flags``: without its mission names, the mission comes as flags), the
        stack's settings."""
        svc = self.doc["services"][name]
        env = without_mission_env(os.environ)
        env["PYTHONPATH"] = os.pathsep.join([str(REPO), env.get("PYTHONPATH", "")]).rstrip(
            os.pathsep)
        for key, value in svc.get("environment", {}).items():
            env[key] = (self.ports.rewrite(key, value, exposed=bool(self.cfg.role))
                        if key in ENDPOINT_KEYS else str(value))
        if mission_flags:
            env = without_mission_env(env)
        env.update(self.overrides())
        if self.cfg.role:  # this host's router; the run's traffic, per process
            env["ZENOH_CONNECT"] = self.endpoint
            env["TRAFFIC_PATH"] = str(self.cfg.run_dir / "traffic" / "{service}-{pid}.json")
        elif self.cfg.join:  # another machine's router: everything through it (its peers'
            env["ZENOH_CONNECT"] = self.cfg.join  # loopback locators mean nothing here)
            env["ZENOH_MODE"] = "client"
        env.update(self.cfg.extra_env.get(name, {}))
        return env

    def router_argv(self) -> list[str]:
        """This host's router: listening on :attr:`router_listen`, joining the routers the
        file's router command connects to (an air host's: the ground's)."""
        argv = [sys.executable, "-m", "services.router", "--zenoh-listen", self.router_listen]
        connect = router_connect(self.doc, self.router_name) if self.cfg.role else []
        return argv + (["--zenoh-connect", ",".join(connect)] if connect else [])

    def argv(self, name: str, mission: list[str] | None = None) -> list[str]:
        """``name``'s command line, with the ``mission``'s configuration flags (the
        supervisor's)."""
        cmd = list(self.doc["services"][name]["command"])
        return [sys.executable if cmd[0] == "python" else cmd[0], *cmd[1:], *(mission or [])]

    def service_names(self) -> list[str]:
        """The services to run: those without a compose ``profiles`` key, and those of the
        profiles in :attr:`StackConfig.profiles` (as ``docker compose --profile``)."""
        names = [n for n, svc in self.doc["services"].items() if n != self.router_name and (
            not svc.get("profiles") or set(svc["profiles"]) & set(self.cfg.profiles))]
        return [n for n in names if not self.cfg.services or n in self.cfg.services]

    def viewer_url(self) -> str:
        """The live view's WebSocket URL (services/viewer), "" when it does not run."""
        if "viewer" not in self.service_names():
            return ""
        listen = self.service_env("viewer").get("VIEWER_LISTEN", "")
        return "ws://" + listen.removeprefix("tcp/") if listen else ""

    def web_url(self) -> str:
        """The live view's web page (services/viewer), "" when it does not run."""
        if "viewer" not in self.service_names():
            return ""
        listen = self.service_env("viewer").get("WEB_LISTEN", "")
        return "http://" + listen.removeprefix("tcp/") + "/" if listen else ""

    def start(self) -> None:
        self.logs.mkdir(parents=True, exist_ok=True)
        if self.tls_dir is not None:
            from services import certs

            certs.make(self.tls_dir)  # keeps a complete directory as it is
        env = dict(os.environ, PYTHONPATH=str(REPO), PYTHONUNBUFFERED="1",
                   LOG_FORMAT=self.cfg.log_format, UAV_ID=self.cfg.uav_id,
                   ZENOH_TLS_DIR=str(self.tls_dir or ""))
        if self.cfg.role:
            env.update(router_env(self.doc, self.router_name), PLACEMENT=self.cfg.role)
            env.pop("ROUTER_CONNECT", None)  # its --zenoh-connect says it
        if self.router_listen:
            self.group.start("router", self.router_argv(), env, self.logs / "router.log")
        for name in self.service_names():
            if name not in self.cfg.deferred:
                self.start_service(name)

    def start_service(self, name: str, log_tag: str = "") -> None:
        """Start ``name`` (and its replicas: system2, system2-2, …), each process logging to
        ``<proc>[-log_tag].log`` (a tag keeps a restarted process's log apart)."""
        supervisor = name == "supervisor"
        mission = self.mission_argv() if supervisor else None
        for k in range(self.cfg.scale.get(name, 1)):
            proc = name if k == 0 else f"{name}-{k + 1}"
            log = f"{proc}-{log_tag}.log" if log_tag else f"{proc}.log"
            self.group.start(proc, self.argv(name, mission),
                             self.service_env(name, mission_flags=supervisor), self.logs / log)

    def start_deferred(self) -> None:
        """Start the services :attr:`StackConfig.deferred` held back."""
        for name in self.service_names():
            if name in self.cfg.deferred:
                self.start_service(name)

    def stop(self) -> dict[str, int]:
        return self.group.stop_all(last="router")

    def __enter__(self) -> Stack:
        try:
            self.start()
        except BaseException:
            self.stop()
            raise
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()


#: services that may run as several replicas (services/common/keys.py REPLICATED)
SCALABLE = ("system1", "system2")


def parse_scale(items: list[str]) -> dict[str, int]:
    """``["system2=3", …]`` → ``{"system2": 3}``; raises ValueError for anything else."""
    out: dict[str, int] = {}
    for item in items:
        name, _, n = item.partition("=")
        if name not in SCALABLE or not n.isdigit() or not 1 <= int(n) <= 16:
            raise ValueError(f"--scale takes SERVICE=N with SERVICE one of {SCALABLE} and "
                             f"1 <= N <= 16, got {item!r}")
        out[name] = int(n)
    return out


def wait_router(endpoint: str, timeout_s: float = 30.0) -> None:
    """Wait until the router's TCP ``endpoint`` accepts connections (then zenoh.open is quick).

    Raises TimeoutError after ``timeout_s``.
    """
    host, port = endpoint.removeprefix("tcp/").rsplit(":", 1)
    deadline = time.monotonic() + timeout_s
    while True:
        try:
            socket.create_connection((host, int(port)), timeout=0.5).close()
            return
        except OSError:
            if time.monotonic() > deadline:
                raise TimeoutError(f"no router at {endpoint} within {timeout_s} s") from None
            time.sleep(0.05)


@contextmanager
def client_session(endpoint: str, tls_dir: Path | str | None = None,
                   identity: str = "monitor") -> Iterator[Any]:
    """A Zenoh client session on ``endpoint`` (blocks until the router answers).

    With ``tls_dir`` (services.certs) it connects over mutual TLS as ``identity``
    ("monitor" may only listen: services/common/acl.py).
    """
    import zenoh

    from services.common import bus

    conf = zenoh.Config()
    conf.insert_json5("mode", '"client"')
    conf.insert_json5("scouting/multicast/enabled", "false")
    if tls_dir:
        endpoint = bus.tls_endpoints([endpoint])[0]
        conf.insert_json5("transport/link/tls", json.dumps(bus.tls_config(str(tls_dir),
                                                                          identity)))
    conf.insert_json5("connect/endpoints", json.dumps([endpoint]))
    conf.insert_json5("connect/timeout_ms", "-1")
    conf.insert_json5("connect/exit_on_failure", "false")
    conf.insert_json5("connect/retry",
                      "{period_init_ms: 50, period_max_ms: 500, period_increase_factor: 2}")
    with zenoh.open(conf) as session:
        yield session


# -- following a mission --------------------------------------------------------------------------
@dataclass
class Outcome:
    ended: bool
    success: bool = False
    failure_cause: str = ""
    steps: int = 0
    message: str = ""

    @classmethod
    def of(cls, ev: Any) -> Outcome | None:
        """The outcome a MissionEvent ENDED or ABORTED tells; None for any other event."""
        from services.msgs import supervisor_pb2

        if ev.kind == supervisor_pb2.MISSION_EVENT_KIND_ENDED:
            return cls(True, ev.success, ev.failure_cause, ev.step, ev.message)
        if ev.kind == supervisor_pb2.MISSION_EVENT_KIND_ABORTED:
            return cls(False, message=f"aborted: {ev.message}")
        return None


def follow(stack: Stack, timeout_s: float, quiet: bool = False) -> Outcome:
    """Print the mission's progress until it ends, a process dies or ``timeout_s`` passes."""
    import queue

    from services.common import keys
    from services.msgs import supervisor_pb2

    events: queue.Queue[bytes] = queue.Queue()
    with client_session(stack.endpoint, stack.tls_dir) as session:
        sub = session.declare_subscriber(keys.mission_event(stack.cfg.uav_id),
                                         lambda s: events.put(s.payload.to_bytes()))
        deadline = time.monotonic() + timeout_s
        try:
            while time.monotonic() < deadline:
                dead = stack.group.dead()
                if dead:
                    names = ", ".join(f"{p.name} (exit {p.popen.returncode})" for p in dead)
                    return Outcome(False, message=f"process ended early: {names}")
                ev = next_event(events)
                if ev is None:
                    continue
                kind = ev.kind
                if kind == supervisor_pb2.MISSION_EVENT_KIND_STARTED and not quiet:
                    print(f"mission {ev.mission_id} started: controller={ev.controller} "
                          f"seed={ev.seed} {ev.message}", flush=True)
                elif kind == supervisor_pb2.MISSION_EVENT_KIND_STEP and not quiet:
                    print(f"t={ev.step:3d} S{ev.flown_system} pos=({ev.position.east_m:6.1f},"
                          f"{ev.position.north_m:6.1f}) fires={ev.fires_active} "
                          f"plan={ev.plan_status}", flush=True)
                elif kind in (supervisor_pb2.MISSION_EVENT_KIND_PAUSED,
                              supervisor_pb2.MISSION_EVENT_KIND_RESUMED,
                              supervisor_pb2.MISSION_EVENT_KIND_WAYPOINTS) and not quiet:
                    name = supervisor_pb2.MissionEventKind.Name(kind).rsplit("_", 1)[-1].lower()
                    print(f"t={ev.step:3d} {name}: {ev.message}", flush=True)
                elif (outcome := Outcome.of(ev)) is not None:
                    return outcome
            return Outcome(False, message=f"no mission end within {timeout_s:.0f} s")
        finally:
            sub.undeclare()


def run_mission(cfg: StackConfig, timeout_s: float = 600.0, figures: bool = True,
                quiet: bool = False, compose: Path = COMPOSE) -> tuple[Outcome, dict[str, int]]:
    """Start the stack, follow one mission, stop everything; returns the outcome and exit codes."""
    cfg.run_dir.mkdir(parents=True, exist_ok=True)
    stack = Stack(cfg, compose)
    with stack:
        if not quiet:
            tls = f" (TLS: {stack.tls_dir})" if stack.tls_dir else ""
            print(f"stack: router {stack.endpoint}{tls}, services "
                  f"{', '.join(stack.service_names())} (MAVLink ports "
                  f"{dict(stack.ports.ports)}); logs in {stack.logs}/",
                  flush=True)
            if stack.web_url():
                print(f"live view: {stack.web_url()} in a browser; {stack.viewer_url()} in "
                      f"Foxglove or Lichtblick (open connection, Foxglove WebSocket)",
                      flush=True)
        try:
            outcome = follow(stack, timeout_s, quiet)
        except KeyboardInterrupt:
            outcome = Outcome(False, message="interrupted")
    codes = {p.name: int(p.popen.returncode) for p in stack.group.procs}
    if figures and outcome.ended and (cfg.run_dir / "steps.csv").is_file():
        try:
            from dualpilot.viz.mission import make_figures
        except ImportError:
            pass
        else:
            make_figures(cfg.run_dir)
    return outcome, codes
