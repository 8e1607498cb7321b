"""dualpilot.warmup: after it, flying missions compiles nothing (no first plan waits for Numba);
after :func:`~dualpilot.warmup.warm_up_3d`, 3-D missions neither (System 1's CPU cap would
otherwise count the compilation of the 3-D kernels)."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

_CHECK = r"""
import json
from numba.core.registry import CPUDispatcher
import dualpilot.model.hull_kernels as g, dualpilot.model.reach_kernel as d
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
    entry = ("dualpilot.model.hull_kernels.monotone_chain", "dualpilot.model.hull_kernels.faces",
             "dualpilot.model.hull_kernels.hull_distances", "dualpilot.model.reach_kernel.reach",
             "dualpilot.system1.lqr._track_axes", "dualpilot.system1.lqr._norm_loop",
             "dualpilot.system1.lqr._arc_lengths", "dualpilot.system2.fast.mehrotra.mehrotra")
    for name in entry:  # every kernel a plan calls is ready
        assert report["after"][name] >= 1, name
    assert min(report["steps"]) >= 10  # real missions flew
    assert report["new"] == {}  # and none of them compiled a new specialisation


_CHECK_3D = r"""
import json
from numba.core.registry import CPUDispatcher
import dualpilot.model.hull_kernels as g, dualpilot.model.reach_kernel as d
import dualpilot.model.segment_kernels as s3
import dualpilot.system1.lqr as l, dualpilot.system2.fast.mehrotra as m
from dualpilot.warmup import warm_up_3d

def counts():
    return {f"{mod.__name__}.{k}": len(v.signatures) for mod in (g, d, s3, l, m)
            for k, v in vars(mod).items() if isinstance(v, CPUDispatcher)}

warm_up_3d()
after = counts()
from dualpilot.mission.config import MissionConfig
from dualpilot.mission.local import local_mission
from dualpilot.mission.params import Controller
steps, climbs = [], []
settings = (("dim", 3), ("fire_height", "uniform"), ("fire_height_min_m", 10.0),
            ("fire_height_max_m", 40.0), ("s1_altitude", "volume"))
for ctl in (Controller.CC, Controller.S1, Controller.S2):
    res = local_mission(MissionConfig(controller=ctl, seed=0, settings=settings)).run()
    steps.append(res.steps)
    z = [r.state[2] for r in res.records]
    climbs.append(float(max(z) - min(z)))
new = {k: v - after[k] for k, v in counts().items() if v != after[k]}
print(json.dumps({"after": after, "new": new, "steps": steps, "climbs": climbs}))
"""


@pytest.mark.slow  # a process of its own
def test_3d_missions_after_the_3d_warm_up_compile_nothing() -> None:
    out = subprocess.run([sys.executable, "-c", _CHECK_3D], capture_output=True, text=True,
                         timeout=300, check=True)
    report = json.loads(out.stdout.strip().splitlines()[-1])
    # the entry points a 3-D plan calls from Python (the kernels they call compile with them)
    entry = ("dualpilot.model.segment_kernels.one_prism_d2",
             "dualpilot.model.segment_kernels.prism_distances")
    for name in entry:  # every 3-D kernel a plan calls is ready
        assert report["after"][name] >= 1, name
    assert min(report["steps"]) >= 10  # real missions flew
    assert max(report["climbs"]) > 5.0  # and used the third dimension
    assert report["new"] == {}  # none of them compiled a new specialisation


_CHECK_ONE = r"""
import json, sys
import numpy as np
from numba.core.registry import CPUDispatcher
from dualpilot.warmup import warm_up

OTHER = {1: "dualpilot.system2.fast.planner", 2: "dualpilot.system1.planner"}[SYSTEM]

def counts():
    return {f"{name}.{k}": len(v.signatures) for name, mod in list(sys.modules.items())
            if name.startswith("dualpilot") for k, v in vars(mod).items()
            if isinstance(v, CPUDispatcher)}

took = warm_up((SYSTEM,))
after = counts()
other_after_warm_up = OTHER in sys.modules
from dualpilot.model.dynamics import DynamicsParams
from dualpilot.model.geometry import Rect
from dualpilot.plan import Objective
from dualpilot.planners import build_planner
from dualpilot.spec import MissionSpec
hulls = (Rect(300.0, 300.0, 80.0, 60.0).polytope(), Rect(520.0, 610.0, 40.0, 120.0).polytope(),
         Rect(700.0, 420.0, 90.0, 90.0).polytope())
statuses = []
for limit in ("axis", "norm"):
    spec = MissionSpec(dynamics=DynamicsParams(speed_limit=limit))
    for method in METHODS:
        planner = build_planner(SYSTEM, spec, method)
        for state in (np.array([*spec.start, 0.0, 0.0]), np.array([200.0, 150.0, 4.0, 3.0])):
            for k in (1, 3):
                plan = planner.plan(state, hulls[:k], Objective.ENERGY)
                statuses.append(plan.status.value)
new = {k: v - after.get(k, 0) for k, v in counts().items() if v != after.get(k, 0)}
print(json.dumps({"took": took, "again": warm_up((SYSTEM,)), "other": other_after_warm_up,
                  "other_after_plans": OTHER in sys.modules, "new": new,
                  "statuses": statuses}))
"""


@pytest.mark.slow  # a process of its own
@pytest.mark.parametrize(("system", "methods"), [(1, ("rrt", "rrt+du")), (2, ("fast",))])
def test_one_systems_warm_up_loads_its_kernels_and_not_the_others(
        system: int, methods: tuple[str, ...]) -> None:
    code = f"SYSTEM = {system}\nMETHODS = {methods!r}\n{_CHECK_ONE}"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=300, check=True)
    report = json.loads(out.stdout.strip().splitlines()[-1])
    assert report["took"] > 0 and report["again"] == 0.0  # once a process
    assert not report["other"] and not report["other_after_plans"]  # a planner service's own
    assert len(report["statuses"]) == 2 * len(methods) * 2 * 2  # every plan was made
    assert report["new"] == {}  # and none of them compiled a new specialisation
