"""The stack and the in-process loop run the one mission step: identical step records.

Every mission below is flown twice: through the stack (a shared router, EWS and
planner pair; a uavsim and a supervisor per vehicle, unpaced) and in-process
(dualpilot.mission.local). The records must agree step for step over the
whole mission: the decision (Ξ, P, A, Ψ, S), the system flown, the plan
statuses, the fire sub-steps, the planned positions, the state and control,
and the outcome. Numbers that crossed MAVLink (float32 positions and
setpoints) are compared to 1e-3; everything discrete exactly. The in-process
twin is worked out in a thread of the test process while the stack flies
(:func:`fly`): from the start when it needs nothing of the stack's run, else as
soon as that run's mission has ended.

With ``timing="measured"`` a step's fire sub-steps are ⌈T_s / 0.5 s⌉ of the
planners' measured compute times, which differ between two runs (a loaded
machine makes one plan take longer on one side only). The in-process reference
therefore replays the stack's measured compute times (:class:`ReplayedTimes`):
the k-th answer of each system carries the stack's k-th recorded compute time,
so both sides fly the same timing and any difference is a defect.

The vehicle measures its state in float32 (LOCAL_POSITION_NED) and flies
float32 setpoints with its own tracking controller, so the stack's states are
the in-process ones to about one float32 step (4e-6 m at 50 m). On physics
fires System 2's fast planner meets near-ties between homotopies that this
one step decides (``s2+risk`` on grass-15 seed 0 flies another plan at step 32
for it). Those missions are therefore compared given the same measurements:
the in-process twin's vehicle (:class:`ReplayedStates`) checks each state the
stack's vehicle measured against Eq. (1) from the previous one and the
commanded control (to ``ATOL``) and then observes that measurement, as
:class:`ReplayedTimes` replays measured compute times.
"""

from __future__ import annotations

import contextlib
import json
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from dualpilot.mission.config import MissionConfig
from dualpilot.mission.local import LocalVehicle, local_mission
from dualpilot.mission.params import Timing
from dualpilot.mission.ports import PlannerPort, PlanRequest
from dualpilot.mission.records import read_step_log, result_from_log
from dualpilot.mission.result import MissionResult
from dualpilot.mission.step import Mission
from dualpilot.plan import Plan
from services import launch
from tests.support.fleet import FleetRun, fly_fleet
from tests.support.waits import check

pytestmark = [pytest.mark.slow, pytest.mark.timeout(600)]

SEEDS = (0, 1, 2, 3, 4)
#: numbers that crossed MAVLink as float32 (m, m/s, N)
ATOL = 1e-3


def assert_same_mission(stack: MissionResult, local: MissionResult, what: str,
                        atol: float = ATOL) -> None:
    assert (stack.success, stack.failure_cause, stack.steps) == (
        local.success, local.failure_cause, local.steps), what
    assert len(stack.records) == len(local.records), what
    for a, b in zip(stack.records, local.records, strict=True):
        where = f"{what}, step {b.t}"
        assert (a.t, a.system, a.plan_status, a.fire_substeps, a.fires_active) == (
            b.t, b.system, b.plan_status, b.fire_substeps, b.fires_active), where
        da, db = a.decision, b.decision
        assert (da.attention, da.system, da.objective) == (db.attention, db.system,
                                                           db.objective), where
        for name in ("xi", "p", "psi"):
            assert np.allclose(getattr(da, name), getattr(db, name), atol=atol), (where, name)
        assert np.allclose(a.state, b.state, atol=atol), (where, a.state, b.state)
        assert np.allclose(a.control, b.control, atol=atol), (where, a.control, b.control)
        assert a.planned_positions.shape == b.planned_positions.shape, where
        assert np.allclose(a.planned_positions, b.planned_positions,
                           atol=max(1e-2, atol)), where
    bound = energy_bound(stack, local)
    assert abs(stack.energy - local.energy) <= bound + 1e-9, (what, stack.energy, local.energy,
                                                             bound)


