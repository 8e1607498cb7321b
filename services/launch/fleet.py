"""Several vehicles against one EWS and one pair of planner services (benchmarks/load_vehicles.py),
and mission after mission on the same shared services (benchmarks/soak.py): :class:`Fleet`.

A vehicle has a uavsim and a supervisor of its own (:meth:`Fleet.start_vehicle`),
or shares a vehicle host with others (:meth:`Fleet.start_hosted`): one uavsim
process simulating several vehicles and one supervisor process flying them
(``UAV_IDS``: MAVLink instance k on the base port + k, system id 1 + k)."""

from __future__ import annotations

import re
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from dualpilot.mission.config import MissionConfig
from dualpilot.mission.config_args import config_to_argv
from services.launch.compose import COMPOSE
from services.launch.processes import Proc, free_port, free_port_run
from services.launch.stack import Outcome, Stack, StackConfig, client_session, next_event

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

    ``uav_ids`` are the ids the ``shared`` services serve (a planner may run elsewhere:
    ``services.launch --join``); :meth:`start_vehicle`
    starts one vehicle's uavsim and supervisor for one mission (offboard link on
    a free loopback port, no ground-station link), :meth:`wait_end` waits for
    its MissionEvent ENDED/ABORTED, :meth:`stop_vehicle` stops them. The same
    vehicle id can fly mission after mission (a soak): the shared services
    keep running. ``cfg.run_dir`` holds the shared services' logs.
    """

    def __init__(self, cfg: StackConfig, uav_ids: list[str], compose: Path = COMPOSE,
                 shared: tuple[str, ...] = SHARED_SERVICES):
        ids = ",".join(uav_ids)
        extra = {name: {"UAV_IDS": ids, **cfg.extra_env.get(name, {})} for name in shared}
        self.cfg = cfg
        viewer = ("viewer",) if "viewer" in cfg.profiles else ()  # the live view: every vehicle
        self.stack = Stack(replace(cfg, services=shared + viewer, uav_id=uav_ids[0],
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
                      env: Mapping[str, str] | None = None,
                      config: MissionConfig | None = None) -> Vehicle:
        """Start ``uav_id``'s uavsim and supervisor flying seed ``seed`` into ``run_dir``: the
        fleet's mission, or ``config`` (its seed and mission id this vehicle's)."""
        port = free_port("udp")
        run_dir.mkdir(parents=True, exist_ok=True)
        mid = mission_id or re.sub(r"[^A-Za-z0-9_\-]", "-", f"{uav_id}-{run_dir.name}")[:64]
        mission = None if config is None else config_to_argv(replace(config, seed=seed,
                                                                     mission_id=mid))
        common = {"UAV_ID": uav_id, "UAV_IDS": "", "RUN_DIR": str(run_dir),
                  "TLOG_PATH": str(run_dir / "vehicle.tlog"),
                  "STREAM_STATS_PATH": str(run_dir / "stream.json"), **(env or {})}
        own = {"uavsim": {"MAVLINK_URL": f"udpin:127.0.0.1:{port}", "GCS_URL": ""},
               "supervisor": {"MAVLINK_URL": f"udpout:127.0.0.1:{port}",
                              **({"MISSION_SEED": str(seed), "MISSION_ID": mid}
                                 if mission is None else {})}}
        v = Vehicle(uav_id, seed, run_dir, mid, port)
        for name in VEHICLE_SERVICES:
            flags = mission if name == "supervisor" else None
            penv = self.stack.service_env(name, mission_flags=flags is not None)
            penv.update(common)
            penv.update(own[name])
            v.procs.append(self.stack.group.start(f"{name}-{uav_id}",
                                                  self.stack.argv(name, flags), penv,
                                                  run_dir / "logs" / f"{name}.log"))
        self.vehicles[uav_id] = v
        return v

    def start_hosted(self, uav_ids: list[str], seeds: list[int], out: Path,
                     env: Mapping[str, str] | None = None, tag: str = "",
                     config: MissionConfig | None = None,
                     service_env: Mapping[str, Mapping[str, str]] | None = None
                     ) -> list[Vehicle]:
        """Start one uavsim and one supervisor process for all of ``uav_ids`` (vehicle k flies
        ``seeds[k]`` into ``out/<uav>``); returns the vehicles (their processes are the host's,
        shared). ``env`` goes to both, ``service_env[name]`` to ``name`` alone. Stop them with
        :meth:`stop_vehicle` of any of them."""
        if len(seeds) != len(uav_ids):
            raise ValueError("one seed per vehicle")
        base = free_port_run(len(uav_ids), "udp")
        tag = tag or out.name
        mid = f"{{uav}}-{tag}"[:64]
        mission = None if config is None else config_to_argv(replace(config, mission_id=mid))
        common = {"UAV_ID": uav_ids[0], "UAV_IDS": ",".join(uav_ids),
                  "RUN_DIR": str(out / "{uav}"),
                  "TLOG_PATH": str(out / "{uav}" / "vehicle.tlog"),
                  "STREAM_STATS_PATH": str(out / "{uav}" / "stream.json"),
                  "MAV_SYSID": "1", **(env or {})}
        own = {"uavsim": {"MAVLINK_URL": f"udpin:127.0.0.1:{base}", "GCS_URL": ""},
               "supervisor": {"MAVLINK_URL": f"udpout:127.0.0.1:{base}",
                              "MISSION_SEEDS": ",".join(str(s) for s in seeds),
                              **({"MISSION_ID": mid} if mission is None else {})}}
        for name, extra in (service_env or {}).items():
            own[name].update(extra)
        host = f"host-{uav_ids[0]}"
        procs = []
        for uav in uav_ids:
            (out / uav).mkdir(parents=True, exist_ok=True)
        for name in VEHICLE_SERVICES:
            flags = mission if name == "supervisor" else None
            penv = self.stack.service_env(name, mission_flags=flags is not None)
            penv.update(common)
            penv.update(own[name])
            procs.append(self.stack.group.start(f"{name}-{host}", self.stack.argv(name, flags),
                                                penv, out / f"{host}-{name}.log"))
        vehicles = []
        for k, uav in enumerate(uav_ids):
            v = Vehicle(uav, seeds[k], out / uav, f"{uav}-{tag}"[:64], base + k, procs)
            self.vehicles[uav] = v
            vehicles.append(v)
        return vehicles

    def stop_vehicle(self, uav_id: str) -> dict[str, int]:
        """Stop a vehicle's processes (SIGINT, then SIGKILL); returns their exit codes. A
        hosted vehicle's processes are its host's: the host's other vehicles go too."""
        v = self.vehicles.pop(uav_id)
        codes: dict[str, int] = {}
        for other in [u for u, w in self.vehicles.items() if w.procs is v.procs]:
            del self.vehicles[other]
        for proc in v.procs:
            codes[proc.name] = self.stack.group.stop(proc)
            self.stack.group.procs.remove(proc)
        return codes

    def wait_end(self, mission_ids: dict[str, str], timeout_s: float,
                 on_end: Callable[[str, Outcome], None] | None = None) -> dict[str, Outcome]:
        """Wait for the end of the missions {uav: mission id}; a vehicle whose process died or
        that did not end in time gets an Outcome with ``ended=False``. ``on_end(uav, outcome)``
        is called as each mission's outcome is known (its records are written by then)."""
        out: dict[str, Outcome] = {}
        deadline = time.monotonic() + timeout_s
        by_mission = {mid: uav for uav, mid in mission_ids.items()}

        def known(uav: str, outcome: Outcome) -> None:
            out[uav] = outcome
            if on_end is not None:
                on_end(uav, outcome)

        while len(out) < len(mission_ids) and time.monotonic() < deadline:
            for proc in self.stack.group.dead():
                for uav in [u for u, v in self.vehicles.items() if proc in v.procs]:
                    if uav in mission_ids and uav not in out:
                        known(uav, Outcome(False, message=f"{proc.name} exited "
                                                          f"{proc.popen.returncode}"))
            ev = next_event(self._events)
            if ev is None:
                continue
            ended = by_mission.get(ev.mission_id)
            outcome = Outcome.of(ev)
            if ended is not None and ended not in out and outcome is not None:
                known(ended, outcome)
        for uav in mission_ids:
            if uav not in out:
                known(uav, Outcome(False, message=f"no mission end within {timeout_s:.0f} s"))
        return out
