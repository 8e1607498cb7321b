"""How the supervisor talks to the stack: its timeouts, deadlines and limits (StackParams)."""

from __future__ import annotations

from dataclasses import dataclass

from dualpilot.model.stale_fire import StaleFireParams


@dataclass(frozen=True)
class AirLinkParams:
    """The air–ground link as the supervisor on the UAV sees it (docs/deployment.md)."""

    #: the services behind the link (``ews``, ``system2``); empty: every service is on this
    #: host (the whole stack on one machine), no link faults are named, no allowance is added
    services: frozenset[str] = frozenset()
    #: the round trip the link adds (wall s): added to every wait for a service behind it
    #: (plan deadlines, the forecast's wait, a paced fire advance's)
    rtt_s: float = 0.0
    #: a round trip longer than this (wall s) makes the step's link ``link_degraded``
    degraded_rtt_s: float = 1.0

    def allowance_s(self, service: str) -> float:
        """What a wait for ``service`` adds for the link (wall s)."""
        return self.rtt_s if service in self.services else 0.0


@dataclass(frozen=True)
class StackParams:
    """How the supervisor talks to the stack."""

    #: how long a plan request waits (wall s), System 1 and System 2; None: tied to the
    #: control period ΔT by ``plan_deadline_periods`` (the paper's modelled planning times
    #: stay a modelling choice of the step, never a wait)
    plan_deadline_s: tuple[float, float] | None = None
    #: the deadlines in control periods ΔT: 2 ΔT for System 1, 5 ΔT (the paper's 5 s) for System 2
    plan_deadline_periods: tuple[float, float] = (2.0, 5.0)
    #: a planner that misses this many deadlines in a row is unavailable until it answers a
    #: health query (its ``status/<service>`` queryable)
    deadline_misses: int = 2
    health_every_s: float = 2.0    # wall s between health queries of an unavailable planner
    health_timeout_s: float = 0.5
    #: uavsim's token gone and no heartbeat for this long (s, after the link's 3 s): the
    #: mission ends ("vehicle_lost", an ``end`` line) instead of waiting ``pause_limit_s``
    vehicle_gone_s: float = 5.0
    fire_timeout_s: float = 30.0
    vehicle_timeout_s: float = 10.0
    altitude_m: float = 50.0
    offboard_timeout_s: float = 30.0  # taking the vehicle (heartbeat, position, mode, arm)
    mission_wait_s: float = 5.0       # downloading the vehicle's mission before step 0
    prepare_timeout_s: float = 60.0   # a planner's warm-up (not a flight plan: no deadline)
    pause_limit_s: float = 300.0      # abort when paused for longer
    #: fire data at least this old (simulated s) is stale (dualpilot/model/stale_fire.py)
    stale: StaleFireParams = StaleFireParams()
    #: flush the step record (steps.jsonl) at most this long after a line (s); 0: every line
    record_flush_s: float = 0.0
    #: how long a forecast query to the EWS waits (wall s); past it the step flies without
    #: the forecast (the forecast_stale fault)
    forecast_timeout_s: float = 10.0
    #: a paced (real-time) mission waits for a forecast at most this many control periods
    #: (wall s, as the plan deadlines; never longer than ``forecast_timeout_s``): the step keeps
    #: its beat and flies without a forecast that comes later (forecast_stale)
    forecast_deadline_periods: float = 0.5
    #: the systems whose plan requests name their forecast by reference instead of carrying
    #: it (services/common/convert/plan.py: the planner takes it from the EWS on its own side
    #: of the link); System 2, which runs beside the EWS on the ground (docs/deployment.md)
    forecast_by_reference: frozenset[int] = frozenset({2})
    #: a paced mission (speed factor > 0) waits for a fire advance its pacing plus this many
    #: control periods ΔT (wall s, at most ``fire_timeout_s``); 0: ``fire_timeout_s`` alone.
    #: Behind a dead link the step then flies on with ageing fire data within the period
    fire_deadline_periods: float = 0.0
    #: the air–ground link (a split deployment): the services behind it and its allowance
    link: AirLinkParams = AirLinkParams()

    def forecast_wait_s(self, dt_s: float, speed_factor: float) -> float:
        """How long a forecast query waits (wall s): ``forecast_timeout_s`` in lockstep
        (speed factor 0), else ``forecast_deadline_periods`` × ΔT at most; plus the link's
        allowance when the EWS is behind it."""
        if speed_factor <= 0:
            return self.forecast_timeout_s
        return (min(self.forecast_timeout_s, self.forecast_deadline_periods * dt_s)
                + self.link.allowance_s("ews"))

    def fire_wait_s(self, pacing_s: float, dt_s: float, speed_factor: float) -> float:
        """How long a fire advance waits (wall s): ``fire_timeout_s``; in a paced mission with
        ``fire_deadline_periods``, its pacing (``pacing_s``: until its last sub-step is due)
        plus that many ΔT and the link's allowance, at most ``fire_timeout_s``."""
        if speed_factor <= 0 or self.fire_deadline_periods <= 0:
            return self.fire_timeout_s
        return min(self.fire_timeout_s, max(0.0, pacing_s) + self.fire_deadline_periods * dt_s
                   + self.link.allowance_s("ews"))
