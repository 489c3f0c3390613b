"""docs/architecture.md's table of the rooms of ``bench/`` names every module of every
room, and every room it names exists: the table is how a newcomer finds a module, so a
module added without a line there is a module the docs hide."""

from __future__ import annotations

import re
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
DOC = REPO / "docs" / "architecture.md"
#: rooms whose modules the table lists one by one (console/ and commands/ are described
#: as a whole: a window's parts, one module per subcommand)
LISTED = ("engine", "rig", "plans", "store", "plan_runner", "figures", "jobs", "qt", "serve",
          "paths", "cli_args")


def _rooms_table() -> dict[str, str]:
    text = DOC.read_text(encoding="utf-8")
    table = text.split("<!-- rooms", 1)[1].split("<!-- /rooms -->", 1)[0]
    rows = {}
    for line in table.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) == 4 and (m := re.fullmatch(r"`([a-z_]+)(?:/|\.py)`", cells[1])):
            rows[m.group(1)] = cells[2]
    return rows


def test_every_room_of_bench_has_a_row_and_every_row_a_room() -> None:
    rows = _rooms_table()
    rooms = {p.name for p in (REPO / "bench").iterdir()
             if p.is_dir() and (p / "__init__.py").exists()}
    top = {p.stem for p in (REPO / "bench").glob("*.py") if p.stem != "__init__"}
    assert set(rows) == rooms | top


def test_the_table_names_every_module_of_the_listed_rooms() -> None:
    rows = _rooms_table()
    for room in LISTED:
        modules = {p.stem for p in (REPO / "bench" / room).glob("*.py")
                   if p.stem != "__init__"}
        named = set(re.findall(r"`([a-z_]+)`", rows[room]))
        assert modules <= named, f"bench/{room}/: {sorted(modules - named)} not in the table"
