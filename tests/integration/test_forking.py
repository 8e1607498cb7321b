"""Services forked from the warm server (services/forking/server.py) start and end as fresh
interpreters do.

The same probe program (tests/support/forkprobe.py) is started through
:class:`services.launch.processes.ProcessGroup` both ways: as ``python -m`` in a fresh
interpreter and from the fork server. What it reports of its start (argv, working directory,
environment, session, standard input) and how it ends (exit status, output, atexit and
threads, SIGINT caught or not) must be the values written here, for both.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from services.forking import server
from services.launch.processes import REPO, Proc, ProcessGroup
from tests.support.waits import wait_for

PROBE = [sys.executable, "-m", "tests.support.forkprobe"]
WAYS = ["fresh", "forked"]


@pytest.fixture(autouse=True)
def fork_off_after() -> Iterator[None]:
    """SIGINT as an interactive launcher has it (a test process may inherit it ignored: a
    script's nohup'd background job), fork off afterwards."""
    old = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, old)
    server.disable()


def start(way: str, action: str, tmp_path: Path) -> tuple[ProcessGroup, Proc, Path]:
    if way == "forked":
        server.enable()
    else:
        server.disable()
    env = {"PATH": os.environ["PATH"], "PYTHONPATH": str(REPO), "PYTHONUNBUFFERED": "1",
           "PROBE_WHO": "the probe", "PROBE_EMPTY": ""}
    log = tmp_path / f"{way}-{action}.log"
    group = ProcessGroup()
    proc = group.start("probe", [*PROBE, action, "--flag", "two words"], env, log)
    assert isinstance(proc.popen, server.ForkedProcess) == (way == "forked")
    return group, proc, log


def ended(group: ProcessGroup, proc: Proc, timeout_s: float = 60.0) -> int:
    code = proc.popen.wait(timeout_s)
    group.stop(proc)
    return int(code)


def lines(log: Path) -> list[str]:
    return log.read_text().splitlines() if log.is_file() else []


def report(log: Path) -> dict[str, object]:
    return dict(json.loads(lines(log)[0]))


@pytest.mark.parametrize("way", WAYS)
def test_the_program_starts_with_what_it_was_given(way: str, tmp_path: Path) -> None:
    group, proc, log = start(way, "plain", tmp_path)
    assert ended(group, proc) == 0
    assert report(log) == {
        "argv": ["plain", "--flag", "two words"], "argv0": "forkprobe.py", "cwd": str(REPO),
        "env": {"PROBE_WHO": "the probe", "PROBE_EMPTY": ""}, "has_home": False,
        "own_session": True, "own_group": True, "stdin_null": True, "main": True}


@pytest.mark.parametrize("way", WAYS)
def test_exit_statuses_are_the_interpreters(way: str, tmp_path: Path) -> None:
    group, proc, log = start(way, "exit3", tmp_path)
    assert ended(group, proc) == 3
    group, proc, log = start(way, "raise", tmp_path)
    assert ended(group, proc) == 1
    assert lines(log)[-1] == "RuntimeError: the probe's uncaught error"
    assert "Traceback (most recent call last):" in lines(log)


@pytest.mark.parametrize("way", WAYS)
def test_threads_are_joined_before_the_atexit_handlers_run(way: str, tmp_path: Path) -> None:
    group, proc, log = start(way, "atexit", tmp_path)
    assert ended(group, proc) == 0
    assert lines(log)[1:] == ["thread finished", "atexit ran"]


@pytest.mark.parametrize("way", WAYS)
def test_an_idle_executor_left_running_does_not_hold_the_exit(way: str, tmp_path: Path) -> None:
    group, proc, log = start(way, "executor", tmp_path)
    assert ended(group, proc, timeout_s=20.0) == 0
    assert lines(log)[1:] == ["task ran"]


@pytest.mark.parametrize("way", WAYS)
def test_sigint_to_the_group_interrupts_the_program(way: str, tmp_path: Path) -> None:
    group, proc, log = start(way, "clean-sigint", tmp_path)
    wait_for(lambda: len(lines(log)) >= 1, 60.0, "the probe's report")
    assert group.stop(proc) == 0
    assert lines(log)[-1] == "interrupted"
    group, proc, log = start(way, "sigint", tmp_path)
    wait_for(lambda: len(lines(log)) >= 1, 60.0, "the probe's report")
    time.sleep(0.2)  # in its loop
    assert group.stop(proc) == -2  # uncaught: it dies by SIGINT
    assert lines(log)[-1] == "KeyboardInterrupt"


@pytest.mark.parametrize("way", WAYS)
def test_a_launcher_that_ignores_sigint_passes_it_on(way: str, tmp_path: Path) -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    group, proc, log = start(way, "clean-sigint", tmp_path)
    signal.signal(signal.SIGINT, signal.default_int_handler)
    wait_for(lambda: len(lines(log)) >= 1, 60.0, "the probe's report")
    os.killpg(proc.popen.pid, signal.SIGINT)
    time.sleep(0.5)
    assert proc.popen.poll() is None  # ignored, as an exec'd child inherits it
    assert group.stop(proc, grace_s=0.5) == -9
    assert lines(log)[1:] == []


@pytest.mark.parametrize("way", WAYS)
def test_a_forked_program_starts_with_the_servers_heap_frozen(way: str, tmp_path: Path) -> None:
    # services/forking/warm.py freezes what the server loaded (about 240,000 objects the
    # collector tracks), so a forked program's collections walk only the objects it makes
    group, proc, log = start(way, "heap", tmp_path)
    assert ended(group, proc) == 0
    frozen = json.loads(lines(log)[1])["frozen"]
    assert frozen > 100_000 if way == "forked" else frozen == 0


def test_a_forked_program_still_running_times_out_like_popen(tmp_path: Path) -> None:
    group, proc, log = start("forked", "clean-sigint", tmp_path)
    with pytest.raises(subprocess.TimeoutExpired):
        proc.popen.wait(0.2)
    assert proc.popen.poll() is None
    assert group.stop(proc) == 0


def test_only_this_pythons_module_commands_are_forked() -> None:
    assert server.module_of([sys.executable, "-m", "services.ews", "--x"]) == "services.ews"
    assert server.module_of(["python3", "-m", "services.ews"]) is None
    assert server.module_of([sys.executable, "script.py"]) is None
    assert server.module_of(["ip", "netns", "exec", "air", sys.executable, "-m", "x"]) is None
