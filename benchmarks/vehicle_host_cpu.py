"""The vehicle host's CPU per vehicle, without the rest of the stack.

One uavsim host process simulates ``--vehicles`` N vehicles in lockstep (as
in a hosted fleet: one offboard link each on consecutive UDP ports, a flight
log and stream statistics per vehicle), driven by a companion in this
process that does what a fleet's supervisor host and its stream process send
each vehicle: a HEARTBEAT at 1 Hz, the setpoint stream at 20 Hz, MIS_ID asked
at 1 Hz, offboard mode and arming, and a new setpoint stamp (one step of Eq.
(1)) every ``--step-s`` wall seconds (6 s: the paper's timing at real time).
The companion reads and drops what the vehicles send.

After ``--warmup-s`` it measures, over ``--seconds``, the host's CPU (user +
system, % of one core, per vehicle), its context switches per second
(voluntary: wake-ups; involuntary: preemptions) and its threads, from /proc.
CPU time is what this measures: it hardly depends on other load, unlike a
latency; run it at ``nice`` on a shared machine.

    .venv/bin/python benchmarks/vehicle_host_cpu.py --vehicles 1,25,50
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import select
import socket
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import harness  # noqa: F401  (the repository on the path: before its packages)

from services.common import mav
from services.common.mavframe import Framer
from services.launch.processes import REPO, free_port_run

m = mav.mavlink
TICK = os.sysconf("SC_CLK_TCK")
SETPOINT_HZ = 20.0
ARDUPILOT_GUIDED = 4


def proc_cpu(pid: int) -> tuple[float, int, int, int, float]:
    """(user + system CPU s, voluntary and involuntary context switches, threads, system CPU
    s) of ``pid``."""
    stat = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    cpu = (int(stat[11]) + int(stat[12])) / TICK
    system = int(stat[12]) / TICK
    vol = invol = threads = 0
    for task in Path(f"/proc/{pid}/task").iterdir():
        try:
            status = dict(line.split(":", 1) for line in
                          (task / "status").read_text().splitlines() if ":" in line)
        except OSError:  # a thread that ended meanwhile
            continue
        vol += int(status["voluntary_ctxt_switches"])
        invol += int(status["nonvoluntary_ctxt_switches"])
        threads += 1
    return cpu, vol, invol, threads, system


@dataclass
class Companion:
    """What one vehicle's companion sends it (a fleet supervisor's link and stream)."""

    sock: socket.socket
    addr: tuple[str, int]
    framer: Framer
    mav: Any  # pymavlink, for the few commands
    next_sp: float = 0.0
    next_hb: float = 0.0
    next_poll: float = 0.0
    due_ms: int = 0

    def send(self, data: bytes) -> None:
        with contextlib.suppress(OSError):  # the vehicle not up yet (ICMP port unreachable)
            self.sock.sendto(data, self.addr)

    def command(self, cmd: int, *params: float) -> None:
        p = [float(v) for v in params] + [0.0] * (7 - len(params))
        self.send(self.mav.command_long_encode(self.framer.sysid, 1, cmd, 0, *p)
                  .pack(self.mav))

    def tick(self, now: float) -> float:
        """Send what is due; the next time something is."""
        if now >= self.next_hb:
            self.send(self.framer.heartbeat(m.MAV_TYPE_ONBOARD_CONTROLLER,
                                            m.MAV_AUTOPILOT_INVALID, 0, 0, m.MAV_STATE_ACTIVE))
            self.next_hb = now + 1.0
        if now >= self.next_sp:
            self.send(self.framer.set_position_target_local_ned(
                self.due_ms, self.framer.sysid, 1, m.MAV_FRAME_LOCAL_NED, mav.TYPE_MASK_POS_VEL,
                (50.0, 50.0, -50.0, 0.0, 0.0, 0.0)))
            self.next_sp = now + 1.0 / SETPOINT_HZ
        if now >= self.next_poll:
            self.send(self.mav.param_request_read_encode(self.framer.sysid, 1, b"MIS_ID", -1)
                      .pack(self.mav))
            self.next_poll = now + 1.0
        return min(self.next_hb, self.next_sp, self.next_poll)


class NullFile:
    def write(self, _data: bytes) -> None:
        pass


def companions(n: int, base: int) -> list[Companion]:
    out = []
    for k in range(n):
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        sock.bind(("127.0.0.1", 0))
        sock.setblocking(False)
        sysid = 1 + k
        out.append(Companion(sock, ("127.0.0.1", base + k),
                             Framer(sysid, mav.MAV_COMP_ID_ONBOARD_COMPUTER),
                             m.MAVLink(NullFile(), srcSystem=sysid,
                                       srcComponent=mav.MAV_COMP_ID_ONBOARD_COMPUTER)))
    return out


def drive(comps: list[Companion], until: float, step_s: float, t_arm: float) -> None:
    """The companions' loop until ``until`` (monotonic s): streams, arms at ``t_arm``, steps."""
    armed = False
    next_step = t_arm + step_s
    by_fd = {c.sock.fileno(): c for c in comps}
    while (now := time.monotonic()) < until:
        wake = min(c.tick(now) for c in comps)
        if not armed and now >= t_arm:
            for c in comps:
                c.command(m.MAV_CMD_DO_SET_MODE, m.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED,
                          ARDUPILOT_GUIDED)
                c.command(m.MAV_CMD_COMPONENT_ARM_DISARM, 1.0)
            armed = True
        if armed and now >= next_step:
            for c in comps:
                c.due_ms += 1000
                c.next_sp = now  # a new stamp goes at once, as the supervisor's does
            next_step += step_s
        ready, _, _ = select.select(list(by_fd), [], [], max(0.0, min(wake, until) - now))
        for fd in ready:
            sock = by_fd[fd].sock
            while True:
                try:
                    sock.recv(4096)
                except OSError:  # drained (BlockingIOError) or an ICMP error
                    break


