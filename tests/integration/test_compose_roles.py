"""The deployment's roles: docker-compose.<role>.yml merged over docker-compose.yml, offline.

Each service of the stack runs on exactly one host (air: the vehicle, the supervisor, System
1; ground: the EWS, System 2, the viewer); every service is a client of its own host's router
and only the air router joins the ground's, so the one Zenoh session across the link is the
routers'. The launcher (``--role``) reads the same files: what it starts is what compose would.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest
import yaml

from services import launch
from services.launch.__main__ import parser, stack_config
from services.launch.compose import merge
from services.launch.roles import role_file, router_connect
from tests.integration.test_compose import compose_spec_errors

pytestmark = pytest.mark.timeout(30)

AIR = ["system1", "uavsim", "supervisor"]
GROUND = ["ews", "system2"]
GROUND_ZENOH = "tcp/10.10.1.2:7447"


def role_doc(role: str) -> dict[str, Any]:
    return launch.load_compose(env={"GROUND_ZENOH": GROUND_ZENOH},
                               overrides=[role_file(role)])


def test_compose_merges_as_docker_compose_does() -> None:
    base = {"services": {"a": {"command": ["x", "1"], "environment": {"K": "1", "L": "2"},
                               "cap_add": ["SYS_NICE"]}}}
    over = {"services": {"a": {"command": ["y"], "environment": {"L": "3"},
                               "cap_add": ["SYS_NICE", "NET_ADMIN"], "profiles": ["air"]},
                         "b": {"image": "i"}}}
    assert merge(base, over) == {"services": {
        "a": {"command": ["y"], "environment": {"K": "1", "L": "3"},
              "cap_add": ["SYS_NICE", "NET_ADMIN"], "profiles": ["air"]},
        "b": {"image": "i"}}}


@pytest.mark.parametrize("role", ["air", "ground"])
def test_each_role_is_a_valid_compose_file(role: str) -> None:
    merged = yaml.safe_dump(role_doc(role))
    assert compose_spec_errors(merged) == ""


def test_every_service_runs_on_exactly_one_host(tmp_path: Path) -> None:
    whole = launch.Stack(launch.StackConfig(run_dir=tmp_path, free_ports=True,
                                            profiles=("viewer",)))
    air = launch.Stack(launch.StackConfig(run_dir=tmp_path, free_ports=True, role="air",
                                          join=GROUND_ZENOH))
    ground = launch.Stack(launch.StackConfig(run_dir=tmp_path, free_ports=True, role="ground",
                                             profiles=("viewer",)))
    assert air.service_names() == AIR
    assert ground.service_names() == [*GROUND, "viewer"]
    assert sorted(air.service_names() + ground.service_names()) == sorted(
        whole.service_names())


def test_every_service_is_a_client_of_its_hosts_router(tmp_path: Path) -> None:
    air = launch.Stack(launch.StackConfig(run_dir=tmp_path, free_ports=True, role="air",
                                          join=GROUND_ZENOH))
    assert air.router_argv()[-2:] == ["--zenoh-connect", GROUND_ZENOH]
    assert air.router_listen.startswith("tcp/127.0.0.1:")
    for name in AIR:
        env = air.service_env(name, mission_flags=name == "supervisor")
        assert env["ZENOH_MODE"] == "client" and env["ZENOH_CONNECT"] == air.endpoint, name
        assert env["PLACEMENT"] == "air"
    sup = air.service_env("supervisor", mission_flags=True)
    assert sup["LINK_SERVICES"] == "ews,system2" and float(sup["LINK_RTT_S"]) > 0
    assert float(sup["FIRE_DEADLINE_PERIODS"]) > 0
    ground = launch.Stack(launch.StackConfig(run_dir=tmp_path, free_ports=True, role="ground",
                                             listen="tcp/0.0.0.0:7447"))
    assert ground.router_argv()[-2:] == ["--zenoh-listen", "tcp/0.0.0.0:7447"]
    assert ground.endpoint == "tcp/127.0.0.1:7447"
    for name in GROUND:
        env = ground.service_env(name)
        assert env["ZENOH_MODE"] == "client" and env["ZENOH_CONNECT"] == ground.endpoint
        assert env["PLACEMENT"] == "ground" and "LINK_SERVICES" not in env


def test_the_air_router_joins_the_ground_with_a_short_lease() -> None:
    doc = role_doc("air")
    assert router_connect(doc, "zenoh") == [GROUND_ZENOH]
    cmd = doc["services"]["zenoh"]["command"]
    assert "--cfg=transport/link/tx/lease:3000" in cmd
    assert doc["services"]["zenoh"]["environment"]["ROUTER_CONNECT"] == GROUND_ZENOH
    assert router_connect(role_doc("ground"), "zenoh") == []


@pytest.mark.parametrize(("argv", "match"), [
    (["--role", "air"], "--role air needs --join"),
    (["--role", "ground", "--join", "tcp/h:7447"], "no --join"),
    (["--listen", "tcp/0.0.0.0:7447"], "--listen goes with --role ground"),
    (["--role", "ground", "--listen", "udp/x:1"], "--listen takes tcp/HOST:PORT"),
    (["--role", "air", "--join", "tcp/h:7447", "--viewer"], "live view runs on the ground"),
    (["--role", "air", "--join", "tcp/h:7447", "--vehicles", "2"], "--vehicles goes with"),
    (["--services", "system2"], "--services and --uav-ids go with"),
])
def test_the_launchers_role_flags_are_checked(argv: list[str], match: str) -> None:
    with pytest.raises(ValueError, match=match):
        stack_config(parser().parse_args(argv))


def test_an_air_host_flies_the_vehicle_it_is_told(tmp_path: Path) -> None:
    """``--uav-id``: a fleet's vehicles on shared ground services each fly under their own id."""
    cfg = stack_config(parser().parse_args(["--role", "air", "--join", GROUND_ZENOH,
                                            "--uav-id", "uav7", "--out", str(tmp_path)]))
    assert cfg.uav_id == "uav7"
    assert launch.Stack(cfg).service_env("supervisor")["UAV_ID"] == "uav7"
    assert stack_config(parser().parse_args(["--out", str(tmp_path)])).uav_id == "uav1"
    with pytest.raises(ValueError, match="vehicle id"):
        stack_config(parser().parse_args(["--uav-id", "uav/1", "--out", str(tmp_path)]))


