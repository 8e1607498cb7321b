"""The planners of a mission, built by name from its :class:`dualpilot.spec.MissionSpec`.

One registry, like python-control's ``trajectory_method=``: System 1's "rrt"
(Alg. 1 + LQR) and "rrt+du" (its LQR with the Δu penalty), System 2's "fast" (the
default), "exact" (the cvxpy MIQP, solved in a killable worker process), "fast+exact",
"thorough" and "certified" (the fast plan with a lower bound on (P2) proven by branch and
bound). With ``risk`` a method's risk-aware variant (System 1's "rrt" and "rrt+du",
System 2's "fast") also takes the fire forecast as a chance constraint
(dualpilot/model/risk.py). Every planner implements :class:`dualpilot.plan.Planner`.

The registry is the public extension point of entry-point group ``dualpilot.planners``
(:mod:`dualpilot.extensions`): each name is a :class:`PlannerMethod`; the built-ins are the
entry points of :data:`BUILTIN`, and a separately installed package adds a method of
System 1 or System 2 by naming its own (docs/extending.md). The first method of a system
(the built-ins come first) is its default.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from dualpilot.extensions import ExtensionError, Registry
from dualpilot.plan import Planner
from dualpilot.spec import MissionSpec
from dualpilot.system2.problem import System2Params

if TYPE_CHECKING:
    from dualpilot.model.fire_height import FireHeightParams
    from dualpilot.system1.planner import System1Params

__all__ = ["PlannerMethod", "Planner", "build_planner", "build_planners", "default_method",
           "method_names", "planner_method", "risk_aware_names"]

#: A constructor of the registry: (spec, that system's parameters or None for the defaults)
#: -> Planner.
Constructor = Callable[[MissionSpec, Any], Planner]
#: Which 3-D missions a method of ``dims`` {2, 3} plans: (the 3-D spec, the fronts' height
#: reading, the fire scenario) -> "" (it plans them) or why not, a sentence after its name.
Scope3 = Callable[[MissionSpec, "FireHeightParams", str], str]


@dataclass(frozen=True)
class PlannerMethod:
    """One planning method of the registry: the system it plans for (1 or 2), how it is
    built, and how its risk-aware variant is built (None: it has none).

    Each constructor gets the mission's spec and that system's parameters
    (:class:`~dualpilot.system1.planner.System1Params` or
    :class:`~dualpilot.system2.problem.System2Params`; None: the defaults) and returns a
    :class:`~dualpilot.plan.Planner` of ``system``; a risk-aware one is a
    :class:`~dualpilot.plan.ForecastPlanner`.
    """

    system: int
    build: Constructor
    build_risk: Constructor | None = None
    #: one line for listings
    summary: str = ""
    #: the dimensions (``DynamicsParams.dim``) it plans in: 2 (the top-down evaluation)
    #: unless it says 3 too (docs/three_d.md)
    dims: frozenset[int] = frozenset({2})
    #: for a method of 3-D missions over some fronts only: which (None: every one); read
    #: before a mission starts (:mod:`dualpilot.mission.dimension`)
    scope3: Scope3 | None = None

    def __post_init__(self) -> None:
        if self.system not in (1, 2):
            raise ValueError(f"a planning method plans for System 1 or 2, not {self.system!r}")
        if not self.dims or not self.dims <= {2, 3}:
            raise ValueError(f"a planning method plans in 2-D, 3-D or both, not {self.dims}")


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


def _certified_scope(spec: MissionSpec, heights: FireHeightParams, scenario: str) -> str:
    from dualpilot.system2.certify.planner3 import certifies_3d

    return certifies_3d(spec, heights, scenario)


def _rrt_risk(spec: MissionSpec, params: System1Params | None) -> Planner:
    from dualpilot.system1.planner import RiskSystem1, System1Params

    return RiskSystem1(spec, params or System1Params())


def _rrt_du_risk(spec: MissionSpec, params: System1Params | None) -> Planner:
    from dataclasses import replace

    from dualpilot.system1.planner import RiskSystem1, System1Params

    return RiskSystem1(spec, replace(params or System1Params(), tracker="lqr_du"))


RRT = PlannerMethod(1, _rrt, _rrt_risk, "Alg. 1 (RRT, or the operator's waypoints) with LQR "
                    "tracking", frozenset({2, 3}))
RRT_DU = PlannerMethod(1, _rrt_du, _rrt_du_risk, "Alg. 1 with LQR tracking under a Δu penalty",
                       frozenset({2, 3}))
FAST = PlannerMethod(2, _fast, _fast_risk, "(P2) by homotopy-seeded convex restrictions",
                     dims=frozenset({2, 3}))
EXACT = PlannerMethod(2, _exact, None, "(P2) as the cvxpy MIQP, in a killable worker process",
                      dims=frozenset({2, 3}))
ANYTIME = PlannerMethod(2, _anytime, None, "the fast plan, then SCIP seeded with it",
                        dims=frozenset({2, 3}))
THOROUGH = PlannerMethod(2, _thorough, None, "the fast method, every homotopy to convergence",
                         dims=frozenset({2, 3}))
CERTIFIED = PlannerMethod(2, _certified, None, "the fast plan with a lower bound on (P2) "
                          "proven by branch and bound", dims=frozenset({2, 3}),
                          scope3=_certified_scope)

#: The built-in methods: entry points of ``dualpilot.planners`` (name -> "module:attribute"),
#: each system's default first.
BUILTIN: Mapping[str, str] = {
    "rrt": "dualpilot.planners:RRT", "rrt+du": "dualpilot.planners:RRT_DU",
    "fast": "dualpilot.planners:FAST", "exact": "dualpilot.planners:EXACT",
    "fast+exact": "dualpilot.planners:ANYTIME", "thorough": "dualpilot.planners:THOROUGH",
    "certified": "dualpilot.planners:CERTIFIED",
}
#: The registry of planning methods (built-in and installed).
REGISTRY: Registry[PlannerMethod] = Registry(
    "dualpilot.planners", PlannerMethod, BUILTIN, what="planning method",
    name_pattern=r"[a-z][a-z0-9_.+-]{0,63}")


def planner_method(name: str) -> PlannerMethod:
    """The method registered as ``name`` (ValueError: none is)."""
    return REGISTRY.get(name)


def method_names(system: int) -> tuple[str, ...]:
    """The names of ``system``'s methods, its default first (loads every installed method)."""
    return tuple(n for n in REGISTRY.names() if REGISTRY.get(n).system == system)