def measure(n: int, args: argparse.Namespace, out: Path) -> dict[str, Any]:
    base = free_port_run(n, "udp")
    ids = ",".join(f"f{k + 1}" for k in range(n))
    run = out / f"n{n}"
    run.mkdir(parents=True, exist_ok=True)
    env = dict(os.environ, PYTHONPATH=str(REPO), UAV_IDS=ids, UAV_ID="f1",
               MAVLINK_URL=f"udpin:127.0.0.1:{base}", GCS_URL="", UAV_CLOCK="lockstep",
               UAV_START="50,50", UAV_AUTOPILOT="ardupilot", MAV_SYSID="1", UAV_ZENOH="off",
               LOG_FORMAT="text", OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1",
               STREAM_STATS_PATH=str(run / "{uav}" / "stream.json"),
               TLOG_PATH=str(run / "{uav}" / "vehicle.tlog") if args.tlog else "")
    log = (run / "uavsim.log").open("wb")
    proc = subprocess.Popen([sys.executable, "-m", "services.uavsim"], env=env, cwd=REPO,
                            stdout=log, stderr=subprocess.STDOUT)
    comps = companions(n, base)
    try:
        t0 = time.monotonic()
        drive(comps, t0 + args.warmup_s, args.step_s, t0 + 2.0)
        before, w0 = proc_cpu(proc.pid), time.monotonic()
        drive(comps, w0 + args.seconds, args.step_s, t0 + 2.0)
        after, wall = proc_cpu(proc.pid), time.monotonic() - w0
    finally:
        proc.terminate()
        proc.wait(10)
        log.close()
        for c in comps:
            c.sock.close()
    cpu_pct = 100 * (after[0] - before[0]) / wall
    return {"vehicles": n, "wall_s": round(wall, 1), "cpu_pct": round(cpu_pct, 1),
            "cpu_pct_per_vehicle": round(cpu_pct / n, 3),
            "system_pct": round(100 * (after[4] - before[4]) / wall, 1),
            "wakeups_per_s": round((after[1] - before[1]) / wall),
            "preemptions_per_s": round((after[2] - before[2]) / wall),
            "threads": after[3]}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--vehicles", default="1,25,50", help="comma-separated fleet sizes")
    p.add_argument("--seconds", type=float, default=30.0)
    p.add_argument("--warmup-s", type=float, default=8.0)
    p.add_argument("--step-s", type=float, default=6.0,
                   help="wall s between setpoint stamps (one step of Eq. (1) each)")
    p.add_argument("--no-tlog", dest="tlog", action="store_false",
                   help="no flight log (a fleet's vehicles keep one each)")
    p.add_argument("--out", default="")
    args = p.parse_args(argv)
    out = Path(args.out or tempfile.mkdtemp(prefix="host-cpu-")).resolve()
    rows = []
    for n in [int(v) for v in args.vehicles.split(",") if v]:
        rows.append(measure(n, args, out))
        print(json.dumps(rows[-1]), flush=True)
    (out / "host_cpu.json").write_text(json.dumps(rows, indent=1) + "\n")
    print("| N | CPU (% of a core) | per vehicle | wake-ups/s | preemptions/s | threads |")
    print("|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['vehicles']} | {r['cpu_pct']:.1f} | {r['cpu_pct_per_vehicle']:.2f} | "
              f"{r['wakeups_per_s']} | {r['preemptions_per_s']} | {r['threads']} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
