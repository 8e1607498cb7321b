"""The documentation: the site builds strictly, the paths it names exist, and it cites only itself.

* ``mkdocs build --strict`` (mkdocs.yml, docs/): a broken link between pages,
  a missing anchor or a page left out of the nav fails the build.
* README.md and every page of docs/ name files of the repository (links, and
  paths such as ``dualpilot/model/fire.py`` in text or code): each must exist.
* No tracked file cites a file outside the repository (a sibling checkout, a
  machine's scratch or home directories, a document that is not tracked): the
  paper is cited by its title and authors, and what we rely on is written here.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PAGES = sorted((ROOT / "docs").glob("*.md"))
MANUALS = [ROOT / "README.md", *PAGES]

# top-level parts of the tree that prose names by path
TOP = ("dualpilot", "services", "tests", "benchmarks", "docs", "scripts", "proto", "examples")
PATH = re.compile(r"(?<![\w./<-])((?:" + "|".join(TOP) + r")/[\w./-]*)")
LINK = re.compile(r"\]\(([^)\s]+)\)")


def tracked() -> list[Path]:
    out = subprocess.run(["git", "ls-files", "-z"], cwd=ROOT, capture_output=True, check=True)
    return [ROOT / p for p in out.stdout.decode().split("\0") if p]


def text(path: Path) -> str | None:
    try:
        return path.read_text(encoding="utf-8")
    except (UnicodeDecodeError, FileNotFoundError, IsADirectoryError):
        return None


@pytest.mark.slow  # a process of its own (make test-fast leaves it out)
def test_the_site_builds_strictly(tmp_path: Path) -> None:
    # no --quiet: it raises mkdocs' log level above WARNING, and --strict counts only the
    # warnings it logs, so a broken anchor would pass
    env = {**os.environ, "NO_MKDOCS_2_WARNING": "1"}
    run = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict",
         "--config-file", str(ROOT / "mkdocs.yml"), "--site-dir", str(tmp_path / "site")],
        cwd=ROOT, env=env, capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stdout + run.stderr
    assert (tmp_path / "site" / "index.html").is_file()
    for page in PAGES:
        assert (tmp_path / "site" / page.stem / "index.html").is_file() or page.stem == "index"


def test_every_page_is_in_the_nav() -> None:
    nav = (ROOT / "mkdocs.yml").read_text()
    listed = set(re.findall(r":\s*([\w.-]+\.md)\s*$", nav, re.M))
    missing = [p.name for p in PAGES if p.name not in listed]
    assert not missing, f"pages not in mkdocs.yml's nav: {missing}"


def test_readme_links_point_into_the_repository() -> None:
    readme = (ROOT / "README.md").read_text()
    bad = []
    for target in LINK.findall(readme):
        if re.match(r"[a-z]+:", target) or target.startswith("#"):
            continue
        path = (ROOT / target.split("#", 1)[0]).resolve()
        if ROOT not in path.parents or not path.exists():
            bad.append(target)
    assert not bad, f"README.md links to what is not in the repository: {bad}"


def test_paths_named_in_readme_and_docs_exist() -> None:
    bad = []
    for page in MANUALS:
        body = re.sub(r"https?://\S+", "", page.read_text())
        for name in PATH.findall(body):
            name = name.rstrip(".")
            if not (ROOT / name).exists():
                bad.append(f"{page.relative_to(ROOT)}: {name}")
    assert not bad, "paths that do not exist:\n" + "\n".join(bad)


def test_no_file_cites_files_outside_the_repository() -> None:
    files = tracked()
    names = {p.name for p in files}
    # written so that this file does not match itself
    everywhere = [
        re.compile(r"\.\./+shar[e]d\b"),                 # a sibling checkout's shared folder
        re.compile(r"shared/pape[r]\b"),
        re.compile(r"(?<![\w.])/wor[k]/"),                # the machine's work tree
        re.compile(r"(?<![\w.])/hom[e]/\w"),
    ]
    if "ARCHITECTURE" + ".md" not in names:                # not a file of ours
        everywhere.append(re.compile(r"\bARCHITECTUR[E]\.md\b"))
    in_prose = [
        re.compile(r"(?<![\w.])/tm[p]/\w"),               # a scratch file cited as a source
        re.compile(r"\]\((?:\./)?\.\./"),                 # a link that leaves the tree...
    ]
    bad = []
    for path in files:
        body = text(path)
        if body is None:
            continue
        rel = path.relative_to(ROOT)
        patterns = everywhere + (in_prose if path.suffix in (".md", ".rst", ".txt") else [])
        for pattern in patterns:
            for m in pattern.finditer(body):
                if pattern is in_prose[1]:
                    target = body[m.start() + 2:].split(")", 1)[0]
                    if ROOT in (path.parent / target).resolve().parents:
                        continue                          # ...unless it stays inside it
                line = body.count("\n", 0, m.start()) + 1
                bad.append(f"{rel}:{line}: {m.group()}")
    assert not bad, "citations of files outside the repository:\n" + "\n".join(bad)
