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


@pytest.mark.parametrize("data_set", ["sizinglab", "broad", "esc_test"])
def test_each_shipped_data_set_has_its_licence_and_source(data_set: str) -> None:
    folder = REPO / "fixtures" / "data" / data_set
    assert (folder / "LICENSE").stat().st_size > 500
    source = (folder / "SOURCE.md").read_text(encoding="utf-8")
    assert "Shipped in this repository under" in source and "commit" in source
