"""Every reading a parameter, the named profiles and the defects fixed."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from dualpilot.mission.local import local_mission
from dualpilot.mission.params import Controller, MissionParams
from dualpilot.mission.step import attention_distance, counted_regions
from dualpilot.model.dynamics import DynamicsParams
from dualpilot.model.fire import FireParams, FireSnapshot
from dualpilot.model.fire_field import FireField
from dualpilot.model.geometry import Rect
from dualpilot.readings import PROFILES, READINGS, get_profile, parse_settings, parse_value
from dualpilot.spec import MissionSpec
from dualpilot.supervisor.paper.decision import DecisionDynamics, SupervisorParams
from tests.support.missions import config_for

QUIET = FireParams(p_birth=0.0, p_survive=1.0)


# -- the fire process's readings --------------------------------------------------------------
def test_life_per_time_step_draws_birth_and_survival_once_per_step() -> None:
    field = FireField(params=FireParams(p_birth=1.0, p_survive=1.0, life_base="step"))
    rng = np.random.default_rng(0)
    for t in range(3):
        for _ in range(10):  # System 2's ten sub-steps of one step
            field.substep(rng, t)
    assert len(field.fronts) == 3 and [f.born_step for f in field.fronts] == [0, 1, 2]
    per_substep = FireField(params=FireParams(p_birth=1.0, p_survive=1.0))
    for _ in range(10):
        per_substep.substep(rng, 0)
    assert len(per_substep.fronts) == 10


@pytest.mark.parametrize(("extent", "changes"), [("substep", 9), ("step", 2), ("birth", 0)])
def test_extent_is_drawn_when_the_reading_says(extent: str, changes: int) -> None:
    field = FireField(params=replace(QUIET, extent=extent))  # type: ignore[arg-type]
    rng = np.random.default_rng(1)
    field.spawn(rng, 0, center=(500.0, 500.0))
    sides = []
    for t, n in ((0, 4), (1, 3), (2, 3)):  # the birth step, then two new steps
        for _ in range(n):
            field.substep(rng, t)
            r = field.fronts[0].region
            sides.append((r.width, r.height))
    assert sum(a != b for a, b in zip(sides, sides[1:], strict=False)) == changes


def test_default_fire_process_is_todays() -> None:
    """FireParams() draws exactly as before the readings existed (per sub-step life and extent)."""
    rng_a, rng_b = np.random.default_rng(5), np.random.default_rng(5)
    field = FireField()
    explicit = FireField(params=FireParams(life_base="substep", extent="substep"))
    for k in range(60):
        field.substep(rng_a, k // 10)
        explicit.substep(rng_b, k // 10)
    assert field.snapshot().regions == explicit.snapshot().regions and field.next_id > 0


def test_redraws_keep_the_ignition_clearance_when_asked() -> None:
    """Defect: the clearance held only at birth; a redraw 0.5 s later could cover the UAV."""
    uav = np.array([500.0, 500.0])
    keep = (uav, 20.0)

    def worst(redraw_clearance: bool) -> tuple[float, int]:
        params = replace(QUIET, redraw_clearance=redraw_clearance, speed_sigma_mps=0.0,
                         speed_mean_mps=0.0)
        field = FireField(params=params)
        rng = np.random.default_rng(2)
        field.spawn(rng, 0, center=(500.0, 600.0), keep_out=keep)  # 100 m north, clear
        d = []
        for k in range(200):
            field.substep(rng, k, keep_out=keep)
            d.append(field.fronts[0].region.distance(uav))
        return min(d), field.redraws_unclear

    birth_only, _ = worst(False)
    assert birth_only < 20.0, "today's reading: a redraw comes within the clearance"
    clear, unclear = worst(True)
    assert clear >= 20.0 and unclear == 0


def test_a_front_that_moved_onto_the_uav_keeps_its_sides_and_is_counted() -> None:
    params = replace(QUIET, redraw_clearance=True)
    field = FireField(params=params)
    rng = np.random.default_rng(3)
    front = field.spawn(rng, 0, center=(500.0, 500.0))
    field.substep(rng, 0, keep_out=(np.array([500.0, 500.0]), 20.0))
    assert field.redraws_unclear == 1
    r = field.fronts[0].region
    assert (r.width, r.height) == (front.region.width, front.region.height)


def test_a_birth_no_draw_can_keep_clear_is_skipped_and_counted() -> None:
    """Defect: after 1000 failing draws the last one was kept, on top of the UAV."""
    field = FireField(params=FireParams(p_birth=1.0))
    keep = (np.array([500.0, 500.0]), 5000.0)
    born = field.substep(np.random.default_rng(0), 0, keep_out=keep)
    assert born == [] and field.fronts == [] and field.births_skipped == 1
    with pytest.raises(ValueError, match="draws"):
        field.spawn(np.random.default_rng(0), 0, keep_out=keep)


# -- d_t and the failure rule -----------------------------------------------------------------
def _snap(born: tuple[int, ...]) -> FireSnapshot:
    regions = tuple(Rect(100.0 + 300 * k, 100.0, 100.0, 100.0) for k in range(len(born)))
    return FireSnapshot(regions=regions, hulls=tuple(r.polytope() for r in regions),
                        front_ids=tuple(range(len(born))), born_steps=born)


def test_newborn_d_t_sees_the_fronts_born_during_the_last_wait() -> None:
    """Defect: fronts born during step t's wait carry born_step t; step t+1 looked for t+1."""
    snap = _snap((4, 3))
    params = MissionParams(d_t_reading="newborn")
    pos = np.array([100.0, 300.0])
    assert attention_distance(pos, snap, 5, params) == pytest.approx(150.0)
    assert attention_distance(pos, snap, 4, params) == pytest.approx(
        np.hypot(250.0, 150.0))  # the front at x = 400 born during step 3
    assert attention_distance(pos, snap, 7, params) == float("inf")


