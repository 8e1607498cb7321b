"""What each system answered at a step, typed: the record's ``plan_status`` column, parsed.

A step asks one or more systems (the paper's supervisor: the one in control,
then the other; the concurrent supervisor also launches, adopts or declines
System 2's deliberation). Each event is an :class:`Answer`: the system, what
happened (:class:`SystemStatus`: a plan's status, or what the supervisor did
with it) and a note (the run-time monitor's reason for refusing a plan). The
records keep the text form, ``"s2:timeout;s1:ok"`` (:func:`format_answers`),
which :func:`parse_answers` reads back.
"""

from __future__ import annotations

import enum
import re
from collections.abc import Iterable
from dataclasses import dataclass

from dualpilot.arrays import Array
from dualpilot.plan import PlanStatus

#: the run-time monitor's tag in a refused plan's note (dualpilot/mission/monitor.py)
MONITOR_TAG = "monitor"


class SystemStatus(enum.Enum):
    """What a system's turn at a step came to: a plan status, or what the supervisor did."""

    OK = PlanStatus.OK.value
    INFEASIBLE = PlanStatus.INFEASIBLE.value
    TIMEOUT = PlanStatus.TIMEOUT.value
    NO_PATH = PlanStatus.NO_PATH.value
    UNSAFE = PlanStatus.UNSAFE.value
    INVALID_INPUT = PlanStatus.INVALID_INPUT.value
    ERROR = PlanStatus.ERROR.value
    #: the system was not asked: its planner is not available (service gone, demoted)
    UNAVAILABLE = "unavailable"
    #: the concurrent supervisor's System 2 deliberation
    #: (dualpilot/supervisor/concurrent/planning.py)
    LAUNCHED = "launched"
    ADOPTED = "adopted"
    DECLINED = "declined"
    RESTARTED = "restarted"
    STALE_START = "stale_start"
    UNSAFE_AT_ADOPTION = "unsafe_at_adoption"

    @classmethod
    def of(cls, status: PlanStatus) -> SystemStatus:
        """The system status of a plan's status."""
        return cls(status.value)


@dataclass(frozen=True)
class Answer:
    """One system's turn at a step: ``s<system>:<status><note>`` in the record."""

    system: int
    status: SystemStatus
    #: the run-time monitor's reason for refusing a plan ("[monitor: …]"), else ""
    note: str = ""

    def __str__(self) -> str:
        return f"s{self.system}:{self.status.value}{self.note}"

    @property
    def refused_by_monitor(self) -> bool:
        """A plan the run-time monitor refused (never flown)."""
        return self.status is SystemStatus.UNSAFE and self.note.startswith(f"[{MONITOR_TAG}:")


_ANSWER = re.compile(r"s(\d+):([a-z_]+)(.*)", re.DOTALL)


def format_answers(answers: Iterable[Answer]) -> str:
    """The record's text form: the answers in the order they happened, joined by ";"."""
    return ";".join(str(a) for a in answers)


def parse_answers(text: str) -> tuple[Answer, ...]:
    """The answers of a record's ``plan_status`` text (ValueError for text that is not)."""
    out = []
    for part in _split(text):
        match = _ANSWER.fullmatch(part)
        if match is None:
            raise ValueError(f"not a system's answer: {part!r}")
        system, status, note = match.groups()
        out.append(Answer(int(system), SystemStatus(status), note))
    return tuple(out)


def _split(text: str) -> list[str]:
    """``text`` split at the ";" between answers, not those inside a note's brackets."""
    parts, depth, start = [], 0, 0
    for k, ch in enumerate(text):
        depth += (ch == "[") - (ch == "]")
        if ch == ";" and depth == 0:
            parts.append(text[start:k])
            start = k + 1
    parts.append(text[start:])
    return [p for p in parts if p]


def statuses_by_system(answers: Iterable[Answer]) -> dict[int, str]:
    """Each system's statuses at a step (with their notes), in the order the systems were
    first asked; a system's several joined by ";" (``s2:launched;s1:ok;s2:adopted`` →
    {2: "launched;adopted", 1: "ok"}): what the live view shows per system."""
    out: dict[int, list[str]] = {}
    for a in answers:
        out.setdefault(a.system, []).append(f"{a.status.value}{a.note}")
    return {k: ";".join(v) for k, v in out.items()}


@dataclass(frozen=True)
class PlanView:
    """One system's plan at a step: its status and, for the flown plan, its positions (m).

    ``status`` is the step's text for the system ("ok", "timeout", "unavailable",
    "unsafe[monitor: …]"; the concurrent supervisor's several, e.g. "launched;adopted"),
    "" when the system was not asked at that step (a flown plan kept from an earlier one).
    """

    system: int
    status: str
    positions: Array  # (k, 2); (0, 2) for a plan that was not flown
    flown: bool
