"""The yardstick's arithmetic on rows made by hand: achievable missions, % of achievable with its
interval, failures by kind, and the contradiction it refuses."""

from __future__ import annotations

import pytest

from dualpilot.evaluation.stats import wilson_interval
from dualpilot.evaluation.yardstick import ContradictionError, markdown, yardstick
from dualpilot.mission.config import MissionConfig

TODAY = MissionConfig.named("s1")
FIG_R5 = MissionConfig.named("s1", profile="fig-r5")


def row(mission: int, controller: str, success: bool, cause: str = "", substeps: int = 60,
        steps: int = 60, time_s: float = 60.0, energy: float = 100.0) -> dict[str, str]:
    return {"mission": str(mission), "controller": controller, "success": "1" if success else "0",
            "failure_cause": "" if success else cause, "fire_substeps": str(substeps),
            "steps": str(steps), "mission_time_s": str(time_s), "energy": str(energy)}


def oracle(verdicts: list[str]) -> list[dict[str, str]]:
    return [row(i, "oracle", v == "feasible", v) for i, v in enumerate(verdicts)]


VERDICTS = ["feasible", "feasible", "impossible", "unknown", "unknown", "feasible"]


def test_a_controller_against_the_oracle_by_hand() -> None:
    """Achievable: the witnesses 0, 1, 5 and mission 3, which the controller completed; 2 is
    impossible for every controller (today's fires do not depend on the step length), 4 is
    undetermined. Three successes of four achievable: 75 %, the interval from 3 of 5 (4 is
    counted achievable) to 3 of 4."""
    rows = oracle(VERDICTS) + [
        row(0, "s1", True, time_s=50.0, energy=80.0), row(1, "s1", True, time_s=70.0,
                                                          energy=120.0),
        row(2, "s1", False, "fire_contact"), row(3, "s1", True, time_s=60.0, energy=100.0),
        row(4, "s1", False, "step_limit", substeps=150, steps=150),
        row(5, "s1", False, "fire_while_planning")]
    ys = yardstick(rows, TODAY)
    assert ys["achievable"] == 4
    assert ys["oracle"] == {"feasible": 3, "impossible": 1, "unknown": 2}
    s1 = ys["controllers"]["s1"]
    assert s1["successes"] == 3 and s1["achievable"] == 4
    assert s1["of_achievable"] == pytest.approx(0.75)
    assert s1["of_achievable_ci95"] == pytest.approx([wilson_interval(3, 5)[0],
                                                      wilson_interval(3, 4)[1]])
    assert s1["failures"] == {"avoidable": 1, "unavoidable": 1, "undetermined": 1}
    assert s1["mission_time_s_mean"] == pytest.approx(60.0)
    assert s1["energy_mean"] == pytest.approx(100.0)
    assert list(ys["controllers"]) == ["s1", "oracle"]
    assert "| s1 | 50.0 % | 75.0 (" in markdown(ys)


def test_a_completed_mission_called_impossible_is_refused() -> None:
    rows = oracle(VERDICTS) + [row(2, "s2", True, substeps=500, steps=50)]
    with pytest.raises(ContradictionError, match=r"\(2, 's2'\)"):
        yardstick(rows, TODAY)


def test_fires_tied_to_the_step_length_speak_only_for_one_substep_steps() -> None:
    """fig-r5 draws births once a step: the certificate speaks for steps of one sub-step. A
    completion at ten sub-steps a step is another fire and no contradiction: the mission is
    achievable; a failure at one sub-step a step on it is then avoidable (another controller
    made it), and no mission is impossible for every controller."""
    rows = oracle(VERDICTS) + [row(2, "s2", True, substeps=500, steps=50),
                               row(2, "s1", False, "fire_contact", substeps=40, steps=40)]
    ys = yardstick(rows, FIG_R5)
    assert ys["achievable"] == 4
    assert ys["controllers"]["s1"]["failures"] == {"avoidable": 1, "unavoidable": 0,
                                                    "undetermined": 0}
    one_pace = oracle(VERDICTS) + [row(2, "s1", True, substeps=40, steps=40)]
    with pytest.raises(ContradictionError):
        yardstick(one_pace, FIG_R5)


def test_an_evaluation_and_a_sweep_with_the_oracle_carry_the_yardstick(tmp_path: object) -> None:
    """Two missions, in this process: evaluate writes yardstick.md and the summary's yardstick;
    a sweep has one per grid point; every completed mission is achievable."""
    from pathlib import Path

    from dualpilot.evaluation.evaluate import evaluate
    from dualpilot.evaluation.sweep import grid_points, sweep

    out = Path(str(tmp_path))
    summary = evaluate(2, out / "eval", jobs=1, controllers=("s1", "oracle"), progress=False)
    ys = summary["yardstick"]
    assert isinstance(ys, dict) and ys["missions"] == 2
    assert ys["controllers"]["s1"]["successes"] <= ys["achievable"]
    assert (out / "eval" / "yardstick.md").read_text().count("| s1 |") == 1
    swept = sweep(grid_points({}), 2, out / "sweep", jobs=1, controllers=("s1", "oracle"),
                  progress=False)
    assert swept["points"][0]["yardstick"]["controllers"]["oracle"]["n"] == 2


def test_one_anatomy_figure_per_class_the_first_controller_first() -> None:
    from dualpilot.evaluation.anatomy import Case
    from dualpilot.viz.anatomy import figure_cases

    def case(controller: str, index: int) -> Case:
        return Case(index, 0, controller, MissionConfig())

    todo = [case("cc", 1), case("cc", 4), case("lookahead+risk", 7), case("s2", 2)]
    rows = [{"class": "deliberating"}, {"class": "ignition"}, {"class": "ignition"},
            {"class": "error: boom"}]
    got = figure_cases(todo, rows, ["lookahead+risk", "cc", "s2"])
    # ignition from the first controller (mission 7, not cc's 4), deliberating from cc;
    # an error row is no class; classes in CLASSES' order
    assert [(c.controller, c.index, cls) for c, cls in got] == [
        ("cc", 1, "deliberating"), ("lookahead+risk", 7, "ignition")]
