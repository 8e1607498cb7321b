"""What the supervisor publishes as a mission flies: the observer's messages on Zenoh.

The clock and the Decision (``supervisor/decision``) when a setpoint has left,
the vehicle's state (``vehicle/state``), MissionEvents (``mission/event``) and
each step's plans (``supervisor/plans``, for the live view). Every message is
built by its converter (services/common/convert/); publishing never steers the
mission.
"""

from __future__ import annotations

from dualpilot.mission.result import StepRecord
from dualpilot.model.dynamics import Array
from dualpilot.spec import MissionSpec
from dualpilot.supervisor.paper.decision import Decision
from services.common import keys
from services.common.convert import common as common_convert
from services.common.convert import supervisor as supervisor_convert
from services.common.convert import vehicle as vehicle_convert
from services.common.convert.supervisor import DecisionNotes, MissionEvent
from services.msgs import common_pb2

from .ports import StackBus


class Publications:
    """The supervisor's publishers of one vehicle."""

    def __init__(self, b: StackBus, altitude_m: float):
        self.b = b
        self.altitude_m = altitude_m
        uav = b.uav
        self.pubs = {name: b.transport.publisher(key) for name, key in (
            ("decision", keys.decision(uav)), ("state", keys.vehicle_state(uav)),
            ("event", keys.mission_event(uav)), ("clock", keys.clock(uav)),
            ("plans", keys.step_plans(uav)))}

    def _now(self) -> float:
        return self.b.clock.now_s

    def event(self, ev: MissionEvent) -> None:
        self.pubs["event"](supervisor_convert.mission_event_msg(ev, self.b.stamper, self._now()))

    def state(self, x: Array, step: int) -> None:
        self.pubs["state"](vehicle_convert.vehicle_state_msg(
            x, step, self.b.stamper, self._now(), self.altitude_m))

    def step_started(self, decision: Decision, commanded: int, notes: DecisionNotes) -> None:
        """The clock (its anchor for τ_t) and the step's decision, once the setpoint left."""
        clock = common_convert.sim_clock_to_msg(self.b.clock, common_pb2.Clock())
        self.b.stamper.stamp(clock.header, self._now())
        self.pubs["clock"](clock)
        self.pubs["decision"](supervisor_convert.decision_to_msg(
            decision, commanded, self.b.stamper, self._now(), notes))

    def plans(self, record: StepRecord, spec: MissionSpec) -> None:
        self.pubs["plans"](supervisor_convert.step_plans_msg(
            record, self.b.mission_id, spec, self.b.stamper, self._now()))
