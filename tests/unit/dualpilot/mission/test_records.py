"""The incremental mission record (steps.jsonl): round trip, torn lines, survival of SIGKILL."""

from __future__ import annotations

import enum
import json
import os
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from dualpilot.mission.local import local_mission
from dualpilot.mission.params import Controller, MissionParams, Timing
from dualpilot.mission.records import (
    StepLog,
    _clean,
    read_step_log,
    record_from_json,
    result_from_log,
)
from dualpilot.mission.step import Mission
from dualpilot.model.fire import FireParams
from dualpilot.planners import build_planner
from dualpilot.spec import MissionSpec
from tests.support.missions import config_for


def _mission(seed: int = 5, steps: int = 12) -> Mission:
    spec = MissionSpec(seed=seed)
    s1 = build_planner(1, spec)
    config = config_for(spec, Controller.S1, fire=FireParams(p_birth=0.3),
                        mission=MissionParams(max_steps=steps), timing=Timing.PAPER)
    return local_mission(config, planners={1: s1, 2: s1})


def _head(m: Mission) -> dict[str, object]:
    c = m.spec
    return {"controller": "s1", "seed": 5, "timing": "paper", "start": list(c.start),
            "goal": [c.goal.center_x, c.goal.center_y, c.goal.width, c.goal.height],
            "area_size_m": c.area_size_m}


def test_a_mission_rebuilt_from_its_record_is_the_mission(tmp_path: Path) -> None:
    m = _mission()
    path = tmp_path / "steps.jsonl"
    with StepLog(path) as log:
        log.write("mission", **_head(m))
        while (rec := m.step()) is not None:
            log.step(rec, note="x")
        r = m.result
        log.write("end", success=r.success, failure_cause=r.failure_cause,
                  final_state=r.final_state)
    entries = read_step_log(path)
    assert [e["kind"] for e in entries] == ["mission"] + ["step"] * len(r.records) + ["end"]
    back = result_from_log(entries)
    assert back.steps == r.steps and back.failure_cause == r.failure_cause
    assert back.energy == pytest.approx(r.energy, abs=1e-6)
    assert back.switches == r.switches
    for a, b in zip(back.records, r.records, strict=True):
        assert a.t == b.t and a.system == b.system and a.plan_status == b.plan_status
        assert np.allclose(a.state, b.state, atol=1e-6) and np.allclose(a.control, b.control,
                                                                       atol=1e-6)
        assert np.allclose(a.decision.psi, b.decision.psi, atol=1e-6)
        assert a.decision.objective is b.decision.objective
        assert a.snapshot.regions == pytest.approx(b.snapshot.regions) or all(
            np.allclose([x.center_x, x.center_y, x.width, x.height],
                        [y.center_x, y.center_y, y.width, y.height])
            for x, y in zip(a.snapshot.regions, b.snapshot.regions, strict=True))
        assert len(a.snapshot.hulls) == len(b.snapshot.hulls)


def test_inf_d_t_and_numpy_values_are_written_as_json(tmp_path: Path) -> None:
    m = _mission()
    rec = m.step()
    assert rec is not None
    path = tmp_path / "r.jsonl"
    with StepLog(path) as log:
        log.step(rec, arr=np.arange(3), f=np.float64(1.5))
    line = json.loads(path.read_text())
    assert line["arr"] == [0, 1, 2] and line["f"] == 1.5
    assert record_from_json(line).d_t == rec.d_t  # inf when no fire: "inf" on disk


