"""dualpilot.warmup: after it, flying missions compiles nothing (no first plan waits for Numba)."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

_CHECK = r"""
import json
from numba.core.registry import CPUDispatcher
import dualpilot.model.dynamics as d, dualpilot.model.geometry as g
import dualpilot.system1.lqr as l, dualpilot.system2.fast.mehrotra as m
from dualpilot.warmup import warm_up

def counts():
    return {f"{mod.__name__}.{k}": len(v.signatures) for mod in (g, d, l, m)
            for k, v in vars(mod).items() if isinstance(v, CPUDispatcher)}

warm_up()
after = counts()
from dualpilot.mission.config import MissionConfig
from dualpilot.mission.local import local_mission
from dualpilot.mission.params import Controller
steps = []
for name in ("fig-r5", "literal"):  # both speed limits
    for ctl in (Controller.CC, Controller.S1, Controller.S2):
        res = local_mission(MissionConfig(controller=ctl, profile=name, seed=1)).run()
        steps.append(res.steps)
new = {k: v - after[k] for k, v in counts().items() if v != after[k]}
print(json.dumps({"after": after, "new": new, "steps": steps}))
"""


@pytest.mark.slow  # a process of its own (make test-fast leaves it out)
def test_missions_after_the_warm_up_compile_nothing() -> None:
    out = subprocess.run([sys.executable, "-c", _CHECK], capture_output=True, text=True,
                         timeout=300, check=True)
    report = json.loads(out.stdout.strip().splitlines()[-1])
    entry = ("dualpilot.model.geometry._monotone_chain", "dualpilot.model.geometry._faces",
             "dualpilot.model.geometry._hull_distances", "dualpilot.model.dynamics._reach",
             "dualpilot.system1.lqr._track_axes", "dualpilot.system1.lqr._norm_loop",
             "dualpilot.system1.lqr._arc_lengths", "dualpilot.system2.fast.mehrotra.mehrotra")
    for name in entry:  # every kernel a plan calls is ready
        assert report["after"][name] >= 1, name
    assert min(report["steps"]) >= 10  # real missions flew
    assert report["new"] == {}  # and none of them compiled a new specialisation
