"""Mission records on disk: summary.json, steps.csv, trace.json and mission.mcap, and steps.jsonl.

``summary.json`` is the mission's outcome: ``ending`` (how it ended, a value of
:class:`~dualpilot.mission.result.Ending`: ``goal``, or the failure's name; null if it did not
end) and ``success``, then its steps, time, energy and planning times; records of the older
form (``failure_cause``, ``""`` at the goal) read back through :meth:`Ending.read`.
``steps.csv`` has one row per step (``system`` and ``attention`` 1-based as in
the paper; ``system`` 0 means no plan was flown and the UAV braked); ``plan_cost``,
``plan_bound`` and ``certified_gap`` are the flown plan's Eq. (S2) cost, the lower bound
its method proved on the optimum and (cost − bound) / bound, empty when there is none.
``trace.json`` keeps what the figures need: per step the planned positions
and the fire regions and hulls the planners saw; ``mission.mcap`` the live view's Foxglove
channels (dualpilot/viz/foxglove.py). Those four are written when a mission ends;
``steps.jsonl`` (:class:`StepLog`) is written as the mission goes, one JSON
line per step, flushed at once, so it survives a crash of the writer (at
most the line being written is lost) and a mission can be rebuilt from it
(:func:`result_from_log`).

A 3-D mission (``spec.dim == 3``) writes its altitude too, and only it: steps.csv's
state and control columns are x, y, z, vx, vy, vz, ux, uy, uz (:func:`step_columns`);
trace.json's positions are [x, y, z], its steps carry the cuboids' ``tops`` and the hulls'
``hull_tops`` (m) and the document the band and the goal box's altitudes (``altitude``);
steps.jsonl's steps carry ``tops`` and ``hull_tops``. A 2-D record is unchanged, byte for
byte; a record without tops reads back as a snapshot without tops.
"""

from __future__ import annotations

import csv
import enum
import io
import json
import os
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from dualpilot.mission.answers import parse_answers
from dualpilot.mission.result import Ending, MissionResult, StepRecord
from dualpilot.model.dynamics import Array
from dualpilot.model.fire import FireSnapshot
from dualpilot.model.geometry import Polytope, Rect
from dualpilot.model.risk import RiskNote
from dualpilot.plan import Objective
from dualpilot.spec import MissionSpec
from dualpilot.supervisor.paper.decision import Decision

STEP_COLUMNS = [
    "t",
    "x",
    "y",
    "vx",
    "vy",
    "ux",
    "uy",
    "system",
    "d_t",
    "xi1",
    "xi2",
    "xi3",
    "p1",
    "p2",
    "p3",
    "attention",
    "psi1",
    "psi2",
    "fires_active",
    "objective",
    "planning_time_s",
    "fire_substeps",
    "plan_status",
    "source",
    "plan_cost",
    "plan_bound",
    "certified_gap",
]
#: steps.csv's state and control columns of a 3-D mission, in place of the planar ones
_COLUMNS_3D = {"x": ("x", "y", "z"), "vx": ("vx", "vy", "vz"), "ux": ("ux", "uy", "uz")}
_PLANAR_ONLY = frozenset({"y", "vy", "uy"})


def step_columns(dim: int) -> list[str]:
    """steps.csv's columns for a mission of dimension ``dim``: :data:`STEP_COLUMNS` in 2-D;
    in 3-D each position, velocity and force column triple gains its z."""
    if dim == 2:
        return list(STEP_COLUMNS)
    out: list[str] = []
    for name in STEP_COLUMNS:
        if name in _COLUMNS_3D:
            out += _COLUMNS_3D[name]
        elif name not in _PLANAR_ONLY:
            out.append(name)
    return out


def _num(v: float) -> float | str:
    return v if np.isfinite(v) else "inf" if v > 0 else "nan"


def _optional(v: float | None) -> str:
    """A value that may be missing: '' for None, else full precision (inf/nan as text)."""
    if v is None:
        return ""
    x = _num(float(v))
    return x if isinstance(x, str) else repr(x)

