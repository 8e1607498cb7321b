"""Load: 10 vehicles share one EWS and one pair of planner services (benchmarks/load_vehicles.py).

Each vehicle has its own uavsim and supervisor and flies the cognitive
controller with the paper's timing on its own seed, unpaced enough (speed
factor 200) that every process computes all the time; the shared EWS keeps
one fire process per vehicle id. Lockstep makes the supervisor the clock, so
every mission must end exactly as the in-process mission of its seed
(success and step count) with no named fault in its records
(services/supervisor/faults.py), every record be written and every process
exit cleanly, whatever else the machine is doing. The plan deadlines are
raised: a late plan is a wall-clock fault with tests of its own
(test_faults.py, test_attacks.py), not what this test is about. The planner
latency and the stream under that load are printed (and measured by the
benchmarks, not asserted).
"""

from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path
from typing import Any

import pytest

from tests.support.waits import check, logs_in

pytestmark = [pytest.mark.slow, pytest.mark.timeout(420)]

REPO = Path(__file__).resolve().parents[2]
VEHICLES = 10


def _bench(name: str) -> Any:
    """A script of benchmarks/ as a module (benchmarks/ is not a package)."""
    full = f"benchmarks_{name}"
    if full in sys.modules:
        return sys.modules[full]
    if str(REPO / "benchmarks") not in sys.path:  # the scripts import benchmarks/harness.py
        sys.path.insert(0, str(REPO / "benchmarks"))
    spec = importlib.util.spec_from_file_location(full, REPO / "benchmarks" / f"{name}.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[full] = module  # dataclasses look their module up while the class is built
    spec.loader.exec_module(module)
    return module


def test_ten_vehicles_share_one_ews_and_one_planner_pair(tmp_path: Path) -> None:
    bench = _bench("load_vehicles")
    result = bench.run_load(VEHICLES, tmp_path, speed_factor=200.0, timeout_s=300.0,
                            plan_deadline_s="60,60")
    assert set(result.outcomes) == {f"uav{k + 1}" for k in range(VEHICLES)}
    shared = logs_in(tmp_path / "logs")
    for uav, outcome in result.outcomes.items():
        ref = bench.in_process(result.seeds[uav])
        logs = [*logs_in(tmp_path / uav), *shared]
        check(outcome.ended, f"{uav}'s mission to end", logs, outcome)
        assert (outcome.success, outcome.steps) == (ref.success, ref.steps), (uav, outcome)
        assert result.recorded[uav], uav
        check(result.faults[uav] == {}, f"{uav}'s records to name no fault", logs,
              result.faults[uav])
    check(all(code == 0 for code in result.codes.values()), "every process to exit with 0",
          shared, result.codes)
    assert result.steps >= VEHICLES * 50
    print(f"\n{VEHICLES} vehicles, {result.steps} steps in {result.wall_s:.1f} s, "
          f"failsafes {sum(result.failsafes.values())}, longest setpoint gap "
          f"{max(result.stream_max_ms.values()):.1f} ms: " + json.dumps(result.stats()))
