"""A Zenoh session across the test bed's radio link comes back by itself after an outage.

The project's router runs on the ground host, a session of the services' own configuration
on the air host (``services.testbed.zprobe``) asks the router's status every 0.2 s across the
radio link; the link goes down for 10 s, as the end-to-end test's outage will. Nothing is
restarted: the same two processes must be answering again after the outage, and no answer may
have crossed while the link was down.
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path
from typing import Any

import pytest

from services.testbed.bed import TestBed
from services.testbed.impairment import Impairment
from tests.support.waits import wait_for

OUTAGE_S = 10.0


def lines(path: Path) -> list[dict[str, Any]]:
    if not path.is_file():
        return []
    return [json.loads(x) for x in path.read_text().splitlines() if x.endswith("}")]


@pytest.mark.slow
@pytest.mark.timeout(180)
def test_a_zenoh_session_recovers_by_itself_after_a_10_s_outage(testbed: TestBed) -> None:
    air, ground = testbed.host("air"), testbed.host("ground")
    testbed.link("radio").set(Impairment(delay_ms=50.0, jitter_ms=10.0, rate_mbit=1.0))
    endpoint = f"tcp/{ground.address('air')}:7447"
    env = {"LOG_FORMAT": "text", "UAV_ID": "tb"}
    router = ground.start("router", [sys.executable, "-m", "services.router",
                                     "--zenoh-listen", endpoint], env)
    out = testbed.logs / "probe.jsonl"
    probe = air.start("zprobe", [sys.executable, "-m", "services.testbed.zprobe",
                                 "--zenoh-connect", endpoint, "--out", str(out)], env)
    logs = {"router": router.log_path, "zprobe": probe.log_path, "probe.jsonl": out}
    wait_for(lambda: sum(x["ok"] for x in lines(out)) >= 5, 60.0,
             "five answers from the router across the radio link", logs=logs)

    before = time.monotonic()
    testbed.link("radio").outage(OUTAGE_S)
    after = time.monotonic()
    back = before + OUTAGE_S
    wait_for(lambda: any(x["ok"] and x["sent"] >= after + OUTAGE_S for x in lines(out)), 90.0,
             "an answer to a query sent after the outage", logs=logs)

    assert router.popen.poll() is None and probe.popen.poll() is None  # nobody restarted
    record = lines(out)
    during = [x for x in record if after <= x["sent"] and x["done"] < back]
    assert during and not any(x["ok"] for x in during), "an answer crossed a dead link"
    stats = testbed.link("radio").stats()["directions"]
    assert stats["air"]["blackholed"] > 0 and stats["ground"]["blackholed"] > 0
