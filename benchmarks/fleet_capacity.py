"""Fleet capacity at real time: N vehicles sharing one EWS and a planner pool, per N.

For each N of ``--vehicles`` a fresh stack (router, EWS, ``--replicas`` of
System 1 and System 2 serving every vehicle id) and N vehicles fly
``--controller`` missions (default cc; any ``dualpilot evaluate`` name, e.g.
concurrent+risk) on ``--scenario`` (default: the paper's fires), paper
timing, at speed factor ``--speed-factor`` (1: real time),
seeds 0..N-1, each capped at ``--max-steps``. Vehicles are hosted
(``--layout hosted``, the default: one uavsim process simulating them all and
``--hosts`` supervisor processes flying them, each with one stream process)
or get two processes each (``--layout processes``, as before fleets were
hosted). Measured per N, from the vehicles' records and from /proc:

Vehicle k of a host takes off ``--stagger-s`` × k after the first (a fleet
launched one vehicle after another, not all in the same millisecond).

* plan round trip per request (request → reply: Zenoh, the replica's queue,
  the plan), p50 and p99 over every request of every vehicle (``requests.csv``):
  those a step waits for and those asked in the background by the concurrent
  supervisor (also apart), and the planners' own share (service time);
* the setpoint stream as each vehicle saw it (``stream.json``): the worst
  vehicle's p99.9 gap and the longest gap; offboard-loss failsafes; the
  named faults of the step records;
* CPU (user + system, % of one core) and memory (PSS, MB) of the vehicles'
  processes per vehicle, and of the shared services.

The capacity is the largest N with p99 round trip ≤ ``--p99-ms`` and no
failsafe. Prints a table; ``--out`` keeps every run and ``capacity.json``.

    .venv/bin/python benchmarks/fleet_capacity.py --vehicles 10,25,40
    .venv/bin/python benchmarks/fleet_capacity.py --vehicles 25 --controller concurrent+risk \
        --scenario shrub
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import signal
import sys
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import harness  # the repository on the path: before its packages
import numpy as np

from dualpilot.mission.config import MissionConfig
from services import launch

TICK = os.sysconf("SC_CLK_TCK")


# -- /proc --------------------------------------------------------------------------------------
def cpu_s(pid: int) -> float:
    """User + system CPU seconds of ``pid`` (0 once it is gone)."""
    try:
        fields_ = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return 0.0
    return (int(fields_[11]) + int(fields_[12])) / TICK


def pss_mb(pid: int) -> float:
    """Proportional set size of ``pid`` (MB): shared pages split among their users."""
    try:
        for line in Path(f"/proc/{pid}/smaps_rollup").read_text().splitlines():
            if line.startswith("Pss:"):
                return int(line.split()[1]) / 1024.0
    except OSError:
        pass
    return 0.0


def children(pid: int) -> list[int]:
    out = []
    for task in Path(f"/proc/{pid}/task").glob("*"):
        try:
            out += [int(c) for c in (task / "children").read_text().split()]
        except OSError:
            continue
    return out


@dataclass
class Sampler:
    """Samples the PSS of groups of processes every ``every_s``, keeping each one's peak."""

    groups: dict[str, list[int]]
    every_s: float = 2.0
    peak: dict[int, float] = field(default_factory=dict)
    _stop: threading.Event = field(default_factory=threading.Event)

    def adopt_children(self) -> None:
        """Add each process's children (the supervisors' stream processes) to its group."""
        for group, pids in self.groups.items():
            self.groups[group] = sorted({*pids, *(c for pid in pids for c in children(pid))})

    def pids(self) -> list[int]:
        return [pid for pids in self.groups.values() for pid in pids]

    def sample(self) -> None:
        self.adopt_children()
        for pid in self.pids():
            self.peak[pid] = max(self.peak.get(pid, 0.0), pss_mb(pid))

    def run(self) -> None:
        while not self._stop.wait(self.every_s):
            self.sample()

    def start(self) -> None:
        self.adopt_children()
        self.sample()
        threading.Thread(target=self.run, daemon=True).start()

    def stop(self) -> None:
        self._stop.set()
        self.sample()

    def mb(self, group: str) -> float:
        return sum(self.peak.get(p, 0.0) for p in self.groups[group])


def parent(pid: int) -> int:
    """The parent of ``pid`` (0 once it is gone)."""
    try:
        return int(Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[1])
    except OSError:
        return 0


# -- one N -------------------------------------------------------------------------------------
quantiles = harness.quantiles  # p50, p99, max (2 decimals) and n