def atomic_write(path: Path, text: str) -> Path:
    """Write ``text`` to ``path`` atomically: a temporary file beside it, fsync, rename.

    A reader (or a crash, or a full disk) sees the old file or the whole new
    one, never a truncated one; on an error the temporary file is removed and
    the OSError raised.
    """
    path = Path(path)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        with tmp.open("w", encoding="utf-8", newline="") as fh:
            fh.write(text)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return path


def write_summary(result: MissionResult, out: Path) -> Path:
    return atomic_write(out / "summary.json", json.dumps(result.summary(), indent=2) + "\n")


def write_steps_csv(result: MissionResult, out: Path) -> Path:
    path = out / "steps.csv"
    with io.StringIO(newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow(step_columns(result.spec.dim))
        for r in result.records:
            d = r.decision
            writer.writerow(
                [
                    r.t,
                    *(f"{v:.6g}" for v in r.state),
                    *(f"{v:.6g}" for v in r.control),
                    r.system,
                    _num(r.d_t),
                    *(f"{v:.6g}" for v in d.xi),
                    *(f"{v:.6g}" for v in d.p),
                    d.attention,
                    *(f"{v:.6g}" for v in d.psi),
                    r.fires_active,
                    d.objective.value,
                    f"{r.planning_time_s:.6g}",
                    r.fire_substeps,
                    r.plan_status,
                    r.info.get("source", ""),
                    *(_optional(v) for v in (r.cost, r.bound, r.certified_gap)),
                ]
            )
        return atomic_write(path, fh.getvalue())


def _tops(snapshot: FireSnapshot) -> dict[str, list[float]]:
    """The snapshot's tops as a record's keys (none for a snapshot without tops)."""
    if not snapshot.has_tops:
        return {}
    return {"tops": [float(v) for v in snapshot.tops_m],
            "hull_tops": [float(v) for v in snapshot.hull_tops_m]}


def _altitude(spec: MissionSpec) -> dict[str, object]:
    """trace.json's ``altitude`` key of a 3-D mission (none in 2-D): the band, the start and
    G_o's altitudes and the goal box's (m)."""
    if spec.dim != 3:
        return {}
    b, g = spec.band, spec.goal_box
    return {"altitude": {"floor_m": b.floor_m, "ceiling_m": b.ceiling_m,
                         "start_m": b.start_altitude_m, "goal_m": g.center_z,
                         "goal_box_m": [g.z_lo, g.z_hi]}}


def write_trace(result: MissionResult, out: Path) -> Path:
    cfg = result.spec
    dim = cfg.dim
    steps = []
    for r in result.records:
        steps.append(
            {
                "t": r.t,
                "system": r.system,
                "position": [round(float(v), 3) for v in r.state[:dim]],
                "plan": np.round(r.planned_positions, 2).tolist(),
                "regions": [
                    [rc.center_x, rc.center_y, rc.width, rc.height] for rc in r.snapshot.regions
                ],
                "hulls": [np.round(h.vertices, 2).tolist() for h in r.snapshot.hulls],
                **_tops(r.snapshot),
            }
        )
    final = (result.final_state if result.final_state is not None
             else np.full(2 * dim, np.nan))
    doc = {
        "controller": result.controller,
        "seed": result.seed,
        **Ending.fields(result.ending),
        "start": list(cfg.start),
        "goal": [cfg.goal.center_x, cfg.goal.center_y, cfg.goal.width, cfg.goal.height],
        "area_size_m": cfg.area_size_m,
        **_altitude(cfg),
        "final_position": [float(v) for v in final[:dim]],
        "steps": steps,
    }
    return atomic_write(out / "trace.json", json.dumps(doc) + "\n")


def write_all(result: MissionResult, out: Path, uav: str = "uav1") -> list[Path]:
    """summary.json, steps.csv, trace.json and mission.mcap (dualpilot/viz/foxglove.py: the
    live view's channels for vehicle ``uav``, on the mission's simulated clock)."""
    from dualpilot.viz.foxglove import write_mcap

    out.mkdir(parents=True, exist_ok=True)
    return [write_summary(result, out), write_steps_csv(result, out), write_trace(result, out),
            write_mcap(result, out, uav)]


def read_steps_csv(path: Path) -> dict[str, np.ndarray]:
    """Numeric columns of steps.csv as float arrays (text columns as object arrays); a 3-D
    mission's z, vz and uz too."""
    with Path(path).open() as fh:
        reader = csv.DictReader(fh)
        rows = list(reader)
        header = reader.fieldnames or []
    cols: dict[str, np.ndarray] = {}
    for name in STEP_COLUMNS + [c for c in ("z", "vz", "uz") if c in header]:
        vals = [row.get(name, "") for row in rows]
        try:  # an empty cell of a numeric column (no bound, say) reads as nan
            cols[name] = np.array([float(v) if v != "" else np.nan for v in vals])
        except ValueError:
            cols[name] = np.array(vals, dtype=object)
    return cols


# -- the incremental record: steps.jsonl ----------------------------------------------------------
#: Name of the incremental record next to steps.csv.
STEP_LOG = "steps.jsonl"


def _floats(a: object) -> list[object]:
    """Full precision (a float's repr round-trips); non-finite values as text."""
    return [_num(float(v)) for v in np.asarray(a, dtype=float).ravel()]


def _back(vals: list[Any]) -> Array:
    return np.array([float(v) for v in vals])  # float("inf") / float("nan") parse


def record_to_json(r: StepRecord) -> dict[str, object]:
    """One :class:`StepRecord` as a JSON-able dict (state, control and decision exact; the
    plan and fire geometry to 1e-3 m; inf/nan as text)."""
    d = r.decision
    return {
        "t": r.t, "time_s": r.time_s, "state": _floats(r.state), "control": _floats(r.control),
        "system": r.system,
        "plan_status": r.plan_status, "planning_time_s": r.planning_time_s,
        "fire_substeps": r.fire_substeps, "d_t": _num(r.d_t), "fires_active": r.fires_active,
        "decision": {"t": d.t, "d_t": _num(d.d_t), "xi": _floats(d.xi), "p": _floats(d.p),
                     "attention": d.attention, "psi": _floats(d.psi), "system": d.system,
                     "objective": d.objective.value},
        "plan": np.round(np.asarray(r.planned_positions, dtype=float), 3).tolist(),
        "regions": [[rc.center_x, rc.center_y, rc.width, rc.height] for rc in r.snapshot.regions],
        "hulls": [np.round(h.vertices, 3).tolist() for h in r.snapshot.hulls],
        **_tops(r.snapshot),
        "front_ids": list(r.snapshot.front_ids), "born_steps": list(r.snapshot.born_steps),
        "info": json.loads(json.dumps(r.info, default=str)),
        "cost": None if r.cost is None else _num(r.cost),
        "bound": None if r.bound is None else _num(r.bound),
        "certified_gap": None if r.certified_gap is None else _num(r.certified_gap),
        **({} if r.risk is None else {"risk": {
            "alpha": r.risk.alpha,
            "zones": [np.round(z.vertices, 3).tolist() for z in r.risk.zones]}}),
    }


def record_from_json(doc: dict[str, Any]) -> StepRecord:
    """The inverse of :func:`record_to_json`."""
    d = doc["decision"]
    decision = Decision(t=int(d["t"]), d_t=float(d["d_t"]), xi=_back(d["xi"]), p=_back(d["p"]),
                        attention=int(d["attention"]), psi=_back(d["psi"]),
                        system=int(d["system"]), objective=Objective(d["objective"]))
    plan = np.asarray(doc["plan"], dtype=float)
    snapshot = FireSnapshot(
        regions=tuple(Rect(*(float(v) for v in rc)) for rc in doc["regions"]),
        hulls=tuple(Polytope.from_vertices(np.asarray(h, dtype=float)) for h in doc["hulls"]),
        front_ids=tuple(int(v) for v in doc.get("front_ids", [])),
        born_steps=tuple(int(v) for v in doc.get("born_steps", [])),
        tops_m=tuple(float(v) for v in doc.get("tops", [])),
        hull_tops_m=tuple(float(v) for v in doc.get("hull_tops", [])))
    control = _back(doc["control"])
    return StepRecord(
        t=int(doc["t"]), state=_back(doc["state"]), control=control,
        decision=decision, system=int(doc["system"]),
        answers=parse_answers(str(doc["plan_status"])),
        planning_time_s=float(doc["planning_time_s"]), fire_substeps=int(doc["fire_substeps"]),
        d_t=float(doc["d_t"]), fires_active=int(doc["fires_active"]),
        planned_positions=plan if plan.size else np.empty((0, len(control))),
        snapshot=snapshot,
        info=dict(doc.get("info", {})), time_s=float(doc.get("time_s", 0.0)),
        risk=_risk_from_json(doc.get("risk")), cost=_maybe(doc.get("cost")),
        bound=_maybe(doc.get("bound")))


def _maybe(v: Any) -> float | None:
    """An optional number of steps.jsonl (None, a number, or inf/nan as text)."""
    return None if v is None else float(v)


def _risk_from_json(doc: dict[str, Any] | None) -> RiskNote | None:
    """A record's risk zones (the forecast's slice is not recorded in steps.jsonl)."""
    if doc is None:
        return None
    zones = tuple(Polytope.from_vertices(np.asarray(z, dtype=float)) for z in doc["zones"])
    return RiskNote(None, zones, float(doc["alpha"]))


class StepLog:
    """An append-only JSON-lines record, one object per line, flushed as it goes.

    Each :meth:`write` appends one line ``{"kind": …, …}`` and flushes it to
    the operating system at once (``flush_every_s`` = 0, the default) or when
    the previous flush is at least ``flush_every_s`` old, so a SIGKILL of the
    writing process loses at most the lines of the last ``flush_every_s``
    seconds (with 0: at most the line being written, which
    :func:`read_step_log` skips). ``fsync_every_s`` also asks the disk to
    keep them (against power loss; None: never).
    """

    def __init__(self, path: Path, flush_every_s: float = 0.0,
                 fsync_every_s: float | None = None):
        if flush_every_s < 0 or (fsync_every_s is not None and fsync_every_s < 0):
            raise ValueError("flush_every_s and fsync_every_s must be >= 0")
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.fh = self.path.open("a", encoding="utf-8")
        self.flush_every_s = flush_every_s
        self.fsync_every_s = fsync_every_s
        self._flushed = self._synced = time.monotonic()
        self.lines = 0
        self.failed: OSError | None = None

    def write(self, kind: str, **fields: object) -> None:
        """Append ``{"kind": kind, **fields}`` as one line.

        After a write error (a full disk) the record stops: this and every later
        write raises the OSError (:attr:`failed`), so no line is written after
        a partly written one.
        """
        if self.failed is not None:
            raise self.failed
        line = _json_line({"kind": kind, **fields})
        try:
            self.fh.write(line + "\n")
            self.lines += 1
            now = time.monotonic()
            if now - self._flushed >= self.flush_every_s:
                self.fh.flush()
                self._flushed = now
                if self.fsync_every_s is not None and now - self._synced >= self.fsync_every_s:
                    os.fsync(self.fh.fileno())
                    self._synced = now
        except OSError as err:
            self.failed = err
            raise

    def step(self, record: StepRecord, **extra: object) -> None:
        """Append one step: the record (:func:`record_to_json`) and ``extra`` fields."""
        self.write("step", **record_to_json(record), **extra)

    def close(self) -> None:
        if not self.fh.closed:
            try:
                self.fh.close()  # flushes what is buffered
            except OSError as err:
                self.failed = self.failed or err

    def __enter__(self) -> StepLog:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _json_line(doc: dict[str, Any]) -> str:
    """``json.dumps(_clean(doc))``, fast: the C encoder first (arrays, numpy scalars and enums
    through ``default``), :func:`_clean` only for a document with a non-finite float or a
    key JSON has no spelling for (the encoder refuses both)."""
    try:
        return json.dumps(doc, allow_nan=False, default=_json_default)
    except (ValueError, TypeError):
        return json.dumps(_clean(doc), allow_nan=False)


def _json_default(v: Any) -> Any:
    """What :func:`_clean` makes of a value the JSON encoder does not know."""
    if isinstance(v, np.ndarray):
        return v.tolist()
    if isinstance(v, np.generic):
        return v.item()
    if isinstance(v, enum.Enum):
        return v.value
    return str(v)


def _clean(v: Any) -> Any:
    """JSON-able: arrays as lists, enums as values, non-finite floats as "inf"/"-inf"/"nan"."""
    if isinstance(v, dict):
        return {str(k): _clean(x) for k, x in v.items()}
    if isinstance(v, list | tuple):
        return [_clean(x) for x in v]
    if isinstance(v, np.ndarray):
        return _clean(v.tolist())
    if isinstance(v, np.generic):
        return _clean(v.item())
    if isinstance(v, enum.Enum):
        return _clean(v.value)
    if isinstance(v, float):
        return v if np.isfinite(v) else ("nan" if v != v else "inf" if v > 0 else "-inf")
    if v is None or isinstance(v, str | int | bool):
        return v
    return str(v)


def read_step_log(path: Path) -> list[dict[str, Any]]:
    """Every complete line of a :class:`StepLog` (a torn last line, from a crash, is skipped)."""
    out: list[dict[str, Any]] = []
    with Path(path).open(encoding="utf-8") as fh:
        for line in fh:
            if not line.endswith("\n"):
                break  # the line being written when the writer died
            try:
                out.append(json.loads(line))
            except json.JSONDecodeError:
                break
    return out


def result_from_log(entries: list[dict[str, Any]], dt_s: float = 1.0) -> MissionResult:
    """Rebuild a mission's result from its record: the ``mission`` line, then its steps.

    Energy, switches and time are re-accounted with :meth:`MissionResult.add_flight`
    over the steps that were flown: a step line's ``flown`` (default: every step but
    a final one caught while planning).
    """
    head = next((e for e in entries if e.get("kind") == "mission"), None)
    if head is None:
        raise ValueError("the record has no 'mission' line")
    g = head["goal"]
    spec = MissionSpec(start=(float(head["start"][0]), float(head["start"][1])),
                       goal=Rect(*(float(v) for v in g)), area_size_m=float(head["area_size_m"]),
                       seed=int(head["seed"]))
    spec = replace(spec, d_safe_m=float(head.get("d_safe_m", spec.d_safe_m)),
                   clearance_m=float(head.get("clearance_m", spec.clearance_m)))
    result = MissionResult(controller=str(head["controller"]), timing=str(head["timing"]),
                           spec=spec)
    steps = [e for e in entries if e.get("kind") == "step"]
    end = next((e for e in reversed(entries) if e.get("kind") == "end"), None)
    ending = None if end is None else Ending.read(end)
    caught = ending is Ending.FIRE_WHILE_PLANNING
    prev: Array | None = None
    for i, e in enumerate(steps):
        rec = record_from_json(e)
        result.records.append(rec)
        if prev is None:
            prev = np.zeros(len(rec.control))
        if e.get("flown", not (caught and i == len(steps) - 1)):
            result.add_flight(rec.control, prev, dt_s)
            prev = rec.control
    if end is not None:
        result.ending = ending
        if end.get("final_state") is not None:
            result.final_state = _back(end["final_state"])
    return result
