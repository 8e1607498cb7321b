"""The plan round trip with the forecast and without it, through the stack.

    .venv/bin/python benchmarks/risk_round_trip.py --scenario grass-15 --seeds 0-4

Flies each seed through the stack (a router, the EWS, one replica of each
planner, one vehicle at a time, unpaced) with each controller of ``--pairs``
(default: ``s1,s1+risk,s2,s2+risk,concurrent,concurrent+risk``), and reads
every plan request from the run's ``requests.csv``
(services/supervisor/runlog.py): its round trip (request → checked reply:
Zenoh, the replica's decoding, plan and encoding), the service's own time and
the request's size. Prints p50 and p99 per controller and system, and for
each risk-aware controller the ratio of its median round trip to its paper
twin's (the same seeds; the plans differ, so the planners' own time is shown
beside the round trip). One run, numbers from this run only.
"""

from __future__ import annotations

import argparse
import csv
import tempfile
from pathlib import Path

import harness  # the repository on the path: before its packages

from dualpilot.mission.config import MissionConfig
from services import launch


def parse_seeds(text: str) -> list[int]:
    lo, _, hi = text.partition("-")
    return list(range(int(lo), int(hi or lo) + 1))


def fly(fleet: launch.Fleet, controller: str, seeds: list[int], scenario: str,
        out: Path) -> list[dict[str, str]]:
    """Every plan request of ``controller``'s missions over ``seeds`` (rows of requests.csv)."""
    uav = fleet.uav_ids[0]
    rows: list[dict[str, str]] = []
    for seed in seeds:
        settings = (("scenario", scenario),) if scenario else ()
        config = MissionConfig.named(controller, seed=seed, settings=settings)
        run_dir = out / f"{controller.replace('+', '-')}-s{seed}"
        v = fleet.start_vehicle(uav, seed, run_dir, env={"SPEED_FACTOR": "0"}, config=config)
        ended = fleet.wait_end({uav: v.mission_id}, 600.0)[uav].ended
        fleet.stop_vehicle(uav)
        if not ended:
            raise SystemExit(f"{controller} seed {seed} did not end: see {run_dir}")
        with (run_dir / "requests.csv").open() as fh:
            rows += [{**r, "controller": controller} for r in csv.DictReader(fh)]
    return rows


def summary(rows: list[dict[str, str]]) -> dict[str, dict[str, dict[str, float]]]:
    """Per system: round trip and service time (ms) and request size (kB), p50 / p99 / n."""
    out = {}
    for system in ("1", "2"):
        sel = [r for r in rows if r["system"] == system and r["status"] == "ok"]
        if sel:
            out[f"S{system}"] = {
                "rtt": harness.quantiles([float(r["round_trip_s"]) for r in sel], scale=1e3),
                "service": harness.quantiles([float(r["service_s"]) for r in sel], scale=1e3),
                "kB": harness.quantiles([float(r["request_bytes"]) for r in sel], scale=1e-3)}
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenario", default="grass-15")
    ap.add_argument("--seeds", default="0-4")
    ap.add_argument("--pairs", default="s1,s1+risk,s2,s2+risk,concurrent,concurrent+risk")
    ap.add_argument("--out", default="")
    args = ap.parse_args()
    out = Path(args.out or tempfile.mkdtemp(prefix="risk-rtt-")).resolve()
    seeds = parse_seeds(args.seeds)
    cfg = launch.StackConfig(run_dir=out / "shared", speed_factor=0.0, free_ports=True,
                             log_format="text")
    results = {}
    with launch.Fleet(cfg, ["rt0"]) as fleet:
        for controller in args.pairs.split(","):
            results[controller] = summary(fly(fleet, controller, seeds, args.scenario, out))
    harness.emit(results, out / "risk_round_trip.json")
    print(f"\n{args.scenario or 'paper fires'}, seeds {args.seeds}, unpaced, one vehicle, "
          "successful plans only")
    print("| controller | system | requests | round trip p50 / p99 (ms) | service p50 / p99 (ms) "
          "| request p50 / p99 (kB) |")
    print("|---|---|---|---|---|---|")
    for controller, per in results.items():
        for system, q in per.items():
            print(f"| {controller} | {system} | {q['rtt']['n']} | {q['rtt']['p50']:.1f} / "
                  f"{q['rtt']['p99']:.1f} | {q['service']['p50']:.1f} / "
                  f"{q['service']['p99']:.1f} | {q['kB']['p50']:.2f} / {q['kB']['p99']:.2f} |")
    for controller, per in results.items():
        twin = controller.removesuffix("+risk")
        if controller.endswith("+risk") and twin in results:
            for system, q in per.items():
                base = results[twin].get(system)
                if base:
                    print(f"{controller} / {twin} {system}: round trip p50 "
                          f"{q['rtt']['p50'] / base['rtt']['p50']:.2f}x, p99 "
                          f"{q['rtt']['p99'] / base['rtt']['p99']:.2f}x; transport (round trip "
                          f"- service) p50 {q['rtt']['p50'] - q['service']['p50']:.1f} vs "
                          f"{base['rtt']['p50'] - base['service']['p50']:.1f} ms")
    print(f"run directory: {out}")


if __name__ == "__main__":
    main()
