"""The extension points: registries filled from entry points (dualpilot/extensions.py).

Built-in and installed entry points pass one loader; a clash, a bad name, a part that does
not load or is of the wrong type, or a part the registry refuses is an ExtensionError that
names who registered it. The registries here are real ones over real entry points (the
installed example package's among them), not stand-ins.
"""

from __future__ import annotations

from importlib.metadata import EntryPoint

import pytest

from dualpilot.extensions import ExtensionError, Registry, installed_points, origin
from dualpilot.mission.params import Controller
from dualpilot.planners import BUILTIN as PLANNERS_BUILTIN
from dualpilot.planners import REGISTRY as PLANNERS
from dualpilot.planners import PlannerMethod, planner_method
from dualpilot.supervisor.interface import SupervisorEntry
from dualpilot.supervisor.paper.planning import PaperSupervisor
from dualpilot.supervisor.registry import BUILTIN as SUPERVISORS_BUILTIN
from dualpilot.supervisor.registry import REGISTRY as SUPERVISORS
from dualpilot.supervisor.registry import supervisor_entry, supervisor_names

#: parts the tests below register under names of their own
SOLO = SupervisorEntry(lambda config, spec: PaperSupervisor(), frozenset({Controller.S1}))
WRONG_S1 = SupervisorEntry(lambda config, spec: PaperSupervisor(), system1_method="fast")


def planners(builtins: dict[str, str], installed: tuple[EntryPoint, ...] = ()
             ) -> Registry[PlannerMethod]:
    return Registry("dualpilot.planners", PlannerMethod, builtins, what="planning method",
                    name_pattern=PLANNERS.pattern.pattern, installed=lambda group: installed)


def supervisors(builtins: dict[str, str]) -> Registry[SupervisorEntry]:
    return Registry("dualpilot.supervisors", SupervisorEntry, builtins, what="supervisor",
                    name_pattern=SUPERVISORS.pattern.pattern, reserved=SUPERVISORS.reserved,
                    check=SUPERVISORS.check, installed=lambda group: ())


def test_the_builtins_are_entry_points_first_in_their_order() -> None:
    assert PLANNERS.names()[:7] == ("rrt", "rrt+du", "fast", "exact", "fast+exact", "thorough",
                                    "certified") == tuple(PLANNERS_BUILTIN)
    assert supervisor_names()[:3] == ("paper", "concurrent", "lookahead") == tuple(
        SUPERVISORS_BUILTIN)
    assert all(origin(PLANNERS.points()[n]) == "dualpilot (built in)" for n in PLANNERS_BUILTIN)
    assert planner_method("fast").system == 2 and planner_method("rrt+du").system == 1
    assert supervisor_entry("paper").controllers == frozenset(Controller)
    # the installed ones follow, each from its package
    for point in installed_points("dualpilot.supervisors"):
        assert point.name in supervisor_names()[3:] and point.dist is not None
        assert origin(point).startswith(f"package {point.dist.name} ")


def test_an_unknown_name_says_what_is_installed() -> None:
    with pytest.raises(ValueError, match=r"unknown supervisor 'warp'; installed: paper, "
                                         r"concurrent, lookahead"):
        supervisor_entry("warp")
    with pytest.raises(ValueError, match=r"unknown planning method 'warp'; installed: rrt, "):
        planner_method("warp")


def test_a_name_registered_twice_is_an_error_naming_both() -> None:
    twice = planners({"rrt": "dualpilot.planners:RRT"},
                     (EntryPoint("rrt", "dualpilot.planners:FAST", "dualpilot.planners"),))
    with pytest.raises(ExtensionError, match=r"'rrt' is registered twice, by dualpilot \(built "
                                             r"in\) \(dualpilot.planners:RRT\) and by dualpilot "
                                             r"\(built in\) \(dualpilot.planners:FAST\)"):
        twice.names()


def test_a_clash_with_an_installed_package_names_the_package() -> None:
    installed = {p.name: p for p in installed_points("dualpilot.planners")}
    assert "straight" in installed, "the example package is not installed: run make setup"
    dist = installed["straight"].dist
    assert dist is not None
    # a registry whose built-ins already have the name the example package installs
    clash = Registry("dualpilot.planners", PlannerMethod,
                     {"straight": "dualpilot.planners:RRT"}, what="planning method",
                     name_pattern=PLANNERS.pattern.pattern)
    with pytest.raises(ExtensionError, match=rf"'straight' is registered twice, by dualpilot "
                                             rf"\(built in\) .* and by package {dist.name} "):
        clash.names()


def test_a_name_of_the_wrong_form_or_a_reserved_one_is_refused() -> None:
    with pytest.raises(ExtensionError, match=r"registers 'Fast Lane' .* a name must match"):
        planners({"Fast Lane": "dualpilot.planners:FAST"}).names()
    with pytest.raises(ExtensionError, match=r"registers 's1' .* it is reserved \(cc, oracle, "
                                             r"s1, s2\)"):
        supervisors({"s1": "dualpilot.supervisor.paper.planning:ENTRY"}).names()


def test_a_broken_part_is_an_error_when_it_is_used_and_names_its_entry_point() -> None:
    broken = planners({"rrt": "dualpilot.planners:RRT",
                       "gone": "dualpilot.no_such_module:METHOD",
                       "typo": "dualpilot.planners:NO_SUCH_METHOD",
                       "odd": "dualpilot.spec:MissionSpec"})
    assert broken.names() == ("rrt", "gone", "typo", "odd")
    assert broken.get("rrt") is planner_method("rrt")  # the others do not stop this one
    with pytest.raises(ExtensionError, match=r"'gone' = dualpilot.no_such_module:METHOD of "
                                             r"dualpilot \(built in\) does not load: "
                                             r"ModuleNotFoundError"):
        broken.get("gone")
    with pytest.raises(ExtensionError, match=r"'typo' .* does not load: AttributeError"):
        broken.get("typo")
    with pytest.raises(ExtensionError, match=r"'odd' .* is a type, not a PlannerMethod"):
        broken.get("odd")


def test_a_supervisor_the_registry_refuses() -> None:
    refused = supervisors({"solo": "tests.unit.dualpilot.test_extensions:SOLO",
                           "wrongs1": "tests.unit.dualpilot.test_extensions:WRONG_S1"})
    with pytest.raises(ExtensionError, match=r"'solo' .* is refused: a supervisor other than "
                                             r"the paper's runs the cognitive controller only"):
        refused.get("solo")
    with pytest.raises(ExtensionError, match=r"'wrongs1' .* is refused: its System 1 method "
                                             r"'fast' is not System 1's"):
        refused.get("wrongs1")


def test_a_planning_method_plans_for_system_1_or_2() -> None:
    with pytest.raises(ValueError, match="System 1 or 2, not 3"):
        PlannerMethod(3, lambda spec, params: None)  # type: ignore[arg-type, return-value]
