"""What the occupancy forecast costs a mission step at paper settings.

Each mission (configuration (S, i) of ``--seed`` S, the profile's readings and
``--scenario``'s fire process, paper timing) is flown twice by each controller:
as the paper's step, and with the fire port's forecast (dualpilot/model/forecast.py,
or a scenario's level set run ahead, dualpilot/model/physics_forecast.py; default
parameters) made
at every step once the supervisor has chosen the system, exactly where a
risk-aware planner would ask for it. The forecast changes nothing the mission
does, so both flights are the same steps; the CPU time of this process over each
``Mission.step`` is measured (not wall time: on a shared machine other jobs
would set it), the two flights of a mission one after the other. Reported per
controller: median step time without and with the forecast, their ratio, the
ratio of total time, and the forecast's own median time (for a scenario also how
often the kept run-ahead was reused). With ``--risk`` the "+risk" controllers are
timed too (their steps differ: they plan on the forecast).

    .venv/bin/python benchmarks/forecast_step_cost.py [--missions 20] [--seed 2000]
        [--profiles today,fig-r5] [--controllers cc,s1,s2,concurrent] [--risk]
        [--scenario paper|grass-15|shrub|...]
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from typing import Any

import numpy as np

from dualpilot.evaluation.missions import Task
from dualpilot.mission.config import MissionConfig
from dualpilot.mission.local import LocalFires, local_mission
from dualpilot.mission.result import Ending, StepRecord
from dualpilot.model.physics_forecast import RunAhead
from dualpilot.model.scenarios import PAPER, scenario_names
from dualpilot.supervisor.paper.decision import Decision


class Forecaster:
    """A step observer that makes the fire port's forecast once the system is chosen."""

    def __init__(self, mission: Any):
        self.mission = mission
        self.times: list[float] = []

    def decided(self, t: int, decision: Decision, commanded: int) -> None:
        fires = self.mission.fires
        assert isinstance(fires, LocalFires)
        t0 = time.process_time()
        fires.forecast(self.mission.substeps_per_step(commanded or 1))
        self.times.append(time.process_time() - t0)

    def commanded(self, t: int, flown: int, info: dict[str, object]) -> None: ...

    def recorded(self, record: StepRecord, flown: bool) -> None: ...

    def ended(self, record: StepRecord, ending: Ending) -> None: ...


def fly(profile: str, index: int, seed: int, controller: str, forecast: bool,
        scenario: str = PAPER) -> tuple[list[float], list[float], int, tuple[int, int]]:
    """Step CPU times (s), forecast CPU times (s), the steps' total fronts of one mission and
    (reused, fresh) run-aheads of a scenario's forecast."""
    base = MissionConfig(profile=profile, settings=(("scenario", scenario),))
    mission = local_mission(Task.of(index, seed, controller, base).mission())
    obs = Forecaster(mission) if forecast else None
    mission.observer = obs
    steps: list[float] = []
    fronts = 0
    while True:
        fronts += len(mission.fires.snapshot().regions)
        t0 = time.process_time()
        rec = mission.step()
        if rec is None:
            break
        steps.append(time.process_time() - t0)
    fires = mission.fires
    assert isinstance(fires, LocalFires)
    ahead = fires.field.physics.run_ahead if fires.field.physics is not None else None
    copies = (ahead.reused, ahead.fresh) if isinstance(ahead, RunAhead) else (0, 0)
    return steps, (obs.times if obs is not None else []), fronts, copies


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--missions", type=int, default=20)
    ap.add_argument("--seed", type=int, default=2000)
    ap.add_argument("--profiles", default="today,fig-r5")
    ap.add_argument("--controllers", default="cc,s1,s2,concurrent")
    ap.add_argument("--risk", action="store_true", help="also time the +risk controllers")
    ap.add_argument("--scenario", default=PAPER, choices=scenario_names(),
                    help="the fire process (default: the paper's rectangles)")
    ap.add_argument("--json", type=Path, default=Path("runs/forecast_step_cost.json"))
    args = ap.parse_args()
    for prof in args.profiles.split(","):  # compile and warm every kernel (and cache) first
        fly(prof, 0, args.seed, "cc", True, args.scenario)
    rows: list[dict[str, Any]] = []
    print(f"scenario {args.scenario}, {args.missions} missions, seed {args.seed}\n")
    print("| profile | controller | steps | fronts/step | step median CPU ms (paper) "
          "| with forecast | ratio of medians | ratio of totals | forecast median CPU ms "
          "| run-aheads reused |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for prof in args.profiles.split(","):
        for c in args.controllers.split(","):
            plain: list[float] = []
            withf: list[float] = []
            ftimes: list[float] = []
            risky: list[float] = []
            fronts = reused = fresh = 0
            for i in range(args.missions):
                a, _, n_f, _ = fly(prof, i, args.seed, c, False, args.scenario)
                b, f, _, (r, n) = fly(prof, i, args.seed, c, True, args.scenario)
                assert len(a) == len(b), "the forecast changed the mission"
                plain += a
                withf += b
                ftimes += f
                fronts += n_f
                reused, fresh = reused + r, fresh + n
                if args.risk:
                    risky += fly(prof, i, args.seed, c + "+risk", False, args.scenario)[0]
            row = {"profile": prof, "scenario": args.scenario, "controller": c,
                   "steps": len(plain),
                   "fronts_per_step": fronts / len(plain),
                   "step_ms_median": 1e3 * float(np.median(plain)),
                   "step_ms_median_with_forecast": 1e3 * float(np.median(withf)),
                   "ratio_of_medians": float(np.median(withf) / np.median(plain)),
                   "ratio_of_totals": float(np.sum(withf) / np.sum(plain)),
                   "forecast_ms_median": 1e3 * float(np.median(ftimes)),
                   "forecast_ms_mean": 1e3 * float(np.mean(ftimes)),
                   "run_aheads_reused": reused, "run_aheads_fresh": fresh}
            if risky:
                row["risk_step_ms_median"] = 1e3 * float(np.median(risky))
                row["risk_ratio_of_totals"] = float(np.sum(risky) / np.sum(plain))
            rows.append(row)
            print(f"| {prof} | {c} | {row['steps']} | {row['fronts_per_step']:.2f} | "
                  f"{row['step_ms_median']:.2f} | {row['step_ms_median_with_forecast']:.2f} | "
                  f"{row['ratio_of_medians']:.3f} | {row['ratio_of_totals']:.3f} | "
                  f"{row['forecast_ms_median']:.3f} | "
                  f"{'' if not reused + fresh else f'{reused / (reused + fresh):.0%}'} |"
                  + (f" +risk: {row['risk_step_ms_median']:.2f} ms, total "
                     f"{row['risk_ratio_of_totals']:.2f}x" if risky else ""), flush=True)
    args.json.parent.mkdir(parents=True, exist_ok=True)
    args.json.write_text(json.dumps({"missions": args.missions, "seed": args.seed,
                                     "scenario": args.scenario, "rows": rows}, indent=1) + "\n")


if __name__ == "__main__":
    main()
