"""What a mission produced: one :class:`StepRecord` per step, the :class:`MissionResult` and
how the mission ended (:class:`Ending`).

A record on disk (summary.json, trace.json) writes the end as ``"ending"``, the value of
:class:`Ending` (``null`` for a mission that did not end, e.g. an aborted stack run), beside
``"success"`` (``ending == "goal"``); a success has no cause. Records written before the end
was typed say ``"failure_cause"`` instead (``""`` at the goal): :meth:`Ending.read` reads both.
"""

from __future__ import annotations

import enum
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from dualpilot.mission.answers import Answer, format_answers
from dualpilot.model.dynamics import Array
from dualpilot.model.fire import FireSnapshot
from dualpilot.model.risk import RiskNote
from dualpilot.plan import certified_gap
from dualpilot.spec import MissionSpec
from dualpilot.supervisor.paper.decision import Decision


class Ending(enum.Enum):
    """How a mission ended: at the goal, or the failure that ended it (Sec. IV's rules)."""

    GOAL = "goal"
    #: the flown segment passed within d_safe of an active region
    FIRE_CONTACT = "fire_contact"
    #: the plant's flown path passed within d_safe of an active region, the planned segment
    #: did not (dualpilot/mission/flight.py)
    TRACKING_BREACH = "tracking_breach"
    #: the idle UAV came within d_safe of a region while the fires advanced (planning)
    FIRE_WHILE_PLANNING = "fire_while_planning"
    #: within d_safe while the fires advanced in flight (``fire_substeps_per_motion``)
    FIRE_IN_FLIGHT = "fire_in_flight"
    #: fire data that caught up after the stack's EWS was back put a region within d_safe
    FIRE_WHILE_STALE = "fire_while_stale"
    #: the step limit (``max_steps``) came first
    STEP_LIMIT = "step_limit"
    #: the stack lost the vehicle for good
    VEHICLE_LOST = "vehicle_lost"
    #: the mission could not be flown (an evaluation's error row)
    ERROR = "error"

    @property
    def success(self) -> bool:
        return self is Ending.GOAL

    @property
    def failure_cause(self) -> str:
        """The failure's name, "" at the goal: the evaluation's ``failure_cause`` column
        (results.csv), a mission event's and a steps.jsonl ``end`` line's (summary.json and
        trace.json write :meth:`fields` instead)."""
        return "" if self.success else self.value

    @staticmethod
    def fields(ending: Ending | None) -> dict[str, object]:
        """How summary.json and trace.json write ``ending``: ``{"success": …, "ending": …}``
        (``"ending"`` is None while the mission has not ended; no cause at the goal)."""
        return {"success": ending is Ending.GOAL,
                "ending": None if ending is None else ending.value}

    @classmethod
    def read(cls, record: Mapping[str, Any]) -> Ending | None:
        """The ending a record says (summary.json, trace.json, a steps.jsonl ``end`` line), in
        either form: ``"ending"`` (:meth:`fields`), or the older ``"success"`` with
        ``"failure_cause"`` (``""`` at the goal). None: the mission did not end. ValueError
        for a value that is no ending, or a record with neither form."""
        if "ending" in record:
            value = record["ending"]
            return None if value is None else cls(value)
        if "success" not in record:
            raise ValueError("the record says nothing of how the mission ended "
                             "(no 'ending', no 'success')")
        if record["success"]:
            return cls.GOAL
        cause = record.get("failure_cause") or ""
        return cls(cause) if cause else None


@dataclass(frozen=True)
class StepRecord:
    """Everything that happened at one step (for steps.csv, trace.json and the figures).

    ``planned_positions`` is (T+1, 2), the flown plan's positions x^p_{t..t+T|t}
    (m); (0, 2) when no plan was flown.
    """

    t: int
    state: Array  # before the control
    control: Array
    decision: Decision
    system: int  # the system whose plan was flown (0: none, braked)
    answers: tuple[Answer, ...]  # each system's turn at this step, in order
    planning_time_s: float
    fire_substeps: int
    d_t: float
    fires_active: int
    planned_positions: Array
    snapshot: FireSnapshot
    info: dict[str, object] = field(default_factory=dict)
    #: τ_t, the mission's simulated time (s) when the step began: the sub-steps of T_f and the
    #: flights of ΔT before it (the log time of mission.mcap)
    time_s: float = 0.0
    #: the forecast the flown plan was made on: its next slice and risk zones (None: none)
    risk: RiskNote | None = None
    #: the flown plan's Eq. (S2) cost and proven lower bound on its problem's optimum
    #: (None: no plan flown, or no cost / no bound from its method)
    cost: float | None = None
    bound: float | None = None

    @property
    def certified_gap(self) -> float | None:
        """The flown plan's (cost − bound) / bound (:func:`dualpilot.plan.certified_gap`)."""
        if self.cost is None or self.bound is None:
            return None
        return certified_gap(self.cost, self.bound)

    @property
    def plan_status(self) -> str:
        """The answers as the records write them (``"s2:timeout;s1:ok"``)."""
        return format_answers(self.answers)


