"""Figures of a mission run (dualpilot.viz.mission) on synthetic runs written as records."""

from __future__ import annotations

import json
import struct
from pathlib import Path

import numpy as np
import pytest

from dualpilot.mission.answers import Answer, SystemStatus
from dualpilot.mission.local import local_mission
from dualpilot.mission.params import Controller, MissionParams
from dualpilot.mission.records import write_all
from dualpilot.mission.result import Ending, MissionResult, StepRecord
from dualpilot.model.dynamics import DynamicsParams, hover_state, step
from dualpilot.model.fire import FireParams, FireSnapshot
from dualpilot.model.geometry import Polytope, Rect
from dualpilot.plan import Objective, Plan, Planner, PlanStatus
from dualpilot.spec import MissionSpec
from dualpilot.supervisor.paper.attention import AttentionParams, Logistic, xi
from dualpilot.supervisor.paper.decision import Decision
from dualpilot.viz import mission as plots
from tests.support.missions import config_for

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
ALL_FIGURES = {
    plots.FIG_TRAJECTORY, plots.FIG_ATTENTION, plots.FIG_DIRICHLET, plots.FIG_PSI,
    plots.FIG_PROFILES,
}


class SteerPlanner:
    """Stand-in planner: flies towards G, pushed away from nearby hulls (no guarantees)."""

    method = "steer"

    def __init__(self, system: int, horizon: int, goal: tuple[float, float] = (900.0, 900.0)):
        self.system, self.horizon, self.goal = system, horizon, np.array(goal)
        self.dyn = DynamicsParams()

    def plan(self, state, hulls, objective=Objective.MISSION_TIME, prev_control=None) -> Plan:
        x = np.asarray(state, dtype=float)
        states, controls = [x], []
        speed = 12.0 if self.system == 1 else 9.0
        for _ in range(self.horizon):
            p = x[:2]
            to_goal = self.goal - p
            dist = float(np.linalg.norm(to_goal))
            v_des = to_goal / max(dist, 1.0) * min(speed, dist / 3.0)
            for h in hulls:
                away = p - h.vertices.mean(axis=0)
                gap = h.distance(p)
                if gap < 150.0:
                    v_des += away / max(float(np.linalg.norm(away)), 1.0) * 10.0 * (1 - gap / 150.0)
            u = self.dyn.mass_kg * (v_des - (1 - self.dyn.zeta) * x[2:]) / self.dyn.dt_s
            u = np.clip(u, -self.dyn.u_max_n, self.dyn.u_max_n)
            x = step(x, u, self.dyn)
            states.append(x)
            controls.append(u)
        return Plan(self.system, PlanStatus.OK, np.array(states), np.array(controls), 0.01,
                    objective=objective)


def mission_run(
    out: Path, seed: int = 3, max_steps: int = 40, fire: FireParams = FireParams()
) -> Path:
    planners: dict[int, Planner] = {1: SteerPlanner(1, 25), 2: SteerPlanner(2, 60)}
    config = config_for(MissionSpec(seed=seed), Controller.CC, fire=fire,
                        mission=MissionParams(max_steps=max_steps))
    mission = local_mission(config, planners=planners)
    write_all(mission.run(), out)
    return out


def scripted_run(out: Path, n: int = 12) -> Path:
    """Hand-made records: braked steps with empty plans, d_t inf and nan, one fire."""
    att = AttentionParams()
    region = Rect(500.0, 300.0, 150.0, 120.0)
    hull = Polytope.from_vertices(np.vstack([region.corners(), region.corners() + [60.0, 60.0]]))
    records, psi = [], np.zeros(2)
    for t in range(n):
        pos = np.array([50.0 + 40.0 * t, 50.0 + 35.0 * t])
        d_t = [float("inf"), float("nan"), 120.0][t % 3]
        x = xi(t, 120.0 if not np.isfinite(d_t) else d_t, att)
        a = 1 + t % 3
        psi = 0.5 * psi + (np.array([0.4, -0.4]) if a == 1 else np.array([-0.4, 0.4]))
        system = 0 if t in (4, 5) else int(np.argmax(psi)) + 1
        planned = np.empty((0, 2)) if system == 0 else np.column_stack(
            [pos[0] + np.arange(8) * 30.0, pos[1] + np.arange(8) * 25.0])
        snap = FireSnapshot(regions=(region,), hulls=(hull,)) if t >= 3 else FireSnapshot((), ())
        dec = Decision(t=t, d_t=d_t, xi=x, p=x / x.sum(), attention=a, psi=psi.copy(),
                       system=int(np.argmax(psi)) + 1, objective=Objective.MISSION_TIME)
        records.append(StepRecord(
            t=t, state=hover_state(pos), control=np.zeros(2), decision=dec, system=system,
            answers=(Answer(1, SystemStatus.OK),), planning_time_s=0.1, fire_substeps=1, d_t=d_t,
            fires_active=len(snap.regions), planned_positions=planned, snapshot=snap,
        ))
    result = MissionResult(controller="cc", timing="paper", spec=MissionSpec(),
                           steps=n, records=records, final_state=records[-1].state,
                           ending=Ending.STEP_LIMIT)
    write_all(result, out)
    return out


def png_size(path: Path) -> tuple[int, int]:
    data = path.read_bytes()
    assert data[:8] == PNG_MAGIC, f"{path.name} is not a PNG"
    width, height = struct.unpack(">II", data[16:24])
    return width, height


