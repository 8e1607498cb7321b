"""The unit tests mirror the packages: a test file sits in the folder named after its package.

``tests/unit/<a>/<b>/test_x.py`` tests the package ``a.b`` of this repository
(``dualpilot/…``, ``services/…`` or the example plug-in's ``dualpilot_example``): e.g.
``tests/unit/dualpilot/system2/fast/test_s2_speedups.py`` tests
``dualpilot/system2/fast/``. Only tests of the repository as a whole sit in
``tests/unit/`` itself (``ROOT_TESTS``). Every folder is a package (an ``__init__.py``),
so two packages may each have a ``test_config.py``. docs/testing.md states the rule; a
file that breaks it fails here with the folder it belongs in, read off its imports.
"""

from __future__ import annotations

import ast
from collections import Counter
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
UNIT = ROOT / "tests" / "unit"
#: where the repository's packages live: the root (dualpilot, services) and the example
#: plug-ins' source folders (dualpilot_example)
SOURCES = (ROOT, *sorted(ROOT.glob("examples/*/src")))
#: tests of the repository as a whole: the manual, the import graph, this rule
ROOT_TESTS = frozenset({"test_docs.py", "test_import_cycles.py", "test_lanes.py", "test_layout.py",
                        "test_rooms.py"})
#: folders of test data, not of tests
DATA = "data"


def package_dir(dotted: str) -> Path | None:
    """The source folder of the repository's package ``dotted`` (a.b.c), or None.

    The tests' own packages (``tests…``) are none: they hold tests, not what is tested.
    """
    if dotted.split(".")[0] == "tests":
        return None
    for source in SOURCES:
        folder = source.joinpath(*dotted.split("."))
        if (folder / "__init__.py").is_file():
            return folder
    return None


def package_tested(test: Path) -> str | None:
    """The repository package a test file imports most (names imported), or None.

    ``from a.b import c`` counts for the package ``a.b`` when c is a module or a name in
    it and for ``a.b.c`` when c is a package; ``import a.b.c`` for the package holding the
    module a.b.c.
    """
    counts: Counter[str] = Counter()
    for node in ast.walk(ast.parse(test.read_text(encoding="utf-8"))):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            for alias in node.names:
                full = f"{node.module}.{alias.name}"
                counts[full if package_dir(full) else node.module] += 1
        elif isinstance(node, ast.Import):
            for alias in node.names:
                counts[alias.name] += 1
    packages: Counter[str] = Counter()
    for name, n in counts.items():
        while name and package_dir(name) is None:
            name = name.rpartition(".")[0]
        if name:
            packages[name] += n
    return packages.most_common(1)[0][0] if packages else None


def misplaced(test: Path, unit: Path = UNIT) -> str | None:
    """Why ``test`` (under ``unit``) sits in the wrong folder and where it belongs, or None."""
    rel = test.relative_to(unit)
    folder = rel.parent.parts
    if not folder and rel.name in ROOT_TESTS:
        return None
    if folder and package_dir(".".join(folder)) is not None:
        return None
    where = f"tests/unit/{'/'.join(folder)}" if folder else "tests/unit/"
    package = package_tested(test)
    if package is None:
        hint = ("it imports no package of the repository: put it in the folder of the "
                "package it tests")
    else:
        target = f"tests/unit/{package.replace('.', '/')}/{rel.name}"
        hint = f"it imports mostly {package}: git mv tests/unit/{rel} {target}"
    return (f"tests/unit/{rel}: {where} names no package of the repository. A unit test "
            f"sits in tests/unit/<the path of the package it tests>/ (docs/testing.md, "
            f"'Where a unit test goes'); {hint}")


def test_every_unit_test_sits_in_the_folder_of_a_package() -> None:
    tests = sorted(p for p in UNIT.rglob("test_*.py") if DATA not in p.relative_to(UNIT).parts)
    assert len(tests) > 50
    wrong = [why for why in map(misplaced, tests) if why]
    assert not wrong, "\n".join(wrong)


def test_every_folder_of_unit_tests_is_a_package() -> None:
    folders = {p.parent.relative_to(UNIT) for p in UNIT.rglob("test_*.py")
               if DATA not in p.relative_to(UNIT).parts}
    missing = sorted({f"tests/unit/{sub}" for folder in folders
                      for sub in (folder, *folder.parents)
                      if not (UNIT / sub / "__init__.py").is_file()})
    assert not missing, (f"folders of unit tests without an __init__.py: {missing} (each test "
                         "module is named by its folders, so two packages may each have a "
                         "test_config.py)")


def test_a_test_out_of_place_is_told_where_it_belongs(tmp_path: Path) -> None:
    # a copy of tests/unit/ in tmp_path: a new file there, not in the tree under test
    test = tmp_path / "test_new.py"
    test.write_text("from dualpilot.model.geometry import Rect\n"
                    "from dualpilot.model.dynamics import DynamicsParams, step\n"
                    "from services.common import mav\n")
    why = misplaced(test, unit=tmp_path)
    assert why is not None and why.startswith("tests/unit/test_new.py: tests/unit/ names no")
    assert "git mv tests/unit/test_new.py tests/unit/dualpilot/model/test_new.py" in why
    (tmp_path / "system2").mkdir()
    wrong_folder = tmp_path / "system2" / "test_qp.py"
    wrong_folder.write_text("from dualpilot.system2.fast.qp import QpParams\n")
    why = misplaced(wrong_folder, unit=tmp_path)
    assert why is not None and "tests/unit/system2 names no package" in why
    assert ("git mv tests/unit/system2/test_qp.py "
            "tests/unit/dualpilot/system2/fast/test_qp.py") in why
    (tmp_path / "dualpilot" / "viz").mkdir(parents=True)
    right = tmp_path / "dualpilot" / "viz" / "test_new.py"
    right.write_text("import numpy\n")
    assert misplaced(right, unit=tmp_path) is None


def test_the_rule_reads_folders_and_imports() -> None:
    assert package_dir("dualpilot.system2.fast") == ROOT / "dualpilot" / "system2" / "fast"
    assert package_dir("services.supervisor.link") is not None
    assert package_dir("dualpilot_example") is not None
    assert package_dir("dualpilot.system2.fast.qp") is None  # a module, not a package
    assert package_dir("tests.unit") is None
    assert misplaced(UNIT / "dualpilot" / "system2" / "fast" / "test_s2_speedups.py") is None
    assert misplaced(UNIT / "test_docs.py") is None
    here = package_tested(UNIT / "services" / "supervisor" / "test_pool.py")
    assert here == "services.supervisor"
