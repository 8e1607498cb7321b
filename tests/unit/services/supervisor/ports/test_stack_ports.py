"""The stack's ports without a process: the fire port against the EWS's own handler behind a
fake transport, the vehicle port over a real link to a simulated autopilot.

The fire port must give the step the in-process fire process exactly, age the data
when the EWS does not answer (owed sub-steps, grown margins) and catch up by a
reset and a replay; the vehicle port commands a setpoint due at the step's time
and reads the state at or after it.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pytest

from dualpilot.mission.config import MissionConfig
from dualpilot.mission.local import LocalFires
from services.common import mavmodes, wire
from services.common.clock import SimClock
from services.supervisor.ports import Aborted, StackBus, StackFires, StackParams, StackVehicle
from tests.support.stack import (
    FakeWall,
    InProcessStack,
    SimAutopilot,
    Tokens,
    in_process_ews,
    sim_link,
)


@dataclass
class EwsStack(InProcessStack):
    """The EWS's own handler behind the transport, answering a forecast query in
    ``forecast_takes_s`` (later than its timeout: no answer)."""

    waits: list[float] = field(default_factory=list)  # each query's timeout (wall s)
    forecast_takes_s: float = 0.0

    def query(self, key: str, msg: Any, timeout_s: float, stop: threading.Event,
              trusted: Any) -> tuple[bytes, str]:
        self.waits.append(timeout_s)
        if msg.HasField("forecast") and self.forecast_takes_s > timeout_s:
            raise TimeoutError("no reply on ews/command")
        return super().query(key, msg, timeout_s, stop, trusted)


def fires_port(config: MissionConfig, speed_factor: float = 0.0
               ) -> tuple[StackFires, EwsStack, Tokens]:
    stop = threading.Event()
    stack = EwsStack(in_process_ews(stop), {})
    tokens = Tokens()
    b = StackBus(stack, "u1", "m1", wire.Stamper("supervisor", "u1"), SimClock(speed_factor),
                 stop, StackParams(), tokens.tracker())
    tokens.up("ews")
    return StackFires(b, config.spec(), config), stack, tokens


def down(stack: EwsStack, tokens: Tokens, is_down: bool) -> None:
    """The EWS gone (its token and its answers) or back."""
    stack.ews_down = is_down
    (tokens.down if is_down else tokens.up)("ews")


def test_the_fire_port_is_the_in_process_fire_process() -> None:
    config = MissionConfig(seed=26, profile="fig-r5")
    port, _, _ = fires_port(config)
    local = LocalFires(config.spec(), config.reading().fire)
    assert port.reset().regions == local.snapshot().regions
    keep = (np.array([300.0, 300.0]), 20.0)
    for t, n in [(0, 10), (1, 1), (2, 10), (3, 1)]:
        assert port.advance(t, n, keep) == local.advance(t, n, keep)
        assert port.snapshot().regions == local.snapshot().regions
    assert port.age_s() == 0.0 and not port.stale() and port.margin_m() == 0.0


def test_without_the_ews_the_data_ages_and_an_ews_back_is_replayed() -> None:
    config = MissionConfig(seed=26)
    port, b, tokens = fires_port(config)
    local = LocalFires(config.spec(), config.reading().fire)
    port.reset()
    port.advance(0, 10, None)
    local.advance(0, 10, None)
    down(b, tokens, True)
    assert port.advance(1, 1, None) == [] and port.advance(2, 10, None) == []
    local.advance(1, 1, None)
    local.advance(2, 10, None)
    assert port.age_s() == pytest.approx(11 * 0.5) and port.stale() and port.margin_m() > 75.0
    down(b, tokens, False)
    b.fire_commands.clear()
    assert port.snapshot().regions == local.snapshot().regions  # reset and replayed
    assert b.fire_commands == ["reset", "advance", "advance", "advance"] and port.owed == 0


def test_an_ews_on_another_t_f_is_refused() -> None:
    port, b, _ = fires_port(MissionConfig(seed=3, settings=(("substep_s", 0.25),)))
    port.config = MissionConfig(seed=3)  # the reset carries the default T_f: 0.5 s
    with pytest.raises(Aborted, match="the EWS runs T_f = 0.5 s, the mission 0.25 s"):
        port.reset()


def test_a_forecast_waits_for_its_deadline_lockstep_long_real_time_half_a_period() -> None:
    params = StackParams(forecast_timeout_s=10.0, forecast_deadline_periods=0.5)
    assert params.forecast_wait_s(1.0, 0.0) == 10.0  # lockstep: the timeout
    assert params.forecast_wait_s(1.0, 1.0) == 0.5  # paced: half of ΔT = 1 s, in wall time
    assert params.forecast_wait_s(1.0, 20.0) == 0.5  # as the plan deadlines: wall periods
    assert params.forecast_wait_s(100.0, 1.0) == 10.0  # never longer than the timeout


@pytest.mark.parametrize(("speed", "takes_s", "got"), [
    (0.0, 2.0, True),  # lockstep waits for a slow forecast (up to 10 s)
    (1.0, 0.2, True),  # real time: within half a period
    (1.0, 2.0, False),  # real time: later than half a period, the step goes on without it
])
def test_a_late_forecast_in_real_time_is_a_named_fault(speed: float, takes_s: float,
                                                      got: bool) -> None:
    config = MissionConfig.named("s2+risk", seed=26)
    port, b, _ = fires_port(config, speed)
    b.forecast_takes_s = takes_s
    port.reset()
    port.begin_step(0)
    fc = port.forecast(10)
    assert (fc is not None) == got and b.waits[-1] == (10.0 if speed == 0 else 0.5)
    if got:
        (cost,) = port.forecasts.take_costs()
        assert cost["revision"] == 0 and float(cost["age_s"]) >= 0.0  # type: ignore[arg-type]
        assert speed or cost["age_s"] == 0.0  # lockstep: the clock stands still meanwhile
        assert port.forecasts.take_faults() == []
    else:
        (why,) = port.forecasts.take_faults()
        assert why.startswith("late: ")
        assert port.forecast(10) is None and port.forecasts.take_faults() == []  # one a step


def test_the_vehicle_port_commands_a_setpoint_due_at_the_steps_time() -> None:
    clock, wall = SimClock(0.0), FakeWall()
    b = StackBus(None, "u1", "m1", wire.Stamper("s", "u1"), clock, threading.Event(),  # type: ignore[arg-type]
                 StackParams(), wall=wall)
    vehicle_at = SimAutopilot(np.array([50.0, 50.0, 0.0, 0.0]), time_ms=5000)
    vehicle_at.mode, vehicle_at.armed = mavmodes.PX4_MODES.offboard, True  # flying offboard
    paused: list[int] = []
    vehicle = StackVehicle(b, sim_link(vehicle_at, wall), 1.0, lambda: paused.append(1))
    vehicle.base_ms = 5000
    clock.advance(2.5)  # the step began 2.5 s into the mission
    target = np.array([51.0, 51.0, 1.0, 1.0])
    vehicle.command(target, np.zeros(2), after_s=1.5)  # planning 0.5 s + ΔT
    assert vehicle_at.setpoints[-1] == (target.tolist(), 5000 + 4000)
    assert np.array_equal(vehicle.observe(), target) and clock.now_s == pytest.approx(3.5)
    assert paused == []
