"""The core, every subpackage included, never imports network code (ARCHITECTURE §2)."""

import ast
from pathlib import Path

FORBIDDEN = ("zenoh", "pymavlink", "services", "google.protobuf")


def test_core_modules_import_no_network_code():
    core = Path(__file__).resolve().parents[2] / "dualpilot"
    offenders = []
    for path in sorted(core.rglob("*.py")):
        tree = ast.parse(path.read_text())
        for node in ast.walk(tree):
            names = []
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                names = [node.module]
            offenders += [
                f"{path.relative_to(core)}: {n}"
                for n in names
                if n.split(".")[0] in FORBIDDEN or n in FORBIDDEN
            ]
    assert not offenders, offenders
