"""Failure anatomy: why a controller failed a mission the oracle shows was achievable.

Each avoidable failure of an evaluation (:mod:`dualpilot.evaluation.yardstick`) is
flown again in-process (a seed reproduces a mission exactly) and its last step
read from the records: which front ended it (the regions within d_safe of the idle
UAV, or of its last flown segment, in the fires as they were when it ended), when
that front was born, how long the step's planning took and what was flown. The
class is the first that applies (:data:`CLASSES`):

``out_of_steps``
    the step limit came first;
``deliberating``
    caught while the fires ran more than one planning sub-step (waiting for a slow plan);
``ignition``
    the front that ended it could not be escaped once it was known: either it was born
    after the last control that could have moved the UAV elsewhere was committed (a
    flight p_t → p_{t+1} = p_t + ΔT·v_t is fixed by u_{t−1}, committed at step t − 1
    before that step's sub-steps, and the idle position p_t during step t's sub-steps by
    u_{t−2}: a front born during step t − 1 (fire contact) or t − 2 (caught while
    planning) or later; ``proof`` "committed"), or the oracle's certificate
    (:class:`dualpilot.oracle.certificate.ReachableSet`) run from the UAV's state at the
    first step the front was in its snapshot, on the fires' own future, finds no position
    that survives the next ``ESCAPE_SUBSTEPS`` sub-steps (``proof`` "no escape": no
    controller, however it flew from then on, would have); ``where``: within d_safe of the
    idle UAV, or only of its path;
``refused``
    the failing step flew no plan because the run-time monitor refused one;
``no_plan``
    the failing step flew no plan: no system had a safe one (boxed in);
``known_front``
    a front the step's planner saw when it planned came within d_safe of where the UAV
    went: its motion or growth overtook the plan.
"""

from __future__ import annotations

import csv
import json
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from dualpilot.mission.answers import MONITOR_TAG
from dualpilot.mission.config import MissionConfig
from dualpilot.mission.result import Ending, MissionResult
from dualpilot.mission.step import segment_region_distance
from dualpilot.model.fire import FireSnapshot, Region

CLASSES = ("out_of_steps", "deliberating", "ignition", "refused", "no_plan", "known_front",
           "other")
DESCRIPTIONS = {
    "out_of_steps": "the step limit came first",
    "deliberating": "overtaken while the fires ran more than one sub-step for its plan",
    "ignition": "a front born where it could not be escaped once it was known",
    "refused": "no plan flown: the run-time monitor refused the plan",
    "no_plan": "no plan flown: no system had a safe plan (boxed in)",
    "known_front": "a front its planner saw came within d_safe of where it flew",
    "other": "none of the above",
}


@dataclass(frozen=True)
class Failure:
    """One failure's class and its evidence (front id −1: none found within d_safe)."""

    cls: str
    ending: str
    step: int
    front_id: int
    born_step: int
    where: str
    substeps: int
    system: int
    proof: str = ""

    def row(self) -> dict[str, Any]:
        return {"class": self.cls, "ending": self.ending, "step": self.step,
                "front_id": self.front_id, "born_step": self.born_step, "where": self.where,
                "substeps": self.substeps, "system": self.system, "proof": self.proof}


def replay(config: MissionConfig) -> tuple[MissionResult, FireSnapshot]:
    """The mission of ``config`` flown in-process, and its fires when it ended."""
    from dualpilot.mission.local import local_mission

    mission = local_mission(config)
    result = mission.run()
    return result, mission.fires.snapshot()


def culprit(result: MissionResult, final: FireSnapshot, d_safe_m: float) -> tuple[int, int, str]:
    """(front id, born step, where) of the front that ended the mission: the nearest region
    within d_safe of the idle UAV ("idle"), else of its last segment ("path"); (−1, −1, "")
    when none is (it has moved off again). In 3-D the distances are to the cuboids."""
    last = result.records[-1]
    dim = result.spec.dim
    idle = last.state[:dim]
    end = result.final_state[:dim] if result.final_state is not None else idle
    regions: tuple[Region, ...] = final.regions
    if dim == 3:  # the cuboids' 3-D distances (a snapshot without tops: above the ceiling)
        regions = final.with_tops(result.spec.above_ceiling_m).cuboids()
    best: tuple[float, int, int, str] | None = None
    for region, fid, born in zip(regions, final.front_ids, final.born_steps, strict=True):
        d_idle = region.distance(idle)
        d_path = segment_region_distance(idle, end, (region,))
        if d_idle < d_safe_m and (best is None or d_idle < best[0]):
            best = (d_idle, fid, born, "idle")
        elif d_path < d_safe_m and (best is None or best[3] != "idle" and d_path < best[0]):
            best = (d_path, fid, born, "path")
    return (-1, -1, "") if best is None else best[1:]


def classify(result: MissionResult, final: FireSnapshot,
             config: MissionConfig | None = None) -> Failure:
    """The class of a failed mission (module docstring); with its ``config``, the certificate
    from the first sight of the front that ended it is tried too."""
    last = result.records[-1]
    ending = result.ending or Ending.ERROR
    fid, born, where = culprit(result, final, result.spec.d_safe_m)
    planning = last.fire_substeps

    def failure(cls: str, proof: str = "") -> Failure:
        return Failure(cls, ending.value, last.t, fid, born, where, planning, last.system, proof)

    if ending is Ending.STEP_LIMIT:
        return failure("out_of_steps")
    if ending is Ending.FIRE_WHILE_PLANNING and planning > 1:
        return failure("deliberating")
    latency = 2 if ending is Ending.FIRE_WHILE_PLANNING else 1  # steps the UAV is committed
    if fid >= 0 and born >= last.t - latency:
        return failure("ignition", "committed")
    if fid >= 0 and config is not None and no_escape(result, config, fid):
        return failure("ignition", "no escape")
    if last.system == 0:
        refused = any(MONITOR_TAG in a.note for a in last.answers)
        return failure("refused" if refused else "no_plan")
    if fid >= 0:
        return failure("known_front")
    return failure("other")


