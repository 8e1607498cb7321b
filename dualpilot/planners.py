"""The planners of a mission, built by name from its :class:`dualpilot.spec.MissionSpec`.

One registry, like python-control's ``trajectory_method=``: System 1's "rrt"
(Alg. 1 + LQR) and System 2's "fast" (the default), "exact" (the cvxpy
MIQP, solved in a killable worker process), "fast+exact", "thorough" and "certified"
(the fast plan with a lower bound on (P2) proven by branch and bound).
With ``risk`` a method's risk-aware variant (:data:`RISK_AWARE`: System 1's
"rrt" and "rrt+du", System 2's "fast") also takes the fire forecast as a
chance constraint (dualpilot/model/risk.py).
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
    from dualpilot.system2.fast.risk import RiskSystem2

    return RiskSystem2(spec, params or System2Params())


def _exact(spec: MissionSpec, params: System2Params | None) -> Planner:
    from dualpilot.system2.exact import ExactSystem2

    return ExactSystem2(spec, params or System2Params(), isolate=True)


def _anytime(spec: MissionSpec, params: System2Params | None) -> Planner:
    from dualpilot.system2.anytime import AnytimeSystem2

    return AnytimeSystem2(spec, params or System2Params())


def _thorough(spec: MissionSpec, params: System2Params | None) -> Planner:
    from dualpilot.system2.fast.thorough import ThoroughSystem2

    return ThoroughSystem2(spec, params or System2Params())


def _certified(spec: MissionSpec, params: System2Params | None) -> Planner:
    from dualpilot.system2.certify.planner import CertifiedSystem2
    from dualpilot.warmup import warm_certificate

    warm_certificate()  # its kernels, before its first plan is timed
    return CertifiedSystem2(spec, params or System2Params())


def _rrt_risk(spec: MissionSpec, params: System1Params | None) -> Planner:
    from dualpilot.system1.planner import RiskSystem1, System1Params

    return RiskSystem1(spec, params or System1Params())


def _rrt_du_risk(spec: MissionSpec, params: System1Params | None) -> Planner:
    from dataclasses import replace

    from dualpilot.system1.planner import RiskSystem1, System1Params

    return RiskSystem1(spec, replace(params or System1Params(), tracker="lqr_du"))


SYSTEM1: Mapping[str, System1Constructor] = {"rrt": _rrt, "rrt+du": _rrt_du}
SYSTEM2: Mapping[str, System2Constructor] = {
    "fast": _fast, "exact": _exact, "fast+exact": _anytime, "thorough": _thorough,
    "certified": _certified,
}
#: The risk-aware variant of a method (it also takes the fire forecast, dualpilot/model/risk.py);
#: a method without one cannot fly a risk-aware controller.
RISK_AWARE: Mapping[int, Mapping[str, System1Constructor | System2Constructor]] = {
    1: {"rrt": _rrt_risk, "rrt+du": _rrt_du_risk},
    2: {"fast": _fast_risk},
}
#: Method names per system, the default first.
METHODS: Mapping[int, tuple[str, ...]] = {1: tuple(SYSTEM1), 2: tuple(SYSTEM2)}


def build_planner(system: int, spec: MissionSpec, method: str | None = None,
                  params: System1Params | System2Params | None = None,
                  risk: bool = False) -> Planner:
    """The planner of ``system`` (1 or 2) by method name (default: the system's first); with
    ``risk``, the method's risk-aware variant (:data:`RISK_AWARE`).

    ``params`` are that system's parameters (System1Params / System2Params).
    Raises ValueError for an unknown system or method, or a method with no risk-aware
    variant, TypeError for the other system's parameters.
    """
    if system not in METHODS:
        raise ValueError(f"unknown system {system!r}; choose 1 or 2")
    from dualpilot.warmup import warm_up

    warm_up()  # the compiled kernels, once a process, before any plan is timed
    method = METHODS[system][0] if method is None else method
    if method not in METHODS[system]:
        raise ValueError(f"unknown System {system} method {method!r}; "
                         f"choose from {METHODS[system]}")
    if risk and method not in RISK_AWARE[system]:
        raise ValueError(f"System {system} method {method!r} has no risk-aware variant; "
                         f"those that have: {tuple(RISK_AWARE[system])}")
    if system == 1:
        from dualpilot.system1.planner import System1Params

        if params is not None and not isinstance(params, System1Params):
            raise TypeError(f"System 1 takes System1Params, got {type(params).__name__}")
        make1 = RISK_AWARE[1][method] if risk else SYSTEM1[method]
        return make1(spec, params)  # type: ignore[arg-type]
    if params is not None and not isinstance(params, System2Params):
        raise TypeError(f"System 2 takes System2Params, got {type(params).__name__}")
    make2 = RISK_AWARE[2][method] if risk else SYSTEM2[method]
    return make2(spec, params)  # type: ignore[arg-type]


def build_planners(spec: MissionSpec, methods: Mapping[int, str] | None = None,
                   risk: bool = False, system1_params: System1Params | None = None,
                   system2_params: System2Params | None = None) -> dict[int, Planner]:
    """Both planners of a mission: {system: the planner of ``methods[system]`` (default: each
    system's first method)}, each its risk-aware variant with ``risk``."""
    methods = methods or {1: METHODS[1][0], 2: METHODS[2][0]}
    return {1: build_planner(1, spec, methods[1], system1_params, risk),
            2: build_planner(2, spec, methods[2], system2_params, risk)}
