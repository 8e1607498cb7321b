"""The example plug-in (examples/dualpilot-example), installed by make setup, flies in-process.

Its System 1 method "straight" and its supervisor "proximity" are found by name through
the entry points of its package; the straight line's first controls are worked out by hand
from Eq. (1); the proximity rule is checked on every step of a mission; and both fly in
``dualpilot mission`` and in ``dualpilot evaluate`` with the oracle's columns, as the
in-process mission flies them.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from dualpilot.cli import main
from dualpilot.evaluation.missions import Task
from dualpilot.extensions import origin
from dualpilot.mission.config import MissionConfig, controller_names, parse_controller
from dualpilot.mission.local import local_mission
from dualpilot.mission.params import Controller
from dualpilot.mission.records import read_steps_csv
from dualpilot.mission.result import Ending
from dualpilot.model.dynamics import hover_state
from dualpilot.model.geometry import Rect, path_clearance
from dualpilot.plan import PlanStatus
from dualpilot.planners import REGISTRY, build_planner, method_names
from dualpilot.spec import MissionSpec
from dualpilot.supervisor.registry import supervisor_entry

SPEC = MissionSpec(start=(100.0, 100.0), goal=Rect(900.0, 900.0, 100.0, 100.0))


def test_the_example_is_found_by_name() -> None:
    assert "straight" in method_names(1), "the example package is not installed: make setup"
    assert origin(REGISTRY.points()["straight"]).startswith("package dualpilot-example ")
    assert supervisor_entry("proximity").system1_method == "straight"
    assert {"proximity", "proximity+risk"} <= set(controller_names())
    assert parse_controller("proximity") == (Controller.CC, "proximity", False)
    config = MissionConfig.named("proximity")
    assert config.methods() == {1: "straight", 2: "fast"}
    with pytest.raises(ValueError, match="proximity supervisor does not run s1"):
        MissionConfig(controller=Controller.S1, supervisor="proximity")
    with pytest.raises(ValueError, match="'straight' has no risk-aware variant"):
        build_planner(1, SPEC, "straight", risk=True)


def test_the_straight_line_by_hand() -> None:
    """From rest at (100, 100) towards G's centre (900, 900), no fire, ΔT = 1 s, ζ = 0.2,
    m = 1.05 kg, |u_i| ≤ 7.5 N, v_max = 15 m/s: v* = 15/√2 (1, 1) = 10.6066 (1, 1) m/s.
    Step 0: m v*/ΔT = 11.137 N per axis, scaled to 7.5 N; v_1 = 7.5/1.05 = 7.142857 m/s.
    Step 1: 1.05 (10.6066 − 0.8·7.142857) = 5.13693 N reaches v_2 = v*. Then the drag alone:
    u = 1.05·0.2·10.6066 = 2.22739 N."""
    plan = build_planner(1, SPEC, "straight").plan(hover_state(np.array([100.0, 100.0])), ())
    assert plan.ok and len(plan.controls) == 10 and plan.info["planner"] == "straight"
    v_star = 15.0 / math.sqrt(2.0)
    assert plan.controls[0] == pytest.approx([7.5, 7.5])
    assert plan.controls[1] == pytest.approx([1.05 * (v_star - 0.8 * 7.5 / 1.05)] * 2)
    assert plan.controls[1][0] == pytest.approx(5.13693, abs=1e-5)
    assert plan.controls[2:] == pytest.approx(np.full((8, 2), 1.05 * 0.2 * v_star))
    assert plan.states[1, 2:] == pytest.approx([7.5 / 1.05] * 2)
    assert plan.states[2:, 2:] == pytest.approx(np.full((9, 2), v_star))
    # p_{k+1} = p_k + ΔT v_k: (100, 100), (100, 100), (107.142857, 107.142857), + v* after
    assert plan.states[:3, 0] == pytest.approx([100.0, 100.0, 100.0 + 7.5 / 1.05])
    assert plan.states[3, 0] == pytest.approx(100.0 + 7.5 / 1.05 + v_star)


def test_the_straight_line_brakes_before_a_fire_and_refuses_to_start_inside_one() -> None:
    fire = Rect(200.0, 200.0, 40.0, 40.0).polytope()  # across the line, 100 m ahead
    x0 = hover_state(np.array([100.0, 100.0]))
    free = build_planner(1, SPEC, "straight").plan(x0, ())
    assert path_clearance(free.states[:, :2], (fire,)) < SPEC.clearance_m  # it would hit it
    plan = build_planner(1, SPEC, "straight").plan(x0, (fire,))
    assert plan.ok
    assert path_clearance(plan.states[:, :2], (fire,)) >= SPEC.clearance_m
    assert np.linalg.norm(plan.states[-1, 2:]) < 1e-6  # at rest in front of it
    assert np.linalg.norm(plan.states[-1, :2] - [100.0, 100.0]) > 10.0  # having come closer
    inside = hover_state(np.array([165.0, 165.0]))  # 7 m from its corner: within ε
    assert build_planner(1, SPEC, "straight").plan(inside, (fire,)).status is PlanStatus.UNSAFE


def test_the_proximity_rule_on_every_step_of_a_mission() -> None:
    result = local_mission(MissionConfig.named("proximity", seed=3)).run()
    assert len(result.records) > 20
    for rec in result.records:
        wanted = 2 if rec.d_t < 150.0 else 1
        assert rec.decision.system == wanted, (rec.t, rec.d_t)
        assert rec.answers[0].system == wanted  # the chosen system is asked first
    assert {rec.decision.system for rec in result.records} == {1, 2}
    assert any(rec.system == 1 and rec.answers[0].system == 1 for rec in result.records)


def _mission_cli(tmp_path: Path, *flags: str) -> tuple[dict[str, object], dict[str, np.ndarray]]:
    out = tmp_path / "run"
    assert main(["mission", *flags, "--out", str(out), "--no-figures", "--quiet"]) == 0
    return json.loads((out / "summary.json").read_text()), read_steps_csv(out / "steps.csv")


@pytest.mark.parametrize(("flags", "config"), [
    (("--controller", "proximity", "--seed", "3"), MissionConfig.named("proximity", seed=3)),
    (("--controller", "cc", "--s1-method", "straight", "--seed", "2"),
     MissionConfig.named("cc", seed=2, system1_method="straight")),
])
def test_dualpilot_mission_flies_the_plugins(tmp_path: Path, flags: tuple[str, ...],
                                            config: MissionConfig) -> None:
    summary, steps = _mission_cli(tmp_path, *flags)
    twin = local_mission(config).run()
    assert (summary["success"], summary["steps"], Ending.read(summary)) == (
        twin.success, twin.steps, twin.ending)
    assert summary["energy"] == pytest.approx(twin.energy)
    assert list(steps["system"]) == [float(r.system) for r in twin.records]
    assert 1.0 in steps["system"]  # the straight line flew


@pytest.mark.slow  # the oracle's search: about a minute
def test_dualpilot_evaluate_flies_the_plugins_against_the_oracle(tmp_path: Path) -> None:
    out = tmp_path / "ext"
    assert main(["evaluate", "--missions", "2", "--seed", "0", "--jobs", "1",
                 "--controllers", "proximity,oracle", "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    ys = summary["yardstick"]
    assert list(ys["controllers"]) == ["proximity", "oracle"]
    assert ys["controllers"]["proximity"]["n"] == 2
    assert ys["controllers"]["proximity"]["successes"] <= ys["achievable"]
    assert (out / "yardstick.md").read_text().count("| proximity |") == 1
    rows = (out / "results.csv").read_text().splitlines()
    assert sum(",proximity,paper," in r for r in rows) == 2 and sum(",oracle," in r for r in rows)
    for index in (0, 1):  # each row is the in-process mission's
        twin = local_mission(Task.of(index, 0, "proximity").mission()).run()
        row = next(r for r in rows if r.startswith(f"{index},") and ",proximity," in r)
        assert f",proximity,paper,{int(twin.success)},{twin.failure_cause},{twin.steps}," in row


def test_dualpilot_evaluate_flies_a_builtin_supervisor_with_the_plugins_system1(
        tmp_path: Path) -> None:
    out = tmp_path / "cc"
    assert main(["evaluate", "--missions", "2", "--first-mission", "1", "--seed", "0",
                 "--jobs", "1", "--controllers", "cc", "--s1-method", "straight",
                 "--out", str(out)]) == 0
    rows = (out / "results.csv").read_text().splitlines()
    header = rows[0].split(",")
    for index in (1, 2):
        row = dict(zip(header, next(r for r in rows if r.startswith(f"{index},")).split(","),
                       strict=True))
        twin = local_mission(Task.of(index, 0, "cc", MissionConfig(
            system1_method="straight")).mission()).run()
        assert (row["controller"], row["error"]) == ("cc", "")
        assert (int(row["success"]), int(row["steps"])) == (int(twin.success), twin.steps)
        assert int(row["s1_plans"]) == len(twin.planning_time_s["s1"]) > 0  # it flew