#: sub-steps after the first sight of a front within which no position may survive for its
#: failure to be unavoidable ("no escape")
ESCAPE_SUBSTEPS = 20


def no_escape(result: MissionResult, config: MissionConfig, front_id: int) -> bool:
    """Whether no position survives :data:`ESCAPE_SUBSTEPS` sub-steps from the UAV's state at
    the first step ``front_id`` was in its snapshot, on the mission's fire future (the oracle's
    certificate from a moving state). Only where that future is the flight's own: fires free
    of the step length, or a flight whose steps each took one planning sub-step. In 3-D the
    planar certificate of the mission's planar twin where every front is taller than a UAV
    flies (:mod:`dualpilot.oracle.reduction`), else the certificate's columns
    (:mod:`dualpilot.oracle.columns`)."""
    from dualpilot.model.altitude import planar_state
    from dualpilot.oracle.certificate import ReachableSet
    from dualpilot.oracle.columns import ReachableColumns
    from dualpilot.oracle.future import FireFuture
    from dualpilot.oracle.reduction import not_reduced, planar_twin

    over_band = config.spec().dim == 3 and bool(not_reduced(config))
    planar = config if over_band else planar_twin(config)  # reduced: the planar distances
    future = FireFuture(planar)
    seen = next((k for k, r in enumerate(result.records) if front_id in r.snapshot.front_ids),
                None)
    if seen is None:
        return False
    before = result.records[:seen]
    motion = config.reading().mission.fire_substeps_per_motion
    if not future.schedule_free and any(r.fire_substeps != 1 for r in result.records):
        return False
    substep0 = sum(r.fire_substeps + motion for r in before)
    state = result.records[seen].state
    if over_band:
        reach: ReachableSet | ReachableColumns = ReachableColumns(config, future, state=state,
                                                                  substep0=substep0)
    else:
        reach = ReachableSet(planar, future, state=planar_state(state) if len(state) == 6
                             else state, substep0=substep0)
    got = reach.run(ESCAPE_SUBSTEPS)
    return got is not None and got.verdict == "impossible" and got.reason.startswith("no position")


# -- over an evaluation's run directory ----------------------------------------------------------
@dataclass(frozen=True)
class Case:
    """One avoidable failure to look at: configuration ``index`` of ``seed`` flown by a
    controller with the run's base configuration."""

    index: int
    seed: int
    controller: str
    base: MissionConfig

    def config(self) -> MissionConfig:
        from dualpilot.evaluation.missions import Task

        return Task.of(self.index, self.seed, self.controller, self.base).mission()


def examine(case: Case) -> dict[str, Any]:
    """The anatomy row of one case (for Dask: never raises)."""
    row: dict[str, Any] = {"mission": case.index, "controller": case.controller}
    try:
        config = case.config()
        result, final = replay(config)
        row["seed"] = config.seed
        if result.success:
            row["class"] = "not a failure"
        else:
            row.update(classify(result, final, config).row())
    except Exception as err:  # noqa: BLE001 - recorded, the others go on
        row["class"] = f"error: {type(err).__name__}: {err}"
    return row


def cases(run_dir: Path, controllers: Sequence[str] | None = None) -> list[Case]:
    """The avoidable failures of an evaluation run with the oracle (its run.json and
    results.csv), of ``controllers`` (None: every controller but the oracle)."""
    from dualpilot.evaluation.missions import ORACLE
    from dualpilot.evaluation.results import read_results
    from dualpilot.evaluation.yardstick import Verdicts

    meta = json.loads((run_dir / "run.json").read_text())
    rows = read_results(run_dir / "results.csv")
    if not rows:
        raise ValueError(f"{run_dir} has no results")
    from dualpilot.evaluation.missions import Task, base_of

    base = base_of(meta, rows[0]["timing"])
    verdicts = Verdicts(rows, Task.of(0, meta["seed"], "s1", base).config)
    wanted = set(controllers) if controllers else {r["controller"] for r in rows} - {ORACLE}
    out = []
    for r in rows:
        if (r["controller"] in wanted and r["success"] != "1"
                and verdicts.kind_of_failure(r) == "avoidable"):
            out.append(Case(int(r["mission"]), meta["seed"], r["controller"], base))
    return sorted(out, key=lambda c: (c.controller, c.index))


def anatomy(run_dir: Path, controllers: Sequence[str] | None = None,
            jobs: int = 1) -> list[dict[str, Any]]:
    """Every avoidable failure of ``run_dir`` examined (on Dask with ``jobs`` > 1), written to
    ``anatomy.csv`` there; the rows."""
    from dualpilot.evaluation.runner import execute

    todo = cases(run_dir, controllers)
    rows = sorted(execute(todo, jobs, fn=examine),
                  key=lambda r: (str(r["controller"]), int(str(r["mission"]))))
    columns = ["mission", "seed", "controller", "class", "proof", "ending", "step", "front_id",
               "born_step", "where", "substeps", "system"]
    with (run_dir / "anatomy.csv").open("w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=columns, extrasaction="ignore")
        writer.writeheader()
        writer.writerows(rows)
    return rows


def counts(rows: Sequence[dict[str, Any]]) -> dict[str, dict[str, int]]:
    """Controller → class → number of avoidable failures."""
    out: dict[str, dict[str, int]] = {}
    for r in rows:
        per = out.setdefault(str(r["controller"]), {})
        per[str(r["class"])] = per.get(str(r["class"]), 0) + 1
    return out
