"""Records of a 3-D mission (docs/three_d.md, §11): the altitude and the tops, and only in 3-D."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np

from dualpilot.mission.local import local_mission
from dualpilot.mission.records import (
    STEP_COLUMNS,
    StepLog,
    read_step_log,
    read_steps_csv,
    record_from_json,
    result_from_log,
    step_columns,
    write_steps_csv,
    write_trace,
)
from dualpilot.mission.result import MissionResult
from tests.support.lifted import config_pair, lifted_planners


def _missions() -> tuple[MissionResult, MissionResult]:
    flat, tall = config_pair("s1", 1, "paper", max_steps=30)
    return (local_mission(flat).run(),
            local_mission(tall, planners=lifted_planners(tall, flat)).run())


def test_the_3d_columns() -> None:
    assert step_columns(2) == STEP_COLUMNS
    cols = step_columns(3)
    assert cols[:10] == ["t", "x", "y", "z", "vx", "vy", "vz", "ux", "uy", "uz"]
    assert cols[10:] == STEP_COLUMNS[7:]


def test_a_3d_mission_writes_its_altitude_and_the_tops(tmp_path: Path) -> None:
    flat, tall = _missions()
    write_steps_csv(tall, tmp_path)
    write_trace(tall, tmp_path)
    with (tmp_path / "steps.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    assert list(rows[0]) == step_columns(3) and len(rows) == len(tall.records)
    assert {r["z"] for r in rows} == {"50"} and {r["uz"] for r in rows} == {"0"}
    cols = read_steps_csv(tmp_path / "steps.csv")
    assert np.all(cols["z"] == 50.0) and np.array_equal(cols["x"], [float(f"{r.state[0]:.6g}")
                                                                    for r in tall.records])
    trace = json.loads((tmp_path / "trace.json").read_text())
    assert trace["altitude"] == {"floor_m": 20.0, "ceiling_m": 120.0, "start_m": 50.0,
                                 "goal_m": 50.0, "goal_box_m": [20.0, 120.0]}
    assert len(trace["final_position"]) == 3
    fires = [s for s in trace["steps"] if s["regions"]]
    assert fires and all(len(s["tops"]) == len(s["regions"]) for s in fires)
    assert all(set(s["tops"]) == {145.0} and len(s["hull_tops"]) == len(s["hulls"])
               for s in fires)
    assert all(len(s["position"]) == 3 and all(len(p) == 3 for p in s["plan"])
               for s in trace["steps"])


def test_a_2d_mission_writes_no_altitude(tmp_path: Path) -> None:
    flat, _ = _missions()
    write_steps_csv(flat, tmp_path)
    write_trace(flat, tmp_path)
    assert (tmp_path / "steps.csv").read_text().splitlines()[0] == ",".join(STEP_COLUMNS)
    trace = json.loads((tmp_path / "trace.json").read_text())
    assert "altitude" not in trace and len(trace["final_position"]) == 2
    assert all("tops" not in s and "hull_tops" not in s and len(s["position"]) == 2
               for s in trace["steps"])
    assert "z" not in read_steps_csv(tmp_path / "steps.csv")


def test_a_3d_record_reads_back_with_its_tops(tmp_path: Path) -> None:
    _, tall = _missions()
    path = tmp_path / "steps.jsonl"
    with StepLog(path) as log:
        s = tall.spec
        log.write("mission", controller="s1", seed=s.seed, timing="paper", start=list(s.start),
                  goal=[s.goal.center_x, s.goal.center_y, s.goal.width, s.goal.height],
                  area_size_m=s.area_size_m)
        for rec in tall.records:
            log.step(rec)
        log.write("end", success=tall.success, failure_cause=tall.failure_cause,
                  final_state=tall.final_state)
    entries = read_step_log(path)
    back = result_from_log(entries)
    assert back.energy == tall.energy and back.steps == tall.steps
    for a, b in zip(tall.records, back.records, strict=True):
        assert b.snapshot.tops_m == a.snapshot.tops_m
        assert b.snapshot.hull_tops_m == a.snapshot.hull_tops_m
        assert np.array_equal(a.state, b.state) and len(b.control) == 3
        assert b.planned_positions.shape[1] == 3
    braked = dict(entries[1], plan=[])
    assert record_from_json(braked).planned_positions.shape == (0, 3)
    burning = [e for e in entries if e.get("kind") == "step" and e["regions"]]
    assert burning and all(e["tops"] == [145.0] * len(e["regions"]) for e in burning)