def energy_bound(a: MissionResult, b: MissionResult) -> float:
    """How far apart the energies Σ‖Δu_t‖² of two runs can be given their controls (N²):
    |‖x‖² − ‖y‖²| ≤ (‖x‖ + ‖y‖)·‖x − y‖ for each step's Δu (the controls differ by the
    float32 the state crossed MAVLink in, asserted per step to ATOL)."""
    ua = np.vstack([np.zeros(2)] + [r.control for r in a.records])
    ub = np.vstack([np.zeros(2)] + [r.control for r in b.records])
    da, db = np.diff(ua, axis=0), np.diff(ub, axis=0)
    return float(np.sum((np.linalg.norm(da, axis=1) + np.linalg.norm(db, axis=1))
                        * np.linalg.norm(da - db, axis=1)))


#: seed, controller ("concurrent": cc with the concurrent supervisor), timing, ignition
#: clearance, and optionally the fire scenario
Run = tuple[Any, ...]


class ReplayedTimes:
    """A planner port whose answers carry the compute times another run recorded.

    ``times`` is a stack's ``summary.json`` ``planning_time_s``: every answer's
    compute time, per system in the order the mission core recorded them
    (dualpilot/mission/step.py ``record_time``, once per answer of :meth:`plan`
    and once per :meth:`collect` of a launched request). The k-th answer of
    system s here gets the k-th time of s — at :meth:`collect`, not
    :meth:`launch`, for a deliberation the concurrent supervisor drops
    uncollected records no time on either side. Everything else is the wrapped
    port's.
    """

    def __init__(self, inner: PlannerPort, times: dict[str, list[float]], what: str):
        self.inner, self.what = inner, what
        self.times = {int(k.removeprefix("s")): list(v) for k, v in times.items()}
        self.used = dict.fromkeys(self.times, 0)

    def _timed(self, plan: Plan) -> Plan:
        s = plan.system
        k = self.used.get(s, 0)
        recorded = self.times.get(s, [])
        check(k < len(recorded), f"{self.what}: the in-process mission asks System {s} for "
              f"answer {k + 1} but the stack recorded {len(recorded)}: the missions differ")
        self.used[s] = k + 1
        return replace(plan, compute_time_s=recorded[k])

    def available(self, system: int) -> bool:
        return self.inner.available(system)

    def uses_forecast(self, system: int) -> bool:
        return bool(getattr(self.inner, "uses_forecast", lambda _s: False)(system))

    def plan(self, request: PlanRequest) -> Plan:
        return self._timed(self.inner.plan(request))

    def launch(self, request: PlanRequest) -> object:
        return self.inner.launch(request)

    def collect(self, ticket: object) -> Plan:
        return self._timed(self.inner.collect(ticket))

    def unused(self) -> dict[int, int]:
        """Recorded times no in-process answer took, per system (none when the runs agree)."""
        return {s: len(v) - self.used[s] for s, v in self.times.items() if len(v) > self.used[s]}


class ReplayedStates:
    """A vehicle port that flies Eq. (1) and then observes the state another run measured.

    ``states`` are the stack's measured states: step 0's, every later step's and
    the final one. Each :meth:`observe` predicts the next state with the wrapped
    in-process vehicle (Eq. 1 from the previous measured state and the
    commanded control), fails unless the measurement lies within ``ATOL`` of it,
    and returns the measurement.
    """

    def __init__(self, inner: LocalVehicle, states: Sequence[np.ndarray], what: str):
        self.inner, self.states, self.what = inner, list(states), what
        self.k = 0

    def command(self, target: np.ndarray, control: np.ndarray, after_s: float) -> None:
        self.inner.command(target, control, after_s)

    def observe(self) -> np.ndarray:
        predicted = self.inner.observe()
        self.k += 1
        check(self.k < len(self.states), f"{self.what}: the in-process mission flies step "
              f"{self.k} but the stack measured {len(self.states)} states: the missions differ")
        measured = np.asarray(self.states[self.k], dtype=float)
        check(np.allclose(predicted, measured, atol=ATOL), f"{self.what}: the vehicle's "
              f"measured state {self.k} to be Eq. (1)'s within {ATOL} m, m/s", None,
              (predicted, measured))
        self.inner.state = measured.copy()
        return measured.copy()


