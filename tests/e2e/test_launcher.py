"""The README's command, as a user runs it: ``python -m services.launch …`` in a subprocess."""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from e2e.conftest import run_process
from services.launch import REPO
from tests.support.waits import check, logs_in, wait_for

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
    # the end as summary.json types it: a cause only in the ending ("goal" or the failure's)
    assert re.search(r'"success": (true|false), "ending": "[a-z_]+"', proc.stdout), proc.stdout
    assert "failure_cause" not in proc.stdout
    for name in ("summary.json", "steps.csv", "trace.json", "latency.csv"):
        assert (out / name).is_file(), name
    assert sorted(p.name for p in (out / "logs").iterdir()) == [
        "ews.log", "router.log", "supervisor.log", "system1.log", "system2.log", "uavsim.log"]
    try:
        import dualpilot.viz.mission  # noqa: F401
    except ImportError:
        return
    assert list(out.glob("*.png")), "figures"


def _processes_on(endpoint: str) -> list[int]:
    """The processes whose command line or environment names the Zenoh ``endpoint``."""
    found = []
    for proc in Path("/proc").iterdir():
        if not proc.name.isdigit():
            continue
        try:
            seen = (proc / "cmdline").read_bytes() + (proc / "environ").read_bytes()
        except OSError:
            continue
        if endpoint.encode() in seen:
            found.append(int(proc.name))
    return found


@pytest.mark.parametrize("vehicles", [1, 3])
def test_a_terminated_launcher_stops_every_service(tmp_path: Path, vehicles: int) -> None:
    """``kill`` (SIGTERM) of the launcher, as ``timeout`` sends it: no service outlives it."""
    out = tmp_path / "run"
    proc = subprocess.Popen(
        [sys.executable, "-m", "services.launch", "--controller", "s1", "--seed", "3",
         "--speed-factor", "1", "--free-ports", "--no-figures", "--vehicles", str(vehicles),
         "--out", str(out)], cwd=REPO, env=dict(os.environ, PYTHONPATH=str(REPO)),
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, start_new_session=True)
    try:
        assert proc.stdout is not None
        first = proc.stdout.readline()  # "stack: router tcp/…" / "fleet: N vehicles, router …"
        got = re.search(r"router (tcp/127\.0\.0\.1:\d+)", first)
        check(got is not None, "the launcher to name its router", logs_in(out), first)
        assert got is not None
        endpoint = got.group(1)
        # router, EWS, both planners, the vehicle's (or the hosts') uavsim and supervisor
        wait_for(lambda: len(_processes_on(endpoint)) >= 6, 60.0, "the stack's services to run",
                 logs_in(out), last=lambda: _processes_on(endpoint))
        proc.send_signal(signal.SIGTERM)
        proc.wait(60)
        left = [pid for pid in _processes_on(endpoint) if pid != proc.pid]
        check(not left, "no service to outlive the launcher", logs_in(out), left)
    finally:
        if proc.poll() is None:  # a failed check: stop it as a user would, then for good
            proc.send_signal(signal.SIGTERM)
            try:
                proc.wait(60)
            except subprocess.TimeoutExpired:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait()
