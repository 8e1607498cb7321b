"""No import cycles among the modules of ``dualpilot/`` and ``services/`` (ARCHITECTURE §2).

The graph has an edge a → b for every ``import`` / ``from … import`` in module a that
names module b, at any depth: inside functions too (a lazy import still ties the two
modules together) and under ``if TYPE_CHECKING:`` too (an import for the type checker
alone still makes a circle the reader has to follow: ARCHITECTURE §2). ``from p import
x`` names the module ``p.x`` when there is one, else ``p``; an import of a module outside
the two packages is no edge. A package's ``__init__`` is the module named after it.
"""

from __future__ import annotations

import ast
from collections.abc import Iterator
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
PACKAGES = ("dualpilot", "services")


def module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def modules() -> dict[str, Path]:
    """Every module of the packages, by dotted name."""
    return {module_name(p): p for pkg in PACKAGES for p in sorted((ROOT / pkg).rglob("*.py"))}


def _type_checking(test: ast.expr) -> bool:
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING")


def imported_names(tree: ast.Module, name: str, is_package: bool,
                   type_checking: bool = True) -> Iterator[str]:
    """The dotted names each import statement of a module names (``p`` and ``p.x`` for
    ``from p import x``), relative imports resolved; ``if TYPE_CHECKING:`` bodies included
    unless ``type_checking`` is False."""
    stack: list[ast.AST] = [tree]
    while stack:
        node = stack.pop()
        if not type_checking and isinstance(node, ast.If) and _type_checking(node.test):
            stack.extend(node.orelse)
            continue
        if isinstance(node, ast.Import):
            yield from (alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parts = name.split(".") if is_package else name.split(".")[:-1]
                parts = parts[: len(parts) - node.level + 1]
                base = ".".join([*parts, *([node.module] if node.module else [])])
            yield base
            yield from (f"{base}.{alias.name}" for alias in node.names)
        stack.extend(ast.iter_child_nodes(node))


def import_graph() -> dict[str, set[str]]:
    """Module → the modules of the packages it imports."""
    mods = modules()

    def known(target: str) -> str | None:
        parts = target.split(".")
        while parts and ".".join(parts) not in mods:
            parts.pop()
        return ".".join(parts) or None

    graph: dict[str, set[str]] = {}
    for name, path in mods.items():
        tree = ast.parse(path.read_text(), filename=str(path))
        targets = {known(t) for t in imported_names(tree, name, path.name == "__init__.py")}
        graph[name] = {t for t in targets if t is not None and t != name}
    return graph


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One cycle of ``graph`` as its modules, the first repeated at the end; None if none
    (a depth-first search: an edge back to a module on the current path closes a cycle)."""
    done: set[str] = set()
    for root in sorted(graph):
        if root in done:
            continue
        path = [root]
        branches = [iter(sorted(graph[root]))]
        while branches:
            nxt = next(branches[-1], None)
            if nxt is None:
                done.add(path.pop())
                branches.pop()
            elif nxt in path:
                return [*path[path.index(nxt):], nxt]
            elif nxt not in done:
                path.append(nxt)
                branches.append(iter(sorted(graph.get(nxt, set()))))
    return None


def test_the_graph_sees_lazy_imports_and_type_checking_blocks() -> None:
    src = ("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    import dualpilot.cli\n"
           "else:\n    import dualpilot.spec\n"
           "def f():\n    from dualpilot.model import fire\n    from . import spec\n")
    names = set(imported_names(ast.parse(src), "dualpilot.mission.step", False))
    assert {"dualpilot.model.fire", "dualpilot.mission.spec", "dualpilot.cli",
            "dualpilot.spec"} <= names
    runtime = set(imported_names(ast.parse(src), "dualpilot.mission.step", False, False))
    assert "dualpilot.cli" not in runtime and "dualpilot.spec" in runtime


def test_a_circle_through_a_type_checking_import_is_a_cycle() -> None:
    # a.py imports b for the type checker only, b.py imports a: the graph has the circle
    a = "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from dualpilot.b import B\n"
    b = "from dualpilot.a import A\n"
    graph = {m: {t for t in imported_names(ast.parse(src), m, False) if t in ("dualpilot.a",
                                                                             "dualpilot.b")}
             for m, src in (("dualpilot.a", a), ("dualpilot.b", b))}
    assert find_cycle(graph) == ["dualpilot.a", "dualpilot.b", "dualpilot.a"]


def test_find_cycle_reports_the_modules_of_a_cycle() -> None:
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a", "d"}, "d": set()}
    assert find_cycle(graph) == ["a", "b", "c", "a"]
    assert find_cycle({"a": {"b"}, "b": set(), "c": {"b"}}) is None


def test_no_import_cycles() -> None:
    graph = import_graph()
    assert "dualpilot.mission.step" in graph and "services.supervisor.session" in graph
    cycle = find_cycle(graph)
    assert cycle is None, "import cycle: " + " -> ".join(cycle or [])
