"""The planners of a mission, built by name from its :class:`dualpilot.spec.MissionSpec`.

One registry, like python-control's ``trajectory_method=``: System 1's "rrt"
(Alg. 1 + LQR) and System 2's "fast" (the default), "exact" (the cvxpy
MIQP, solved in a killable worker process), "fast+exact" and "thorough".
The "+risk" methods ("rrt+risk", "rrt+du+risk", "fast+risk") also take the
fire forecast as a chance constraint (dualpilot/model/risk.py).
Every planner implements :class:`dualpilot.plan.Planner`.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING

from dualpilot.plan import Planner
from dualpilot.spec import MissionSpec
from dualpilot.system2.problem import System2Params

if TYPE_CHECKING:
    from dualpilot.system1.planner import System1Params

__all__ = ["METHODS", "Planner", "build_planner", "build_planners"]

#: A constructor of the registry: (spec, params or None for the defaults) -> Planner.
System1Constructor = Callable[[MissionSpec, "System1Params | None"], Planner]
System2Constructor = Callable[[MissionSpec, "System2Params | None"], Planner]


def _rrt(spec: MissionSpec, params: System1Params | None) -> Planner:
    from dualpilot.system1.planner import System1, System1Params

    return System1(spec, params or System1Params())


def _rrt_du(spec: MissionSpec, params: System1Params | None) -> Planner:
    from dataclasses import replace

    from dualpilot.system1.planner import System1, System1Params

    return System1(spec, replace(params or System1Params(), tracker="lqr_du"))


def _fast(spec: MissionSpec, params: System2Params | None) -> Planner:
    from dualpilot.system2.fast.planner import FastSystem2

    return FastSystem2(spec, params or System2Params())


def _fast_risk(spec: MissionSpec, params: System2Params | None) -> Planner:
    from dualpilot.system2.fast.planner import RiskSystem2

    return RiskSystem2(spec, params or System2Params())


def _exact(spec: MissionSpec, params: System2Params | None) -> Planner:
    from dualpilot.system2.exact import ExactSystem2

    return ExactSystem2(spec, params or System2Params(), isolate=True)


def _anytime(spec: MissionSpec, params: System2Params | None) -> Planner:
    from dualpilot.system2.fast.planner import AnytimeSystem2

    return AnytimeSystem2(spec, params or System2Params())


def _thorough(spec: MissionSpec, params: System2Params | None) -> Planner:
    from dualpilot.system2.fast.planner import ThoroughSystem2

    return ThoroughSystem2(spec, params or System2Params())


def _rrt_risk(spec: MissionSpec, params: System1Params | None) -> Planner:
    from dualpilot.system1.planner import RiskSystem1, System1Params

    return RiskSystem1(spec, params or System1Params())


def _rrt_du_risk(spec: MissionSpec, params: System1Params | None) -> Planner:
    from dataclasses import replace

    from dualpilot.system1.planner import RiskSystem1, System1Params

    return RiskSystem1(spec, replace(params or System1Params(), tracker="lqr_du"))


SYSTEM1: Mapping[str, System1Constructor] = {"rrt": _rrt, "rrt+du": _rrt_du,
                                             "rrt+risk": _rrt_risk, "rrt+du+risk": _rrt_du_risk}
SYSTEM2: Mapping[str, System2Constructor] = {
    "fast": _fast, "exact": _exact, "fast+exact": _anytime, "thorough": _thorough,
    "fast+risk": _fast_risk,
}
#: Method names per system, the default first.
METHODS: Mapping[int, tuple[str, ...]] = {1: tuple(SYSTEM1), 2: tuple(SYSTEM2)}


def build_planner(system: int, spec: MissionSpec, method: str | None = None,
                  params: System1Params | System2Params | None = None) -> Planner:
    """The planner of ``system`` (1 or 2) by method name (default: the system's first).

    ``params`` are that system's parameters (System1Params / System2Params).
    Raises ValueError for an unknown system or method, TypeError for the
    other system's parameters.
    """
    if system not in METHODS:
        raise ValueError(f"unknown system {system!r}; choose 1 or 2")
    from dualpilot.warmup import warm_up

    warm_up()  # the compiled kernels, once a process, before any plan is timed
    method = METHODS[system][0] if method is None else method
    if method not in METHODS[system]:
        raise ValueError(f"unknown System {system} method {method!r}; "
                         f"choose from {METHODS[system]}")
    if system == 1:
        from dualpilot.system1.planner import System1Params

        if params is not None and not isinstance(params, System1Params):
            raise TypeError(f"System 1 takes System1Params, got {type(params).__name__}")
        return SYSTEM1[method](spec, params)
    if params is not None and not isinstance(params, System2Params):
        raise TypeError(f"System 2 takes System2Params, got {type(params).__name__}")
    return SYSTEM2[method](spec, params)


def build_planners(spec: MissionSpec, system2_method: str = "fast",
                   system1_params: System1Params | None = None,
                   system2_params: System2Params | None = None,
                   system1_method: str = "rrt") -> dict[int, Planner]:
    """Both planners of a mission: {1: System 1 (``system1_method``), 2: System 2
    (``system2_method``)}."""
    return {1: build_planner(1, spec, system1_method, system1_params),
            2: build_planner(2, spec, system2_method, system2_params)}
