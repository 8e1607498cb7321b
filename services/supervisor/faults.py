"""Named faults: wall-clock events that could make a stack mission differ from its in-process twin.

In lockstep the supervisor is the clock, so a mission flown through the
stack is the in-process mission of its seed, step for step
(tests/e2e/test_lockstep.py) — unless something outside simulated time
acts on it. Each such event is named in the step record (``faults`` of the
``steps.jsonl`` line of the step it touched) and counted in ``summary.json``
(``stack.faults``), so a mission with no faults is one that must equal its
twin, and one with faults says which:

===================  ===========================================================
``vehicle_hold``     the vehicle left offboard mode (the offboard-loss failsafe,
                     an operator's hold); lockstep's failsafe holds the vehicle
                     as it is (services/uavsim/failsafe.py), an operator's brakes
``vehicle_moved``    the vehicle's state changed with no new step (same
                     ``time_boot_ms``): only a hold that brakes does that
``vehicle_lost``     no HEARTBEAT for the link's ``lost_after_s``: the mission paused
``plan_deadline``    a plan request missed its wall-clock deadline (not flown)
``fire_stale``       the EWS did not advance the fires: the planners got the
                     last fire state grown by the credible spread
``forecast_stale``   a risk-aware step got no forecast of its fire state (the
                     EWS gone, late, refusing, or answering for another
                     revision): that step's plans and threat rule went without
                     it, as the paper's (the detail says why)
``link_degraded``    in a split deployment, the air–ground link carried some of
                     the step's exchanges but not all, or slowly
                     (services/supervisor/airlink.py)
``link_lost``        nothing from behind the air–ground link answered during the
                     step: System 1 flies it onboard, the fires age
===================  ===========================================================
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field

VEHICLE_HOLD = "vehicle_hold"
VEHICLE_MOVED = "vehicle_moved"
VEHICLE_LOST = "vehicle_lost"
PLAN_DEADLINE = "plan_deadline"
FIRE_STALE = "fire_stale"
FORECAST_STALE = "forecast_stale"
LINK_DEGRADED = "link_degraded"
LINK_LOST = "link_lost"
NAMES = (VEHICLE_HOLD, VEHICLE_MOVED, VEHICLE_LOST, PLAN_DEADLINE, FIRE_STALE, FORECAST_STALE,
         LINK_DEGRADED, LINK_LOST)


@dataclass
class FaultLog:
    """Turns the supervisor's counters into the faults of each step."""

    totals: Counter[str] = field(default_factory=Counter)
    _seen: dict[str, int] = field(default_factory=dict)
    _pending: list[str] = field(default_factory=list)

    def note(self, name: str, detail: str = "") -> None:
        """A fault seen now; it goes into the next step record."""
        if name not in NAMES:
            raise ValueError(f"unknown fault {name!r}")
        self._pending.append(f"{name}: {detail}" if detail else name)
        self.totals[name] += 1

    def counters(self, **now: int) -> None:
        """Counters that only grow (name → value): each increase is that many faults."""
        for name, value in now.items():
            new = value - self._seen.get(name, 0)
            self._seen[name] = value
            for _ in range(max(0, new)):
                self.note(name)

    def take(self) -> list[str]:
        """The faults since the last call (the step being recorded)."""
        out, self._pending = self._pending, []
        return out
