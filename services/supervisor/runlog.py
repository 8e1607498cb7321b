"""The supervisor's per-step outputs beside dualpilot.mission.records: latency, operator.

``latency.csv`` holds the tick → setpoint latency of every step and
``requests.csv`` every plan request (:class:`Latency`);
:func:`write_operator_columns` adds which reference path System 1 used
(:class:`OperatorRecord`) to ``steps.csv`` and ``trace.json``.
"""

from __future__ import annotations

import csv
import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .pool import Answered

LATENCY_COLUMNS = ["t", "tick_to_setpoint_s", "compute_s", "overhead_s", "requests",
                   "request_wall_s", "service_s"]
REQUEST_COLUMNS = ["t", "system", "background", "round_trip_s", "service_s", "request_bytes",
                   "status"]


@dataclass(frozen=True)
class OperatorRecord:
    """Per step: which reference path System 1 used and whether the operator's was refused."""

    t: int
    waypoints: int
    source: str
    rejected: bool
    note: str


@dataclass
class Latency:
    """Per step: tick → setpoint on the wire (s), the planners' compute (s), the rest (s).

    The tick is the start of the step (after the previous step's pacing); the
    setpoint has left when pymavlink's send returns. ``overhead`` = total −
    compute: decision, Zenoh round trips, encoding and validation;
    ``request_wall`` is the time spent in plan requests (round trip, the
    planner service's decoding and encoding, and compute), ``service`` the
    part of it the planner services report (decode, plan, encode).
    ``requests``: every plan request (:class:`services.supervisor.pool.Answered`),
    those the step waited for and those asked off its path (the concurrent
    supervisor's System 2), one row each in requests.csv.
    """

    rows: list[tuple[int, float, float, float, int, float, float]] = field(default_factory=list)
    requests: list[Answered] = field(default_factory=list)

    def add(self, t: int, total: float, compute: float, requests: int, request_wall: float,
            service: float) -> None:
        self.rows.append((t, total, compute, total - compute, requests, request_wall, service))

    def overhead_ms(self) -> dict[str, float]:
        if not self.rows:
            return {}
        o = np.array([r[3] for r in self.rows]) * 1e3
        return {"median_ms": float(np.median(o)), "p99_ms": float(np.percentile(o, 99)),
                "max_ms": float(o.max()), "n": float(len(o))}

    def write(self, out: Path) -> Path:
        path = out / "latency.csv"
        with path.open("w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(LATENCY_COLUMNS)
            for t, total, compute, overhead, requests, wall, service in self.rows:
                w.writerow([t, f"{total:.6f}", f"{compute:.6f}", f"{overhead:.6f}", requests,
                            f"{wall:.6f}", f"{service:.6f}"])
        with (out / "requests.csv").open("w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(REQUEST_COLUMNS)
            w.writerows([a.step, a.system, int(a.background), f"{a.round_trip_s:.6f}",
                         f"{a.service_s:.6f}", a.request_bytes, a.status]
                        for a in self.requests)
        return path


def write_operator_columns(operator: list[OperatorRecord], out: Path) -> None:
    """Add the operator columns to steps.csv and trace.json (one row/entry per step)."""
    by_t = {op.t: op for op in operator}
    path = out / "steps.csv"
    with path.open(newline="") as fh:
        rows = list(csv.reader(fh))
    if rows:
        rows[0] += ["operator_waypoints", "operator_rejected"]
        for row in rows[1:]:
            op = by_t.get(int(row[0]))
            row += [str(op.waypoints), str(int(op.rejected))] if op else ["0", "0"]
        with path.open("w", newline="") as fh:
            csv.writer(fh).writerows(rows)
    trace_path = out / "trace.json"
    trace = json.loads(trace_path.read_text())
    for entry in trace.get("steps", []):
        op = by_t.get(int(entry["t"]))
        if op is not None:
            entry.update(source=op.source, operator_waypoints=op.waypoints,
                         operator_rejected=op.note if op.rejected else None)
    trace_path.write_text(json.dumps(trace) + "\n")
