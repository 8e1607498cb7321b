"""Soak: consecutive missions through the stack; memory, fds, sockets, processes, records.

The router, the EWS and the System 1 / System 2 services run for the whole
soak (services.launch.Fleet with one vehicle id); every mission starts a fresh
uavsim and supervisor (a vehicle that boots, flies one mission, and is shut
down), flies the cognitive controller with the paper's timing at
``--speed-factor`` on the next of the ten seeds that reach the goal in-process
(benchmarks/load_vehicles.py; ``--seed0 S``: seed S + k instead, most of which
end early in a fire), and is stopped once its MissionEvent ENDED arrives.
After every mission the script samples, for every process it started, the
resident memory (VmRSS), the open file descriptors and sockets and the child
processes (from /proc), and checks that the mission's records (``summary.json``
with its id and step count, ``steps.csv``, ``latency.csv``, the tlog) are on
disk and that the stopped processes are gone.

Reports the RSS growth of each long-lived service from the end of the
warm-up (``--warmup`` missions) to the last mission (target ≤ 10 %), the fd
and socket counts over the soak, processes left behind, missions not
recorded, and the rate (missions per minute, so the time 1,000 would take).

    .venv/bin/python benchmarks/soak.py --missions 100 --speed-factor 1000
"""

from __future__ import annotations

import argparse
import contextlib
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

from dualpilot.mission.config import MissionConfig, Timing
from services import launch

SUCCESS_SEEDS = harness.SUCCESS_SEEDS
MISSION = MissionConfig.named("cc", timing=Timing.PAPER)  # each mission's, with its own seed

UAV = "soak"
LONG_LIVED = ("router", "ews", "system1", "system2")
PAGE_KB = os.sysconf("SC_PAGE_SIZE") // 1024


# -- /proc ----------------------------------------------------------------------------------------
def rss_kb(pid: int) -> int:
    """Resident set size of ``pid`` in kB (0 if it is gone)."""
    try:
        return int(Path(f"/proc/{pid}/statm").read_text().split()[1]) * PAGE_KB
    except (OSError, IndexError, ValueError):
        return 0


def fds(pid: int) -> tuple[int, int]:
    """(open file descriptors, of which sockets) of ``pid``."""
    try:
        names = os.listdir(f"/proc/{pid}/fd")
    except OSError:
        return 0, 0
    sockets = 0
    for name in names:
        with contextlib.suppress(OSError):
            sockets += os.readlink(f"/proc/{pid}/fd/{name}").startswith("socket:")
    return len(names), sockets


def processes() -> dict[int, tuple[int, int]]:
    """pid → (parent pid, session id) of every process on the machine."""
    out = {}
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            stat = Path(f"/proc/{entry}/stat").read_text()
        except OSError:
            continue
        fields_ = stat[stat.rindex(")") + 2:].split()
        out[int(entry)] = (int(fields_[1]), int(fields_[3]))
    return out


# -- the soak -------------------------------------------------------------------------------------
@dataclass
class Sample:
    mission: int
    rss_kb: dict[str, int]
    fds: dict[str, int]
    sockets: dict[str, int]
    children: dict[str, int]


@dataclass
class SoakResult:
    missions: int
    wall_s: float
    successes: int = 0
    samples: list[Sample] = field(default_factory=list)
    not_recorded: list[int] = field(default_factory=list)
    not_ended: list[str] = field(default_factory=list)
    leaked: list[str] = field(default_factory=list)        # processes left behind
    bad_exits: list[str] = field(default_factory=list)
    vehicle_rss_kb: list[int] = field(default_factory=list)  # uavsim + supervisor at mission end

    def growth(self, warmup: int) -> dict[str, float]:
        """Per long-lived service: RSS at the last mission / RSS after the warm-up − 1."""
        if len(self.samples) <= warmup:
            return {}
        first, last = self.samples[warmup - 1 if warmup else 0], self.samples[-1]
        return {n: round(last.rss_kb[n] / first.rss_kb[n] - 1.0, 4)
                for n in LONG_LIVED if first.rss_kb.get(n)}

    def report(self, warmup: int) -> dict[str, Any]:
        rate = self.missions / self.wall_s * 60.0 if self.wall_s else 0.0
        first, last = (self.samples[0], self.samples[-1]) if self.samples else (None, None)
        return {
            "missions": self.missions, "successes": self.successes,
            "wall_s": round(self.wall_s, 1), "missions_per_min": round(rate, 2),
            "extrapolated_1000_missions_min": round(1000 / rate, 1) if rate else None,
            "warmup": warmup, "rss_growth_after_warmup": self.growth(warmup),
            "rss_kb_first": first.rss_kb if first else {},
            "rss_kb_last": last.rss_kb if last else {},
            "fds_first": first.fds if first else {}, "fds_last": last.fds if last else {},
            "fds_max": {n: max(s.fds[n] for s in self.samples) for n in LONG_LIVED}
            if self.samples else {},
            "sockets_first": first.sockets if first else {},
            "sockets_last": last.sockets if last else {},
            "children_max": {n: max(s.children[n] for s in self.samples) for n in LONG_LIVED}
            if self.samples else {},
            "vehicle_rss_kb_first_last": (self.vehicle_rss_kb[:1] + self.vehicle_rss_kb[-1:]),
            "not_recorded": self.not_recorded, "not_ended": self.not_ended,
            "leaked_processes": self.leaked, "bad_exits": self.bad_exits,
        }


