"""docker-compose.yml validated offline, and the local launcher's reading of it.

No Docker engine runs here and Debian's ``docker-compose config -q`` is not
installed. The whole file is parsed by a strict Compose Specification parser
(the ``compose-spec`` package, a dev dependency), and
:func:`services.launch.check_compose` checks the structure the stack relies on
(pinned router image, one image for every service, commands that name existing
service modules, string environments connecting to the router by name); these
tests also check that the launcher maps the same file onto loopback, so the
two ways of running cannot drift apart.
"""

from __future__ import annotations

import copy
import json
import os
import shlex
import shutil
import subprocess
from dataclasses import replace
from pathlib import Path
from typing import Any

import pytest
import yaml

from dualpilot.mission.config import DEFAULT_MISSION, MissionConfig
from dualpilot.mission.config_args import parse_config
from services import launch
from services.common import keys
from services.common.mission_env import MISSION_ENV

pytestmark = pytest.mark.timeout(30)


@pytest.fixture(scope="module")
def doc() -> dict[str, Any]:
    return launch.load_compose()


def test_compose_file_is_valid(doc: dict[str, Any]) -> None:
    services = doc["services"]
    assert services["zenoh"]["image"] == "eclipse/zenoh:1.10.2"
    assert set(services) == {"zenoh", *keys.SERVICES, "viewer"}
    # the live view runs only when asked for (docker compose --profile viewer; launch --viewer)
    assert services["viewer"]["profiles"] == ["viewer"]
    assert "8765:8765/tcp" in services["viewer"]["ports"]
    assert services["viewer"]["environment"]["VIEWER_LISTEN"] == "tcp/0.0.0.0:8765"
    assert "8766:8766/tcp" in services["viewer"]["ports"]  # the web page
    assert services["viewer"]["environment"]["WEB_LISTEN"] == "tcp/0.0.0.0:8766"
    assert "14550:14550/udp" in services["uavsim"]["ports"]
    assert services["supervisor"]["environment"]["MAVLINK_URL"] == "udpout:uavsim:14540"
    assert services["uavsim"]["environment"]["MAVLINK_URL"] == "udpin:0.0.0.0:14540"
    # a planner pool scales (docker compose up --scale system2=3): nothing a second container
    # of the same service would collide on — no fixed name, no published port
    for name in keys.REPLICATED:
        assert not {"container_name", "ports", "hostname"} & set(services[name]), name


def compose_spec_errors(text: str) -> str:
    """The compose-spec parser's complaint about a compose file ('' when it is valid).

    ``compose_spec`` (the Rust crate behind podlet, with Python bindings) parses
    the whole Compose Specification strictly: unknown keys, wrong types and
    malformed ports are errors. It does not expand YAML merge keys (``<<``),
    which Compose itself does, so it reads the file after PyYAML has merged them.
    """
    from compose_spec import PyCompose

    try:
        PyCompose.from_json(json.dumps(yaml.safe_load(text)))
    except ValueError as err:
        return str(err)
    return ""


def test_compose_file_passes_the_compose_spec_parser() -> None:
    assert compose_spec_errors(launch.COMPOSE.read_text()) == ""


@pytest.mark.parametrize(("old", "new", "match"), [
    ("stop_grace_period:", "stop_grace_periodd:", "stop_grace_periodd"),  # a misspelt key
    ("stop_signal: SIGINT", "stop_signal: [SIGINT]", "expected a string"),  # a wrong shape
    ('restart: "no"', "restart: sometimes", "sometimes"),               # an unknown value
    ("init: true", "init: maybe", "boolean"),                           # a wrong type
])
def test_the_compose_spec_parser_catches_what_check_compose_does_not(old: str, new: str,
                                                                     match: str) -> None:
    text = launch.COMPOSE.read_text()
    assert old in text
    bad = text.replace(old, new, 1)
    launch.check_compose(yaml.safe_load(bad))  # the subset we rely on is still intact …
    assert match in compose_spec_errors(bad)    # … but the file is no longer a compose file


@pytest.mark.parametrize(
    ("edit", "match"),
    [
        (lambda d: d["services"]["zenoh"].update(image="eclipse/zenoh:latest"), "pinned"),
        (lambda d: d["services"]["ews"].pop("command"), "missing command"),
        (lambda d: d["services"]["ews"].update(command=["python", "-m", "services.nope"]),
         "not a service module"),
        (lambda d: d["services"]["system1"]["environment"].update(SPEED_FACTOR=1),
         "strings"),
        (lambda d: d["services"]["system2"]["environment"].update(
            ZENOH_CONNECT="tcp/localhost:7447"), "ZENOH_CONNECT"),
        (lambda d: d["services"]["uavsim"].update(image="other:1"), "one image"),
        (lambda d: d["services"]["uavsim"].update(ports=["14550"]), "port"),
        (lambda d: d["services"]["ews"].update(depends_on=[]), "depend_on"),
    ],
)
def test_check_compose_rejects_drift(doc: dict[str, Any], edit: Any, match: str) -> None:
    bad = copy.deepcopy(doc)
    edit(bad)
    with pytest.raises(ValueError, match=match):
        launch.check_compose(bad)


