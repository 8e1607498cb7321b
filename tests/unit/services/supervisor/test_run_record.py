"""The run record: one writer of steps.jsonl and the end-of-run files; storage faults counted."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest

from dualpilot.mission.config import MissionConfig
from dualpilot.mission.local import local_mission
from dualpilot.mission.records import read_step_log, result_from_log
from services.supervisor.ports import Aborted
from services.supervisor.record import LOCK_FILE, RunRecord, StorageFault


def flown(record: RunRecord, steps: int = 6) -> MissionConfig:
    config = MissionConfig(seed=26, settings=(("max_steps", steps),))
    mission = local_mission(config)
    record.open(fresh=True)
    record.head(config, mission.spec, 0.5, 0.0)
    while (rec := mission.step()) is not None:
        record.step(rec, True, sim_time_s=rec.time_s)
    r = mission.result
    record.line("end", success=r.success, failure_cause=r.failure_cause, steps=r.steps)
    record.close()
    return config


def test_the_record_rebuilds_the_mission(tmp_path: Path) -> None:
    record = RunRecord(tmp_path, "m-26")
    record.claim()
    config = flown(record)
    entries = read_step_log(tmp_path / "steps.jsonl")
    head = entries[0]
    assert head["kind"] == "mission" and head["mission_id"] == "m-26" and head["seed"] == 26
    rebuilt = result_from_log(entries)
    direct = local_mission(config).run()
    assert rebuilt.steps == direct.steps and rebuilt.failure_cause == direct.failure_cause
    assert [r.plan_status for r in rebuilt.records] == [r.plan_status for r in direct.records]
    assert record.errors == 0 and not record.fault


def test_an_unfinished_record_of_this_mission_is_found_for_a_resume(tmp_path: Path) -> None:
    record = RunRecord(tmp_path, "m-26")
    record.open(fresh=True)
    record.line("mission", mission_id="m-26")
    record.line("step", t=0)
    record.close()
    assert RunRecord(tmp_path, "m-26").prior() is not None
    assert RunRecord(tmp_path, "another").prior() is None  # not this mission's
    flown(RunRecord(tmp_path, "m-26"))
    assert RunRecord(tmp_path, "m-26").prior() is None  # finished: an end line
    assert list(tmp_path.glob("steps.*.jsonl")), "another mission's record is moved aside"


def test_one_supervisor_per_run_directory(tmp_path: Path) -> None:
    first = RunRecord(tmp_path, "m")
    first.claim()
    assert (tmp_path / LOCK_FILE).exists()
    with pytest.raises(Aborted, match="locked by another supervisor"):
        RunRecord(tmp_path, "m").claim()


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes a read-only directory anyway")
def test_a_read_only_directory_is_refused_before_the_vehicle_is_taken(tmp_path: Path) -> None:
    tmp_path.chmod(0o500)
    try:
        with pytest.raises(Aborted, match="not usable|not writable"):
            RunRecord(tmp_path, "m").claim()
    finally:
        tmp_path.chmod(0o700)


def test_a_write_error_is_counted_once_and_ends_the_mission(tmp_path: Path) -> None:
    record = RunRecord(tmp_path, "m")
    record.open(fresh=True)
    assert record.log is not None
    record.line("step", t=0)
    record.log.failed = OSError(28, "No space left on device")  # the disk filled up
    record.line("step", t=1)
    record.line("step", t=2)
    assert record.errors == 2 and "No space left" in record.fault
    with pytest.raises(StorageFault, match="storage fault"):
        record.check()
    record.close()
    assert [e["t"] for e in read_step_log(tmp_path / "steps.jsonl")] == [0]


def test_the_end_of_run_files_carry_the_stack_section(tmp_path: Path) -> None:
    record = RunRecord(tmp_path, "m-26")
    config = flown(record, steps=4)
    result = result_from_log(read_step_log(tmp_path / "steps.jsonl"))
    result.spec = config.spec()
    record.write(result, "uav1", {"mission_id": "m-26", "faults": {}})
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["stack"]["mission_id"] == "m-26" and summary["stack"]["storage_errors"] == 0
    assert (tmp_path / "steps.csv").is_file() and (tmp_path / "latency.csv").is_file()