def risk_aware_names(system: int) -> tuple[str, ...]:
    """The names of ``system``'s methods that have a risk-aware variant."""
    return tuple(n for n in method_names(system) if REGISTRY.get(n).build_risk is not None)


def default_method(system: int) -> str:
    """``system``'s default method: its first (a built-in; no installed method is loaded)."""
    return next(n for n in REGISTRY.names() if REGISTRY.get(n).system == system)


def _method_of(system: int, name: str) -> PlannerMethod:
    """The method ``name`` of ``system`` (ValueError: unknown, or another system's)."""
    if name not in REGISTRY.names():
        raise ValueError(f"unknown System {system} method {name!r}; "
                         f"choose from {method_names(system)}")
    entry = REGISTRY.get(name)
    if entry.system != system:
        raise ValueError(f"{name!r} is a System {entry.system} method, not System {system}'s; "
                         f"choose from {method_names(system)}")
    return entry


def build_planner(system: int, spec: MissionSpec, method: str | None = None,
                  params: System1Params | System2Params | None = None,
                  risk: bool = False) -> Planner:
    """The planner of ``system`` (1 or 2) by method name (default: the system's first); with
    ``risk``, the method's risk-aware variant.

    ``params`` are that system's parameters (System1Params / System2Params).
    Raises ValueError for an unknown system or method, or a method with no risk-aware
    variant, TypeError for the other system's parameters; ExtensionError for an installed
    method that does not load or builds a planner of another system.
    """
    if system not in (1, 2):
        raise ValueError(f"unknown system {system!r}; choose 1 or 2")
    from dualpilot.warmup import warm_up, warm_up_3d

    warm_up((system,))  # this system's compiled kernels, once a process, before a plan is timed
    if spec.dim == 3:
        warm_up_3d((system,))  # and its 3-D ones, where a 3-D mission is planned
    method = default_method(system) if method is None else method
    entry = _method_of(system, method)
    if risk and entry.build_risk is None:
        raise ValueError(f"System {system} method {method!r} has no risk-aware variant; "
                         f"those that have: {risk_aware_names(system)}")
    if spec.dim not in entry.dims:
        raise ValueError(f"System {system} method {method!r} plans in "
                         f"{' and '.join(f'{d}-D' for d in sorted(entry.dims))} only, not "
                         f"dim={spec.dim}" + (f": {spec.dim}-D planning for it is not built "
                                              "yet (docs/three_d.md, Status)"
                                              if method in BUILTIN else ""))
    if system == 1:
        from dualpilot.system1.planner import System1Params

        if params is not None and not isinstance(params, System1Params):
            raise TypeError(f"System 1 takes System1Params, got {type(params).__name__}")
    elif params is not None and not isinstance(params, System2Params):
        raise TypeError(f"System 2 takes System2Params, got {type(params).__name__}")
    make = entry.build_risk if risk and entry.build_risk is not None else entry.build
    planner = make(spec, params)
    if getattr(planner, "system", None) != system:
        raise ExtensionError(f"the {method!r} method built a planner of system "
                             f"{getattr(planner, 'system', None)!r}, not {system}")
    return planner


def build_planners(spec: MissionSpec, methods: Mapping[int, str] | None = None,
                   risk: bool = False, system1_params: System1Params | None = None,
                   system2_params: System2Params | None = None) -> dict[int, Planner]:
    """Both planners of a mission: {system: the planner of ``methods[system]`` (default: each
    system's first method)}, each its risk-aware variant with ``risk``."""
    methods = methods or {1: default_method(1), 2: default_method(2)}
    return {1: build_planner(1, spec, methods[1], system1_params, risk),
            2: build_planner(2, spec, methods[2], system2_params, risk)}
