"""The supervisor's options (services/supervisor/options.py), in-process: no service started.

The mission's configuration is built here once, from the environment's mission
names (services/common/mission_env.py) and then the command line (a flag wins);
the fleet's vehicles get their seeds, mission ids, run directories and MAVLink
instances; a bad value is an argparse error (exit 2, with the reason), before
anything starts.
"""

from __future__ import annotations

import hashlib
import re
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from dualpilot.mission.config import DEFAULT_MISSION, MissionConfig
from dualpilot.model.forecast import ForecastParams
from services.supervisor.options import Options, StackParams, parse

DOC = "supervisor"
#: the deployment names the supervisor's own flags read (cleared: the tests say everything)
DEPLOYMENT = ("UAV_ID", "UAV_IDS", "ZENOH_CONNECT", "ZENOH_LISTEN", "ZENOH_MODE",
              "ZENOH_TLS_DIR", "SPEED_FACTOR", "MAVLINK_URL", "LOG_LEVEL", "LOG_FORMAT", "NICE",
              "MISSION_SEEDS", "OPERATOR_WAYPOINTS", "RUN_DIR", "START_STAGGER_S",
              "EXIT_AFTER_MISSION", "WAIT_SERVICES_S", "PLAN_DEADLINE_S", "FIRE_TIMEOUT_S",
              "FORECAST_TIMEOUT_S", "FORECAST_DEADLINE_PERIODS", "SETPOINT_RATE_HZ",
              "SETPOINT_STREAM", "MAV_SYSID", "UAV_ALTITUDE_M", "MAVLINK_SIGNING_PASSPHRASE",
              "MAVLINK_SIGNING_KEY_FILE", "VEHICLE_LOST_S")


@pytest.fixture(autouse=True)
def clean_environment(monkeypatch: pytest.MonkeyPatch) -> None:
    for name in DEPLOYMENT:
        monkeypatch.delenv(name, raising=False)


def refused(argv: list[str], capsys: pytest.CaptureFixture[str],
            environ: dict[str, str] | None = None) -> str:
    """The reason argparse gives for refusing ``argv`` (it exits with 2)."""
    with pytest.raises(SystemExit) as exit_:
        parse(argv, DOC, environ or {})
    assert exit_.value.code == 2
    return capsys.readouterr().err


def test_the_defaults_are_one_vehicle_flying_the_default_mission() -> None:
    """Nothing given: the default mission (lookahead+risk, seed 7), as docker compose up
    flies it when the shell sets none of the mission's names."""
    before = int(time.time())
    opts = parse([], DOC, {})
    assert isinstance(opts, Options)
    assert opts.mission == DEFAULT_MISSION and opts.mission.seed == 7
    assert (opts.uavs, opts.seeds, opts.out, opts.waypoints) == (("uav1",), (7,), "", None)
    assert (opts.stagger_s, opts.exit_after_mission, opts.wait_services_s) == (0.0, False, 120.0)
    (mid,) = opts.mission_ids
    assert re.fullmatch(r"uav1-7-\d+", mid) and int(mid.rsplit("-", 1)[1]) >= before
    assert opts.config(0) == replace(DEFAULT_MISSION, mission_id=mid, uav_id="uav1")
    assert opts.stack == StackParams() and opts.link.key is None
    assert (opts.link.rate_hz, opts.link.stream, opts.link.sysid) == (20.0, "process", 1)
    assert opts.run_dir(0) is None and opts.mavlink_url(0) == "udpin:127.0.0.1:14540"


def test_the_environment_says_the_mission_and_a_flag_wins() -> None:
    environ = {"CONTROLLER": "lookahead+risk", "MISSION_SEED": "26", "READINGS_PROFILE": "fig-r5",
               "READINGS": "max_steps=40;zeta=0.35", "S2_TIME_LIMIT_S": "9",
               "FORECAST_PARAMS": "members=8", "MISSION_ID": "from-env"}
    opts = parse(["--seed", "3", "--set", "mass_kg=2", "--s1-method", "rrt"], DOC, environ)
    want = MissionConfig.named(
        "lookahead+risk", seed=3, profile="fig-r5", system1_method="rrt",
        system2_time_limit_s=9.0, mission_id="from-env",
        settings=(("mass_kg", 2.0), ("max_steps", 40), ("zeta", 0.35)),
        forecast=ForecastParams(members=8))
    assert opts.mission == want
    assert opts.mission_ids == ("from-env",) and opts.seeds == (3,)
    assert opts.config(0) == MissionConfig.named(
        "lookahead+risk", seed=3, profile="fig-r5", system1_method="rrt",
        system2_time_limit_s=9.0, mission_id="from-env", uav_id="uav1", settings=want.settings,
        forecast=want.forecast)


