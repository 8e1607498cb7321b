"""The core, every subpackage included, never imports network code (ARCHITECTURE §2).

Forbidden: zenoh, pymavlink, the services (``services``, its generated messages
``services.msgs`` included) and protobuf, by an import statement anywhere in a module
(inside functions and ``if TYPE_CHECKING:`` too) or by ``importlib.import_module`` /
``__import__`` of a literal name.
"""

import ast
from pathlib import Path

FORBIDDEN = ("zenoh", "pymavlink", "services", "google.protobuf")


def _forbidden(name: str) -> bool:
    return any(name == f or name.startswith(f + ".") for f in FORBIDDEN)


def _dynamic_import(node: ast.Call) -> str | None:
    """The literal module name of ``importlib.import_module("m")`` / ``__import__("m")``."""
    func = node.func
    called = func.attr if isinstance(func, ast.Attribute) else getattr(func, "id", None)
    if called not in ("import_module", "__import__") or not node.args:
        return None
    arg = node.args[0]
    return arg.value if isinstance(arg, ast.Constant) and isinstance(arg.value, str) else None


def imported_modules(tree: ast.Module) -> list[str]:
    """Every absolute module name a module imports, statically or by a literal dynamic import."""
    names: list[str] = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names += [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names += [node.module] + [f"{node.module}.{a.name}" for a in node.names]
        elif isinstance(node, ast.Call) and (name := _dynamic_import(node)) is not None:
            names.append(name)
    return names


def test_the_check_sees_every_kind_of_import():
    src = ("import zenoh\nfrom services import msgs\nimport importlib\n"
           "def f():\n    from pymavlink import mavutil\n"
           "    importlib.import_module('services.msgs')\n")
    found = {n for n in imported_modules(ast.parse(src)) if _forbidden(n)}
    assert {"zenoh", "services.msgs", "pymavlink", "pymavlink.mavutil"} <= found
    assert not _forbidden("zenohish") and not _forbidden("servicesx")


def test_core_modules_import_no_network_code():
    core = Path(__file__).resolve().parents[3] / "dualpilot"
    offenders = []
    for path in sorted(core.rglob("*.py")):
        tree = ast.parse(path.read_text())
        offenders += [f"{path.relative_to(core)}: {n}"
                      for n in imported_modules(tree) if _forbidden(n)]
    assert not offenders, offenders
