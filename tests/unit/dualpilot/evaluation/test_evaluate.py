"""The Monte-Carlo runner: files, resume, error rows, identical configurations."""

import csv
import json

import pytest

from dualpilot.evaluation.evaluate import evaluate
from dualpilot.evaluation.missions import mission_spec
from dualpilot.evaluation.stats import mean_interval, wilson_interval
from dualpilot.mission.config import MissionConfig
from dualpilot.mission.params import Timing
from dualpilot.viz.evaluation import plot_fig_r5

SEED3 = MissionConfig(seed=3)


def rows(path):
    with (path / "results.csv").open() as fh:
        return list(csv.DictReader(fh))


@pytest.fixture(scope="module")
def small_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("eval")
    summary = evaluate(2, out, SEED3, jobs=2, progress=False, figure=plot_fig_r5)
    return out, summary


def test_files_and_summary(small_run):
    out, summary = small_run
    assert (out / "fig_r5.png").stat().st_size > 5000
    on_disk = json.loads((out / "summary.json").read_text())
    assert on_disk["missions"] == 2 and on_disk["timing"] == "paper"
    for c in ("cc", "s1", "s2"):
        ctrl = on_disk["controllers"][c]
        assert ctrl["n"] == 2
        for key in ("success_rate", "mission_time_s_mean", "energy_mean", "planning_time_s_median"):
            assert key in ctrl
    assert len(rows(out)) == 6


def test_three_controllers_see_identical_configurations(small_run):
    out, _ = small_run
    by_mission: dict[str, set[tuple[str, ...]]] = {}
    for r in rows(out):
        key = (r["seed"], r["start_x"], r["start_y"], r["goal_x"], r["goal_y"])
        by_mission.setdefault(r["mission"], set()).add(key)
    assert all(len(v) == 1 for v in by_mission.values())
    cfg = mission_spec(3, 0)
    r0 = next(r for r in rows(out) if r["mission"] == "0")
    assert float(r0["start_x"]) == pytest.approx(cfg.start[0])


def test_rerun_skips_recorded_missions(small_run):
    out, _ = small_run
    before = rows(out)
    evaluate(2, out, SEED3, jobs=1, progress=False)
    assert rows(out) == before
    evaluate(3, out, SEED3, jobs=1, controllers=["s1"], progress=False)
    after = rows(out)
    assert len(after) == 7 and after[:6] == before and after[6]["mission"] == "2"


def test_a_mission_that_raises_becomes_an_error_row(tmp_path):
    evaluate(
        1,
        tmp_path,
        MissionConfig(seed=1, system2_method="no-such-method"),
        jobs=1,
        controllers=["s2"],
        progress=False,
    )
    (row,) = rows(tmp_path)
    assert row["failure_cause"] == "error" and "no-such-method" in row["error"]
    assert row["success"] == "0"


def test_timing_mismatch_is_refused(small_run):
    out, _ = small_run
    with pytest.raises(ValueError, match="timing"):
        evaluate(2, out, MissionConfig(seed=3, timing=Timing.MEASURED), jobs=1, progress=False)


def test_intervals_by_hand():
    lo, hi = wilson_interval(8, 10)
    # Wilson, z = 1.96: centre (0.8 + 0.19208) / 1.38416, half 1.96 sqrt(0.016 + 0.0096) / 1.38416
    assert lo == pytest.approx(0.4902, abs=1e-4) and hi == pytest.approx(0.9433, abs=1e-4)
    m, a, b = mean_interval([1.0, 2.0, 3.0])
    assert m == 2.0 and b - m == pytest.approx(1.96 / 3**0.5)


def test_ignition_clearance_reaches_the_mission(tmp_path):
    # Configuration 0 of seed 0 ends at step 1 when a front ignites next to the hovering
    # UAV; with no ignition within 200 m of it the same configuration is flown on.
    from dualpilot.evaluation.missions import Task, run_task

    strict = run_task(Task.of(0, 0, "s2"))
    clear = run_task(Task.of(0, 0, "s2",
                             MissionConfig(settings=(("ignition_clearance_m", 200.0),))))
    assert strict["failure_cause"] == "fire_while_planning" and strict["steps"] == 1
    assert int(str(clear["steps"])) > 1
