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

from __future__ import annotations

import argparse
import contextlib
import json
import os
import re
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import IO, Any

REPO = Path(__file__).resolve().parent.parent
COMPOSE = REPO / "docker-compose.yml"
ROUTER_IMAGE = "eclipse/zenoh"
ENDPOINT_KEYS = ("ZENOH_CONNECT", "ZENOH_LISTEN", "MAVLINK_URL", "GCS_URL")
#: ``udpin:host:port`` (pymavlink) or ``tcp/host:port`` (Zenoh endpoint)
_ENDPOINT = re.compile(r"^(?P<scheme>[a-z]+[:/])(?P<host>[^:/,]+|\[[^\]]+\]):(?P<port>\d{1,5})$")
STOP_GRACE_S = 2.0


# -- the compose file -----------------------------------------------------------------------------
def load_compose(path: Path = COMPOSE) -> dict[str, Any]:
    """Parse and structurally check the compose file (see :func:`check_compose`)."""
    import yaml

    doc = yaml.safe_load(Path(path).read_text())
    check_compose(doc)
    return doc  # type: ignore[no-any-return]


def check_compose(doc: Any) -> None:
    """The subset of the compose spec the stack relies on; raises ValueError with every problem.

    Checks: a ``services`` mapping; exactly one router service from the
    ``eclipse/zenoh`` image at a pinned tag (not ``latest``); every other
    service has an ``image`` and a ``build``, a list-form ``command`` running
    ``python -m services.<name>`` for an existing module, a string-valued
    ``environment`` mapping that connects to the router by its service name,
    and ``depends_on`` the router; ports are ``"host:container[/proto]"``.
    """
    problems: list[str] = []
    if not isinstance(doc, dict) or not isinstance(doc.get("services"), dict):
        raise ValueError("compose file needs a 'services' mapping")
    services: dict[str, Any] = doc["services"]
    routers = [n for n, s in services.items()
               if isinstance(s, dict) and str(s.get("image", "")).startswith(ROUTER_IMAGE + ":")]
    if len(routers) != 1:
        problems.append(f"exactly one {ROUTER_IMAGE}:<tag> router service needed, got {routers}")
    for name in routers:
        tag = str(services[name]["image"]).split(":", 1)[1]
        if not re.fullmatch(r"\d+\.\d+\.\d+", tag):
            problems.append(f"router image tag must be pinned (x.y.z), got {tag!r}")
    router = routers[0] if len(routers) == 1 else "zenoh"
    images = set()
    for name, svc in services.items():
        if name in routers:
            continue
        if not isinstance(svc, dict):
            problems.append(f"{name}: not a mapping")
            continue
        for key in ("image", "build", "command", "environment"):
            if key not in svc:
                problems.append(f"{name}: missing {key}")
        images.add(svc.get("image"))
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
        for dep in dep_names:
            if dep not in services:
                problems.append(f"{name}: depends_on unknown service {dep}")
    for name, svc in services.items():
        for port in (svc.get("ports", []) if isinstance(svc, dict) else []):
            if not re.fullmatch(r"\d{1,5}:\d{1,5}(/(tcp|udp))?", str(port)):
                problems.append(f"{name}: port {port!r} is not 'host:container[/proto]'")
    if len(images) > 1:
        problems.append(f"every service should use one image, got {sorted(map(str, images))}")
    if problems:
        raise ValueError("docker-compose.yml: " + "; ".join(problems))


def published_ports(doc: Mapping[str, Any]) -> dict[int, str]:
    """Container ports published by any service → protocol."""
    out: dict[int, str] = {}
    for svc in doc["services"].values():
        for port in svc.get("ports", []):
            spec, _, proto = str(port).partition("/")
            out[int(spec.split(":")[1])] = proto or "tcp"
    return out


# -- ports ----------------------------------------------------------------------------------------
def free_port(proto: str = "tcp") -> int:
    kind = socket.SOCK_STREAM if proto == "tcp" else socket.SOCK_DGRAM
    with socket.socket(socket.AF_INET, kind) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def port_is_free(port: int, proto: str) -> bool:
    kind = socket.SOCK_STREAM if proto == "tcp" else socket.SOCK_DGRAM
    with socket.socket(socket.AF_INET, kind) as s:
        try:
            s.bind(("127.0.0.1", port))
        except OSError:
            return False
        return True


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

    def rewrite(self, key: str, value: str) -> str:
        """``scheme:host:port`` / ``proto/host:port`` → loopback and a local port (or a list)."""
        proto = _proto_of(key, value)
        out = []
        for item in filter(None, (v.strip() for v in value.split(","))):
            m = _ENDPOINT.match(item)
            if m is None:
                raise ValueError(f"{key}: cannot map endpoint {item!r} to loopback")
            port = int(m.group("port"))  # 0: the system picks one (each process its own)
            out.append(f"{m.group('scheme')}127.0.0.1:{self.local(port, proto) if port else 0}")
        return ",".join(out)


