"""What a user gets with ``--set dim=3`` (dualpilot/mission/dimension.py, docs/three_d.md).

A controller flies a 3-D mission when its supervisor and the planning method of every
system it asks say they plan in 3-D; of the built-in parts System 1's methods, System 2's
"fast", "thorough", "exact" and "fast+exact" and every built-in supervisor do (so every
built-in controller name flies with its default methods); System 2's "certified" plans
3-D missions whose fronts are all taller than the ceiling less ε (the reading
``fire_height``), and a controller asking it on a mission whose fronts may be lower is
refused before its mission starts, by name, with every part that does not plan it and
that its 3-D planning is not built yet; an evaluation, a sweep and the stack refuse
before any mission. A method that says it plans
in 3-D (here System 1's rrt under the reduction, a real registry's entry point) flies,
and the refusals then name it among the controllers that fly.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

import dualpilot.planners as planners
from dualpilot.cli import main
from dualpilot.evaluation.evaluate import evaluate
from dualpilot.evaluation.sweep import Point, sweep
from dualpilot.extensions import Registry
from dualpilot.mission.config import MissionConfig, controller_names
from dualpilot.mission.dimension import check_dimension, flying_controllers, refusals
from dualpilot.mission.local import local_mission
from services.common.stack_dims import check_stack_dimension
from services.supervisor.options import parse
from tests.support.lifted import assert_same_mission

NOT_BUILT = r"3-D planning for (it|these) is not built yet \(docs/three_d.md, Status\)"
#: every built-in controller name, flying dim=3 with its default methods (System 1's rrt and
#: rrt+du and System 2's fast plan in 3-D, and every built-in supervisor supervises it:
#: docs/three_d.md, 5, 6 and 8)
ALL = ("cc", "s1", "s2", "concurrent", "cc+risk", "s1+risk", "s2+risk", "concurrent+risk",
       "lookahead", "lookahead+risk")
FLYING = "Controllers that fly dim=3: " + ", ".join(ALL)
#: System 2's methods that plan 3-D missions over tall fronts only: every controller that asks
#: System 2 (all but s1) is refused with one of them over low fronts (``LOW``), naming it,
#: and the list of those that fly is s1's
PLANAR_S2 = ("certified",)
FLYING_PLANAR_S2 = "Controllers that fly dim=3: s1, s1+risk"
#: fronts 5-40 m tall on the paper's process: lower than the ceiling less ε (95 m)
LOW = (("fire_height", "uniform"), ("fire_height_min_m", 5.0), ("fire_height_max_m", 40.0))
LOW_FLAGS = ["--set", "fire_height=uniform", "--set", "fire_height_min_m=5", "--set",
             "fire_height_max_m=40"]
#: the certified method's refusal over ``LOW``
SCOPED = ("plans dim=3 only where every front's top is above the ceiling less ε (95 m) and "
          "the start is at G_o's altitude (fire_height=above-ceiling, or uniform with "
          "fire_height_min_m above 95 m); here fire_height=uniform from 5 m")


@pytest.mark.parametrize("method", PLANAR_S2)
@pytest.mark.parametrize("name", ["cc", "s2", "concurrent", "lookahead"])
@pytest.mark.parametrize("risk", ["", "+risk"])
def test_a_controller_asking_a_planar_method_refuses_a_3d_mission_by_name(
        name: str, risk: str, method: str) -> None:
    config = MissionConfig.named(name + risk, profile="today-3d", system2_method=method,
                                 settings=LOW)
    assert refusals(config) == (f"System 2 method '{method}' {SCOPED}",)
    with pytest.raises(ValueError) as err:
        local_mission(config)
    text = str(err.value)
    assert text.startswith(f"controller '{name + risk}' does not fly dim=3: System 2 method "
                           f"'{method}' {SCOPED}: ")
    assert text.endswith(FLYING_PLANAR_S2)
    assert re.search(NOT_BUILT, text)
    # over fronts taller than the ceiling (today-3d's reading) it flies
    tall = MissionConfig.named(name + risk, profile="today-3d", system2_method=method)
    assert refusals(tall) == ()
    check_dimension(tall)


@pytest.mark.parametrize("name", ["cc", "s1", "s2", "concurrent", "lookahead"])
@pytest.mark.parametrize("risk", ["", "+risk"])
@pytest.mark.parametrize("method", ["fast", "thorough", "exact", "fast+exact"])
def test_every_built_in_controller_flies_a_3d_mission(name: str, risk: str,
                                                      method: str) -> None:
    config = MissionConfig.named(name + risk, profile="today-3d", system2_method=method)
    assert refusals(config) == ()
    check_dimension(config)


def test_the_2d_mission_is_not_refused() -> None:
    for name in controller_names():
        config = MissionConfig.named(name)
        assert refusals(config) == ()
        check_dimension(config)
    assert flying_controllers(MissionConfig()) == controller_names()
    assert flying_controllers(MissionConfig(profile="today-3d")) == ALL


def test_an_installed_part_is_named_as_one() -> None:
    """The example package's supervisor "proximity" (System 1 "straight") says neither 3-D:
    the message tells the installed parts from the built-in ones."""
    assert "proximity" in controller_names(), "the example package is not installed"
    with pytest.raises(ValueError) as err:
        check_dimension(MissionConfig.named("proximity", profile="today-3d"))
    text = str(err.value)
    assert ("the proximity supervisor supervises missions in 2-D only; System 1 method "
            "'straight' plans in 2-D only: installed as a plug-in, they do not declare dim 3 "
            "(dims)") in text
    assert "System 2 method 'fast'" not in text


def test_the_command_line_refuses_with_a_message_not_a_traceback(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "m"
    code = main(["mission", "--controller", "concurrent", "--s2-method", "certified", "--seed",
                 "26", "--timing", "paper", "--set", "dim=3", *LOW_FLAGS, "--out", str(out),
                 "--quiet"])
    err = capsys.readouterr().err
    assert code == 2 and not out.exists()
    assert err.startswith("dualpilot: error: controller 'concurrent' does not fly dim=3: System "
                          f"2 method 'certified' {SCOPED}: 3-D planning for it is not "
                          "built yet")
    assert "Traceback" not in err


def test_an_evaluation_and_a_sweep_refuse_before_any_mission(tmp_path: Path) -> None:
    base = MissionConfig(profile="today-3d", system2_method="certified", settings=LOW)
    with pytest.raises(ValueError) as err:
        evaluate(2, tmp_path / "e", base, controllers=["concurrent", "s1", "oracle"],
                 progress=False)
    lines = str(err.value).splitlines()
    assert lines[0] == "dim=3: these controllers do not fly it"
    assert lines[1].split(":")[0] == "  concurrent"  # the oracle judges 3-D missions
    assert lines[2] == FLYING_PLANAR_S2
    assert not (tmp_path / "e").exists()
    with pytest.raises(ValueError, match="dim=3: these controllers do not fly it"):
        sweep([Point(0, "today", (("dim", 3),) + LOW)], 1, tmp_path / "s", base=base,
              controllers=["concurrent", "oracle"], progress=False)
    assert not (tmp_path / "s").exists()


def test_the_stack_takes_a_3d_mission_its_controller_flies_and_refuses_the_others(
        capsys: pytest.CaptureFixture[str]) -> None:
    for name in ("s2", "concurrent", "lookahead"):
        opts = parse(["--controller", name, "--set", "dim=3"], "supervisor", environ={})
        assert opts.mission.spec().dim == 3
    with pytest.raises(SystemExit) as exited:
        parse(["--controller", "concurrent", "--s2-method", "certified", "--set", "dim=3",
               *LOW_FLAGS], "supervisor", environ={})
    assert exited.value.code == 2
    assert ("controller 'concurrent' does not fly dim=3: System 2 method 'certified' "
            f"{SCOPED}") in capsys.readouterr().err
    opts = parse(["--controller", "concurrent", "--s2-method", "certified", "--set", "dim=3"],
                 "supervisor", environ={})  # fronts taller than the ceiling: it flies
    assert opts.mission.spec().dim == 3


@pytest.fixture
def lifted_rrt(monkeypatch: pytest.MonkeyPatch) -> str:
    """The planners' registry with one more method, "lifted-rrt" (tests/support/lifted.py),
    registered by a real entry point beside the built-ins and the installed ones."""
    registry = Registry("dualpilot.planners", planners.PlannerMethod,
                        {**planners.BUILTIN, "lifted-rrt": "tests.support.lifted:LIFTED_RRT"},
                        what="planning method", name_pattern=planners.REGISTRY.pattern.pattern)
    monkeypatch.setattr(planners, "REGISTRY", registry)
    return "lifted-rrt"


def test_a_method_that_says_3d_flies_and_is_listed(lifted_rrt: str) -> None:
    settings = (("scenario", "grass-5"), ("max_steps", 150))
    flat = MissionConfig.named("s1", seed=1, settings=settings)
    tall = MissionConfig.named("s1", seed=1, system1_method=lifted_rrt, settings=settings
                               ).with_settings({"dim": 3, "fire_height": "above-ceiling"})
    assert refusals(tall) == ()
    # every supervisor flies the named System 1 method, and System 2's fast plans in 3-D
    assert flying_controllers(tall) == ALL
    with pytest.raises(ValueError, match=r"Controllers that fly dim=3: s1, s1\+risk$"):
        check_dimension(MissionConfig.named("concurrent", system1_method=lifted_rrt,
                                            system2_method="certified", profile="today-3d",
                                            settings=LOW))
    a = local_mission(flat).run()
    assert a.success and a.steps == 97
    assert_same_mission(a, local_mission(tall).run())
    # the stack flies the 3-D mission of a controller that flies it, and refuses the others
    # with the controller's own refusal, before any service is asked
    check_stack_dimension(tall)
    check_stack_dimension(MissionConfig.named("concurrent", system1_method=lifted_rrt,
                                              profile="today-3d"))
    with pytest.raises(ValueError, match=r"controller 'concurrent' does not fly dim=3: System "
                                         r"2 method 'certified' plans dim=3 only where"):
        check_stack_dimension(MissionConfig.named("concurrent", system1_method=lifted_rrt,
                                                  system2_method="certified",
                                                  profile="today-3d", settings=LOW))
