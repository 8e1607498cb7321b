"""A deployment's link settings: the Zenoh lease a session announces, the router joining
another, and what the test bed's mission reports per step (worked out by hand)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from services.common import cli
from services.common.bus.config import zenoh_config
from services.testbed.linkbytes import Counters
from services.testbed.mission import Flown, air_argv, describe, ground_argv, wire_per_step


def settings(*argv: str) -> cli.Settings:
    p = cli.parser("router", "test")
    return cli.settings("router", p.parse_args(["--zenoh-mode", "router", *argv]))


def test_the_lease_is_zenohs_own_unless_set() -> None:
    assert settings().zenoh_lease_ms == 0
    conf = json.loads(zenoh_config(settings()).get_json("transport/link/tx/lease"))
    short = json.loads(zenoh_config(settings("--zenoh-lease-ms", "3000")).get_json(
        "transport/link/tx/lease"))
    assert short == 3000 and conf != 3000  # Zenoh's default stays where none is asked


@pytest.mark.parametrize("ms", ["100", "700000"])
def test_a_lease_outside_half_a_second_to_ten_minutes_is_refused(ms: str) -> None:
    with pytest.raises(ValueError, match="--zenoh-lease-ms must be 0 or in 500..600000"):
        settings("--zenoh-lease-ms", ms)


def test_the_lease_comes_from_the_environment(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("ZENOH_LEASE_MS", "2500")
    assert settings().zenoh_lease_ms == 2500


def test_the_link_per_step_on_the_wire() -> None:
    w = wire_per_step(Counters(tx_bytes=12_000, rx_bytes=130_000, tx_packets=90,
                               rx_packets=110), 10)
    assert w["air_to_ground_per_step"] == 1200.0 and w["ground_to_air_per_step"] == 13000.0
    assert w["bytes_per_step"] == 14200.0 and wire_per_step(None, 10) == {}


def test_the_mission_across_the_hosts_is_the_launchers_roles(tmp_path: Path) -> None:
    from services.testbed.mission import FlightPlan

    g = ground_argv("tcp/10.10.1.2:7447", tmp_path, "uav1")
    assert g[1:5] == ["-m", "services.launch", "--role", "ground"]
    assert g[g.index("--listen") + 1] == "tcp/10.10.1.2:7447"
    a = air_argv("tcp/10.10.1.2:7447", tmp_path, FlightPlan())
    assert a[3:7] == ["--role", "air", "--join", "tcp/10.10.1.2:7447"]
    assert a[-6:] == ["--controller", "concurrent+risk", "--seed", "26", "--timing",
                      "measured"]


def test_a_flown_mission_is_described_in_a_few_lines(tmp_path: Path) -> None:
    link = {"steps": 56, "wire_mission": {"air_to_ground_per_step": 1201.3,
                                          "ground_to_air_per_step": 12748.6},
            "payload_per_step": {"air_to_ground": 350.4, "ground_to_air": 11912.8},
            "payload": [{"from": "ground", "key": "dualpilot/*/ews/command", "kind": "reply",
                         "bytes_per_step": 8517.3}]}
    text = describe(Flown(tmp_path, 0, {"seconds": 10.0, "at_step": 10}, link))
    assert text.splitlines() == [
        "air launcher exit 0; 56 steps",
        "radio link per step (wire): 1201 B air→ground, 12749 B ground→air",
        "payload per step: 350 B up, 11913 B down",
        "  ground→ dualpilot/*/ews/command reply: 8517 B/step",
        "outage: 10 s from step 10"]


def test_a_missions_seed_is_the_missions_not_the_impairers() -> None:
    """``python -m services.testbed mission --controller lookahead+risk --seed 7`` flies seed 7
    (the flags the test bed does not know are the mission's); the impairers' draws have
    their own flag."""
    from services.testbed.__main__ import parser

    args, extra = parser().parse_known_args(
        ["mission", "--controller", "lookahead+risk", "--seed", "7", "--impairer-seed", "3"])
    assert extra == ["--controller", "lookahead+risk", "--seed", "7"]
    assert args.impairer_seed == 3
