"""The run record: one writer for a mission's ``steps.jsonl`` and its files at the end.

:class:`RunRecord` owns the run directory of one mission: it locks it (one
supervisor writes a run directory at a time) and checks it is writable before
the vehicle is taken, finds the unfinished record of a mission to resume,
writes ``steps.jsonl`` as the mission flies (a ``mission`` line, one ``step``
line per step, ``event`` lines, an ``end`` line; dualpilot.mission.records.StepLog)
and, at the end, ``summary.json`` (with the stack's section), ``steps.csv``,
``trace.json`` and ``latency.csv``. A write error never crashes the
supervisor: it is counted and logged, and the mission ends by policy
(:meth:`check`).
"""

from __future__ import annotations

import fcntl
import json
import logging
import os
import time
from pathlib import Path
from typing import IO, Any

from dualpilot.mission.config import MissionConfig
from dualpilot.mission.records import (
    STEP_LOG,
    StepLog,
    atomic_write,
    read_step_log,
    record_to_json,
    write_all,
)
from dualpilot.mission.result import MissionResult, StepRecord
from dualpilot.spec import MissionSpec
from services.common import rejections
from services.common.log import fields

from .ports import Aborted
from .runlog import Latency, OperatorRecord, write_operator_columns

log = logging.getLogger("services.supervisor.session")

#: the run directory's lock file: one supervisor at a time writes a run directory
LOCK_FILE = ".supervisor.lock"


class StorageFault(Aborted):
    """The step record could not be written (a full or read-only disk): the mission ends."""


Entries = list[dict[str, Any]]


class RunRecord:
    """The records of one mission in ``directory`` (None: the mission keeps no record)."""

    def __init__(self, directory: Path | None, mission_id: str, flush_every_s: float = 0.0):
        self.dir = directory
        self.mission_id = mission_id
        self.flush_every_s = flush_every_s
        self.log: StepLog | None = None
        self.lock: IO[str] | None = None  # held while flying: until the process ends
        self.errors = 0  # write errors (a full disk)
        self.fault = ""  # the first one, which ends the mission
        self.latency = Latency()
        self.operator: list[OperatorRecord] = []

    # -- before the vehicle is taken --------------------------------------------------------------
    def claim(self) -> None:
        """Lock the run directory (``fcntl.flock``, exclusive, held until the process ends) and
        probe it (a file written, fsynced and removed); Aborted (nothing armed) otherwise."""
        if self.dir is None:
            return
        try:
            self.dir.mkdir(parents=True, exist_ok=True)
            fh = (self.dir / LOCK_FILE).open("a+")
        except OSError as err:
            raise Aborted(f"run directory {self.dir} not usable: {err}") from err
        try:
            fcntl.flock(fh.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as err:
            fh.close()
            raise Aborted(f"run directory {self.dir} is locked by another supervisor") from err
        self.lock = fh
        probe = self.dir / f".probe.{os.getpid()}"
        try:
            with probe.open("w") as pf:
                pf.write("x" * 4096)
                pf.flush()
                os.fsync(pf.fileno())
            probe.unlink()
        except OSError as err:
            probe.unlink(missing_ok=True)
            raise Aborted(f"run directory {self.dir} not writable: {err}") from err

    def prior(self) -> Entries | None:
        """This mission's record left by a supervisor that stopped before its end, if any."""
        if self.dir is None or not (self.dir / STEP_LOG).is_file():
            return None
        try:
            entries = read_step_log(self.dir / STEP_LOG)
        except (OSError, UnicodeDecodeError) as err:
            log.warning("unreadable step record: a new mission", extra=fields(error=str(err)))
            return None
        head = next((e for e in entries if e.get("kind") == "mission"), None)
        if head is None or head.get("mission_id") != self.mission_id or any(
                e.get("kind") == "end" for e in entries):
            return None
        return entries

    # -- while flying ------------------------------------------------------------------------------
    def open(self, fresh: bool) -> None:
        """Start ``steps.jsonl`` (a fresh mission's: another mission's record is moved aside)."""
        if self.dir is None:
            return
        path = self.dir / STEP_LOG
        if fresh and path.exists():
            path.replace(path.with_suffix(f".{int(time.time())}.jsonl"))  # another mission's
        self.log = StepLog(path, flush_every_s=self.flush_every_s)

    def head(self, config: MissionConfig, spec: MissionSpec, substep_s: float,
             speed_factor: float) -> None:
        """The ``mission`` line: what the mission is, enough to rebuild its result."""
        s = spec
        self.line("mission", mission_id=self.mission_id, controller=config.controller.value,
                  seed=s.seed, timing=config.timing.value, start=list(s.start),
                  goal=[s.goal.center_x, s.goal.center_y, s.goal.width, s.goal.height],
                  area_size_m=s.area_size_m, d_safe_m=s.d_safe_m, clearance_m=s.clearance_m,
                  substep_s=substep_s, dt_s=s.dynamics.dt_s, speed_factor=speed_factor,
                  ignition_clearance_m=config.reading().mission.ignition_clearance_m)

    def line(self, kind: str, **values: object) -> None:
        """Append one line; a write error is counted, logged once and ends the mission."""
        if self.log is None or self.log.fh.closed:
            return
        try:
            self.log.write(kind, wall_time_s=round(time.time(), 3), **values)
        except (OSError, ValueError) as err:  # a full disk must not crash the supervisor
            self.errors += 1
            if not self.fault:
                self.fault = f"step record not written: {err}"
                rejections.rejected("record", rejections.invalid(self.fault), log,
                                    key="storage/steps.jsonl", reason="write_error")

    def step(self, record: StepRecord, flown: bool, **values: object) -> None:
        self.line("step", **record_to_json(record), flown=flown, **values)

    def check(self) -> None:
        """Raise StorageFault after a write error (policy: the mission ends, the vehicle holds:
        the supervisor stops commanding new targets)."""
        if self.fault:
            raise StorageFault(f"storage fault: {self.fault}")

    def close(self) -> None:
        if self.log is not None:
            self.log.close()
            if self.log.failed is not None and not self.fault:
                self.fault = f"step record not written: {self.log.failed}"

    # -- at the end --------------------------------------------------------------------------------
    def write(self, result: MissionResult, uav: str, stack: dict[str, object]) -> list[Path]:
        """summary.json (with ``stack``), steps.csv, trace.json (dualpilot.mission.records),
        the operator columns and latency.csv."""
        assert self.dir is not None
        out = self.dir
        paths = write_all(result, out, uav=uav)
        write_operator_columns(self.operator, out)
        summary = json.loads((out / "summary.json").read_text())
        summary["stack"] = {**stack, "storage_errors": self.errors,
                            "setpoint_overhead": self.latency.overhead_ms()}
        atomic_write(out / "summary.json", json.dumps(summary, indent=2, default=str) + "\n")
        paths.append(self.latency.write(out))
        return paths
