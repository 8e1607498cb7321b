"""What crosses the air–ground link per key: each process's counts, put together by host.

The rows are worked out by hand: a key's bytes cross from A to B when a process on A sends
them and a process on B receives them; what a host's own processes say to each other never
crosses.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from services.common.traffic import OTHER, Traffic, path_for, pattern, write
from services.testbed.linkbytes import Counters, crossing, per_step, read_tables


def test_a_key_counts_under_its_pattern_for_every_vehicle_and_replica() -> None:
    assert pattern("dualpilot/uav1/plan/system2/0a1b2c") == "dualpilot/*/plan/system2/*"
    assert pattern("dualpilot/uav7/ews/command") == "dualpilot/*/ews/command"
    assert pattern("dualpilot/uav1/plan/system2") == "dualpilot/*/plan/system2"
    assert pattern("elsewhere/x") == "elsewhere/x"


def test_messages_and_bytes_add_up_per_key_kind_and_direction() -> None:
    t = Traffic()
    t.sent("dualpilot/uav1/ews/command", "query", 40)
    t.sent("dualpilot/uav2/ews/command", "query", 60)
    t.received("dualpilot/uav1/ews/command", "reply", 9000)
    assert t.snapshot() == [
        {"key": "dualpilot/*/ews/command", "kind": "query", "direction": "sent",
         "messages": 2, "bytes": 100},
        {"key": "dualpilot/*/ews/command", "kind": "reply", "direction": "received",
         "messages": 1, "bytes": 9000}]
    with pytest.raises(ValueError, match="not counted"):
        t.sent("k", "publish", 1)


def test_past_its_row_limit_a_table_counts_the_rest_together() -> None:
    t = Traffic(max_rows=2)
    for k in range(4):
        t.sent(f"k{k}", "put", 10)
    rows = {r["key"]: r["bytes"] for r in t.snapshot()}
    assert rows == {"k0": 10, "k1": 10, OTHER: 20}


def table(host: str, service: str, rows: list[tuple[str, str, str, int, int]]) -> dict:
    return {"service": service, "host": host, "pid": 1,
            "rows": [{"key": k, "kind": kind, "direction": d, "messages": m, "bytes": b}
                     for k, kind, d, m, b in rows]}


def test_what_crossed_is_what_one_host_sent_and_the_other_received(tmp_path: Path) -> None:
    ews = "dualpilot/*/ews/command"
    plan = "dualpilot/*/plan/system2/*"
    step = "dualpilot/*/supervisor/step"
    tables = [
        table("air", "supervisor", [(ews, "query", "sent", 10, 500),
                                    (ews, "reply", "received", 10, 80_000),
                                    (plan, "query", "sent", 5, 2_000),
                                    (plan, "reply", "received", 5, 3_000),
                                    (step, "put", "sent", 10, 1_000)]),
        table("air", "system1", [(step, "put", "received", 10, 1_000)]),  # air to air
        table("ground", "ews", [(ews, "query", "received", 10, 500),
                                (ews, "reply", "sent", 10, 80_000)]),
        table("ground", "system2", [(plan, "query", "received", 5, 2_000),
                                    (plan, "reply", "sent", 5, 3_000)]),
        table("", "viewer", [(step, "put", "received", 10, 1_000)]),  # no host: left out
    ]
    d = tmp_path / "traffic"
    for i, t in enumerate(tables):
        write(d / f"{i}.json", t["service"], t["host"], traffic_of(t))
    got = crossing(read_tables([d]), "air", "ground")
    assert [(r["key"], r["kind"], r["from"], r["to"], r["bytes"]) for r in got] == [
        (ews, "reply", "ground", "air", 80_000),
        (plan, "reply", "ground", "air", 3_000),
        (plan, "query", "air", "ground", 2_000),
        (ews, "query", "air", "ground", 500)]
    assert not any(r["both_sides"] for r in got)
    assert per_step(got, 10)[0]["bytes_per_step"] == 8000.0


def traffic_of(t: dict) -> Traffic:
    out = Traffic()
    for r in t["rows"]:
        for _ in range(r["messages"] - 1):
            out.count(r["key"], r["kind"], r["direction"], 0)
        out.count(r["key"], r["kind"], r["direction"], r["bytes"])
    return out


def test_a_table_is_written_where_traffic_path_says(tmp_path: Path) -> None:
    p = path_for(str(tmp_path / "{service}-{pid}.json"), "ews", pid=42)
    assert p == tmp_path / "ews-42.json"
    t = Traffic()
    t.sent("dualpilot/u/ews/fires", "put", 7)
    write(p, "ews", "ground", t)
    doc = json.loads(p.read_text())
    assert doc["host"] == "ground" and doc["rows"][0]["bytes"] == 7


def test_interface_counters_subtract() -> None:
    assert Counters(1000, 5000, 10, 20) - Counters(100, 500, 1, 2) == Counters(900, 4500, 9,
                                                                                18)
