"""A mission flown through the whole stack while a fuzzer floods every Zenoh entry point.

The stack (router + five services, as docker-compose.yml) flies the seeded
mission of test_mission.py; from the moment the services are alive until the
mission ends, the test process throws bad input (tests/integration/test_fuzz.py's
corpus: random/truncated bytes, wrong types, NaN, far-outside coordinates,
unknown schema versions, 10 MB payloads) at ``ews/command``, ``plan/system1``,
``plan/system2``, ``operator/waypoints`` and every ``status/<service>``.
The mission must still reach the goal, every process exit cleanly, and every
rejection be counted in the status of the service that received it.
"""

from __future__ import annotations

import threading
from typing import Any

import pytest
from integration.conftest import _wait_until
from integration.test_fuzz import FloodResult, check_counted, counters, flood

from dualpilot.mission.config import MissionConfig
from e2e.conftest import alive, router_ready, successful_seed
from services import launch
from services.common import bus
from tests.support.waits import check, explain, logs_in, wait_for

pytestmark = [pytest.mark.slow, pytest.mark.timeout(420)]

SPEED_FACTOR = 100.0
SERVICES = ("ews", "system1", "system2", "supervisor", "uavsim")


def test_mission_succeeds_under_a_fuzz_flood(tmp_path: Any) -> None:
    seed, _ = successful_seed()
    run_dir = tmp_path / f"fuzz-cc-s{seed}"
    cfg = launch.StackConfig(run_dir=run_dir, mission=MissionConfig(seed=seed),
                             speed_factor=SPEED_FACTOR, free_ports=True, uav_id="fuzz",
                             log_format="text")
    stack = launch.Stack(cfg)
    stop = threading.Event()
    floods: list[FloodResult] = []
    errors: list[BaseException] = []
    with stack:
        logs = logs_in(stack.logs)
        router_ready(stack.endpoint, logs)
        with launch.client_session(stack.endpoint) as session:
            live = bus.Liveliness(session, cfg.uav_id)
            alive(live, ["ews", "system1", "system2"], 90, logs)
            before = counters(session, cfg.uav_id)

            def fuzz() -> None:
                try:
                    floods.append(flood(session, cfg.uav_id, 10**9, huge=2, seed=7, stop=stop,
                                        status_services=SERVICES))
                except BaseException as err:  # reported by the main thread
                    errors.append(err)

            fuzzer = threading.Thread(target=fuzz, name="fuzzer", daemon=True)
            fuzzer.start()
            outcome = launch.follow(stack, timeout_s=300.0, quiet=True)
            stop.set()
            wait_for(lambda: not fuzzer.is_alive(), 180, "the fuzzer thread to stop", logs)
            assert not errors, errors
            check(floods, "the fuzzer's result", logs)
            result = floods[0]
            try:  # its own waits and asserts name the service and key; the logs are added
                check_counted(session, cfg.uav_id, before, result, _wait_until)
            except AssertionError as err:
                pytest.fail(explain(f"every fuzz input to be counted in the status of the "
                                    f"service that received it: {err}", logs), pytrace=False)
            statuses = {s: bus.query_status(session, cfg.uav_id, s) for s in SERVICES}
    codes = {p.name: int(p.popen.returncode) for p in stack.group.procs}
    check(outcome.ended and outcome.success, "the mission to reach the goal under the flood",
          logs, outcome)
    check(codes == dict.fromkeys(codes, 0), "every process to exit with 0", logs, codes)
    sent = sum(result.sent.values())
    assert min(result.sent.values()) > 100, result.sent
    for name in ("ews", "system1", "system2"):
        assert statuses[name]["rejected_total"] > 0, statuses[name]
    print(f"\nfuzz during the mission: {sent} inputs in {result.wall_s:.1f} s "
          f"({result.sent}); mission {outcome.steps} steps, success")
