"""The sweep runner: a grid on Dask, resume after SIGKILL, one runner with evaluate."""

from __future__ import annotations

import csv
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from dualpilot.evaluation.evaluate import evaluate
from dualpilot.evaluation.missions import COLUMNS, MEASURED_COLUMNS
from dualpilot.evaluation.sweep import SWEEP_COLUMNS, grid_points, parse_axes, sweep
from dualpilot.mission.config import MissionConfig
from dualpilot.viz.sweep import plot_sweep

pytestmark = pytest.mark.timeout(120)

SHORT = {"max_steps": 4}  # short missions: the runner is under test, not the planners


def rows(path: Path) -> list[dict[str, str]]:
    with (path / "results.csv").open() as fh:
        return list(csv.DictReader(fh))


def same(row: dict[str, str]) -> tuple[tuple[str, str], ...]:
    """A row without what is measured (wall and compute time)."""
    return tuple((k, row[k]) for k in COLUMNS if k not in MEASURED_COLUMNS)


def test_grid_points_are_the_product_then_the_list() -> None:
    pts = grid_points(parse_axes(["ignition_clearance_m=none,20", "profile=today,fig-r5"]),
                      points=[{"profile": "literal", "max_steps": 5}])
    assert [p.label for p in pts] == [
        "profile=today ignition_clearance_m=none", "profile=fig-r5 ignition_clearance_m=none",
        "profile=today ignition_clearance_m=20.0", "profile=fig-r5 ignition_clearance_m=20.0",
        "profile=literal max_steps=5"]
    with pytest.raises(ValueError, match="one of"):
        grid_points({"extent": ["forever"]})


def test_small_sweep_on_an_in_process_local_cluster(tmp_path: Path) -> None:
    from distributed import LocalCluster

    points = grid_points({"life_base": ["substep", "step"]}, points=[])
    points = [type(p)(p.index, p.profile, (*p.settings, ("max_steps", 4))) for p in points]
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=False,
                      dashboard_address=":0") as cluster:
        summary = sweep(points, 2, tmp_path, MissionConfig(seed=3),
                        scheduler=cluster.scheduler_address, progress=False, figure=plot_sweep)
    got = rows(tmp_path)
    assert len(got) == 2 * 2 * 3 and list(got[0]) == SWEEP_COLUMNS
    assert {r["life_base"] for r in got} == {"substep", "step"}
    # configuration i is the same for every controller and grid point
    by_mission: dict[str, set[tuple[str, ...]]] = {}
    for r in got:
        by_mission.setdefault(r["mission"], set()).add((r["seed"], r["start_x"], r["goal_y"]))
    assert all(len(v) == 1 for v in by_mission.values())
    assert (tmp_path / "results.parquet").stat().st_size > 0
    import pyarrow.parquet as pq

    assert pq.read_table(tmp_path / "results.parquet").num_rows == 12
    assert (tmp_path / "fig_sweep.png").stat().st_size > 5000
    assert len(summary["points"]) == 2
    on_disk = json.loads((tmp_path / "summary.json").read_text())
    assert set(on_disk["points"][0]["controllers"]) == {"cc", "s1", "s2"}


def test_sweep_and_evaluate_give_identical_rows(tmp_path: Path) -> None:
    evaluate(2, tmp_path / "e", MissionConfig(seed=5, profile="fig-r5",
                                              settings=tuple(SHORT.items())),
             jobs=1, progress=False)
    pts = grid_points({}, points=[{"profile": "fig-r5", **SHORT}])
    sweep(pts, 2, tmp_path / "s", MissionConfig(seed=5), jobs=1, progress=False)
    ev, sw = rows(tmp_path / "e"), rows(tmp_path / "s")
    assert sorted(map(same, ev)) == sorted(map(same, sw)) and len(ev) == 6


@pytest.mark.slow  # a process of its own (make test-fast leaves it out)
def test_a_killed_sweep_resumes_without_duplicates_or_gaps(tmp_path: Path) -> None:
    out = tmp_path / "run"
    argv = [sys.executable, "-m", "dualpilot.cli", "sweep", "--missions", "6", "--jobs", "1",
            "--seed", "2", "--set", "max_steps=6", "--set", "ignition_clearance_m=none,30",
            "--out", str(out), "--no-figures"]
    proc = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                            start_new_session=True)
    try:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            path = out / "results.csv"
            if path.exists() and path.read_text().count("\n") >= 4:  # header + 3 rows
                break
            time.sleep(0.05)
        os.killpg(proc.pid, signal.SIGKILL)
    finally:
        proc.wait(timeout=30)
    assert proc.returncode == -signal.SIGKILL
    first = rows(out)
    assert 3 <= len(first) < 36, "killed mid-run"
    done = subprocess.run(argv, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr[-2000:]
    final = rows(out)
    keys = [(r["label"], r["mission"], r["controller"]) for r in final]
    assert len(keys) == len(set(keys)) == 6 * 2 * 3
    assert final[: len(first)] == first, "recorded rows are kept, not redone"


def _square_or_fail(x: int) -> dict[str, object]:
    if x == 7:
        raise RuntimeError("worker gone")
    return {"x": x, "square": x * x}


def test_results_arrive_in_batches_and_a_failed_task_becomes_an_error_row() -> None:
    """Every finished task yields its row once; a task whose future fails (a dead worker)
    yields an error row naming it, and the others still arrive."""
    from dualpilot.evaluation.runner import execute

    out = list(execute(list(range(40)), jobs=2, processes=False, fn=_square_or_fail))
    assert len(out) == 40
    good = sorted(int(str(r["x"])) for r in out if "x" in r)
    assert good == [x for x in range(40) if x != 7]
    assert all(r["square"] == int(str(r["x"])) ** 2 for r in out if "x" in r)
    (bad,) = [r for r in out if "x" not in r]
    assert bad["task"] == "7" and "worker lost: RuntimeError: worker gone" in str(bad["error"])
