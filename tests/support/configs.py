"""Random mission configurations (hypothesis): every controller, reading, method and geometry."""

from __future__ import annotations

import dataclasses
from typing import Any

from hypothesis import strategies as st

from dualpilot.mission.config import MissionConfig, controller_names
from dualpilot.mission.params import Timing
from dualpilot.model.forecast import ForecastParams
from dualpilot.model.geometry import Rect
from dualpilot.model.risk import RiskParams
from dualpilot.readings import PROFILES
from dualpilot.supervisor.concurrent.rule import ConcurrentParams


def _concurrent() -> st.SearchStrategy[ConcurrentParams]:
    unit = st.floats(0.0, 1.0, allow_nan=False)
    return st.builds(
        ConcurrentParams,
        threat_margin_m=st.none() | st.floats(0.0, 200.0, allow_nan=False),
        check_steps=st.integers(1, 40), reanchor_tol_m=st.floats(0.0, 20.0),
        reanchor_tol_mps=st.floats(0.0, 5.0), max_wait_hazard=unit,
        q_rate=st.floats(0.01, 1.0), switch_margin=st.floats(-1.0, 1.0),
        energy_scale_n2=st.floats(0.1, 100.0),
        s2_unavailable=st.sampled_from(["keep", "system1"]),
        reanchor_tol=st.sampled_from(["fixed", "tube"]),
        risk=st.builds(RiskParams, alpha=st.floats(0.0, 0.99)))


#: reading overrides with the values their fields take (a few of each kind)
SETTINGS: dict[str, st.SearchStrategy[Any]] = {
    "scenario": st.sampled_from(["paper", "grass-5", "grass-15", "shrub"]),
    "max_steps": st.integers(1, 400),
    "ignition_clearance_m": st.none() | st.floats(0.0, 100.0),
    "p_birth": st.floats(0.0, 1.0),
    "d_t_reading": st.sampled_from(["active", "newborn", "hull"]),
    "keep_extinct_hulls": st.booleans(),
    "speed_limit": st.sampled_from(["axis", "norm"]),
    "dim": st.sampled_from([2, 3]),
    "ceiling_m": st.floats(60.0, 300.0),
    "goal_altitude_m": st.none() | st.floats(20.0, 60.0),
    "goal_vertical": st.sampled_from(["band", "cube"]),
    "fire_height": st.sampled_from(["auto", "above-ceiling"]),
    "plume_intensity": st.sampled_from(["front", "head"]),
    "uav_limit_c": st.floats(31.0, 80.0),
    "risk_zone_height": st.sampled_from(["band", "fire"]),
}


@st.composite
def configs(draw: st.DrawFn) -> MissionConfig:
    name = draw(st.sampled_from(controller_names()))
    names = draw(st.lists(st.sampled_from(sorted(SETTINGS)), unique=True, max_size=4))
    settings_ = tuple((n, draw(SETTINGS[n])) for n in names)
    size = draw(st.floats(400.0, 5000.0))
    w = draw(st.floats(10.0, 200.0))
    cx = draw(st.floats(w / 2, size - w / 2))
    cy = draw(st.floats(w / 2, size - w / 2))
    start = draw(st.none() | st.tuples(st.floats(0.0, size), st.floats(0.0, size)))
    return MissionConfig.named(
        name, timing=draw(st.sampled_from(list(Timing))), seed=draw(st.integers(0, 2**63)),
        profile=draw(st.sampled_from(list(PROFILES))), settings=settings_,
        system1_method=draw(st.sampled_from(["", "rrt", "rrt+du"])),
        system2_method=draw(st.sampled_from(["fast", "exact", "thorough"])),
        system2_time_limit_s=draw(st.floats(0.01, 3600.0)),
        concurrent=dataclasses.replace(draw(_concurrent()), threat="current"),
        forecast=draw(st.builds(ForecastParams, members=st.integers(1, 256),
                                resolution_m=st.floats(1.0, 50.0),
                                horizon_s=st.floats(0.0, 120.0),
                                interval_s=st.floats(0.1, 10.0))),
        goal=Rect(cx, cy, w, w), area_size_m=size, start=start,
        mission_id=draw(st.text("abc-_0123456789", max_size=20).filter(
            lambda m: not m.startswith("-"))))