def measured_states(run_dir: Path) -> list[np.ndarray]:
    """The states the stack's vehicle measured: every step's and the final one."""
    result = result_from_log(read_step_log(run_dir / "steps.jsonl"))
    check(result.final_state is not None, f"{run_dir}: a final state in steps.jsonl")
    return [r.state for r in result.records] + [np.asarray(result.final_state)]


def recorded_times(run_dir: Path) -> dict[str, list[float]]:
    """The stack's compute time of every answer, per system (summary.json planning_time_s)."""
    summary = json.loads((run_dir / "summary.json").read_text())
    times: dict[str, list[float]] = summary["planning_time_s"]
    return times


def replayed(mission: Mission, run_dir: Path, what: str) -> MissionResult:
    """Run the in-process ``mission`` with the compute times the stack recorded in ``run_dir``;
    fails, saying so, when the stack recorded answers the in-process mission never asked."""
    port = ReplayedTimes(mission.planners, recorded_times(run_dir), what)
    mission.planners = port
    result = mission.run()
    check(not port.unused(), f"{what}: the stack recorded answers the in-process mission did "
          f"not ask for (per system: how many): the missions differ", None, port.unused())
    return result


#: the in-process twin of a run flown through the stack, given the run and its run directory
Reference = Callable[[Run, Path], MissionResult]


@dataclass
class Flown:
    """A run flown through the stack: its run directory, its records as a result, and the
    in-process twin :func:`fly` was asked to work out (None if it was not)."""

    run_dir: Path
    result: MissionResult
    reference: MissionResult | None = None


def fly(fleet: launch.Fleet, runs: Sequence[Run], out: Path,
        reference: Reference | None = None, from_records: bool = True) -> dict[Run, Flown]:
    """Fly ``runs`` (seed, controller, timing, ignition clearance) at once, one vehicle each;
    per run its run directory, its records as a result and, with ``reference``, its
    in-process twin, worked out in a thread of this process while the stack flies: each once
    its mission has ended and its records are written (``from_records``: the twin replays
    them), else all from the start."""
    dirs = [out / "-".join(str(v) for v in (run[1], run[2], f"s{run[0]}", f"ic{run[3]}",
                                            *run[4:])) for run in runs]
    fleet_runs = [FleetRun(f"the mission {run}", run[0], run_dir, {"SPEED_FACTOR": "0"},
                           config_of(*run)) for run, run_dir in zip(runs, dirs, strict=True)]
    with ThreadPoolExecutor(max_workers=1, thread_name_prefix="in-process") as pool:
        twins: dict[int, Future[MissionResult]] = {}

        def work_out(k: int) -> None:
            if reference is not None and k not in twins:
                twins[k] = pool.submit(reference, runs[k], dirs[k])

        flown = fly_fleet(fleet, fleet_runs, on_start=None if from_records else work_out,
                          on_end=work_out)
        results = {run: Flown(run_dir, result_from_log(read_step_log(run_dir / "steps.jsonl")))
                   for run, run_dir in zip(runs, flown, strict=True)}
        for k, run in enumerate(runs):
            twin = twins.get(k)
            results[run].reference = twin.result() if twin is not None else None
    return results


def twin_of(flown: Flown) -> MissionResult:
    """The in-process twin :func:`fly` worked out for a run."""
    assert flown.reference is not None, "fly was given no reference"
    return flown.reference


def config_of(seed: int, controller: str, timing: str, clear: float | None,
              scenario: str = "") -> MissionConfig:
    """The configuration of a run: the same one flies through the stack and in-process."""
    settings: list[tuple[str, object]] = []
    if clear is not None:
        settings.append(("ignition_clearance_m", clear))
    if scenario:
        settings.append(("scenario", scenario))
    return MissionConfig.named(controller, seed=seed, timing=Timing(timing),
                               settings=tuple(settings))