def recorded(run_dir: Path, mission_id: str, steps: int) -> bool:
    try:
        summary = json.loads((run_dir / "summary.json").read_text())
    except (OSError, ValueError):
        return False
    stack = summary.get("stack", {})
    return (stack.get("mission_id", summary.get("mission_id")) == mission_id
            and int(summary.get("steps", -1)) == steps
            and all((run_dir / f).is_file() for f in ("steps.csv", "latency.csv",
                                                      "vehicle.tlog")))


def run_soak(n: int, out: Path, speed_factor: float = 1000.0, seed0: int | None = None,
             timeout_s: float = 300.0, max_wall_s: float | None = None,
             quiet: bool = True, stop: threading.Event | None = None) -> SoakResult:
    """Fly up to ``n`` consecutive missions (fewer if ``max_wall_s`` runs out or ``stop`` is set
    between missions); the stack is stopped on the way out either way."""
    cfg = launch.StackConfig(run_dir=out, speed_factor=speed_factor, free_ports=True,
                             log_format="text")
    t0 = time.monotonic()
    result = SoakResult(0, 0.0)
    sessions: set[int] = set()
    with launch.Fleet(cfg, [UAV]) as fleet:
        shared = {p.name: p.popen.pid for p in fleet.stack.group.procs}
        sessions.update(shared.values())
        for k in range(n):
            if (max_wall_s is not None and time.monotonic() - t0 > max_wall_s) or (
                    stop is not None and stop.is_set()):
                break
            run_dir = out / f"m{k:04d}"
            seed = SUCCESS_SEEDS[k % len(SUCCESS_SEEDS)] if seed0 is None else seed0 + k
            v = fleet.start_vehicle(UAV, seed, run_dir, mission_id=f"soak-{k:04d}",
                                    config=MISSION)
            pids = [p.popen.pid for p in v.procs]
            sessions.update(pids)
            o = fleet.wait_end({UAV: v.mission_id}, timeout_s)[UAV]
            result.vehicle_rss_kb.append(sum(rss_kb(pid) for pid in pids))
            codes = fleet.stop_vehicle(UAV)
            result.bad_exits += [f"m{k}: {name} {c}" for name, c in codes.items() if c != 0]
            result.missions += 1
            if not o.ended:
                result.not_ended.append(f"m{k}: {o.message}")
            result.successes += bool(o.success)
            if not (o.ended and recorded(run_dir, v.mission_id, o.steps)):
                result.not_recorded.append(k)
            procs = processes()
            result.leaked += [f"m{k}: pid {pid} ({name})" for name, pid in
                              zip(("uavsim", "supervisor"), pids, strict=True) if pid in procs]
            kids = {name: sum(1 for pp, _ in procs.values() if pp == pid)
                    for name, pid in shared.items()}
            fd = {name: fds(pid) for name, pid in shared.items()}
            result.samples.append(Sample(k, {nm: rss_kb(pid) for nm, pid in shared.items()},
                                         {nm: f[0] for nm, f in fd.items()},
                                         {nm: f[1] for nm, f in fd.items()}, kids))
            if not quiet:
                s = result.samples[-1]
                print(f"mission {k}: seed {seed} ended={o.ended} success={o.success} "
                      f"steps={o.steps} rss_MB=" + ",".join(
                          f"{nm}:{s.rss_kb[nm] / 1024:.0f}" for nm in LONG_LIVED)
                      + f" fds={sum(s.fds.values())} t={time.monotonic() - t0:.0f}s",
                      flush=True)
        result.wall_s = time.monotonic() - t0
    codes = {p.name: int(p.popen.returncode) for p in fleet.stack.group.procs}
    result.bad_exits += [f"{name}: {c}" for name, c in codes.items() if c != 0]
    left = [pid for pid, (_, sid) in processes().items() if sid in sessions]
    result.leaked += [f"after stop: pid {pid}" for pid in left]
    return result


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--missions", type=int, default=1000)
    p.add_argument("--max-wall-s", type=float, default=None,
                   help="stop starting missions after this much wall time")
    p.add_argument("--speed-factor", type=float, default=1000.0)
    p.add_argument("--seed0", type=int, default=None,
                   help="fly seeds S, S+1, … (default: cycle the ten successful seeds)")
    p.add_argument("--warmup", type=int, default=0,
                   help="missions before the memory baseline (default: 10 %%, at least 10)")
    p.add_argument("--out", default="", help="run directory (default: a temporary one)")
    args = p.parse_args(argv)
    out = Path(args.out) if args.out else Path(tempfile.mkdtemp(prefix="soak-"))
    stop = threading.Event()  # SIGINT/SIGTERM: finish the mission in flight, report, clean up

    def on_signal(signum: int, _frame: object) -> None:
        print(f"signal {signum}: stopping after this mission", flush=True)
        stop.set()

    signal.signal(signal.SIGINT, on_signal)
    signal.signal(signal.SIGTERM, on_signal)
    result = run_soak(args.missions, out.resolve(), args.speed_factor, args.seed0,
                      max_wall_s=args.max_wall_s, quiet=False, stop=stop)
    warmup = args.warmup or max(10, result.missions // 10)
    rep = result.report(warmup)
    print(json.dumps(rep, indent=1))
    growth = max(rep["rss_growth_after_warmup"].values(), default=0.0)
    ok = (growth <= 0.10 and not result.leaked and not result.not_recorded
          and not result.bad_exits)
    print(f"{'PASS' if ok else 'FAIL'}: {result.missions} missions in {result.wall_s:.0f} s, "
          f"max RSS growth after warm-up {growth:.1%}, leaked {len(result.leaked)}, "
          f"not recorded {len(result.not_recorded)}; run directory {out}")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
