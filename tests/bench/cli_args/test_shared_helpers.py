"""Library helpers the CLI commands share: catalog choice, the design table's cells, the
sizing options, a run refused by the constants fit."""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import numpy as np
import pytest

from bench.cli_args.option_values import option_defaults
from bench.cli_args.sizing_args import (
    add_measured_args,
    add_rule_args,
    json_default,
    measured_from_args,
    rules_from_args,
)
from bench.errors import RigError
from bench.figures.design_tables import format_cell
from bench.store.catalogs import SHIPPED_CATALOGS, default_catalog, load, shipped_catalog
from bench.store.constants_fit import fit_for_store
from optimizer.errors import CatalogError, RequestError


def test_catalog_names_env_and_default(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("ROTORBENCH_CATALOG", raising=False)
    assert default_catalog() == SHIPPED_CATALOGS / "thesis-e"
    assert load(None).source == shipped_catalog("thesis-e").source
    assert "thesis-d" in str(load(Path("thesis-d")).source)
    monkeypatch.setenv("ROTORBENCH_CATALOG", "thesis-d")
    assert default_catalog() == SHIPPED_CATALOGS / "thesis-d"
    monkeypatch.setenv("ROTORBENCH_CATALOG", "nosuch")
    with pytest.raises(CatalogError, match="ROTORBENCH_CATALOG=nosuch"):
        load(None)


def test_format_cell():
    assert format_cell(None, ".1f") == "-"
    assert format_cell(math.nan, ".1f") == "-"
    assert format_cell(math.inf, ".1f") == "-"
    assert format_cell(12.345, ".1f") == "12.3"
    assert format_cell("P4", "s") == "P4"


def test_json_default():
    doc = {"a": np.float64(1.5), "b": (1, 2), "c": np.int64(3)}
    assert json.loads(json.dumps(doc, default=json_default)) == {"a": 1.5, "b": [1, 2], "c": 3}
    with pytest.raises(TypeError, match="not JSON serialisable: object"):
        json.dumps({"x": object()}, default=json_default)


def _parse(*argv):
    p = argparse.ArgumentParser()
    add_measured_args(p)
    add_rule_args(p)
    args = p.parse_args(list(argv))
    args._defaults = option_defaults(p, args)  # as bench.cli.main keeps them
    return args


def test_measured_and_rule_options():
    args = _parse()
    assert measured_from_args(args, None) is None and rules_from_args(args) is None
    # --measured alone: the store of $ROTORBENCH_STORE, else ./runs (resolved when read)
    assert _parse("--measured").measured == ""
    with pytest.raises(RequestError, match="--esc-mode only applies with --measured"):
        measured_from_args(_parse("--esc-mode", "diode"), None)
    with pytest.raises(RequestError, match="--no-rule has no effect without --flyable"):
        rules_from_args(_parse("--no-rule", "frame"))
    rules = rules_from_args(_parse("--flyable", "--no-rule", "frame", "--tip-speed-max", "200"))
    assert "frame" not in rules.enabled and rules.tip_speed_m_s == 200.0


def test_fit_for_store_refuses_other_run_kinds(tmp_path):
    import pandas as pd

    run = tmp_path / "r"
    run.mkdir()
    comp = {k: "x" for k in ("motor", "propeller", "esc", "esc_mode", "battery")}
    (run / "run.json").write_text(json.dumps({"kind": "step2", "components": comp}),
                                  encoding="utf-8")
    pd.DataFrame({"t_s": [0.0, 1.0], "rpm": [0.0, 1.0]}).to_parquet(run / "samples.parquet")
    with pytest.raises(RigError, match="run kind 'step2': only step1 and sweep runs"):
        fit_for_store(run)