def test_a_fleet_flies_one_seed_id_directory_and_instance_per_vehicle(tmp_path: Path) -> None:
    out = str(tmp_path / "{uav}")
    opts = parse(["--uav-ids", "a,b,c", "--seed", "5", "--out", out, "--mission-id", "m-{uav}",
                  "--mavlink-url", "udpout:127.0.0.1:14600", "--sysid", "10"], DOC, {})
    assert opts.uavs == ("a", "b", "c") and opts.seeds == (5, 6, 7)
    assert opts.mission_ids == ("m-a", "m-b", "m-c")
    assert opts.config(1) == replace(DEFAULT_MISSION, seed=6, mission_id="m-b", uav_id="b")
    assert opts.run_dir(2) == tmp_path / "c"
    assert opts.mavlink_url(2) == "udpout:127.0.0.1:14602" and opts.link.sysid == 10
    given = parse(["--uav-ids", "a,b", "--seeds", "3,9", "--out", out,
                   "--mavlink-url", "udpout:127.0.0.1:14600"], DOC, {"MISSION_SEED": "1"})
    assert given.seeds == (3, 9) and given.config(1).seed == 9


@pytest.mark.parametrize(("argv", "reason"), [
    (["--uav-ids", "a,b", "--seeds", "1,2,3", "--mavlink-url", "udpout:h:1"],
     "--seeds gives 3 seeds for 2 vehicles"),
    (["--uav-ids", "a,b", "--out", "runs/x", "--mavlink-url", "udpout:h:1"],
     "--out must contain {uav}"),
    (["--uav-ids", "a,b", "--mission-id", "same", "--mavlink-url", "udpout:h:1"],
     "--mission-id must contain {uav}"),
    (["--uav-ids", "a,b", "--sysid", "255", "--mavlink-url", "udpout:h:1"], "passes 255"),
    (["--uav-ids", "a,b"], "no port"),  # the default URL has one: a URL without
    (["--plan-deadline-s", "1"], "two positive numbers"),
    (["--plan-deadline-s", "1,-2"], "two positive numbers"),
    (["--fire-timeout-s", "0"], "must be positive"),
    (["--forecast-deadline-periods", "-1"], "must be positive"),
    (["--vehicle-lost-s", "0"], "--vehicle-lost-s must be > 0"),
    (["--start-stagger-s", "601"], r"--start-stagger-s must be in \[0, 600\]"),
    (["--speed-factor", "-1"], "speed"),
    (["--mission-id", "a b"], "must match"),
    (["--waypoints", "1,2;3"], "waypoints must look like"),
    (["--controller", "warp"], "invalid choice: 'warp'"),
    (["--set", "warp=1"], "unknown parameter 'warp'"),
    (["--s2-time-limit-s", "-5"], "system2_time_limit_s must be a positive"),
])
def test_a_bad_value_is_refused_with_its_reason(argv: list[str], reason: str,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    if argv[:1] == ["--uav-ids"] and "--mavlink-url" not in argv:
        argv = [*argv, "--mavlink-url", "udpout:localhost"]
    assert re.search(reason, refused(argv, capsys))


def test_a_bad_mission_name_in_the_environment_is_refused_as_its_flag(
        capsys: pytest.CaptureFixture[str]) -> None:
    assert "argument --controller: invalid choice: 'warp'" in refused(
        [], capsys, {"CONTROLLER": "warp"})
    assert "--supervisor concurrent contradicts --controller lookahead" in refused(
        [], capsys, {"CONTROLLER": "lookahead", "SUPERVISOR": "concurrent"})


def test_the_link_takes_its_stream_rate_altitude_and_signing_key(tmp_path: Path) -> None:
    opts = parse(["--setpoint-rate-hz", "50", "--setpoint-stream", "thread", "--altitude-m",
                  "80", "--signing-passphrase", "secret", "--vehicle-lost-s", "2",
                  "--plan-deadline-s", "0.5,4", "--waypoints", "100,200;300,400"], DOC, {})
    assert (opts.link.rate_hz, opts.link.stream, opts.link.altitude_m) == (50.0, "thread", 80.0)
    assert opts.link.key == hashlib.sha256(b"secret").digest() and opts.link.lost_after_s == 2.0
    assert opts.stack.plan_deadline_s == (0.5, 4.0) and opts.stack.altitude_m == 80.0
    assert opts.waypoints is not None
    assert np.array_equal(opts.waypoints, [[100.0, 200.0], [300.0, 400.0]])
    raw = tmp_path / "key"
    raw.write_bytes(bytes(range(32)))
    keyed = parse(["--signing-key-file", str(raw), "--signing-passphrase", "ignored"], DOC, {})
    assert keyed.link.key == bytes(range(32))  # the file wins


def test_the_help_lists_the_environment_names(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        parse(["--help"], DOC, {})
    text = capsys.readouterr().out
    assert "READINGS_PROFILE" in text and "--s2-time-limit-s" in text
    assert "S2_TIME_LIMIT_S" in text