def test_a_role_keeps_its_processes_traffic_in_the_run(tmp_path: Path) -> None:
    cfg = stack_config(parser().parse_args(["--role", "ground", "--out", str(tmp_path)]))
    env = launch.Stack(cfg).service_env("ews")
    assert env["TRAFFIC_PATH"] == str(tmp_path / "traffic" / "{service}-{pid}.json")
    assert json.loads(json.dumps(cfg.services)) == []


def test_the_air_host_flies_system1_while_system2_is_unavailable(tmp_path: Path) -> None:
    """The air role's concurrent supervisor plans with System 1 without System 2
    (``s2_unavailable=system1``), in the launcher and in compose alike; a mission's own
    ``--concurrent s2_unavailable=keep`` wins; no other host or launch changes it."""
    def concurrent(argv: list[str]) -> str:
        cfg = stack_config(parser().parse_args([*argv, "--out", str(tmp_path)]))
        return cfg.mission.concurrent.s2_unavailable

    air = ["--role", "air", "--join", GROUND_ZENOH]
    assert concurrent(air) == "system1"
    assert concurrent([*air, "--concurrent", "check_steps=5"]) == "system1"
    assert concurrent([*air, "--concurrent", "s2_unavailable=keep"]) == "keep"
    assert concurrent([]) == concurrent(["--role", "ground"]) == "keep"
    env = role_doc("air")["services"]["supervisor"]["environment"]
    assert env["CONCURRENT_PARAMS"].split(";")[0] == "s2_unavailable=system1"
    assert "CONCURRENT_PARAMS" not in role_doc("ground")["services"]["supervisor"].get(
        "environment", {})