def test_every_kind_of_value_is_written_as_the_plain_cleaner_writes_it(tmp_path: Path) -> None:
    """The encoder's fast path and the recursive cleaner write the same line, with and
    without a non-finite float (which sends the whole line through the cleaner)."""
    class Colour(enum.Enum):
        RED = "red"

    finite = {"a": np.array([[0.5, 1.0], [2.0, 3.25]]), "n": np.int64(7), "b": np.bool_(True),
              "f32": np.float32(0.25), "e": Colour.RED, "t": (1, "x", None), "o": Path("p"),
              "k": {3: 1.5}}
    for doc in (finite, {**finite, "inf": float("inf"), "nan": np.array([np.nan, -np.inf])}):
        path = tmp_path / "v.jsonl"
        path.unlink(missing_ok=True)
        with StepLog(path) as log:
            log.write("x", **doc)
        line = path.read_text()
        assert line == json.dumps(_clean({"kind": "x", **doc}), allow_nan=False) + "\n"
    assert json.loads(line)["nan"] == ["nan", "-inf"] and json.loads(line)["k"] == {"3": 1.5}


def test_a_torn_last_line_is_skipped(tmp_path: Path) -> None:
    path = tmp_path / "r.jsonl"
    path.write_text('{"kind": "a"}\n{"kind": "b"}\n{"kind": "c", "x": [1, 2')
    assert [e["kind"] for e in read_step_log(path)] == ["a", "b"]
    path.write_text('{"kind": "a"}\nnot json\n{"kind": "c"}\n')
    assert [e["kind"] for e in read_step_log(path)] == ["a"]


def test_bad_flush_period_is_refused(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="flush_every_s"):
        StepLog(tmp_path / "r.jsonl", flush_every_s=-1)


def test_every_line_written_survives_sigkill(tmp_path: Path) -> None:
    """A writer killed with SIGKILL: every line it reported written is on disk and parses."""
    path = tmp_path / "r.jsonl"
    code = textwrap.dedent(f"""
        import sys
        from dualpilot.mission.records import StepLog
        log = StepLog({str(path)!r})
        i = 0
        while True:
            log.write("step", t=i, pad="x" * 200)
            if i == 500:
                print("written", flush=True)
            i += 1
    """)
    proc = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE,
                            cwd=Path(__file__).resolve().parents[4])
    try:
        assert proc.stdout is not None and proc.stdout.readline().strip() == b"written"
    finally:
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait()
    entries = read_step_log(path)
    assert len(entries) > 500
    assert [e["t"] for e in entries] == list(range(len(entries)))


def test_each_step_records_the_flown_plans_cost_bound_and_certified_gap(tmp_path: Path
                                                                         ) -> None:
    """System 2 by the "certified" method: steps.csv and steps.jsonl carry each flown plan's
    cost, bound and gap, and a record rebuilt from steps.jsonl has them back."""
    import csv

    from dualpilot.mission.records import write_all
    from dualpilot.plan import certified_gap
    from dualpilot.system2.certify.bnb import CertifyParams
    from dualpilot.system2.certify.planner import CertifiedSystem2
    from dualpilot.system2.problem import System2Params

    spec = MissionSpec(seed=5)
    s2 = CertifiedSystem2(spec, System2Params(), CertifyParams(time_budget_s=0.3))
    config = config_for(spec, Controller.S2, fire=FireParams(p_birth=0.3),
                        mission=MissionParams(max_steps=3), timing=Timing.PAPER)
    m = local_mission(config, planners={1: build_planner(1, spec), 2: s2})
    with StepLog(tmp_path / "steps.jsonl") as log:
        log.write("mission", **_head(m))
        while (rec := m.step()) is not None:
            log.step(rec)
    flown = [r for r in m.result.records if r.system == 2]
    assert flown
    for r in flown:
        assert r.cost is not None and r.bound is not None and r.bound <= r.cost
        assert r.certified_gap == certified_gap(r.cost, r.bound)
    back = result_from_log(read_step_log(tmp_path / "steps.jsonl"))
    assert [(r.cost, r.bound) for r in back.records] == [(r.cost, r.bound)
                                                       for r in m.result.records]
    write_all(m.result, tmp_path)
    with (tmp_path / "steps.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    for row, r in zip(rows, m.result.records, strict=True):
        want = tuple("" if v is None else repr(v) for v in (r.cost, r.bound, r.certified_gap))
        assert (row["plan_cost"], row["plan_bound"], row["certified_gap"]) == want
