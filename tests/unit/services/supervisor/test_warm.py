"""services/supervisor/warm.py: the supervisor's warm-up loads every kernel its own step runs.

The supervisor plans nothing itself (the planner services do), so its warm-up loads only
the kernels of its step: the hulls' segment distances, the risk zones' cell hulls and the
lookahead supervisor's lattice moves. After it, missions of every kind of supervisor step
(the paper's, the concurrent one with forecast threats, the lookahead one) call no new
specialisation of those kernels.
"""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

_CHECK = r"""
import json
from numba.core.registry import CPUDispatcher
import dualpilot.model.hull_kernels as g, dualpilot.model.risk_kernels as r
import dualpilot.spacetime.lattice as s
from services.supervisor.warm import warm_kernels

def counts():
    return {f"{mod.__name__}.{k}": len(v.signatures) for mod in (g, r, s)
            for k, v in vars(mod).items() if isinstance(v, CPUDispatcher)}

before = counts()
took = warm_kernels()
after = counts()
again = warm_kernels()
from dualpilot.mission.config import MissionConfig
from dualpilot.mission.local import local_mission
steps = []
for name in ("cc", "concurrent+risk", "lookahead+risk"):
    config = MissionConfig.named(name, seed=0, settings=(("scenario", "grass-15"),))
    steps.append(local_mission(config).run().steps)
new = {k: v - after[k] for k, v in counts().items() if v != after[k] and k in KERNELS}
print(json.dumps({"before": before, "after": after, "new": new, "steps": steps,
                  "took": took, "again": again}))
"""
KERNELS = ("dualpilot.model.hull_kernels.hull_distances", "dualpilot.model.risk_kernels.groups",
           "dualpilot.model.risk_kernels.group_hulls", "dualpilot.spacetime.lattice.move_clear")


@pytest.mark.slow  # a process of its own (make test-fast leaves it out)
def test_missions_after_the_supervisors_warm_up_load_no_kernel_of_its_step() -> None:
    code = f"KERNELS = {KERNELS!r}\n{_CHECK}"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=300, check=True)
    report = json.loads(out.stdout.strip().splitlines()[-1])
    for name in KERNELS:  # loaded by the warm-up, not before
        assert report["before"][name] == 0 and report["after"][name] == 1, name
    assert report["took"] > 0 and report["again"] == 0.0  # once a process
    assert min(report["steps"]) >= 10  # real missions flew
    assert report["new"] == {}  # and none of them needed another specialisation