@dataclass
class MissionResult:
    controller: str
    timing: str
    spec: MissionSpec
    #: the controller's name as ``dualpilot evaluate`` spells it (``lookahead+risk``: the
    #: supervisor and the forecast with it; ``controller`` alone says which systems fly);
    #: empty where a record does not say (``summary()`` then gives ``controller``)
    controller_name: str = ""
    #: how the mission ended (None while it flies)
    ending: Ending | None = None
    steps: int = 0
    mission_time_s: float = 0.0
    energy: float = 0.0
    planning_time_s: dict[str, list[float]] = field(default_factory=lambda: {"s1": [], "s2": []})
    switches: int = 0
    switch_energy: float = 0.0  # the part of ``energy`` spent at the switch steps (N²)
    records: list[StepRecord] = field(default_factory=list)
    final_state: Array | None = None
    #: the mission's simulated time (s) when it ended (0 while it flies)
    sim_time_s: float = 0.0
    #: each flown step's horizontal distance (m) between the plant's path and the planned
    #: segment at every integration step (dualpilot/mission/flight.py; empty: not recorded)
    tracking_error_m: list[Array] = field(default_factory=list)

    @property
    def seed(self) -> int:
        return self.spec.seed

    @property
    def success(self) -> bool:
        return self.ending is Ending.GOAL

    @property
    def failure_cause(self) -> str:
        """:attr:`Ending.failure_cause`: "" at the goal or while flying, else the failure's
        name."""
        return "" if self.ending is None else self.ending.failure_cause

    def tracking_percentiles(self) -> tuple[float, float] | None:
        """(p50, p99) (m, rounded to 0.1 mm) of the horizontal tracking error over every
        integration step of the mission (results.csv's ``tracking_error_p50_m`` and ``_p99_m``);
        None when none was recorded (the ideal plant, nothing flown)."""
        if not self.tracking_error_m:
            return None
        p50, p99 = np.percentile(np.concatenate(self.tracking_error_m), [50, 99])
        return round(float(p50), 4), round(float(p99), 4)

    def add_flight(self, control: Array, prev_control: Array, dt_s: float) -> None:
        """Account one flown step (its record already appended): energy, switches, time.

        Energy is Σ‖u_t − u_{t−1}‖² (N²); a switch is a change of the system in
        control, braking steps (system 0) do not count.
        """
        du2 = float(np.sum((np.asarray(control) - np.asarray(prev_control)) ** 2))
        self.energy += du2
        flown = self.records[-1].system
        earlier = next((r.system for r in reversed(self.records[:-1]) if r.system), 0)
        if flown and earlier and flown != earlier:
            self.switches += 1
            self.switch_energy += du2
        self.steps += 1
        self.mission_time_s = self.steps * dt_s

    def summary(self) -> dict[str, object]:
        s = self.spec
        return {
            "controller": self.controller,
            "seed": self.seed,
            "timing": self.timing,
            **Ending.fields(self.ending),
            "steps": self.steps,
            "mission_time_s": self.mission_time_s,
            "energy": self.energy,
            "planning_time_s": self.planning_time_s,
            "switches": self.switches,
            "switch_energy": self.switch_energy,
            "start": list(s.start),
            "goal": {
                "center": [s.goal.center_x, s.goal.center_y],
                "size": [s.goal.width, s.goal.height],
            },
            "d_safe_m": s.d_safe_m,
            "clearance_m": s.clearance_m,
            # a flying plant's tube (d_safe_m and clearance_m include it): written when used
            **({"tracking_margin_m": s.tracking_margin_m} if s.tracking_margin_m else {}),
            # and its flight's tracking error, when one was recorded
            **({"tracking_error_p50_m": tracked[0], "tracking_error_p99_m": tracked[1]}
               if (tracked := self.tracking_percentiles()) is not None else {}),
            # the controller as dualpilot evaluate names it (cc, lookahead+risk, …)
            "controller_name": self.controller_name or self.controller,
        }