def test_newborn_d_t_is_finite_in_a_whole_mission() -> None:
    """Seed 26 of the issue: d_t was inf on every step."""
    mission = local_mission(config_for(MissionSpec(seed=26), Controller.S1,
                                       mission=MissionParams(d_t_reading="newborn",
                                                             max_steps=40)))
    d = [r.d_t for r in mission.run().records]
    assert any(np.isfinite(v) for v in d)


def test_hull_d_t_is_the_nearest_hull() -> None:
    snap = _snap((0,))
    pos = np.array([100.0, 300.0])
    assert attention_distance(pos, snap, 1, MissionParams(d_t_reading="hull")) == (
        pytest.approx(150.0))


def test_failure_rules_choose_the_regions_that_count() -> None:
    snap = _snap((2, 3))
    any_ = counted_regions(snap, 3, MissionParams(), 20.0, {})
    assert any_ == snap.regions
    assert counted_regions(snap, 3, MissionParams(failure_rule="newborn"), 20.0, {}) == (
        snap.regions[1],)
    # become: only fronts that were clear (>= d_safe) at the previous check
    become = MissionParams(failure_rule="become")
    assert counted_regions(snap, 3, become, 20.0, {0: 5.0, 1: 30.0}) == (snap.regions[1],)
    assert counted_regions(snap, 3, become, 20.0, {}) == ()


def test_become_spares_a_front_born_on_the_uav_until_it_has_been_clear() -> None:
    """The mission goes on under "become" where "any" ends it at the ignition."""
    spec = MissionSpec(seed=0)
    fire = FireParams(p_birth=1.0)

    def run(rule: str) -> tuple[bool, str, int]:
        m = local_mission(config_for(spec, Controller.S1, fire=fire, mission=MissionParams(
            failure_rule=rule, max_steps=3)))  # type: ignore[arg-type]
        r = m.run()
        return r.success, r.failure_cause, r.steps

    _, cause_any, steps_any = run("any")
    _, cause_become, steps_become = run("become")
    assert steps_become >= steps_any
    assert cause_become in ("step_limit", "fire_while_planning", "fire_contact", "")
    assert cause_any in ("fire_while_planning", "fire_contact", "step_limit")


def test_bad_readings_are_refused() -> None:
    with pytest.raises(ValueError, match="life_base"):
        FireParams(life_base="hour")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="failure_rule"):
        MissionParams(failure_rule="never")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="attention_draw"):
        SupervisorParams(attention_draw="vote")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="speed_limit"):
        DynamicsParams(speed_limit="box")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="one of"):
        parse_value("speed_limit", "box")


# -- the attention draw -----------------------------------------------------------------------
def test_argmax_attention_is_deterministic_and_leaves_the_stream() -> None:
    rng = np.random.default_rng(0)
    sup = DecisionDynamics(rng, SupervisorParams(attention_draw="argmax"))
    d = sup.decide(0, float("inf"))
    assert d.attention == int(np.argmax(d.xi)) + 1
    assert d.p == pytest.approx(d.xi / d.xi.sum())
    assert rng.random() == np.random.default_rng(0).random()


def test_sampled_attention_is_unchanged_by_default() -> None:
    a = DecisionDynamics(np.random.default_rng(4)).decide(3, 50.0)
    b = DecisionDynamics(np.random.default_rng(4),
                         SupervisorParams(attention_draw="sample")).decide(3, 50.0)
    assert a.attention == b.attention and np.array_equal(a.p, b.p)