# -- processes ------------------------------------------------------------------------------------
@dataclass
class Proc:
    name: str
    popen: subprocess.Popen[bytes]
    log_path: Path
    log_file: IO[bytes]


class ProcessGroup:
    """Child processes, each in its own session, stopped with SIGINT then SIGKILL."""

    def __init__(self) -> None:
        self.procs: list[Proc] = []

    def start(self, name: str, argv: list[str], env: Mapping[str, str], log_path: Path) -> Proc:
        log_path.parent.mkdir(parents=True, exist_ok=True)
        fh = log_path.open("wb")
        popen = subprocess.Popen(argv, env=dict(env), cwd=REPO, stdin=subprocess.DEVNULL,
                                 stdout=fh, stderr=subprocess.STDOUT, start_new_session=True)
        proc = Proc(name, popen, log_path, fh)
        self.procs.append(proc)
        return proc

    def dead(self) -> list[Proc]:
        return [p for p in self.procs if p.popen.poll() is not None]

    def stop(self, proc: Proc, grace_s: float = STOP_GRACE_S) -> int:
        """SIGINT, wait ``grace_s``, then SIGKILL; returns the exit code."""
        if proc.popen.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(proc.popen.pid, signal.SIGINT)
            try:
                proc.popen.wait(grace_s)
            except subprocess.TimeoutExpired:
                with contextlib.suppress(ProcessLookupError):
                    os.killpg(proc.popen.pid, signal.SIGKILL)
                proc.popen.wait()
        proc.log_file.close()
        return int(proc.popen.returncode)

    def stop_all(self, grace_s: float = STOP_GRACE_S, last: str | None = None) -> dict[str, int]:
        """Stop every process (in parallel), the one named ``last`` after the others."""
        first = [p for p in self.procs if p.name != last]
        codes: dict[str, int] = {}
        threads = [threading.Thread(target=lambda p=p: codes.__setitem__(p.name,
                                                                          self.stop(p, grace_s)))
                   for p in first]
        for th in threads:
            th.start()
        for th in threads:
            th.join()
        for p in self.procs:
            if p.name == last:
                codes[p.name] = self.stop(p, grace_s)
        return codes


def next_event(events: Any, timeout_s: float = 0.2) -> Any:
    """The next readable MissionEvent from the queue ``events`` within ``timeout_s``, else None."""
    import queue

    from services.common import codec
    from services.msgs import supervisor_pb2

    try:
        raw = events.get(timeout=timeout_s)
    except queue.Empty:
        return None
    try:
        return codec.parse(raw, supervisor_pb2.MissionEvent)
    except codec.CodecError:
        return None


# -- the stack ------------------------------------------------------------------------------------
@dataclass
class StackConfig:
    """What to run and how (flags of the launcher; environment overrides of the services)."""

    run_dir: Path
    seed: int = 7
    speed_factor: float = 20.0
    controller: str = "cc"
    timing: str = "paper"
    s2_method: str = "fast"
    max_steps: int = 150
    ignition_clearance_m: float | None = None  # MissionParams.ignition_clearance_m
    uav_id: str = "uav1"
    waypoints: str = ""
    free_ports: bool = False
    log_format: str = "json"
    log_level: str = "INFO"
    mission_id: str = ""
    services: tuple[str, ...] = ()  # empty: every service of the compose file
    extra_env: dict[str, dict[str, str]] = field(default_factory=dict)  # per service