def test_launcher_maps_compose_onto_loopback(tmp_path: Path) -> None:
    stack = launch.Stack(launch.StackConfig(
        run_dir=tmp_path, free_ports=True, speed_factor=0,
        mission=MissionConfig.named("s1", seed=11)))
    assert stack.service_names() == ["ews", "system1", "system2", "uavsim", "supervisor"]
    sup = stack.service_env("supervisor", mission_flags=True)
    uav = stack.service_env("uavsim")
    mission_names = {name for name, _, _ in MISSION_ENV}
    for env in (sup, uav, stack.service_env("ews")):
        assert env["ZENOH_CONNECT"] == stack.endpoint
        assert not mission_names & set(env), "the mission reaches the supervisor as flags"
    cmd = stack.argv("supervisor", stack.mission_argv())
    assert cmd[1:3] == ["-m", "services.supervisor"]
    assert parse_config(cmd[3:]) == MissionConfig.named("s1", seed=11,
                                                        mission_id=tmp_path.name)
    sup_port = sup["MAVLINK_URL"].rsplit(":", 1)[1]
    assert sup["MAVLINK_URL"] == f"udpout:127.0.0.1:{sup_port}"
    assert uav["MAVLINK_URL"] == f"udpin:127.0.0.1:{sup_port}"  # the same offboard link
    assert uav["GCS_URL"].startswith("udpin:127.0.0.1:")
    assert stack.argv("ews")[1:] == ["-m", "services.ews"]


def test_the_viewer_runs_only_in_its_profile(tmp_path: Path) -> None:
    plain = launch.Stack(launch.StackConfig(run_dir=tmp_path, free_ports=True))
    assert "viewer" not in plain.service_names() and plain.viewer_url() == ""
    assert plain.web_url() == ""
    stack = launch.Stack(launch.StackConfig(run_dir=tmp_path, free_ports=True,
                                            profiles=("viewer",)))
    assert stack.service_names() == ["ews", "system1", "system2", "uavsim", "supervisor",
                                     "viewer"]
    env = stack.service_env("viewer")
    port = int(env["VIEWER_LISTEN"].rsplit(":", 1)[1])
    assert env["VIEWER_LISTEN"] == f"tcp/127.0.0.1:{port}" and port != 8765  # free port
    assert stack.viewer_url() == f"ws://127.0.0.1:{port}"
    web = int(env["WEB_LISTEN"].rsplit(":", 1)[1])
    assert env["WEB_LISTEN"] == f"tcp/127.0.0.1:{web}" and web not in (8766, port)
    assert stack.web_url() == f"http://127.0.0.1:{web}/"
    assert env["ZENOH_CONNECT"] == stack.endpoint
    assert stack.argv("viewer")[1:] == ["-m", "services.viewer"]