def in_process(run: Run, replay: Path | None = None, states: bool = False) -> MissionResult:
    """The in-process mission of ``run`` (seed, controller, timing, clearance[, scenario]);
    with ``replay`` (a stack's run directory) and measured timing, flown with the compute
    times that run recorded (:class:`ReplayedTimes`); with ``states`` too, observing the
    states that run's vehicle measured (:class:`ReplayedStates`)."""
    seed, controller, timing, clear, *scenario = run
    mission = local_mission(config_of(seed, controller, timing, clear, *scenario))
    if replay is not None and states:
        vehicle = mission.vehicle
        assert isinstance(vehicle, LocalVehicle)
        mission.vehicle = ReplayedStates(vehicle, measured_states(replay), str(run))
    if replay is not None and Timing(timing) is Timing.MEASURED:
        return replayed(mission, replay, f"{controller} {timing} seed {seed}")
    return mission.run()


@contextlib.contextmanager
def unpaced_fleet(tmp_path_factory: pytest.TempPathFactory, name: str, prefix: str,
                  vehicles: int) -> Iterator[tuple[launch.Fleet, Path]]:
    """A shared router, EWS and planner pair, unpaced, for ``vehicles`` vehicle ids
    ``<prefix>0…``; yields the fleet and its output directory."""
    out = tmp_path_factory.mktemp(name)
    cfg = launch.StackConfig(run_dir=out / "shared", speed_factor=0.0, free_ports=True,
                             log_format="text")
    with launch.Fleet(cfg, [f"{prefix}{k}" for k in range(vehicles)]) as f:
        yield f, out


@pytest.fixture(scope="module")
def fleet(tmp_path_factory: pytest.TempPathFactory) -> Any:
    with unpaced_fleet(tmp_path_factory, "lockstep", "ls", len(SEEDS)) as f:
        yield f


@pytest.mark.parametrize("timing", ["paper", "measured"])
@pytest.mark.parametrize("controller", ["cc", "s1", "s2", "concurrent"])
def test_stack_and_in_process_records_are_identical(fleet: Any, controller: str,
                                                    timing: str) -> None:
    f, out = fleet
    runs = [(seed, controller, timing, None) for seed in SEEDS]
    # paper timing: the in-process mission is the run's alone; measured: it replays the stack's
    flown = fly(f, runs, out, lambda run, run_dir: in_process(run, replay=run_dir),
                from_records=timing == "measured")
    for run, got in flown.items():
        assert_same_mission(got.result, twin_of(got), str(run))


def replaying_states(run: Run, run_dir: Path) -> MissionResult:
    """The in-process twin of ``run`` given the states its stack run's vehicle measured."""
    return in_process(run, run_dir, states=True)


def forecasts_in(run_dir: Path) -> tuple[int, int]:
    """(forecasts received, forecast_stale faults) of a stack run (summary.json)."""
    stack = json.loads((run_dir / "summary.json").read_text())["stack"]
    return int(stack["forecast"].get("received", 0)), int(stack["faults"].get("forecast_stale",
                                                                              0))


@pytest.mark.parametrize("scenario", ["grass-15", "shrub"])
@pytest.mark.parametrize("controller", ["s2+risk", "s1+risk", "concurrent+risk"])
def test_risk_aware_controllers_fly_the_in_process_mission_through_the_stack(
        fleet: Any, controller: str, scenario: str) -> None:
    """fast+risk, rrt+risk and the concurrent supervisor with forecast threats on physics
    fires: the forecast the EWS makes for each step's fire state crosses the wire to the
    supervisor and in every risk-aware plan request, and each whole mission is the
    in-process one given the vehicle's measurements (:class:`ReplayedStates`), step for
    step."""
    f, out = fleet
    runs = [(seed, controller, "paper", None, scenario) for seed in SEEDS[:3]]
    for run, got in fly(f, runs, out, replaying_states).items():
        received, stale = forecasts_in(got.run_dir)
        assert received > 0 and stale == 0, (run, received, stale)
        assert_same_mission(got.result, twin_of(got), str(run))


def test_a_fleet_of_five_with_mixed_controllers_on_shrub(fleet: Any) -> None:
    """Five vehicles at once on shrub fires, each its own controller (risk-aware or not) and
    fire process on the shared EWS and planners: each mission is its in-process twin given
    its vehicle's measurements."""
    f, out = fleet
    names = ("concurrent+risk", "s1+risk", "cc", "s2+risk", "cc+risk")
    runs = [(seed, name, "paper", None, "shrub") for seed, name in zip(SEEDS, names,
                                                                      strict=True)]
    for run, got in fly(f, runs, out, replaying_states).items():
        received, stale = forecasts_in(got.run_dir)
        assert stale == 0 and (received > 0) == run[1].endswith("+risk"), (run, received)
        assert_same_mission(got.result, twin_of(got), str(run))


