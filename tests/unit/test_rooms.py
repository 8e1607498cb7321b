"""Rooms of one concern: the house's size limits on the code of dualpilot/ and services/.

docs/architecture.md: no class over 300 lines, no file over 600, no function over 60 and
no constructor over 8 arguments (``self`` aside), generated messages (services/msgs)
aside. A room that outgrows them is split by concern, not squeezed.
"""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
GENERATED = ROOT / "services" / "msgs"
MAX_FILE, MAX_CLASS, MAX_FUNCTION, MAX_ARGS = 600, 300, 60, 8


def _sources() -> list[Path]:
    files = [p for pkg in ("dualpilot", "services") for p in sorted((ROOT / pkg).rglob("*.py"))]
    return [p for p in files if GENERATED not in p.parents]


def oversized(text: str, name: str) -> list[str]:
    """Each limit the module ``name`` of source ``text`` breaks, as 'name:line what (size)'."""
    lines = text.count("\n")
    found = [f"{name} file ({lines} lines)"] if lines > MAX_FILE else []
    for node in ast.walk(ast.parse(text)):
        if not isinstance(node, ast.ClassDef | ast.FunctionDef | ast.AsyncFunctionDef):
            continue
        size = (node.end_lineno or node.lineno) - node.lineno + 1
        if isinstance(node, ast.ClassDef):
            if size > MAX_CLASS:
                found.append(f"{name}:{node.lineno} class {node.name} ({size} lines)")
            continue
        if size > MAX_FUNCTION:
            found.append(f"{name}:{node.lineno} function {node.name} ({size} lines)")
        args = node.args
        n = len(args.posonlyargs) + len(args.args) + len(args.kwonlyargs) - 1  # self
        if node.name == "__init__" and n > MAX_ARGS:
            found.append(f"{name}:{node.lineno} constructor ({n} arguments)")
    return found


def test_every_room_keeps_the_house_limits() -> None:
    files = _sources()
    assert len(files) > 100
    broken = [line for path in files
              for line in oversized(path.read_text(encoding="utf-8"),
                                    path.relative_to(ROOT).as_posix())]
    assert not broken, "\n".join(broken)


def test_the_check_sees_a_room_too_big() -> None:
    body = "\n".join(f"    x{k} = {k}" for k in range(61))
    args = ", ".join(f"a{k}" for k in range(9))
    src = f"def long():\n{body}\n\n\nclass C:\n    def __init__(self, {args}):\n        pass\n"
    found = oversized(src, "probe.py")
    assert found == ["probe.py:1 function long (62 lines)", "probe.py:66 constructor (9 arguments)"]
    assert oversized(src.replace(", a8", ""), "p.py") == ["p.py:1 function long (62 lines)"]
    assert oversized("x = 1\n" * 601, "big.py") == ["big.py file (601 lines)"]