def check_pngs(paths: list[Path], run_dir: Path) -> None:
    assert {p.name for p in paths} == ALL_FIGURES
    for p in paths:
        assert p.parent == run_dir and p.stat().st_size > 5_000
        w, h = png_size(p)
        assert 600 <= w <= 4000 and 300 <= h <= 3000, (p.name, w, h)


def test_mission_run_writes_every_figure(tmp_path: Path) -> None:
    run = mission_run(tmp_path / "run")
    check_pngs(plots.make_figures(run), run)


def test_one_step_run(tmp_path: Path) -> None:
    run = mission_run(tmp_path / "one", max_steps=1)
    assert len(json.loads((run / "trace.json").read_text())["steps"]) == 1
    check_pngs(plots.make_figures(run), run)


def test_run_without_fires(tmp_path: Path) -> None:
    run = mission_run(tmp_path / "nofire", max_steps=5, fire=FireParams(p_birth=0.0))
    data = plots.load_run(run)
    assert np.all(np.isinf(data.columns["d_t"]))
    check_pngs(plots.make_figures(run), run)


def test_braked_steps_empty_plans_and_nan_distance(tmp_path: Path) -> None:
    run = scripted_run(tmp_path / "scripted")
    data = plots.load_run(run)
    assert list(data.systems[4:6]) == [0, 0]
    assert np.isnan(data.columns["d_t"][1]) and np.isinf(data.columns["d_t"][0])
    check_pngs(plots.make_figures(run, steps=[0, 4, 5, 11]), run)


def test_panel_steps_bad_index_and_missing_files(tmp_path: Path) -> None:
    run = scripted_run(tmp_path / "scripted", n=3)
    with pytest.raises(ValueError, match="outside the run"):
        plots.make_figures(run, steps=[0, 3])
    with pytest.raises(FileNotFoundError, match="is missing: not a mission run"):
        plots.make_figures(tmp_path)


def test_choose_panel_steps_prefers_switches() -> None:
    systems = [2] * 17 + [1] * 21 + [2] * 22  # switches at 17 and 38, as in the paper
    picks = plots.choose_panel_steps(systems)
    assert len(picks) == 6 and picks[0] == 10 and picks[-1] == 59
    assert {17, 38} <= set(picks)
    assert plots.choose_panel_steps([1, 2, 0]) == [0, 1, 2]
    assert plots.switch_steps([1, 0, 1, 2, 0, 2, 1]) == [3, 6]


def test_choose_dirichlet_steps() -> None:
    xi1 = np.ones(60)
    xi1[30] = 9.0
    assert plots.choose_dirichlet_steps(xi1) == [0, 10, 30, 59]
    assert plots.choose_dirichlet_steps([1.0]) == [0]
    assert len(plots.choose_dirichlet_steps(np.ones(8))) == 4


def test_dirichlet_samples_reproducible_on_simplex() -> None:
    a = plots.dirichlet_samples(np.array([1.0, 7.9, 1.2]), t=10)
    b = plots.dirichlet_samples(np.array([1.0, 7.9, 1.2]), t=10)
    assert a.shape == (200, 3) and np.array_equal(a, b)
    np.testing.assert_allclose(a.sum(axis=1), 1.0)
    # vertices of the simplex map to the triangle's corners
    corners = [[0, 0], [1, 0], [0.5, np.sqrt(3) / 2]]
    np.testing.assert_allclose(plots.to_simplex_xy(np.eye(3)), corners)


def test_fig3_curves_equal_eq_ksi(tmp_path: Path) -> None:
    params = AttentionParams()
    fig = plots.figure_attention_profiles(params)
    ax_d, ax_t = fig.axes[:2]
    lines = {
        ln.get_label(): np.asarray(ln.get_xydata(), dtype=float)
        for ax in (ax_d, ax_t)
        for ln in ax.get_lines()
    }
    names = (r"$\xi_1$: response time", r"$\xi_2$: mission time", r"$\xi_3$: energy")
    xi1, xi2, xi3 = (lines[k] for k in names)
    assert xi1[0, 0] == 0.0 and xi1[-1, 0] == 400.0 and xi2[-1, 0] == 80.0
    for d in (0.0, 40.0, 200.0, 400.0):
        (row,) = np.flatnonzero(np.isclose(xi1[:, 0], d))
        assert xi1[row, 1] == pytest.approx(xi(0.0, d, params)[0])
    for t in (0.0, 10.0, 40.0, 80.0):
        (row,) = np.flatnonzero(np.isclose(xi2[:, 0], t))
        ref = xi(t, float("inf"), params)
        assert xi2[row, 1] == pytest.approx(ref[1]) and xi3[row, 1] == pytest.approx(ref[2])
    # by hand from Eq. (KSI): ξ3(10) = 7 / (1 + 10) + 1, ξ2(10) = 7 − 7/11 + 1
    (row,) = np.flatnonzero(np.isclose(xi3[:, 0], 10.0))
    assert xi3[row, 1] == pytest.approx(7 / 11 + 1) and xi2[row, 1] == pytest.approx(8 - 7 / 11)
    # a different parameter set changes the curve, and the file is written
    other = AttentionParams(response=Logistic(a=20.0, b=0.05, c=5.0, d=2.0))
    prof = plots.attention_profiles(other)
    assert prof["xi1"][0] == pytest.approx(xi(0.0, 0.0, other)[0])
    path = plots.plot_attention_profiles(tmp_path / "fig3.png", other)
    assert png_size(path)[0] >= 600
