"""The mission's environment names (services/common/mission_env.py): one table, one reader.

Each name stands for one configuration flag of ``dualpilot mission``
(dualpilot/mission/config_args.py) and every flag has one name; an environment
reads back as the configuration its flags say (random configurations,
hypothesis); a flag on the command line wins over the environment; and no
module of ``dualpilot/`` or ``services/`` but the table's own reads a mission
name from the environment.
"""

from __future__ import annotations

import argparse
import re
from pathlib import Path

import pytest
from hypothesis import given, settings

from dualpilot.mission.config import MissionConfig
from dualpilot.mission.config_args import add_config_arguments, config_to_argv, parse_config
from dualpilot.supervisor.concurrent.rule import ConcurrentParams
from services.common.mission_env import (
    MISSION_ENV,
    env_argv,
    help_text,
    without_mission_env,
)
from tests.support.configs import configs

ROOT = Path(__file__).resolve().parents[4]
NAMES = [name for name, _, _ in MISSION_ENV]


def config_flags() -> set[str]:
    p = argparse.ArgumentParser()
    add_config_arguments(p)
    return {s for a in p._actions for s in a.option_strings if s not in ("-h", "--help")}


def as_environment(config: MissionConfig) -> dict[str, str]:
    """The environment that says ``config``: each of its flags under the table's name (a
    repeatable flag's values joined with ';')."""
    name_of = {flag: (name, is_list) for name, flag, is_list in MISSION_ENV}
    env: dict[str, str] = {}
    for item in config_to_argv(config):
        flag, _, value = item.partition("=")
        name, is_list = name_of[flag]
        env[name] = f"{env[name]};{value}" if is_list and name in env else value
    return env


def test_every_configuration_flag_has_one_name_and_every_name_one_flag() -> None:
    flags = [flag for _, flag, _ in MISSION_ENV]
    assert len(set(NAMES)) == len(NAMES) and len(set(flags)) == len(flags)
    assert set(flags) == config_flags()
    assert all(name in help_text() for name in NAMES)


def test_the_architecture_page_shows_the_table() -> None:
    text = (ROOT / "docs" / "architecture.md").read_text()
    shown = re.findall(r"^  \| `([A-Z0-9_]+)` \| `(--[a-z0-9-]+)`", text, re.MULTILINE)
    assert shown == [(name, flag) for name, flag, _ in MISSION_ENV]


@settings(max_examples=100, derandomize=True)
@given(configs())
def test_an_environment_reads_back_as_the_configuration_it_says(config: MissionConfig) -> None:
    assert parse_config(env_argv(as_environment(config))) == config


def test_the_environment_gives_the_defaults_and_a_flag_overrides_it() -> None:
    env = {"CONTROLLER": "concurrent+risk", "MISSION_SEED": "26", "READINGS_PROFILE": "fig-r5",
           "FIRE_SCENARIO": "shrub", "MAX_STEPS": "60", "CONCURRENT_PARAMS": "check_steps=5",
           "S2_METHOD": "thorough", "S2_TIME_LIMIT_S": "12.5", "READINGS": "zeta=0.35; ",
           "GOAL": "", "UAV_ID": "not-a-mission-name"}
    assert env_argv(env) == [
        "--controller=concurrent+risk", "--seed=26", "--profile=fig-r5", "--set=zeta=0.35",
        "--scenario=shrub", "--max-steps=60", "--s2-method=thorough",
        "--s2-time-limit-s=12.5", "--concurrent=check_steps=5"]
    assert parse_config(env_argv(env)) == MissionConfig.named(
        "concurrent+risk", seed=26, profile="fig-r5", system2_method="thorough",
        system2_time_limit_s=12.5,
        settings=(("max_steps", 60), ("scenario", "shrub"), ("zeta", 0.35)),
        concurrent=ConcurrentParams(check_steps=5))
    flags = [*env_argv(env), "--controller", "s1", "--set", "mass_kg=2"]
    got = parse_config(flags)
    assert got.controller_name == "s1" and dict(got.settings)["mass_kg"] == 2.0
    assert dict(got.settings)["zeta"] == 0.35  # a repeatable flag adds to the environment's
    with pytest.raises(ValueError, match="max_steps is set twice"):
        parse_config([*env_argv(env), "--set", "max_steps=5"])


def test_a_process_handed_its_mission_as_flags_inherits_no_mission_name() -> None:
    env = {name: "x" for name in NAMES} | {"UAV_ID": "uav7", "RUN_DIR": "/tmp/r"}
    assert without_mission_env(env) == {"UAV_ID": "uav7", "RUN_DIR": "/tmp/r"}


def test_no_other_module_reads_a_mission_name_from_the_environment() -> None:
    """``env("CONTROLLER", …)``, ``os.environ.get("MISSION_SEED")``, ``environ["GOAL"]``, …
    anywhere else would be a second road for a setting."""
    names = "|".join(NAMES)
    read = re.compile(rf"""(?:\benv|getenv|environ\.get|setdefault)\(\s*["']({names})["']"""
                      rf"""|environ\[\s*["']({names})["']\s*\]""")
    own = ROOT / "services" / "common" / "mission_env.py"
    found = [f"{path.relative_to(ROOT)}: {m.group(0)}"
             for pkg in ("dualpilot", "services") for path in sorted((ROOT / pkg).rglob("*.py"))
             if path != own and "msgs" not in path.parts
             for m in read.finditer(path.read_text())]
    assert found == []