def test_the_ignition_clearance_reaches_the_stack(fleet: Any) -> None:
    """--ignition-clearance through the stack: the EWS keeps new fronts 20 m off the UAV, and
    the missions are those of the in-process loop with the same reading."""
    f, out = fleet
    runs = [(seed, "cc", "paper", 20.0) for seed in SEEDS[:3]]
    flown = fly(f, runs, out, lambda run, _: in_process(run), from_records=False)
    results = {run: got.result for run, got in flown.items()}
    for run, got in flown.items():
        assert_same_mission(got.result, twin_of(got), str(run))
    # the reading matters: without it, some of these missions differ
    plain = [in_process((seed, "cc", "paper", None)) for seed, *_ in runs]
    assert [r.steps for r in plain] != [results[run].steps for run in runs]


def fly_cc_on_stack(fleet: Any, seeds: tuple[int, ...], env: dict[str, str], tag: str
                    ) -> list[tuple[int, Path, MissionResult]]:
    """CC missions of ``seeds`` with paper timing on the stack, ``env`` added to the
    supervisor's and uavsim's settings: (seed, run directory, the records as a result)."""
    f, out = fleet
    base = {"CONTROLLER": "cc", "TIMING": "paper", "SPEED_FACTOR": "0",
            "IGNITION_CLEARANCE_M": "", "SUPERVISOR": "paper"}
    runs = [FleetRun(f"the {tag} mission of seed {seed}", seed, out / f"{tag}-s{seed}",
                     {**base, **env}) for seed in seeds]
    return [(seed, run_dir, result_from_log(read_step_log(run_dir / "steps.jsonl")))
            for seed, run_dir in zip(seeds, fly_fleet(f, runs), strict=True)]


@pytest.mark.parametrize("profile", ["literal", "fig-r5"])
def test_a_profile_given_to_the_supervisor_alone_reaches_the_ews(fleet: Any,
                                                                 profile: str) -> None:
    """The shared EWS runs its default reading; the supervisor's profile (its
    READINGS_PROFILE) travels in every FireReset, so the missions are the in-process ones
    under that profile."""
    env = {"READINGS_PROFILE": profile}
    for seed, _, stack in fly_cc_on_stack(fleet, SEEDS[:3], env, f"profile-{profile}"):
        local = local_mission(MissionConfig(seed=seed, profile=profile)).run()
        assert_same_mission(stack, local, f"{profile} seed {seed}",
                            ATOL)


def test_the_speed_limit_reaches_system1_system2_and_uavsim(fleet: Any) -> None:
    """SPEED_LIMIT=norm (|v| ≤ 15 m/s) on the supervisor and uavsim of today's profile: the
    spec carries it to the planner services, and every step is the in-process loop's under
    the same reading. A place still clipping per axis would fly faster on the diagonal."""
    env = {"READINGS_PROFILE": "today", "SPEED_LIMIT": "norm"}
    for seed, run_dir, stack in fly_cc_on_stack(fleet, SEEDS[:2], env, "speed-norm"):
        uavsim_log = run_dir / "logs" / "uavsim.log"
        check("speed_limit=norm" in uavsim_log.read_text(), "uavsim to log speed_limit=norm",
              [uavsim_log])
        local = local_mission(MissionConfig(seed=seed, settings=(("speed_limit", "norm"),))).run()
        assert_same_mission(stack, local, f"norm seed {seed}", ATOL)
        systems = {r.system for r in stack.records}
        assert {1, 2} <= systems, systems  # both planners flew under the reading
        speeds = [float(np.hypot(*r.state[2:])) for r in stack.records]
        assert max(speeds) <= 15.0 + ATOL
        axis = local_mission(MissionConfig(seed=seed)).run()
        assert max(float(np.hypot(*r.state[2:])) for r in axis.records) > 15.5
