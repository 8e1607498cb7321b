"""Skill of the occupancy forecast on held-out missions: Brier score vs persistence, reliability.

Flies ``--missions`` missions of each ``--runs`` entry PROFILE:CONTROLLER in
this process (configurations (S, i) of ``--seed`` S, which no test or tuning
run flew: they used seed 0) at paper timing, on ``--scenario``'s fire process.
At each step, once the supervisor has
chosen the system, the fire port's forecast is issued from the step's fire
state (dualpilot/model/forecast.py, or a scenario's level set run ahead,
dualpilot/model/physics_forecast.py; time-steps as the chosen system's); the
truth is the fire process itself, every sub-step, run on past the mission's end
until every forecast's horizon has passed. For each horizon h (5, 10, 30 s) and
every cell centre of the grid:

* Brier score B = mean (p − o)², p the forecast, o ∈ {0, 1} the truth at h;
* persistence: the fires stay as they are, p = o at the issue time;
* Brier skill score BSS = 1 − B / B_persistence (1: perfect; 0: no better);
* reliability: the observed frequency of o = 1 per bin of p.

Prints a markdown table, writes the numbers as JSON and the reliability diagram
(default ``docs/figures/forecast_reliability.png``; for a scenario
``docs/figures/forecast_reliability_<scenario>.png``).

    .venv/bin/python benchmarks/forecast_skill.py [--missions 50] [--seed 1000]
        [--runs today:cc,fig-r5:cc,fig-r5:s2] [--scenario paper|grass-15|shrub|...]
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from dualpilot.evaluation.missions import Task
from dualpilot.mission.config import MissionConfig
from dualpilot.mission.local import LocalFires, local_mission
from dualpilot.mission.result import Ending, StepRecord
from dualpilot.model.fire import Region
from dualpilot.model.forecast import LEVELS, OccupancyForecast, occupancy
from dualpilot.model.geometry import Rect
from dualpilot.model.scenarios import PAPER, scenario_names
from dualpilot.readings import get_profile
from dualpilot.supervisor.paper.decision import Decision

HORIZONS_S = (5.0, 10.0, 30.0)
#: reliability bins of the forecast probability: finer near 0, where most cells are
EDGES = np.array([0.0, 0.005, 0.02, 0.05, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9,
                  0.995, 1.0 + 1e-9])


class Recorder:
    """Forecasts at each step (the observer) and the truth after every sub-step (the fires)."""

    def __init__(self, fires: LocalFires, ks: tuple[int, ...]):
        self.fires = fires
        self.ks = ks
        self.mission: Any = None
        self.truth: dict[int, np.ndarray] = {}
        self.issued: list[tuple[int, np.ndarray, dict[int, np.ndarray]]] = []
        self.shape: tuple[int, int] = (0, 0)
        self.res = 0.0
        self._record()

    def _record(self) -> None:
        f = self.fires.field
        fc = self.fires.forecast_params
        self.res = fc.resolution_m
        n = int(np.ceil(f.area_size_m / fc.resolution_m - 1e-9))
        self.shape = (n, n)
        regions: list[Rect] = [fr.region for fr in f.fronts]
        self.truth[f.substeps_done] = occupancy(regions, self.res, self.shape)

    def advance(self, t: int, n: int, keep_out: Any) -> list[tuple[Region, ...]]:
        out: list[tuple[Region, ...]] = []
        for _ in range(n):
            out += LocalFires.advance(self.fires, t, 1, keep_out)
            self._record()
        return out

    # -- StepObserver --------------------------------------------------------------
    def decided(self, t: int, decision: Decision, commanded: int) -> None:
        n = self.mission.substeps_per_step(commanded)
        fc: OccupancyForecast | None = self.fires.forecast(n)
        assert fc is not None
        d = self.fires.field.substeps_done
        slices = {k: fc.level(fc.horizons.index(k)) for k in self.ks}  # uint8: P·255
        self.issued.append((d, self.truth[d], slices))

    def commanded(self, t: int, flown: int, info: dict[str, object]) -> None: ...

    def recorded(self, record: StepRecord, flown: bool) -> None: ...

    def ended(self, record: StepRecord, ending: Ending) -> None: ...


def fly(profile: str, index: int, seed: int, controller: str,
        ks: tuple[int, ...], scenario: str = PAPER) -> Recorder:
    # the forecast is scored, not flown: the controller's plain variant flies
    base = MissionConfig(profile=profile, settings=(("scenario", scenario),))
    config = replace(Task.of(index, seed, controller, base).mission(), risk=False)
    mission = local_mission(config)
    fires = mission.fires
    assert isinstance(fires, LocalFires)
    rec = Recorder(fires, ks)
    rec.mission = mission
    mission.observer = rec
    fires.advance = rec.advance  # type: ignore[method-assign]
    mission.run()
    # the fire process goes on after the mission: until the last forecast's horizon
    t = mission.result.steps
    clear = config.reading().mission.ignition_clearance_m
    keep = None if clear is None else (mission.state[:2].copy(), clear)
    n = max(1, mission.substeps_per_step(2 if controller == "s2" else 1))
    while fires.field.substeps_done < rec.issued[-1][0] + max(ks):
        rec.advance(t, n, keep)
        t += 1
    return rec


def score(recs: list[Recorder], ks: tuple[int, ...]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for k in ks:
        se_f = se_p = cells = 0.0
        per_mission: list[float] = []
        counts = np.zeros(len(EDGES) - 1)
        hits = np.zeros(len(EDGES) - 1)
        psum = np.zeros(len(EDGES) - 1)
        for rec in recs:
            mf = mp = 0.0
            for d, now, slices in rec.issued:
                truth = rec.truth[d + k].astype(float)
                p = slices[k] / LEVELS
                mf += float(((p - truth) ** 2).sum())
                mp += float(((now - truth) ** 2).sum())
                b = np.digitize(p.ravel(), EDGES) - 1
                counts += np.bincount(b, minlength=len(counts))
                hits += np.bincount(b, weights=truth.ravel(), minlength=len(counts))
                psum += np.bincount(b, weights=p.ravel(), minlength=len(counts))
            se_f += mf
            se_p += mp
            cells += len(rec.issued) * truth.size
            if mp > 0:
                per_mission.append(1.0 - mf / mp)
        bf, bp = se_f / cells, se_p / cells
        out[str(k)] = {
            "brier": bf, "brier_persistence": bp, "bss": 1.0 - bf / bp if bp else float("nan"),
            "bss_median_per_mission": float(np.median(per_mission)) if per_mission else None,
            "forecasts": sum(len(r.issued) for r in recs), "cells": cells,
            "bins": {"counts": counts.tolist(), "observed": (hits / np.maximum(counts, 1)).tolist(),
                     "mean_p": (psum / np.maximum(counts, 1)).tolist()},
        }
    return out


def plot(results: dict[str, dict[str, Any]], substep_s: float, path: Path,
         scenario: str = PAPER) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    profiles = list(results)
    fig, axes = plt.subplots(2, len(profiles), figsize=(5.4 * len(profiles), 8.2),
                             gridspec_kw={"height_ratios": [3, 1.4]}, squeeze=False)
    colors = {"5": "#1f77b4", "10": "#ff7f0e", "30": "#2ca02c"}
    for j, prof in enumerate(profiles):
        ax, hist = axes[0, j], axes[1, j]
        ax.plot([0, 1], [0, 1], color="0.6", lw=1, ls="--", label="perfect reliability")
        for key, r in results[prof].items():
            h = float(key) * substep_s
            b = r["bins"]
            counts = np.array(b["counts"])
            keep = counts >= 50
            c = colors.get(f"{h:g}")
            ax.plot(np.array(b["mean_p"])[keep], np.array(b["observed"])[keep], "o-", color=c,
                    label=f"{h:g} s: BSS {r['bss']:.2f} (Brier {r['brier']:.4f} vs "
                          f"persistence {r['brier_persistence']:.4f})")
            centres = 0.5 * (EDGES[:-1] + np.minimum(EDGES[1:], 1.0))
            hist.semilogy(centres, np.maximum(counts, 0.8), "o-", color=c, ms=3, label=f"{h:g} s")
        ax.set(xlim=(0, 1), ylim=(0, 1), xlabel="forecast probability",
               ylabel="observed frequency", title=prof)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7.5, loc="upper left")
        hist.set(xlim=(0, 1), xlabel="forecast probability", ylabel="cells (log)")
        hist.grid(alpha=0.3)
        hist.legend(fontsize=7.5)
    what = "" if scenario == PAPER else f" on {scenario} (level set run ahead)"
    fig.suptitle(f"Occupancy forecast{what}, held-out missions: reliability 5, 10 and 30 s "
                 "ahead (bins of ≥ 50 cells)", fontsize=10)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--missions", type=int, default=50, help="per run (default 50)")
    ap.add_argument("--seed", type=int, default=1000, help="configurations (S, i) of this S")
    ap.add_argument("--runs", default="today:cc,fig-r5:cc,fig-r5:s2",
                    help="PROFILE:CONTROLLER,... (controllers cc, s1, s2, concurrent)")
    ap.add_argument("--scenario", default=PAPER, choices=scenario_names(),
                    help="the fire process (default: the paper's rectangles)")
    ap.add_argument("--figure", type=Path, default=None,
                    help="default docs/figures/forecast_reliability[_SCENARIO].png")
    ap.add_argument("--json", type=Path, default=None,
                    help="default runs/forecast_skill[_SCENARIO].json")
    args = ap.parse_args()
    tail = "" if args.scenario == PAPER else f"_{args.scenario}"
    args.figure = args.figure or Path(f"docs/figures/forecast_reliability{tail}.png")
    args.json = args.json or Path(f"runs/forecast_skill{tail}.json")
    t0 = time.perf_counter()
    results: dict[str, dict[str, Any]] = {}
    substep_s = 0.5
    for run in args.runs.split(","):
        prof, _, controller = run.partition(":")
        substep_s = get_profile(prof).fire.substep_s
        ks = tuple(round(h / substep_s) for h in HORIZONS_S)
        recs = [fly(prof, i, args.seed, controller or "cc", ks, args.scenario)
                for i in range(args.missions)]
        results[f"{prof}, {controller or 'cc'}"] = score(recs, ks)
    print(f"{args.missions} missions a run, seed {args.seed}, scenario {args.scenario}, "
          f"paper timing; "
          f"{time.perf_counter() - t0:.0f} s\n")
    print("| profile, controller | horizon | forecasts | Brier forecast | Brier persistence | BSS "
          "| BSS median per mission |")
    print("|---|---|---|---|---|---|---|")
    for prof, res in results.items():
        for key, r in res.items():
            med = r["bss_median_per_mission"]
            print(f"| {prof} | {float(key) * substep_s:g} s | {r['forecasts']} | "
                  f"{r['brier']:.5f} | {r['brier_persistence']:.5f} | {r['bss']:.3f} | "
                  f"{'' if med is None else f'{med:.3f}'} |")
    args.json.parent.mkdir(parents=True, exist_ok=True)
    args.json.write_text(json.dumps({"missions": args.missions, "seed": args.seed,
                                     "scenario": args.scenario, "results": results},
                                    indent=1) + "\n")
    plot(results, substep_s, args.figure, args.scenario)
    print(f"\n{args.json}, {args.figure}")


if __name__ == "__main__":
    main()