def test_yaml_and_launcher_agree_on_every_variable(doc: dict[str, Any], tmp_path: Path,
                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    """Every compose variable reaches the local process (endpoints rewritten, rest verbatim),
    but the supervisor's mission names: the launcher hands it its mission as flags, and no
    process inherits a mission name from the launcher's own environment."""
    raw = yaml.safe_load(launch.COMPOSE.read_text())
    monkeypatch.setenv("READINGS", "max_steps=3")  # the launcher's shell: never inherited
    stack = launch.Stack(launch.StackConfig(run_dir=tmp_path, free_ports=True))
    overridden = set(stack.overrides())
    mission_names = {name for name, _, _ in MISSION_ENV}
    for name in stack.service_names():
        env = stack.service_env(name, mission_flags=name == "supervisor")
        assert "READINGS" not in env, name
        for key, value in raw["services"][name]["environment"].items():
            if key in launch.ENDPOINT_KEYS or key in overridden:
                continue
            if name == "supervisor" and key in mission_names:
                assert key not in env, key
                continue
            assert env[key] == value, (name, key)
    # compose's own supervisor (no launcher) reads them: services/common/mission_env.py
    compose_env = raw["services"]["supervisor"]["environment"]
    assert {"CONTROLLER", "MISSION_SEED", "TIMING"} <= set(compose_env) & mission_names


def test_compose_v1_accepts_the_file_and_the_router_override() -> None:
    """Compose v1.29 (Debian's docker-compose) rejects a top-level ``name:``; the override
    swaps the eclipse/zenoh router for the project's own, from the project's image."""
    raw = yaml.safe_load(launch.COMPOSE.read_text())
    assert set(raw) <= {"services", "x-service", "x-env"}, sorted(raw)
    override_path = launch.COMPOSE.with_name("docker-compose.router.yml")
    override = yaml.safe_load(override_path.read_text())
    zenoh = override["services"]["zenoh"]
    assert zenoh["image"] == raw["services"]["ews"]["image"]
    assert zenoh["command"][:3] == ["python", "-m", "services.router"]
    assert "tcp/0.0.0.0:7447" in zenoh["command"]
    assert compose_spec_errors(override_path.read_text()) == ""
    assert raw["services"]["supervisor"]["environment"]["EXIT_AFTER_MISSION"] == "1"


def test_variables_are_filled_in_as_compose_does() -> None:
    from services.launch.compose import COMPOSE, interpolate

    env = {"CONTROLLER": "concurrent+risk", "EMPTY": ""}
    assert interpolate({"a": ["${CONTROLLER:-cc}", "${EMPTY:-x}", "${UNSET}", "$$HOME",
                              "n${UNSET:-1}m", 7]}, env) == {
        "a": ["concurrent+risk", "x", "", "$HOME", "n1m", 7]}
    chosen = launch.load_compose(COMPOSE, env)["services"]["supervisor"]["environment"]
    assert chosen["CONTROLLER"] == "concurrent+risk"
    # unset, the mission's names are empty: the flags' defaults, the default mission's
    unset = launch.load_compose(COMPOSE, {})["services"]["supervisor"]["environment"]
    assert (unset["CONTROLLER"], unset["MISSION_SEED"], unset["TIMING"]) == ("", "", "")


# -- the default mission: make run, make mission and docker compose up fly the same one ---------
#: the Makefile's variables a user sets (`make run SEED=3`); a newcomer's make has none
MAKE_VARIABLES = ("CONTROLLER", "SEED", "TIMING", "PROFILE", "SUPERVISOR", "SPEED", "OUT", "TLS",
                  "CERTS", "VIEWER")


def make_arguments(target: str, program: str, **variables: str) -> list[str]:
    """The arguments ``make <target>`` runs ``program`` with (``make -n``: printed, not run;
    the target's own recipe, the last line, after its prerequisites' such as ``setup``'s), as
    a newcomer's make runs it: none of the Makefile's variables in the environment (nor a
    calling make's), only ``variables`` on the command line."""
    make = shutil.which("make")
    assert make is not None, "make is needed: the README's commands are make targets"
    env = {k: v for k, v in os.environ.items()
           if k not in MAKE_VARIABLES and k not in ("MAKEFLAGS", "MFLAGS", "MAKELEVEL")}
    out = subprocess.run([make, "-n", "--no-print-directory", target,
                          *(f"{k}={v}" for k, v in variables.items())],
                         cwd=launch.REPO, env=env, capture_output=True, text=True, timeout=20,
                         check=True).stdout
    for line in reversed(out.replace("\\\n", " ").splitlines()):
        words = shlex.split(line) if f" {program} " in f"{line} " else []
        if program in words:
            return words[words.index(program) + 1:]
    raise AssertionError(f"make -n {target} runs no {program}:\n{out}")


def make_run_mission(**variables: str) -> MissionConfig:
    """The mission ``make run`` flies through the stack (services.launch's flags)."""
    from dualpilot.mission.config_args import config_from_args
    from services.launch.__main__ import parser

    return config_from_args(parser().parse_args(make_arguments("run", "services.launch",
                                                               **variables)))


def make_mission_mission() -> MissionConfig:
    """The mission ``make mission`` flies in-process (``dualpilot mission``'s flags)."""
    from dualpilot.cli import build_parser
    from dualpilot.mission.config_args import config_from_args

    argv = make_arguments("mission", "mission")
    return config_from_args(build_parser().parse_args(["mission", *argv]))


def compose_up_mission(**shell: str) -> MissionConfig:
    """The mission ``docker compose up`` flies: the supervisor's own options, parsed in the
    environment compose gives its container when the shell sets ``shell`` (none: a
    newcomer's shell)."""
    from services.supervisor import options

    env = launch.load_compose(launch.COMPOSE, shell)["services"]["supervisor"]["environment"]
    return options.parse([], "supervisor", environ=env).mission


def test_make_run_and_compose_up_fly_the_same_default_mission() -> None:
    """One default mission (DEFAULT_MISSION): ``make run``, its in-process twin ``make
    mission`` and ``docker compose up`` fly the same controller, seed, timing and reading."""
    def same(c: MissionConfig) -> MissionConfig:
        return replace(c, mission_id="", uav_id="")

    run, twin, up = make_run_mission(), make_mission_mission(), compose_up_mission()
    assert same(run) == same(up), (run, up)
    assert same(twin) == same(run)
    assert same(run) == DEFAULT_MISSION
    assert (run.controller_name, run.seed, run.timing.value, run.profile) == (
        "lookahead+risk", 7, "paper", "today")
    # the comparison sees a difference: a seed of make run's own is not compose's
    assert make_run_mission(SEED="26").seed == 26 != up.seed
    # and the shell's variables reach both
    assert same(compose_up_mission(CONTROLLER="cc", MISSION_SEED="26")) == same(
        make_run_mission(CONTROLLER="cc", SEED="26")) == MissionConfig.named("cc", seed=26)