class Stack:
    """The router and the services of the compose file as local processes (a context manager)."""

    def __init__(self, cfg: StackConfig, compose: Path = COMPOSE):
        self.cfg = cfg
        self.doc = load_compose(compose)
        services = self.doc["services"]
        self.router_name = next(n for n, s in services.items()
                                if str(s.get("image", "")).startswith(ROUTER_IMAGE))
        self.ports = PortMap(published_ports(self.doc), cfg.free_ports)
        self.zenoh_port = self.ports.local(7447, "tcp")
        self.endpoint = f"tcp/127.0.0.1:{self.zenoh_port}"
        self.group = ProcessGroup()
        self.logs = cfg.run_dir / "logs"

    def overrides(self) -> dict[str, str]:
        c = self.cfg
        return {
            "UAV_ID": c.uav_id, "SPEED_FACTOR": str(c.speed_factor), "MISSION_SEED": str(c.seed),
            "CONTROLLER": c.controller, "TIMING": c.timing, "S2_METHOD": c.s2_method,
            "MAX_STEPS": str(c.max_steps), "RUN_DIR": str(c.run_dir),
            "MISSION_ID": c.mission_id or c.run_dir.name, "EXIT_AFTER_MISSION": "0",
            "OPERATOR_WAYPOINTS": c.waypoints, "LOG_FORMAT": c.log_format,
            "IGNITION_CLEARANCE_M": ("" if c.ignition_clearance_m is None
                                     else repr(c.ignition_clearance_m)),
            "TLOG_PATH": str(c.run_dir / "vehicle.tlog"),
            "LOG_LEVEL": c.log_level, "PYTHONUNBUFFERED": "1",
        }

    def service_env(self, name: str) -> dict[str, str]:
        svc = self.doc["services"][name]
        env = dict(os.environ)
        env["PYTHONPATH"] = os.pathsep.join([str(REPO), env.get("PYTHONPATH", "")]).rstrip(
            os.pathsep)
        for key, value in svc.get("environment", {}).items():
            env[key] = self.ports.rewrite(key, value) if key in ENDPOINT_KEYS else str(value)
        env.update(self.overrides())
        env.update(self.cfg.extra_env.get(name, {}))
        return env

    def argv(self, name: str) -> list[str]:
        cmd = list(self.doc["services"][name]["command"])
        return [sys.executable if cmd[0] == "python" else cmd[0], *cmd[1:]]

    def service_names(self) -> list[str]:
        names = [n for n in self.doc["services"] if n != self.router_name]
        return [n for n in names if not self.cfg.services or n in self.cfg.services]

    def start(self) -> None:
        self.logs.mkdir(parents=True, exist_ok=True)
        env = dict(os.environ, PYTHONPATH=str(REPO), PYTHONUNBUFFERED="1",
                   LOG_FORMAT=self.cfg.log_format, UAV_ID=self.cfg.uav_id)
        self.group.start("router", [sys.executable, "-m", "services.router", "--zenoh-listen",
                                    self.endpoint], env, self.logs / "router.log")
        for name in self.service_names():
            self.group.start(name, self.argv(name), self.service_env(name),
                             self.logs / f"{name}.log")

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
def client_session(endpoint: str) -> Iterator[Any]:
    """A Zenoh client session on ``endpoint`` (blocks until the router answers)."""
    import zenoh

    conf = zenoh.Config()
    conf.insert_json5("mode", '"client"')
    conf.insert_json5("scouting/multicast/enabled", "false")
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


