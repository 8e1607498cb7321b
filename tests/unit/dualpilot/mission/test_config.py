"""The one mission configuration: its typed fields, the controller names, the flags and back.

A configuration written as flags (:func:`config_to_argv`) reads back as itself,
for random configurations (hypothesis); its wire form is
tests/integration/test_config_wire.py's, its environment names the services'
(tests/unit/services/common/test_mission_env.py).
"""

from __future__ import annotations

import dataclasses

import pytest
from hypothesis import given, settings

from dualpilot.mission.config import (
    DEFAULT_MISSION,
    MissionConfig,
    controller_names,
    parse_controller,
)
from dualpilot.mission.config_args import (
    concurrent_names,
    config_to_argv,
    parse_config,
)
from dualpilot.mission.local import local_mission
from dualpilot.mission.params import Controller, Timing
from dualpilot.mission.result import Ending
from dualpilot.model.forecast import ForecastParams
from dualpilot.model.geometry import Rect
from dualpilot.supervisor.concurrent.rule import ConcurrentParams
from dualpilot.supervisor.registry import supervisor_entry, supervisor_names
from tests.support.configs import configs


def test_every_controller_name_is_three_typed_fields_and_back() -> None:
    seen = set()
    names = controller_names()
    for name in names:
        controller, supervisor, risk = parse_controller(name)
        config = MissionConfig(controller=controller, supervisor=supervisor, risk=risk)
        assert config.controller_name == name and MissionConfig.named(name) == config
        seen.add((controller, supervisor, risk))
    # the built-ins, in the order tables list them; then two per installed supervisor
    assert names[:10] == ("cc", "s1", "s2", "concurrent", "cc+risk", "s1+risk", "s2+risk",
                          "concurrent+risk", "lookahead", "lookahead+risk")
    installed = supervisor_names()[3:]
    assert names[10:] == tuple(n + r for n in installed for r in ("", "+risk"))
    assert len(seen) == len(names) == 10 + 2 * len(installed)
    with pytest.raises(ValueError, match=r"unknown controller 'cc\+fast'"):
        parse_controller("cc+fast")


def test_the_supervisor_gives_system1_its_method_and_risk_the_threat_rule() -> None:
    assert MissionConfig.named("cc").methods() == {1: "rrt", 2: "fast"}
    assert MissionConfig.named("concurrent").methods() == {1: "rrt+du", 2: "fast"}
    # a method left to the supervisor follows it; one chosen stays whoever supervises
    assert MissionConfig.named("cc").system1_method == ""
    chosen = MissionConfig.named("cc", system1_method="rrt")
    assert dataclasses.replace(chosen, supervisor="concurrent").methods()[1] == "rrt"
    assert supervisor_entry("concurrent").system1_method == "rrt+du"
    assert MissionConfig.named("concurrent").concurrent.threat == "current"
    assert MissionConfig.named("concurrent+risk").concurrent.threat == "forecast"
    with pytest.raises(ValueError, match="forecast threats are the risk-aware"):
        MissionConfig(concurrent=ConcurrentParams(threat="forecast"))
    with pytest.raises(ValueError, match="concurrent supervisor does not run s2"):
        MissionConfig(controller=Controller.S2, supervisor="concurrent")


def test_settings_are_typed_sorted_and_checked_by_the_reading() -> None:
    c = MissionConfig(settings=(("scenario", "shrub"), ("max_steps", "40")))
    assert c.settings == (("max_steps", 40), ("scenario", "shrub"))
    assert c.reading().fire.scenario == "shrub" and c.reading().mission.max_steps == 40
    with pytest.raises(ValueError, match="unknown parameter 'warp'"):
        MissionConfig(settings=(("warp", 9),))
    with pytest.raises(ValueError, match="scenario must be one of"):
        MissionConfig(settings=(("scenario", "tundra"),))
    with pytest.raises(ValueError, match="unknown profile"):
        MissionConfig(profile="lenient")


def test_the_spec_is_the_configs_geometry_and_the_readings_dynamics() -> None:
    c = MissionConfig(seed=5, goal=Rect(600.0, 700.0, 80.0, 80.0), area_size_m=800.0,
                      profile="literal")
    spec = c.spec(start=(10.0, 20.0))
    assert (spec.seed, spec.goal, spec.area_size_m, spec.start) == (
        5, Rect(600.0, 700.0, 80.0, 80.0), 800.0, (10.0, 20.0))
    assert spec.dynamics.speed_limit == "norm"  # the literal profile's reading
    with pytest.raises(ValueError, match="outside"):
        MissionConfig(goal=Rect(990.0, 990.0, 100.0, 100.0))


def test_the_in_process_mission_flies_the_configs_controller_and_planners() -> None:
    mission = local_mission(MissionConfig.named("concurrent+risk", seed=3,
                                                settings=(("max_steps", 3),)))
    assert mission.controller is Controller.CC and mission.forecast_systems == {1, 2}
    planners = mission.planners.planners  # type: ignore[attr-defined]
    assert planners[1].method == "rrt+du+risk" and planners[2].method == "fast+risk"
    assert mission.run().steps <= 3


