"""A mission's end, typed in its records: ``"ending"`` (a value of :class:`Ending`) beside
``"success"``, no cause at the goal; records of the older form (``"failure_cause"``, ``""`` at
the goal; tests/unit/dualpilot/mission/data/old_records/, written before the end was typed)
still read."""

from __future__ import annotations

import json
import shutil
from pathlib import Path
from typing import Any

import pytest

from dualpilot.mission.config import MissionConfig
from dualpilot.mission.local import local_mission
from dualpilot.mission.records import StepLog, read_step_log, result_from_log, write_all
from dualpilot.mission.result import Ending, MissionResult
from dualpilot.model.geometry import Rect
from dualpilot.viz.mission import load_run, make_figures

OLD = Path(__file__).parent / "data" / "old_records"
#: the missions of the old records (their README): a goal 150 m from the start
NEAR_GOAL = Rect(200.0, 200.0, 100.0, 100.0)


def _json(path: Path) -> dict[str, Any]:
    doc: dict[str, Any] = json.loads(path.read_text())
    return doc


def flown(controller: str, out: Path) -> MissionResult:
    """The mission of an old record (seed 3, the near goal, paper timing), flown and written."""
    result = local_mission(MissionConfig.named(controller, seed=3, goal=NEAR_GOAL)).run()
    write_all(result, out)
    return result


# -- the form ---------------------------------------------------------------------------------
def test_the_records_write_the_ending_and_no_cause_at_the_goal() -> None:
    assert Ending.fields(Ending.GOAL) == {"success": True, "ending": "goal"}
    assert Ending.fields(Ending.FIRE_CONTACT) == {"success": False, "ending": "fire_contact"}
    assert Ending.fields(Ending.STEP_LIMIT) == {"success": False, "ending": "step_limit"}
    assert Ending.fields(None) == {"success": False, "ending": None}  # it did not end
    for ending in (*Ending, None):
        assert Ending.read(Ending.fields(ending)) is ending


def test_a_successful_mission_s_summary_has_no_cause(tmp_path: Path) -> None:
    result = flown("s1", tmp_path)
    summary, trace = _json(tmp_path / "summary.json"), _json(tmp_path / "trace.json")
    assert result.ending is Ending.GOAL and result.steps == 15
    for doc in (summary, trace):
        assert doc["ending"] == "goal" and doc["success"] is True, doc.keys()
        assert "failure_cause" not in doc
    assert list(summary)[:6] == ["controller", "seed", "timing", "success", "ending", "steps"]


def test_the_summary_names_the_controller_as_evaluate_does() -> None:
    # "controller" says which systems fly (the lookahead supervisor flies both: cc);
    # "controller_name" the name the mission was asked with
    config = MissionConfig.named("lookahead+risk", seed=7, settings=(("max_steps", 2),))
    summary = local_mission(config).run().summary()
    assert (summary["controller"], summary["controller_name"]) == ("cc", "lookahead+risk")
    old = MissionResult(controller="s1", timing="paper", spec=config.spec())
    assert old.summary()["controller_name"] == "s1"  # a record that does not say


def test_a_failed_mission_s_summary_has_its_cause(tmp_path: Path) -> None:
    result = flown("s2", tmp_path)
    summary, trace = _json(tmp_path / "summary.json"), _json(tmp_path / "trace.json")
    assert result.ending is Ending.FIRE_WHILE_PLANNING and result.steps == 3
    for doc in (summary, trace):
        assert doc["ending"] == "fire_while_planning" and doc["success"] is False
        assert "failure_cause" not in doc
        assert Ending.read(doc) is Ending.FIRE_WHILE_PLANNING


def test_a_step_limit_is_an_ending_of_its_own(tmp_path: Path) -> None:
    config = MissionConfig.named("s1", seed=3, goal=NEAR_GOAL, settings=(("max_steps", 4),))
    result = local_mission(config).run()
    write_all(result, tmp_path)
    assert _json(tmp_path / "summary.json")["ending"] == "step_limit" and result.steps == 4