def request_quantiles(rows: list[dict[str, str]]) -> dict[str, dict[str, float]]:
    """Round trip (ms) of every request, of those a step waited for and of the background
    ones; the planner services' own time (decode, plan, encode) per system; the request's
    size (bytes)."""
    def ms(sel: list[dict[str, str]], col: str) -> dict[str, float]:
        return quantiles([float(r[col]) * 1e3 for r in sel])

    fore = [r for r in rows if r["background"] == "0"]
    back = [r for r in rows if r["background"] == "1"]
    return {"round_trip_ms": ms(rows, "round_trip_s"),
            "round_trip_waited_ms": ms(fore, "round_trip_s"),
            "round_trip_background_ms": ms(back, "round_trip_s"),
            "service_s1_ms": ms([r for r in rows if r["system"] == "1"], "service_s"),
            "service_s2_ms": ms([r for r in rows if r["system"] == "2"], "service_s"),
            "request_bytes": quantiles([float(r["request_bytes"]) for r in rows])}


def fleet_mission(args: argparse.Namespace) -> MissionConfig:
    """Every vehicle's mission: ``--controller`` (paper timing) on ``--scenario`` (none: the
    paper's fires), capped at ``--max-steps``."""
    settings: list[tuple[str, object]] = [("max_steps", args.max_steps)]
    if args.scenario:
        settings.append(("scenario", args.scenario))
    return MissionConfig.named(args.controller, settings=tuple(settings))


def fly(n: int, out: Path, args: argparse.Namespace) -> dict[str, Any]:
    uavs = [f"f{k + 1}" for k in range(n)]
    scale = {"system1": args.s1_replicas, "system2": args.s2_replicas}
    mission = fleet_mission(args)
    cfg = launch.StackConfig(run_dir=out / "shared", speed_factor=args.speed_factor,
                             free_ports=True, log_format="text", scale=scale, mission=mission)
    env = {"START_STAGGER_S": str(args.stagger_s)}
    seeds = list(range(n))
    t0 = time.monotonic()
    with launch.Fleet(cfg, uavs) as fleet:
        shared = [p.popen.pid for p in fleet.stack.group.procs]
        names = {p.popen.pid: p.name for p in fleet.stack.group.procs}
        if args.layout == "hosted":
            chunks = np.array_split(np.arange(n), args.hosts)
            vehicles = []
            for chunk in chunks:
                ids = [uavs[k] for k in chunk]
                vehicles += fleet.start_hosted(ids, [seeds[k] for k in chunk], out, env=env,
                                               tag=f"n{n}", config=mission)
        else:
            vehicles = [fleet.start_vehicle(uav, seed, out / uav, env=env, config=mission)
                        for uav, seed in zip(uavs, seeds, strict=True)]
        own = sorted({p.popen.pid for v in vehicles for p in v.procs})
        names.update({p.popen.pid: p.name for v in vehicles for p in v.procs})
        time.sleep(3.0)  # the supervisors have started their stream processes
        sampler = Sampler({"shared": shared, "vehicles": own})
        sampler.start()
        cpu0 = {p: cpu_s(p) for p in sampler.pids()}
        t_fly = time.monotonic()
        outcomes = fleet.wait_end({v.uav_id: v.mission_id for v in vehicles}, args.timeout_s)
        wall = time.monotonic() - t_fly
        sampler.stop()
        used = {p: cpu_s(p) - cpu0.get(p, 0.0) for p in sampler.pids()}
        cpu = {g: sum(used[p] for p in pids) for g, pids in sampler.groups.items()}
        by_process: dict[str, float] = {}  # % of one core, by service (children: "/child")
        for pid, s_cpu in used.items():
            name = names.get(pid) or f"{names.get(parent(pid), '?')}/child"
            by_process[name] = by_process.get(name, 0.0) + round(100 * s_cpu / wall, 1)
        for v in vehicles:
            if v.uav_id in fleet.vehicles:
                fleet.stop_vehicle(v.uav_id)
    requests: list[dict[str, str]] = []  # every plan request of every vehicle
    worst_p999, longest, failsafes, steps = 0.0, 0.0, 0, 0
    faults: dict[str, int] = {}
    for uav in uavs:
        run = out / uav
        if (run / "latency.csv").is_file():
            with (run / "latency.csv").open() as fh:
                steps += sum(1 for _ in csv.DictReader(fh))
        if (run / "requests.csv").is_file():
            with (run / "requests.csv").open() as fh:
                requests += list(csv.DictReader(fh))
        if (run / "stream.json").is_file():
            s = json.loads((run / "stream.json").read_text())
            worst_p999 = max(worst_p999, s["gaps"]["p999_ms"])
            longest = max(longest, s["gaps"]["max_ms"])
            failsafes += int(s["failsafes"])
        if (run / "summary.json").is_file():
            for name, count in json.loads((run / "summary.json").read_text())["stack"].get(
                    "faults", {}).items():
                faults[name] = faults.get(name, 0) + int(count)
    return {
        "vehicles": n, "controller": args.controller, "scenario": args.scenario or "paper",
        "layout": args.layout, "hosts": args.hosts if args.layout == "hosted"
        else n, "replicas": scale, "ended": sum(o.ended for o in outcomes.values()),
        "steps": steps, "wall_s": round(wall, 1), "total_s": round(time.monotonic() - t0, 1),
        **request_quantiles(requests),
        "stream": {"worst_p999_ms": worst_p999, "max_ms": longest, "failsafes": failsafes},
        "faults": faults,
        "cpu_pct_per_vehicle": round(100 * cpu["vehicles"] / wall / n, 2),
        "cpu_pct_shared": round(100 * cpu["shared"] / wall, 1),
        "pss_mb_per_vehicle": round(sampler.mb("vehicles") / n, 1),
        "pss_mb_shared": round(sampler.mb("shared"), 1),
        "vehicle_processes": len(sampler.groups["vehicles"]),
        "cpu_pct_by_process": dict(sorted(by_process.items())),
    }