# -- flags -> config -> flags ---------------------------------------------------------------------
@settings(max_examples=200, derandomize=True)
@given(configs())
def test_a_config_written_as_flags_reads_back_as_itself(config: MissionConfig) -> None:
    assert parse_config(config_to_argv(config)) == config


def test_every_field_has_a_flag_and_its_default() -> None:
    """A field no flag sets could not be chosen from any command line (nor, through the
    services' table of environment names, from compose)."""
    flags = {f.split("=", 1)[0] for f in config_to_argv(MissionConfig.named(
        "concurrent+risk", settings=(("max_steps", 3),), concurrent=ConcurrentParams(
            check_steps=5), forecast=ForecastParams(members=8), start=(1.0, 2.0)))}
    by_field = {"controller": "--controller", "supervisor": "--controller",
                "risk": "--controller", "timing": "--timing", "seed": "--seed",
                "profile": "--profile", "settings": "--set", "system1_method": "--s1-method",
                "system2_method": "--s2-method", "system2_time_limit_s": "--s2-time-limit-s",
                "concurrent": "--concurrent", "forecast": "--forecast", "goal": "--goal",
                "area_size_m": "--area-size-m", "start": "--start",
                "mission_id": "--mission-id"}
    fields = {f.name for f in dataclasses.fields(MissionConfig)} - {"uav_id"}  # the process's
    assert fields == set(by_field) and set(by_field.values()) <= flags
    assert parse_config([]) == DEFAULT_MISSION
    assert parse_config(["--s2-time-limit-s", "7.5"]).system2_params().time_limit_s == 7.5
    assert parse_config(["--controller", "cc", "--supervisor", "concurrent"]).controller_name == (
        "concurrent")


def test_bad_flags_are_clear_errors() -> None:
    with pytest.raises(ValueError, match="system2_time_limit_s must be a positive"):
        parse_config(["--s2-time-limit-s", "0"])
    with pytest.raises(ValueError, match="max_steps is set twice"):
        parse_config(["--set", "max_steps=5", "--max-steps", "6"])
    with pytest.raises(ValueError, match="--concurrent takes NAME=VALUE"):
        parse_config(["--concurrent", "warp=9"])
    with pytest.raises(ValueError, match="contradicts"):
        parse_config(["--controller", "concurrent", "--supervisor", "paper"])
    assert "risk.alpha" in concurrent_names() and "threat" not in concurrent_names()
    with pytest.raises(ValueError, match="s2_unavailable must be 'keep' or 'system1'"):
        parse_config(["--concurrent", "s2_unavailable=ground"])


def test_what_flies_without_system2_is_a_word_of_the_concurrent_flag() -> None:
    onboard = parse_config(["--controller", "concurrent", "--concurrent",
                            "s2_unavailable=system1"])
    assert onboard.concurrent == ConcurrentParams(s2_unavailable="system1")
    assert "--concurrent=s2_unavailable=system1" in config_to_argv(onboard)
    assert parse_config([]).concurrent.s2_unavailable == "keep"


def test_the_reanchoring_reading_is_a_word_of_the_concurrent_flag() -> None:
    tube = parse_config(["--controller", "lookahead+risk", "--concurrent", "reanchor_tol=tube"])
    assert tube.concurrent == ConcurrentParams(reanchor_tol="tube", threat="forecast")
    assert "--concurrent=reanchor_tol=tube" in config_to_argv(tube)
    assert parse_config(config_to_argv(tube)) == tube
    assert parse_config([]).concurrent.reanchor_tol == "fixed"
    assert not any("reanchor_tol" in a for a in config_to_argv(parse_config([])))
    with pytest.raises(ValueError, match="reanchor_tol must be 'fixed' or 'tube', not 'wide'"):
        parse_config(["--concurrent", "reanchor_tol=wide"])


def test_a_mission_id_that_reads_as_a_flag_is_refused() -> None:
    """argparse reads ``--mission-id=--`` as the end of the flags (an empty list), so an id
    that starts with "-" cannot travel as a flag: the configuration refuses it."""
    for bad in ("--", "-a"):
        with pytest.raises(ValueError, match="mission_id must not start with '-'"):
            MissionConfig.named("cc", mission_id=bad)
    assert parse_config(["--mission-id=a--"]).mission_id == "a--"


# -- the default mission ---------------------------------------------------------------------------
def test_the_flags_default_to_the_default_mission() -> None:
    """No flag and nothing in the environment: the default mission (make run, docker compose
    up and dualpilot mission fly it; tests/integration/test_compose.py)."""
    assert parse_config([]) == DEFAULT_MISSION
    assert (DEFAULT_MISSION.controller_name, DEFAULT_MISSION.seed, DEFAULT_MISSION.timing,
            DEFAULT_MISSION.profile) == ("lookahead+risk", 7, Timing.PAPER, "today")
    assert parse_config(["--controller", "cc", "--seed", "26"]) == MissionConfig.named(
        "cc", seed=26)


@pytest.mark.slow
def test_the_default_mission_reaches_the_goal() -> None:
    """The README's first run, in-process (through the stack, step for step the same:
    tests/e2e/test_lockstep_lookahead.py): the lookahead supervisor with the forecast flies
    seed 7 to G in 65 steps."""
    result = local_mission(DEFAULT_MISSION).run()
    assert (result.ending, result.steps) == (Ending.GOAL, 65)

