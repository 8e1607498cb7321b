"""The stack's ports without a process: the fire port against the EWS's own handler behind a
fake bus, the vehicle port against a fake link.

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
from dualpilot.model.fire import FireParams
from services.common import wire
from services.common.clock import SimClock
from services.common.convert import fire as fire_convert
from services.ews.__main__ import Ews
from services.supervisor.ports import Aborted, Bus, StackFires, StackParams, StackVehicle


class FakeSession:
    """Enough of a Zenoh session for the EWS's publishers (nobody subscribes)."""

    class Publisher:
        class Matching:
            matching = False

        matching_status = Matching()

        def put(self, *args: Any, **kw: Any) -> None:
            pass

    def declare_publisher(self, key: str) -> Publisher:
        return self.Publisher()


@dataclass
class EwsBus(Bus):
    """A Bus whose fire commands go straight to an EWS handler (or nowhere, ``down``)."""

    ews: Any = None
    down: bool = False
    asked: list[str] = field(default_factory=list)
    waits: list[float] = field(default_factory=list)  # each query's timeout (wall s)
    forecast_takes_s: float = 0.0  # how long the EWS takes to answer a forecast query

    def query(self, key: str, msg: Any, timeout_s: float, trusted: Any = None
              ) -> tuple[bytes, str]:
        cmd = fire_convert.fire_command_from_msg(msg)
        self.asked.append(cmd.kind)
        self.waits.append(timeout_s)
        if self.down or (cmd.kind == "forecast" and self.forecast_takes_s > timeout_s):
            raise TimeoutError("no reply on ews/command")
        update = self.ews.handle(cmd)
        return update.SerializeToString(), wire.encoding_name(update)

    def alive(self, service: str) -> bool:
        return not (service == "ews" and self.down)


def fires_port(config: MissionConfig, speed_factor: float = 0.0
               ) -> tuple[StackFires, EwsBus]:
    stop = threading.Event()
    ews = Ews(FakeSession(), "u1", FireParams(), 80.0, stop)  # type: ignore[arg-type]
    b = EwsBus(None, "u1", "m1", wire.Stamper("supervisor", "u1"),  # type: ignore[arg-type]
               SimClock(speed_factor), stop, StackParams(), ews=ews)
    return StackFires(b, config.spec(), config), b


def test_the_fire_port_is_the_in_process_fire_process() -> None:
    config = MissionConfig(seed=26, profile="fig-r5")
    port, _ = fires_port(config)
    local = LocalFires(config.spec(), config.reading().fire)
    assert port.reset().regions == local.snapshot().regions
    keep = (np.array([300.0, 300.0]), 20.0)
    for t, n in [(0, 10), (1, 1), (2, 10), (3, 1)]:
        assert port.advance(t, n, keep) == local.advance(t, n, keep)
        assert port.snapshot().regions == local.snapshot().regions
    assert port.age_s() == 0.0 and not port.stale() and port.margin_m() == 0.0


def test_without_the_ews_the_data_ages_and_an_ews_back_is_replayed() -> None:
    config = MissionConfig(seed=26)
    port, b = fires_port(config)
    local = LocalFires(config.spec(), config.reading().fire)
    port.reset()
    port.advance(0, 10, None)
    local.advance(0, 10, None)
    b.down = True
    assert port.advance(1, 1, None) == [] and port.advance(2, 10, None) == []
    local.advance(1, 1, None)
    local.advance(2, 10, None)
    assert port.age_s() == pytest.approx(11 * 0.5) and port.stale() and port.margin_m() > 75.0
    b.down = False
    b.asked.clear()
    assert port.snapshot().regions == local.snapshot().regions  # reset and replayed
    assert b.asked == ["reset", "advance", "advance", "advance"] and port.owed == 0


def test_an_ews_on_another_t_f_is_refused() -> None:
    port, b = fires_port(MissionConfig(seed=3, settings=(("substep_s", 0.25),)))
    b.ews.own = FireParams(substep_s=0.5)
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
    port, b = fires_port(config, speed)
    b.forecast_takes_s = takes_s
    port.reset()
    port.begin_step(0)
    fc = port.forecast(10)
    assert (fc is not None) == got and b.waits[-1] == (10.0 if speed == 0 else 0.5)
    if got:
        (cost,) = port.take_costs()
        assert cost["revision"] == 0 and float(cost["age_s"]) >= 0.0  # type: ignore[arg-type]
        assert speed or cost["age_s"] == 0.0  # lockstep: the clock stands still meanwhile
        assert port.take_faults() == []
    else:
        (why,) = port.take_faults()
        assert why.startswith("late: ")
        assert port.forecast(10) is None and port.take_faults() == []  # one fault a step


@dataclass
class FakeLink:
    """A vehicle at ``state`` whose clock shows ``time_ms``; a setpoint moves it one step."""

    state: np.ndarray
    time_ms: int = 5000
    flying: bool = True
    sent_to: list[tuple[list[float], int]] = field(default_factory=list)

    def send_setpoint(self, target: np.ndarray, due_ms: int) -> float:
        self.sent_to.append((target.tolist(), due_ms))
        self.time_ms, self.state = due_ms, target
        return 1.0

    def wait_state(self, min_ms: int, timeout_s: float, stop: Any) -> tuple[int, np.ndarray] | None:
        return (self.time_ms, self.state) if self.time_ms >= min_ms else None

    def offboard(self) -> bool:
        return self.flying


def test_the_vehicle_port_commands_a_setpoint_due_at_the_steps_time() -> None:
    clock = SimClock(0.0)
    b = Bus(None, "u1", "m1", wire.Stamper("s", "u1"), clock, threading.Event(),  # type: ignore[arg-type]
            StackParams())
    link = FakeLink(np.array([50.0, 50.0, 0.0, 0.0]))
    paused: list[int] = []
    vehicle = StackVehicle(b, link, 1.0, lambda: paused.append(1))  # type: ignore[arg-type]
    vehicle.base_ms = 5000
    clock.advance(2.5)  # the step began 2.5 s into the mission
    target = np.array([51.0, 51.0, 1.0, 1.0])
    vehicle.command(target, np.zeros(2), after_s=1.5)  # planning 0.5 s + ΔT
    assert link.sent_to == [(target.tolist(), 5000 + 4000)]
    assert np.array_equal(vehicle.observe(), target) and clock.now_s == pytest.approx(3.5)
    assert paused == []
