"""docs/index.md maps the docs: every page of docs/ is linked from it, and every page it
links exists, so a page added without a line there is a page nobody finds."""

from __future__ import annotations

import re
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
DOCS = REPO / "docs"


def _links(page: Path) -> set[str]:
    return set(re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", page.read_text(encoding="utf-8")))


def test_every_docs_page_is_linked_from_the_index() -> None:
    pages = {p.name for p in DOCS.glob("*.md")} - {"index.md"}
    linked = {link for link in _links(DOCS / "index.md") if "/" not in link}
    assert pages - linked == set()


def test_every_page_the_index_links_exists() -> None:
    missing = [link for link in _links(DOCS / "index.md")
               if not link.startswith("http") and not (DOCS / link).exists()]
    assert missing == []


def test_the_readme_links_the_index_and_only_pages_that_exist() -> None:
    links = _links(REPO / "README.md")
    assert "docs/index.md" in links
    missing = [link for link in links
               if not link.startswith("http") and not (REPO / link).exists()]
    assert missing == []


def test_the_readme_stays_a_front_door() -> None:
    """At most 150 lines: the results live in the docs pages."""
    assert len((REPO / "README.md").read_text(encoding="utf-8").splitlines()) <= 150
