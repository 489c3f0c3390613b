"""Model behaviour: grid shape and contract, physics identities, overrides, evaluate_design."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from optimizer.catalog import load_catalog
from optimizer.errors import RequestError
from optimizer.grid import METRIC_KEYS
from optimizer.model import evaluate_design, evaluate_grid

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def cat():
    return load_catalog(ROOT / "fixtures" / "catalogs" / "thesis-e")


def test_grid_contract(cat):
    g = evaluate_grid(cat, 4, 0.5)
    assert g.shape == (4, 3, 4)
    assert set(g.metrics) == set(METRIC_KEYS)
    for key in METRIC_KEYS:
        assert g.metrics[key].shape == g.shape, key
        assert np.all(np.isfinite(g.metrics[key])), key
    assert {c.label for c in g.checks} >= {"motor power", "motor current", "battery current"}
    assert g.feasible().shape == g.shape


def test_unknown_id_names_id_and_catalog(cat):
    with pytest.raises(RequestError, match=r"unknown motor id 'M9' in catalog .*thesis-e"):
        evaluate_design(cat, 4, "P1", "M9", "B1")