def main(argv: list[str] | None = None) -> int:
    # SIGTERM ends the run like Ctrl-C: the stack's processes are stopped on the way out
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(1))
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--vehicles", default="10,25,40", help="comma-separated fleet sizes")
    p.add_argument("--layout", choices=["hosted", "processes"], default="hosted")
    p.add_argument("--hosts", type=int, default=1, help="supervisor processes (hosted)")
    p.add_argument("--s1-replicas", type=int, default=1)
    p.add_argument("--s2-replicas", type=int, default=2)
    p.add_argument("--controller", default="cc",
                   help="every vehicle's controller, a dualpilot evaluate name (cc, "
                        "concurrent+risk, ...)")
    p.add_argument("--scenario", default="", help="fire scenario (grass-15, shrub, ...); "
                                                  "none: the paper's fires")
    p.add_argument("--speed-factor", type=float, default=1.0)
    p.add_argument("--max-steps", type=int, default=40)
    p.add_argument("--stagger-s", type=float, default=0.5,
                   help="vehicle k of a host takes off k times this many s after the first")
    p.add_argument("--p99-ms", type=float, default=100.0)
    p.add_argument("--timeout-s", type=float, default=1200.0)
    p.add_argument("--out", default="")
    args = p.parse_args(argv)
    out = Path(args.out or tempfile.mkdtemp(prefix="fleet-")).resolve()
    rows = []
    for n in [int(v) for v in args.vehicles.split(",") if v]:
        row = fly(n, out / f"n{n}", args)
        rows.append(row)
        print(json.dumps(row), flush=True)
    (out / "capacity.json").write_text(json.dumps(rows, indent=1) + "\n")
    print(f"\nspeed factor {args.speed_factor:g}, {args.controller} on "
          f"{args.scenario or 'the paper fires'}, paper timing, max {args.max_steps} steps, "
          f"{args.layout} ({args.hosts} supervisor host(s)), replicas S1 {args.s1_replicas} "
          f"S2 {args.s2_replicas}, {os.cpu_count()} cores")
    print("| N | steps | RTT p50 | RTT p99 | waited p99 | background p99 | requests "
          "(background) | S2 service p99 | stream p99.9 (worst) | longest gap | failsafes | "
          "faults | CPU/vehicle | CPU shared | PSS/vehicle | PSS shared |")
    print("|" + "---|" * 16)
    for r in rows:
        rt, st = r["round_trip_ms"], r["stream"]
        print(f"| {r['vehicles']} | {r['steps']} | {rt['p50']:.1f} ms | {rt['p99']:.1f} ms | "
              f"{r['round_trip_waited_ms']['p99']:.1f} ms | "
              f"{r['round_trip_background_ms']['p99']:.1f} ms | "
              f"{rt['n']:.0f} ({r['round_trip_background_ms']['n']:.0f}) | "
              f"{r['service_s2_ms']['p99']:.1f} ms | "
              f"{st['worst_p999_ms']:.1f} ms | {st['max_ms']:.1f} ms | {st['failsafes']} | "
              f"{sum(r['faults'].values())} | {r['cpu_pct_per_vehicle']:.2f} % | "
              f"{r['cpu_pct_shared']:.0f} % | {r['pss_mb_per_vehicle']:.1f} MB | "
              f"{r['pss_mb_shared']:.0f} MB |")
        print("  CPU by process (% of one core): " + ", ".join(
            f"{k} {v:g}" for k, v in r["cpu_pct_by_process"].items()))
    ok = [r["vehicles"] for r in rows if r["round_trip_ms"]["p99"] <= args.p99_ms
          and r["stream"]["failsafes"] == 0 and r["ended"] == r["vehicles"]]
    print(f"largest N with p99 round trip <= {args.p99_ms:g} ms and no failsafe: "
          f"{max(ok) if ok else 'none'}")
    print(f"run directory: {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