# -- profiles ---------------------------------------------------------------------------------
def test_profiles_are_complete_and_documented() -> None:
    assert {"today", "literal", "fig-r5"} <= set(PROFILES)
    today = get_profile("today")
    assert today.fire == FireParams() and today.mission == MissionParams()
    assert today.supervisor == SupervisorParams()
    for p in PROFILES.values():
        assert set(p.readings()) == set(READINGS)
        assert p.summary and p.sources and all("'" in s or "→" in s for s in p.sources)
    fig = get_profile("fig-r5")
    assert (fig.fire.life_base, fig.fire.extent, fig.mission.ignition_clearance_m) == (
        "step", "birth", 20.0)
    lit = get_profile("literal")
    assert lit.mission.ignition_clearance_m is None and lit.fire.life_base == "step"
    with pytest.raises(ValueError, match="unknown profile"):
        get_profile("nope")


def test_settings_are_parsed_by_the_field_type() -> None:
    p = get_profile("fig-r5").with_settings(parse_settings(
        ["ignition_clearance_m=none", "redraw_clearance=true", "p_birth=0.2", "max_steps=9",
         "attention_draw=argmax", "extent=step"]))
    assert p.mission.ignition_clearance_m is None and p.fire.redraw_clearance is True
    assert p.fire.p_birth == 0.2 and p.mission.max_steps == 9 and p.fire.extent == "step"
    assert p.supervisor.attention_draw == "argmax"
    with pytest.raises(ValueError, match="unknown parameter"):
        parse_settings(["warp=9"])
    with pytest.raises(ValueError, match="one of"):
        parse_value("d_t_reading", "closest")


def test_the_speed_limit_is_a_reading_of_the_profiles() -> None:
    """Sec. IV-A "a maximum velocity of 15m/s": literal bounds |v|, today and fig-r5 per axis."""
    assert "speed_limit" in READINGS
    assert get_profile("today").dynamics == DynamicsParams()
    assert get_profile("fig-r5").dynamics.speed_limit == "axis"
    lit = get_profile("literal")
    assert lit.dynamics == DynamicsParams(speed_limit="norm")
    assert lit.readings()["speed_limit"] == "norm"
    assert any("maximum velocity of 15m/s" in s for s in lit.sources)
    norm = get_profile("today").with_settings(parse_settings(["speed_limit=norm"]))
    assert norm.dynamics.speed_limit == "norm" and norm.mission == MissionParams()
    spec = MissionSpec(seed=3)
    assert norm.spec(spec) == replace(spec, dynamics=DynamicsParams(speed_limit="norm"))
    assert get_profile("today").spec(spec) is spec


def test_the_speed_limit_reaches_mission_and_evaluate(tmp_path, capsys) -> None:  # type: ignore
    """--set speed_limit=norm on ``mission`` and ``evaluate``: the flown speeds stay ≤ 15 m/s,
    while the default flies faster on the diagonal (S2, 12 steps from (50, 50))."""
    from dualpilot.cli import main
    from dualpilot.mission.records import read_steps_csv

    speeds = {}
    for sl in ("axis", "norm"):
        out = tmp_path / sl
        assert main(["mission", "--controller", "s2", "--seed", "1", "--quiet", "--out",
                     str(out), "--no-figures", "--set", "max_steps=12",
                     "--set", f"speed_limit={sl}"]) == 0
        steps = read_steps_csv(out / "steps.csv")
        speeds[sl] = float(np.max(np.hypot(steps["vx"], steps["vy"])))
    assert speeds["norm"] <= 15.0 + 1e-6 < speeds["axis"]
    argv = ["evaluate", "--missions", "1", "--jobs", "1", "--controllers", "s2",
            "--set", "max_steps=3", "--set", "speed_limit=norm", "--out", str(tmp_path / "e")]
    assert main(argv) == 0
    summary = json.loads((tmp_path / "e" / "summary.json").read_text())
    assert summary["readings"]["speed_limit"] == "norm"
    capsys.readouterr()
    assert main(["profiles"]) == 0
    assert "speed_limit" in capsys.readouterr().out


def test_profiles_command_lists_the_values(capsys: pytest.CaptureFixture[str]) -> None:
    from dualpilot.cli import main

    assert main(["profiles"]) == 0
    out = capsys.readouterr().out
    for name in PROFILES:
        assert name in out
    assert "life_base" in out and "ignition_clearance_m" in out and "Sec. IV" in out


def test_every_reading_reaches_evaluate_from_the_command_line(tmp_path) -> None:  # type: ignore
    """Defect: evaluate passed only the ignition clearance."""
    from dualpilot.cli import main

    out = tmp_path / "e"
    argv = ["evaluate", "--missions", "1", "--jobs", "1", "--controllers", "s1",
            "--profile", "literal", "--set", "max_steps=3", "--set", "attention_draw=argmax",
            "--set", "redraw_clearance=true", "--out", str(out)]
    assert main(argv) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["profile"] == "literal"
    r = summary["readings"]
    assert (r["life_base"], r["failure_rule"], r["attention_draw"], r["redraw_clearance"]) == (
        "step", "become", "argmax", True)
