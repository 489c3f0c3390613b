"""A clone with nothing beside it is what a user gets: no code, test, benchmark or doc
reaches for a folder next to the repository, and the data sets it ships carry their
licence and say under what they are redistributed."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
TEXT = ("*.py", "*.md", "*.toml", "Makefile", "*.txt", "*.cfg", "*.sh")
# the folder beside the repository, written as a relative path or as a pathlib parent of
# this repository (built from its parts, so this file does not name it itself)
_NAME = "sha" + "red"
OUTSIDE = re.compile(rf"\.\./{_NAME}\b|parent\s*/\s*[\"']{_NAME}[\"']|"
                     rf"parents\[2\]\s*/\s*[\"']{_NAME}")


def _files() -> list[Path]:
    skip = {".venv", ".git", "out", "runs", "build", "dist"}
    found = []
    for pattern in TEXT:
        for p in REPO.rglob(pattern):
            if not skip & set(p.relative_to(REPO).parts):
                found.append(p)
    return found


def test_nothing_reaches_beside_the_repository() -> None:
    hits = [f"{p.relative_to(REPO)}:{i}: {line.strip()}"
            for p in _files()
            for i, line in enumerate(p.read_text(encoding="utf-8", errors="replace")
                                     .splitlines(), 1)
            if OUTSIDE.search(line)]
    assert hits == []


@pytest.mark.parametrize("data_set", ["optimizer/data/sizinglab", "fixtures/data/broad",
                                      "fixtures/data/esc_test", "fixtures/data/px4_ulog"])
def test_each_shipped_data_set_has_its_licence_and_source(data_set: str) -> None:
    folder = REPO / data_set
    assert (folder / "LICENSE").stat().st_size > 500
    source = (folder / "SOURCE.md").read_text(encoding="utf-8")
    assert "Shipped in this repository under" in source and "commit" in source


def _skips_for_data(path: Path) -> list[str]:
    """Test functions of ``path`` that read the shipped data and can call ``pytest.skip``."""
    import ast

    tree = ast.parse(path.read_text(encoding="utf-8"))
    found = []
    for fn in ast.walk(tree):
        if not isinstance(fn, ast.FunctionDef | ast.AsyncFunctionDef):
            continue
        names = {n.id for n in ast.walk(fn) if isinstance(n, ast.Name)}
        names |= {a.arg for a in fn.args.args}
        skips = any(isinstance(c, ast.Call) and isinstance(c.func, ast.Attribute)
                    and c.func.attr in ("skip", "xfail") for c in ast.walk(fn))
        if skips and names & {"shared_data", "SHARED_DATA"}:
            found.append(f"{path.relative_to(REPO)}::{fn.name}")
    return found


def test_no_test_skips_for_want_of_the_shipped_data() -> None:
    """The data ship with the repository, so a test that reads them fails when they are
    gone; a skip would hide a clone that lost them (make test skipped 44 for want of data)."""
    assert [hit for p in sorted((REPO / "tests").rglob("*.py"))
            for hit in _skips_for_data(p)] == []


NOTES = re.compile(r"reference/[\w-]+\.md")
UNSHIPPED = re.compile(r"not\s+shipped|not\s+in\s+this\s+repository")


def test_the_research_notes_cited_say_they_do_not_ship() -> None:
    """The project's research notes (``reference/*.md``) stay beside the repository: a
    citation of one says so in its paragraph, so a reader of a clone does not look for it."""
    bare = []
    for p in _files():
        text = p.read_text(encoding="utf-8", errors="replace")
        for para in re.split(r"\n\s*\n", text):
            if NOTES.search(para) and not UNSHIPPED.search(para):
                bare.append(f"{p.relative_to(REPO)}: {NOTES.search(para).group()}")
    assert bare == []