# -- reading: both forms ---------------------------------------------------------------------
def test_old_records_read_as_they_were_meant() -> None:
    goal, fire = _json(OLD / "goal" / "summary.json"), _json(OLD / "fire" / "summary.json")
    assert (goal["success"], goal["failure_cause"]) == (True, "")  # the older form
    assert (fire["success"], fire["failure_cause"]) == (False, "fire_while_planning")
    assert Ending.read(goal) is Ending.GOAL
    assert Ending.read(fire) is Ending.FIRE_WHILE_PLANNING
    assert Ending.read(_json(OLD / "goal" / "trace.json")) is Ending.GOAL
    assert Ending.read(_json(OLD / "fire" / "trace.json")) is Ending.FIRE_WHILE_PLANNING


def test_every_form_of_no_ending_and_a_bad_one() -> None:
    assert Ending.read({"ending": None, "success": False}) is None
    assert Ending.read({"success": False, "failure_cause": ""}) is None  # old, did not end
    assert Ending.read({"success": False}) is None
    assert Ending.read({"ending": "step_limit"}) is Ending.STEP_LIMIT
    with pytest.raises(ValueError, match="'landed' is not a valid Ending"):
        Ending.read({"ending": "landed"})
    with pytest.raises(ValueError, match="'landed' is not a valid Ending"):
        Ending.read({"success": False, "failure_cause": "landed"})
    with pytest.raises(ValueError, match="says nothing of how the mission ended"):
        Ending.read({"steps": 3})


def test_the_figures_read_old_and_new_runs_alike(tmp_path: Path) -> None:
    """``dualpilot figures``' reader: the same title from a run of either form."""
    for name, controller, title in (
            ("goal", "s1", "S1 mission, seed 3: reached G after 15 steps"),
            ("fire", "s2", "S2 mission, seed 3: fire while planning after 3 steps")):
        old = tmp_path / f"old-{name}"
        shutil.copytree(OLD / name, old)
        flown(controller, tmp_path / f"new-{name}")
        for run_dir in (old, tmp_path / f"new-{name}"):
            run = load_run(run_dir)
            assert run.title() == title, run_dir
        assert load_run(old).ending is load_run(tmp_path / f"new-{name}").ending
    # without summary.json the trace says it, in either form
    (tmp_path / "old-goal" / "summary.json").unlink()
    assert load_run(tmp_path / "old-goal").ending is Ending.GOAL


@pytest.mark.slow
def test_figures_draw_from_an_old_run(tmp_path: Path) -> None:
    run = tmp_path / "old"
    shutil.copytree(OLD / "fire", run)
    pngs = make_figures(run)
    assert pngs and all(p.is_file() and p.stat().st_size > 1000 for p in pngs)


def test_a_record_s_end_line_reads_in_either_form(tmp_path: Path) -> None:
    """steps.jsonl's ``end`` line: the older ``failure_cause`` (the stack's supervisor writes
    it) and the typed ``ending`` rebuild the same result."""
    mission = local_mission(MissionConfig.named("s2", seed=3, goal=NEAR_GOAL))
    spec = mission.spec
    head = {"controller": "s2", "seed": 3, "timing": "paper", "start": list(spec.start),
            "goal": [NEAR_GOAL.center_x, NEAR_GOAL.center_y, NEAR_GOAL.width,
                     NEAR_GOAL.height], "area_size_m": spec.area_size_m}
    records = []
    while (rec := mission.step()) is not None:
        records.append(rec)
    r = mission.result
    assert r is not None and r.ending is Ending.FIRE_WHILE_PLANNING
    rebuilt = []
    for form, end in (("old", {"success": False, "failure_cause": r.failure_cause}),
                      ("typed", Ending.fields(r.ending))):
        with StepLog(tmp_path / f"{form}.jsonl") as log:
            log.write("mission", **head)
            for rec in records:
                log.step(rec)
            log.write("end", **end, final_state=r.final_state)
        rebuilt.append(result_from_log(read_step_log(tmp_path / f"{form}.jsonl")))
    for back in rebuilt:
        assert back.ending is Ending.FIRE_WHILE_PLANNING and back.steps == r.steps
    assert rebuilt[0].energy == pytest.approx(rebuilt[1].energy)
