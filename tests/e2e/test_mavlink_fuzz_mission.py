"""A mission flown through the whole stack while both MAVLink ports of the vehicle are flooded.

The stack (router + five services, as docker-compose.yml) flies the seeded
mission of test_mission.py; from the moment the vehicle is alive until the
mission ends, the test process throws tests/integration/test_mavlink_fuzz.py's
corpus (random/truncated bytes, bad CRCs, oversize datagrams, MAVLink 1,
unknown ids, wrong types and targets, NaN/inf and far-outside setpoints,
mission items, parameters and commands) at the vehicle's offboard port (the
supervisor's link) and its ground-station port, about 500 datagrams a second
each. The mission must still reach the goal, every process exit cleanly, and
uavsim's status count the rejections under ``mavlink/offboard`` and
``mavlink/gcs``. Only 127.0.0.1.
"""

from __future__ import annotations

import socket
import threading
import time
from typing import Any

import pytest
from integration.test_mavlink_fuzz import Corpus

from dualpilot.mission.config import MissionConfig
from e2e.conftest import alive, router_ready, successful_seed
from services import launch
from services.common import bus
from tests.support.waits import check, logs_in

pytestmark = [pytest.mark.slow, pytest.mark.timeout(420)]

SPEED_FACTOR = 100.0
RATE_PER_PORT = 500.0  # datagrams per second


def flood(port: int, seed: int, stop: threading.Event, sent: dict[str, int], name: str) -> None:
    corpus = Corpus(seed)
    kinds = Corpus.KINDS
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        k = 0
        t0 = time.monotonic()
        while not stop.is_set():
            data, _ = corpus.one(kinds[k % len(kinds)])
            sock.sendto(data, ("127.0.0.1", port))
            k += 1
            sent[name] = k
            ahead = k / RATE_PER_PORT - (time.monotonic() - t0)
            if ahead > 0:
                time.sleep(ahead)


def test_mission_succeeds_while_both_mavlink_ports_are_flooded(tmp_path: Any) -> None:
    seed, _ = successful_seed()
    run_dir = tmp_path / f"mavfuzz-cc-s{seed}"
    cfg = launch.StackConfig(run_dir=run_dir, mission=MissionConfig(seed=seed),
                             speed_factor=SPEED_FACTOR, free_ports=True, uav_id="mavfuzz",
                             log_format="text")
    stack = launch.Stack(cfg)
    stop = threading.Event()
    sent: dict[str, int] = {}
    with stack:
        logs = logs_in(stack.logs)
        router_ready(stack.endpoint, logs)
        ports = {"offboard": stack.ports.ports[14540], "gcs": stack.ports.ports[14550]}
        with launch.client_session(stack.endpoint) as session:
            live = bus.Liveliness(session, cfg.uav_id)
            alive(live, ["uavsim"], 90, logs)
            floods = [threading.Thread(target=flood, args=(port, 7 + k, stop, sent, link),
                                       daemon=True)
                      for k, (link, port) in enumerate(ports.items())]
            for th in floods:
                th.start()
            outcome = launch.follow(stack, timeout_s=300.0, quiet=True)
            stop.set()
            for th in floods:
                th.join(10)
            status = bus.query_status(session, cfg.uav_id, "uavsim")
    codes = {p.name: int(p.popen.returncode) for p in stack.group.procs}
    check(outcome.ended and outcome.success, "the mission to reach the goal under the flood",
          logs, outcome)
    check(codes == dict.fromkeys(codes, 0), "every process to exit with 0", logs, codes)
    assert min(sent.values()) > 200, sent
    for link in ("offboard", "gcs"):
        counted = status["rejected"].get(f"mavlink/{link}", {})
        assert 0 < sum(counted.values()) <= sent[link], (link, counted, sent)
    assert len((run_dir / "logs" / "uavsim.log").read_text()) < 2_000_000
    print(f"\nMAVLink flood during the mission: {sent}; counted "
          f"{ {k: sum(v.values()) for k, v in status['rejected'].items()} }; "
          f"mission {outcome.steps} steps, success")
