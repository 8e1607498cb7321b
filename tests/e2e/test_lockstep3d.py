"""The stack and the in-process loop fly one 3-D mission: identical step records, z included.

``--set dim=3`` through the stack (docs/three_d.md, section 10): the plan requests carry the
3-D state and the obstacles' altitudes, the plans 6-wide states and 3-wide controls, the
fires their tops, the setpoints z (NED, down positive) and LOCAL_POSITION_NED the vehicle's
z and vz; uavsim flies the 3-D Eq. (1) in lockstep. Each mission below is flown through the
stack (a shared router, EWS and planner pair; a uavsim and a supervisor per vehicle,
unpaced) and in-process, and the records must agree on every row as in the 2-D lockstep
tests (tests/e2e/test_lockstep.py): the decision, the system flown, the plan statuses,
the fire sub-steps, the planned positions, the state (x, y, z, vx, vy, vz) and the control
(ux, uy, uz) to 1e-3 (float32 on MAVLink), the outcome.

The missions have paper timing, picked so that the UAV really uses altitude (the
in-process missions climb and descend; each test asserts it). cc:

* the paper's process, seed 0, fronts U[10, 40] m tall (``fire_height=uniform``) and System 1
  searching the volume (``s1_altitude=volume``): 69 steps, altitude 44.5–65.4 m;
* grass-5, seed 2, starting at the band's floor (``start_altitude_m=20``) under the plume's
  tops (``fire_height`` auto): 84 steps, altitude 20–31.3 m;
* the same with the fire forecast (``cc+risk``: the forecast's cells on the wire, the risk
  planners in 3-D): 78 steps to the goal, altitude range 16.9 m; and with the forecast's
  zones as tall as grass-5's head fire (``risk_zone_height=fire``, 10.7 m: every process
  reads the same heights from the configuration): 78 steps, altitude 20–38.0 m;
* shrub, seed 1: at the start altitude 50 m under the default reading (its plume is 190 m
  tall, above the 120 m ceiling: the top-down world), and from the floor with System 1
  searching the volume (75 steps, altitude 20–40.1 m).

And the other supervisors on the paper's process with fronts U[5, 40] m tall: ``concurrent``
seed 13 (64 steps to the goal, altitude range 11.2 m) and ``lookahead`` seed 8 (60 steps to
the goal, 22.1 m).

On physics fires the missions are compared given the vehicle's measurements
(:class:`~tests.e2e.test_lockstep.ReplayedStates`), as the 2-D ones are.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from dualpilot.mission.config import MissionConfig
from dualpilot.mission.local import LocalVehicle, local_mission
from dualpilot.mission.params import Timing
from dualpilot.mission.records import read_step_log, result_from_log
from dualpilot.mission.result import MissionResult
from services import launch
from services.common import mav
from tests.e2e.test_lockstep import ATOL, ReplayedStates, measured_states, unpaced_fleet
from tests.support.fleet import FleetRun, fly_fleet

pytestmark = [pytest.mark.slow, pytest.mark.timeout(600)]

#: fronts U[5, 40] m tall on the paper's process
LOW_FRONTS = (("fire_height", "uniform"), ("fire_height_min_m", 5.0), ("fire_height_max_m", 40.0))

#: name: (controller, seed, scenario ("" the paper's process), settings beyond dim=3,
#: altitude used)
MISSIONS: dict[str, tuple[str, int, str, tuple[tuple[str, object], ...], bool]] = {
    "paper-uniform": ("cc", 0, "", (("fire_height", "uniform"), ("fire_height_min_m", 10.0),
                                    ("fire_height_max_m", 40.0), ("s1_altitude", "volume")),
                      True),
    "grass-5-floor": ("cc", 2, "grass-5", (("start_altitude_m", 20.0),), True),
    "grass-5-floor-risk": ("cc+risk", 2, "grass-5", (("start_altitude_m", 20.0),), True),
    "grass-5-floor-risk-fire": ("cc+risk", 2, "grass-5", (("start_altitude_m", 20.0),
                                                          ("risk_zone_height", "fire")), True),
    "shrub": ("cc", 1, "shrub", (), False),
    "shrub-floor": ("cc", 1, "shrub", (("start_altitude_m", 20.0), ("s1_altitude", "volume")),
                    True),
    "concurrent-low": ("concurrent", 13, "", LOW_FRONTS, True),
    "lookahead-low": ("lookahead", 8, "", LOW_FRONTS, True),
}


def config_of(name: str) -> MissionConfig:
    """The mission ``name`` of :data:`MISSIONS` with paper timing, in 3-D."""
    controller, seed, scenario, extra, _ = MISSIONS[name]
    settings: list[tuple[str, object]] = [("dim", 3), *extra]
    if scenario:
        settings.append(("scenario", scenario))
    return MissionConfig.named(controller, seed=seed, timing=Timing.PAPER, settings=tuple(settings))


def in_process(name: str, run_dir: Path) -> MissionResult:
    """The in-process twin of mission ``name``; on a scenario given the states the stack's
    vehicle measured (checked against Eq. (1) to ATOL each step)."""
    mission = local_mission(config_of(name))
    if MISSIONS[name][2]:
        vehicle = mission.vehicle
        assert isinstance(vehicle, LocalVehicle)
        mission.vehicle = ReplayedStates(vehicle, measured_states(run_dir), name)
    return mission.run()


def assert_same_3d_mission(stack: MissionResult, local: MissionResult, what: str) -> None:
    """Every row alike: discrete fields exactly, the 3-D state, control and plan to ATOL."""
    assert (stack.success, stack.failure_cause, stack.steps) == (
        local.success, local.failure_cause, local.steps), what
    assert len(stack.records) == len(local.records), what
    for a, b in zip(stack.records, local.records, strict=True):
        where = f"{what}, step {b.t}"
        assert a.state.shape == b.state.shape == (6,), where
        assert a.control.shape == b.control.shape == (3,), where
        assert (a.t, a.system, a.plan_status, a.fire_substeps, a.fires_active) == (
            b.t, b.system, b.plan_status, b.fire_substeps, b.fires_active), where
        da, db = a.decision, b.decision
        assert (da.attention, da.system, da.objective) == (db.attention, db.system,
                                                           db.objective), where
        for field in ("xi", "p", "psi"):
            assert np.allclose(getattr(da, field), getattr(db, field), atol=ATOL), (where,
                                                                                     field)
        assert np.allclose(a.state, b.state, atol=ATOL), (where, a.state, b.state)
        assert np.allclose(a.control, b.control, atol=ATOL), (where, a.control, b.control)
        assert a.planned_positions.shape == b.planned_positions.shape, where
        assert np.allclose(a.planned_positions, b.planned_positions, atol=1e-2), where
    ua = np.vstack([np.zeros(3)] + [r.control for r in stack.records])
    ub = np.vstack([np.zeros(3)] + [r.control for r in local.records])
    da_, db_ = np.diff(ua, axis=0), np.diff(ub, axis=0)  # |‖x‖² − ‖y‖²| ≤ (‖x‖+‖y‖)‖x − y‖
    bound = float(np.sum((np.linalg.norm(da_, axis=1) + np.linalg.norm(db_, axis=1))
                         * np.linalg.norm(da_ - db_, axis=1)))
    assert abs(stack.energy - local.energy) <= bound + 1e-9, (what, stack.energy,
                                                              local.energy, bound)


def fly(fleet: launch.Fleet, out: Path) -> dict[str, tuple[Path, MissionResult]]:
    """Every mission of :data:`MISSIONS` through the stack at once, one vehicle each: its
    run directory and its records as a result."""
    runs = [FleetRun(f"the 3-D mission {name}", MISSIONS[name][1], out / name,
                     {"SPEED_FACTOR": "0"}, config_of(name)) for name in MISSIONS]
    return {name: (run_dir, result_from_log(read_step_log(run_dir / "steps.jsonl")))
            for name, run_dir in zip(MISSIONS, fly_fleet(fleet, runs), strict=True)}


@pytest.fixture(scope="module")
def flown(tmp_path_factory: pytest.TempPathFactory) -> Iterator[dict[str, Any]]:
    """The missions of :data:`MISSIONS`, flown once through one shared stack."""
    with unpaced_fleet(tmp_path_factory, "lockstep3d", "l3", len(MISSIONS)) as (f, out):
        yield fly(f, out)


@pytest.mark.parametrize("name", list(MISSIONS))
def test_a_3d_mission_through_the_stack_is_the_in_process_one(flown: dict[str, Any],
                                                              name: str) -> None:
    run_dir, stack = flown[name]
    local = in_process(name, run_dir)
    assert_same_3d_mission(stack, local, name)
    z = np.array([r.state[2] for r in stack.records])
    start = config_of(name).spec().band.start_altitude_m
    assert z[0] == pytest.approx(start, abs=ATOL)
    uses_altitude = MISSIONS[name][4]
    # the altitude the UAV flew: climbing and descending where the fires are low enough,
    # kept at the start altitude where every front is taller than the band
    assert (float(np.ptp(z)) > 5.0) == uses_altitude, (name, float(np.ptp(z)))
    assert (float(np.abs([r.control[2] for r in stack.records]).max()) > 1.0) == uses_altitude
    # what a ground station saw on the vehicle's link (its tlog): the setpoints' z, the local
    # position's z and the relative altitude follow the flown altitude
    seen = tlog_altitudes(run_dir / "vehicle.tlog")
    top = float(z.max())
    assert max(seen["LOCAL_POSITION_NED"]) == pytest.approx(top, abs=ATOL)
    assert max(seen["GLOBAL_POSITION_INT"]) == pytest.approx(top, abs=1e-3 + ATOL)
    assert max(seen["SET_POSITION_TARGET_LOCAL_NED"]) >= top - ATOL


def tlog_altitudes(path: Path) -> dict[str, list[float]]:
    """The altitudes (m) in a vehicle's tlog: −z of LOCAL_POSITION_NED and of the setpoints,
    GLOBAL_POSITION_INT's relative_alt."""
    log = mav.mavutil.mavlink_connection(str(path))
    out: dict[str, list[float]] = {"LOCAL_POSITION_NED": [], "GLOBAL_POSITION_INT": [],
                                   "SET_POSITION_TARGET_LOCAL_NED": []}
    try:
        while (msg := log.recv_match(type=list(out))) is not None:
            kind = msg.get_type()
            out[kind].append(msg.relative_alt / 1000.0 if kind == "GLOBAL_POSITION_INT"
                             else -float(msg.z))
    finally:
        log.close()
    return out
