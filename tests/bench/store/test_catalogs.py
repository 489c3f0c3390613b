"""Catalog names and ties as a new user met them."""

from __future__ import annotations

import json
import re
from pathlib import Path

from bench.cli import main

CATALOGS_DOC = Path(__file__).resolve().parents[3] / "docs" / "catalogs.md"


def test_every_catalog_the_docs_name_as_shipped_works_by_name(capsys):
    """docs/catalogs.md names the shipped catalogs; every name it lists works with
    `--catalog NAME` (`thesis-robot`, the section 2.4.1 robot example, is refused there and
    must not be listed as shipped)."""
    text = " ".join(CATALOGS_DOC.read_text(encoding="utf-8").split())
    sentence = re.search(r"The default catalog is `optimizer/data/catalogs/(\S+?)`[^;]*; (.*?) "
                         r"(?:is|are) shipped too", text)
    assert sentence is not None, "docs/catalogs.md: the sentence naming the shipped catalogs moved"
    names = [sentence.group(1), *re.findall(r"`([\w-]+)`", sentence.group(2))]
    assert "thesis-d" in names
    for name in names:
        code = main(["optimize", "--catalog", name, "--json"])
        out, err = capsys.readouterr()
        assert code in (0, 3), f"--catalog {name}: {err}"
        assert json.loads(out)["catalog"].endswith(name)


def test_optimize_explains_what_tied_means_and_names_the_designs(capsys):
    """The Status row said '3 tied' and nothing else."""
    assert main(["optimize"]) == 0
    out = " ".join(capsys.readouterr().out.split())
    assert "3 tied" in out
    assert ("3 tied (4, 6, 8 actuators): P4/M1/B3 (chosen), P4/M2/B3, P4/M3/B3 reach the "
            "same flight-time (within 1e-06 relative) and differ only in the motor; the chosen "
            "one comes first by lower price, then faster actuators") in out
    assert "--current-model drive counts the motor's losses" in out
    assert main(["optimize", "--json"]) == 0
    designs = json.loads(capsys.readouterr().out)["designs"]
    assert designs[0]["tied_designs"] == ["P4/M1/B3", "P4/M2/B3", "P4/M3/B3"]