def follow(stack: Stack, timeout_s: float, quiet: bool = False) -> Outcome:
    """Print the mission's progress until it ends, a process dies or ``timeout_s`` passes."""
    import queue

    from services.common import keys
    from services.msgs import supervisor_pb2

    events: queue.Queue[bytes] = queue.Queue()
    with client_session(stack.endpoint) as session:
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
                elif kind == supervisor_pb2.MISSION_EVENT_KIND_ENDED:
                    return Outcome(True, ev.success, ev.failure_cause, ev.step, ev.message)
                elif kind == supervisor_pb2.MISSION_EVENT_KIND_ABORTED:
                    return Outcome(False, message=f"aborted: {ev.message}")
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
            print(f"stack: router {stack.endpoint}, services {', '.join(stack.service_names())}"
                  f" (MAVLink ports {dict(stack.ports.ports)}); logs in {stack.logs}/",
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


# -- several vehicles, repeated missions -----------------------------------------------------------
#: services one fleet shares (they serve every vehicle id: ``UAV_IDS``, services/common/fleet.py)
SHARED_SERVICES = ("ews", "system1", "system2")
#: services each vehicle has for itself, started per mission
VEHICLE_SERVICES = ("uavsim", "supervisor")


@dataclass
class Vehicle:
    """One vehicle's processes and mission: its uavsim, its supervisor, their MAVLink port."""

    uav_id: str
    seed: int
    run_dir: Path
    mission_id: str
    offboard_port: int
    procs: list[Proc] = field(default_factory=list)


class Fleet:
    """The router and one EWS and pair of planner services shared by several vehicles, each
    vehicle with its own uavsim and supervisor (a context manager).

    ``uav_ids`` are the ids the shared services serve; :meth:`start_vehicle`
    starts one vehicle's uavsim and supervisor for one mission (offboard link on
    a free loopback port, no ground-station link), :meth:`wait_end` waits for
    its MissionEvent ENDED/ABORTED, :meth:`stop_vehicle` stops them. The same
    vehicle id can fly mission after mission (a soak): the shared services
    keep running. ``cfg.run_dir`` holds the shared services' logs.
    """

    def __init__(self, cfg: StackConfig, uav_ids: list[str], compose: Path = COMPOSE):
        ids = ",".join(uav_ids)
        extra = {name: {"UAV_IDS": ids, **cfg.extra_env.get(name, {})}
                 for name in SHARED_SERVICES}
        self.cfg = cfg
        self.stack = Stack(replace(cfg, services=SHARED_SERVICES, uav_id=uav_ids[0],
                                   extra_env={**cfg.extra_env, **extra}), compose)
        self.uav_ids = list(uav_ids)
        self.vehicles: dict[str, Vehicle] = {}
        self._events: Any = None
        self._session_cm: Any = None
        self._sub: Any = None

    @property
    def endpoint(self) -> str:
        return self.stack.endpoint

    def __enter__(self) -> Fleet:
        import queue

        from services.common import keys

        self.stack.__enter__()
        try:
            self._events = queue.Queue()
            self._session_cm = client_session(self.endpoint)
            session = self._session_cm.__enter__()
            self._sub = session.declare_subscriber(
                f"{keys.ROOT}/*/mission/event", lambda s: self._events.put(s.payload.to_bytes()))
        except BaseException:
            self.stack.stop()
            raise
        return self

    def __exit__(self, *exc: object) -> None:
        try:
            if self._sub is not None:
                self._sub.undeclare()
            if self._session_cm is not None:
                self._session_cm.__exit__(None, None, None)
        finally:
            self.stack.stop()

    def start_vehicle(self, uav_id: str, seed: int, run_dir: Path, mission_id: str = "",
                      env: Mapping[str, str] | None = None) -> Vehicle:
        """Start ``uav_id``'s uavsim and supervisor flying seed ``seed`` into ``run_dir``."""
        port = free_port("udp")
        run_dir.mkdir(parents=True, exist_ok=True)
        mid = mission_id or re.sub(r"[^A-Za-z0-9_\-]", "-", f"{uav_id}-{run_dir.name}")[:64]
        common = {"UAV_ID": uav_id, "UAV_IDS": "", "MISSION_SEED": str(seed),
                  "RUN_DIR": str(run_dir), "MISSION_ID": mid,
                  "TLOG_PATH": str(run_dir / "vehicle.tlog"), **(env or {})}
        own = {"uavsim": {"MAVLINK_URL": f"udpin:127.0.0.1:{port}", "GCS_URL": ""},
               "supervisor": {"MAVLINK_URL": f"udpout:127.0.0.1:{port}"}}
        v = Vehicle(uav_id, seed, run_dir, mid, port)
        for name in VEHICLE_SERVICES:
            penv = self.stack.service_env(name)
            penv.update(common)
            penv.update(own[name])
            v.procs.append(self.stack.group.start(f"{name}-{uav_id}", self.stack.argv(name),
                                                  penv, run_dir / "logs" / f"{name}.log"))
        self.vehicles[uav_id] = v
        return v

    def stop_vehicle(self, uav_id: str) -> dict[str, int]:
        """Stop a vehicle's processes (SIGINT, then SIGKILL); returns their exit codes."""
        v = self.vehicles.pop(uav_id)
        codes: dict[str, int] = {}
        for proc in v.procs:
            codes[proc.name] = self.stack.group.stop(proc)
            self.stack.group.procs.remove(proc)
        return codes

    def wait_end(self, mission_ids: dict[str, str], timeout_s: float) -> dict[str, Outcome]:
        """Wait for the end of the missions {uav: mission id}; a vehicle whose process died or
        that did not end in time gets an Outcome with ``ended=False``."""

        from services.msgs import supervisor_pb2

        out: dict[str, Outcome] = {}
        deadline = time.monotonic() + timeout_s
        ends = (supervisor_pb2.MISSION_EVENT_KIND_ENDED, supervisor_pb2.MISSION_EVENT_KIND_ABORTED)
        by_mission = {mid: uav for uav, mid in mission_ids.items()}
        while len(out) < len(mission_ids) and time.monotonic() < deadline:
            for proc in self.stack.group.dead():
                uav = next((u for u, v in self.vehicles.items() if proc in v.procs), None)
                if uav in mission_ids and uav not in out:
                    out[uav] = Outcome(False, message=f"{proc.name} exited "
                                                      f"{proc.popen.returncode}")
            ev = next_event(self._events)
            if ev is None:
                continue
            uav = by_mission.get(ev.mission_id)
            if uav is None or uav in out or ev.kind not in ends:
                continue
            if ev.kind == supervisor_pb2.MISSION_EVENT_KIND_ENDED:
                out[uav] = Outcome(True, ev.success, ev.failure_cause, ev.step, ev.message)
            else:
                out[uav] = Outcome(False, message=f"aborted: {ev.message}")
        for uav in mission_ids:
            out.setdefault(uav, Outcome(False, message=f"no mission end within {timeout_s:.0f} s"))
        return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m services.launch",
                                description=__doc__.splitlines()[0])
    p.add_argument("--seed", type=int, default=7)
    p.add_argument("--speed-factor", type=float, default=20.0,
                   help="simulated s per wall s (0 or inf: unpaced)")
    p.add_argument("--controller", choices=["cc", "s1", "s2"], default="cc")
    p.add_argument("--timing", choices=["paper", "measured"], default="paper")
    p.add_argument("--s2-method", default="fast", help="System 2 method (fast, exact, ...)")
    p.add_argument("--max-steps", type=int, default=150)
    p.add_argument("--ignition-clearance", type=float, default=None,
                   help="no front ignites within this distance (m) of the UAV (as dualpilot "
                        "mission --ignition-clearance)")
    p.add_argument("--waypoints", default="", help="System 1 operator waypoints 'e1,n1;e2,n2'")
    p.add_argument("--out", default="",
                   help="run directory (default runs/<time>-<controller>-s<seed>)")
    p.add_argument("--compose", type=Path, default=COMPOSE)
    p.add_argument("--free-ports", action="store_true",
                   help="free local ports instead of the published 7447 / 14550")
    p.add_argument("--timeout-s", type=float, default=600.0)
    p.add_argument("--log-format", choices=["json", "text"], default="json")
    p.add_argument("--no-figures", action="store_true")
    p.add_argument("--quiet", action="store_true")
    args = p.parse_args(argv)
    run_id = f"{time.strftime('%Y%m%d-%H%M%S')}-{args.controller}-s{args.seed}"
    run_dir = Path(args.out) if args.out else REPO / "runs" / run_id
    cfg = StackConfig(run_dir=run_dir.resolve(), seed=args.seed, speed_factor=args.speed_factor,
                      controller=args.controller, timing=args.timing, s2_method=args.s2_method,
                      max_steps=args.max_steps, waypoints=args.waypoints,
                      ignition_clearance_m=args.ignition_clearance,
                      free_ports=args.free_ports, log_format=args.log_format,
                      mission_id=re.sub(r"[^A-Za-z0-9_\-]", "-", run_dir.name)[:64])
    t0 = time.perf_counter()
    try:
        outcome, codes = run_mission(cfg, args.timeout_s, not args.no_figures, args.quiet,
                                     args.compose)
    except ValueError as err:
        print(f"launch: error: {err}", file=sys.stderr)
        return 2
    wall = time.perf_counter() - t0
    summary_path = cfg.run_dir / "summary.json"
    if summary_path.is_file():
        s = json.loads(summary_path.read_text())
        keep = ("controller", "seed", "timing", "success", "failure_cause", "steps",
                "mission_time_s", "energy", "switches")
        print(json.dumps({k: s.get(k) for k in keep}))
        overhead = s.get("stack", {}).get("setpoint_overhead", {})
        if overhead:
            print(f"tick→setpoint overhead: median {overhead['median_ms']:.2f} ms, "
                  f"p99 {overhead['p99_ms']:.2f} ms")
    bad = {n: c for n, c in codes.items() if c != 0}
    print(f"wall time {wall:.1f} s; services stopped "
          f"({'all cleanly' if not bad else f'non-zero exits: {bad}'}); results in {cfg.run_dir}/")
    if not outcome.ended:
        print(f"launch: mission did not end: {outcome.message}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
