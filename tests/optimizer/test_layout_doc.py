"""docs/architecture.md's table of the floors of ``optimizer/`` names every subpackage and
every module in it, in the order the import-linter contract enforces: the table is how a
newcomer finds a module and learns what it may import, so it must not drift from the code
or from ``pyproject.toml``."""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
DOC = REPO / "docs" / "architecture.md"
PACKAGE = REPO / "optimizer"
CONTRACT = "Floors of optimizer"


def _floors_table() -> list[tuple[int, str, str]]:
    """(floor, name, what lives there) per row, top first."""
    text = DOC.read_text(encoding="utf-8")
    table = text.split("<!-- floors of optimizer", 1)[1]
    table = table.split("<!-- /floors of optimizer -->", 1)[0]
    rows = []
    for line in table.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) == 4 and (m := re.fullmatch(r"`([a-z_]+)(?:/|\.py)`", cells[1])):
            rows.append((int(cells[0]), m.group(1), cells[2]))
    return rows


def _subpackages() -> set[str]:
    return {p.name for p in PACKAGE.iterdir() if p.is_dir() and (p / "__init__.py").exists()}


def test_every_subpackage_of_optimizer_has_a_row_and_every_row_a_package() -> None:
    top = {p.stem for p in PACKAGE.glob("*.py") if p.stem != "__init__"}
    assert {name for _, name, _ in _floors_table()} == _subpackages() | top


def test_the_table_names_every_module_of_every_subpackage() -> None:
    for _, name, what in _floors_table():
        if name not in _subpackages():
            continue
        modules = {p.stem for p in (PACKAGE / name).glob("*.py") if p.stem != "__init__"}
        named = set(re.findall(r"`([a-z_]+)`", what))
        assert modules <= named, f"optimizer/{name}/: {sorted(modules - named)} not in the table"


def test_the_table_floors_are_the_layers_of_the_contract() -> None:
    config = tomllib.loads((REPO / "pyproject.toml").read_text(encoding="utf-8"))
    contracts = config["tool"]["importlinter"]["contracts"]
    (contract,) = [c for c in contracts if c["name"].startswith(CONTRACT)]
    assert contract["type"] == "layers" and contract["containers"] == ["optimizer"]
    layers = [sorted(part.strip() for part in layer.split("|")) for layer in contract["layers"]]
    by_floor: dict[int, list[str]] = {}
    for floor, name, _ in _floors_table():
        by_floor.setdefault(floor, []).append(name)
    assert [sorted(by_floor[f]) for f in sorted(by_floor, reverse=True)] == layers
