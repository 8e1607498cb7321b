"""The README's command, as a user runs it: ``python -m services.launch …`` in a subprocess."""

from __future__ import annotations

import os
import sys
from pathlib import Path

import pytest

from e2e.conftest import run_process
from services.launch import REPO
from tests.support.waits import check, logs_in

pytestmark = [pytest.mark.slow, pytest.mark.timeout(240)]


def test_launch_runs_a_mission_and_leaves_a_run_directory(tmp_path: Path) -> None:
    out = tmp_path / "run"
    proc = run_process(
        [sys.executable, "-m", "services.launch", "--controller", "s1", "--seed", "3",
         "--speed-factor", "50", "--max-steps", "12", "--free-ports", "--out", str(out)],
        200, "services.launch", lambda: logs_in(out), cwd=REPO,
        env=dict(os.environ, PYTHONPATH=str(REPO)))
    check(proc.returncode == 0, "services.launch to exit with 0", logs_in(out),
          proc.stdout[-3000:] + proc.stderr[-3000:])
    assert "t=  0 S1" in proc.stdout  # progress
    assert '"controller": "s1"' in proc.stdout and "services stopped (all cleanly)" in proc.stdout
    for name in ("summary.json", "steps.csv", "trace.json", "latency.csv"):
        assert (out / name).is_file(), name
    assert sorted(p.name for p in (out / "logs").iterdir()) == [
        "ews.log", "router.log", "supervisor.log", "system1.log", "system2.log", "uavsim.log"]
    try:
        import dualpilot.viz.mission  # noqa: F401
    except ImportError:
        return
    assert list(out.glob("*.png")), "figures"
