"""Careless files a new user hands the CLI (issue 21, part 3): bytes that are not UTF-8,
damaged BROAD files, a log cut mid-line, a log with one enormous line. Each answer is one
line on stderr naming the file, exit code 2, no traceback, nothing half-written."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from tests.test_cli_errors import run_bad

NOT_UTF8 = b"# caf\xe9 \xff\xfe\n"


# --- row 10: a catalog's catalog.toml (and every other TOML file) that is not UTF-8 --------


def test_catalog_toml_not_utf8(tmp_path: Path, capsys, fixtures_dir: Path) -> None:
    """`optimize` on a catalog whose catalog.toml holds a Latin-1 byte: a traceback."""
    cat = tmp_path / "cat"
    shutil.copytree(fixtures_dir / "catalogs" / "thesis-e", cat)
    with (cat / "catalog.toml").open("ab") as fh:
        fh.write(NOT_UTF8)
    for argv in (["optimize"], ["pareto"]):  # every sizing command shares the loader
        err = run_bad(capsys, *argv, "--catalog", str(cat))
        assert f"{cat / 'catalog.toml'}: invalid TOML: 'utf-8' codec can't decode" in err


def test_robot_toml_and_csv_not_utf8(tmp_path: Path, fixtures_dir: Path) -> None:
    """The mobile-robot example's robot.toml and batteries.csv read the locale's encoding."""
    from optimizer.errors import CatalogError
    from optimizer.robot import load_robot

    robot = tmp_path / "robot"
    shutil.copytree(fixtures_dir / "catalogs" / "thesis-robot", robot)
    with (robot / "robot.toml").open("ab") as fh:
        fh.write(NOT_UTF8)
    with pytest.raises(CatalogError, match="robot.toml: not valid TOML"):
        load_robot(robot)
    shutil.copy(fixtures_dir / "catalogs" / "thesis-robot" / "robot.toml", robot)
    with (robot / "batteries.csv").open("ab") as fh:
        fh.write(NOT_UTF8)
    with pytest.raises(CatalogError, match="batteries.csv: not UTF-8 text"):
        load_robot(robot)


def test_sequence_toml_not_utf8(tmp_path: Path, capsys) -> None:
    seq = tmp_path / "seq.toml"
    seq.write_bytes(b'name = "x"\n' + NOT_UTF8)
    err = run_bad(capsys, "step", "--sequence", str(seq), "--dry-run")
    assert f"{seq}: not a readable JSON/TOML sequence" in err
