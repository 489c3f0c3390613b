"""The constants stage as a library (bench.store.measured_constants): a store written row by row
read back as the optimizer's overrides, one catalog and ESC mode picked, sources named."""

from __future__ import annotations

import math

import pytest

from bench.store.constants_store import ActuatorKey, ConstantsStore
from bench.store.measured_constants import (
    MeasuredSet,
    find_store,
    is_measured,
    load_measured,
    load_measured_set,
)
from optimizer.catalogs.catalog import load_catalog
from optimizer.errors import RequestError
from optimizer.solve.objectives import single
from optimizer.solve.selection import Requirements
from optimizer.solve.selection_options import solve
from tests.conftest import CATALOGS

CATALOG = CATALOGS / "thesis-e"
STATIC = {"hover_thrust_n": [0.5, 1.0, 2.0, 3.0], "hover_current_a": [0.3, 0.7, 1.6, 2.8],
          "voltage_v": 12.0, "thrust_max_n": 3.0, "k_f_n_s2": 1.2e-6, "k_q_nm_s2": -1.0}
STEP = {"tau_up_s": 0.040, "tau_down_s": 0.060, "latency_s": 0.0}


def _key(prop, motor, mode, catalog="thesis-e"):
    return ActuatorKey(motor, prop, "sim-f30a", mode, "3s", catalog=catalog)


@pytest.fixture
def store(tmp_path):
    s = ConstantsStore(tmp_path / "runs")
    s.put(_key("P1", "M1", "complementary"), "static", "run-sweep", "r/sweep", STATIC)
    s.put(_key("P1", "M1", "complementary"), "step", "run-step-c", "r/step-c", STEP)
    s.put(_key("P1", "M1", "diode"), "step", "run-step-d",
          "r/step-d", {**STEP, "tau_down_s": 0.300, "latency_s": math.nan})
    s.put(_key("P2", "M1", "diode"), "step", "run-step-p2", "r/step-p2", STEP)
    s.put(_key("8x4.5", "dji", "complementary", catalog=""), "step", "run-other", "r/o", STEP)
    return s


def test_load_measured_one_override_per_pair_and_mode(store):
    got = {(o.propeller_id, o.motor_id, o.esc_mode): o
           for o in load_measured(store.root, catalog="thesis-e")}
    assert sorted(got) == [("P1", "M1", "complementary"), ("P1", "M1", "diode"),
                           ("P2", "M1", "diode")]
    comp, diode = got[("P1", "M1", "complementary")], got[("P1", "M1", "diode")]
    assert comp.time_constant_s == pytest.approx(0.050)  # mean of rising and falling
    assert comp.hover_current_a == (0.3, 0.7, 1.6, 2.8) and comp.max_thrust_n == 3.0
    assert comp.source == "step: run-step-c, static: run-sweep"
    # the diode mode has no sweep of its own: it borrows the pair's static curves
    assert diode.current_source == "run-sweep" and diode.hover_thrust_n == comp.hover_thrust_n
    # flight extras: only positive finite numbers (latency 0 allowed, NaN dropped)
    assert comp.k_f_n_s2 == 1.2e-6 and comp.k_m_nm_s2 is None and comp.latency_s == 0.0
    assert diode.latency_s is None
    # a pair without any sweep has no current, only its time constant
    p2 = got[("P2", "M1", "diode")]
    assert not p2.has_current and p2.time_constant_s == pytest.approx(0.050)
    assert len(load_measured(store.root)) == 4  # no catalog filter: the other rig's too


def test_find_store_takes_the_folder_or_its_runs(store, tmp_path):
    assert find_store(store.root) == store.root
    assert find_store(tmp_path) == store.root  # a demo output folder
    with pytest.raises(RequestError, match=r"no constants\.sqlite there or in"):
        find_store(tmp_path / "runs" / "elsewhere")


def test_load_measured_set_picks_the_esc_mode(store, tmp_path):
    cat = load_catalog(CATALOG)
    mset = load_measured_set(tmp_path, cat, None)  # diode: stored for two pairs
    assert mset.esc_mode == "diode" and mset.store == store.root
    assert mset.describe() == {"store": str(store.root), "esc_mode": "diode",
                               "actuators_measured": 2}
    assert load_measured_set(tmp_path, cat, "complementary").esc_mode == "complementary"
    with pytest.raises(RequestError, match="--esc-mode stock: not in"):
        load_measured_set(tmp_path, cat, "stock")
    store.put(_key("P3", "M1", "complementary"), "step", "run-p3", "r/p3", STEP)
    with pytest.raises(RequestError, match="equally many combinations"):
        load_measured_set(tmp_path, cat, None)
    other = tmp_path / "other"
    ConstantsStore(other).put(_key("8x4.5", "dji", "complementary", catalog=""), "step",
                              "run-other", "r/o", STEP)
    with pytest.raises(RequestError, match="no constants stored for catalog 'thesis-e'"):
        load_measured_set(other, cat, None)


def test_measured_set_builds_grids_and_names_sources(store, tmp_path):
    cat = load_catalog(CATALOG)
    mset = load_measured_set(tmp_path, cat, "complementary")
    assert isinstance(mset, MeasuredSet)
    result = solve(cat, single("time-constant"), (4,), Requirements(), "milp", mset)
    d = result.designs[0]
    assert set(mset.grids) == {4}
    sources = d.extra["sources"]
    assert is_measured(sources, "time_constant_ms") == ((d.propeller, d.motor) == ("P1", "M1"))
    assert not is_measured(None, "time_constant_ms")
    assert not is_measured({"current_a": "model (E.67-E.69)"}, "current_a")


def test_stored_spreads_reach_the_overrides_and_old_stores_have_none(tmp_path):
    s = ConstantsStore(tmp_path / "runs")
    spread = {"tau_up_std_s": 0.002, "tau_down_std_s": 0.004, "latency_std_s": 0.0}
    s.put(_key("P1", "M1", "complementary"), "step", "run-step", "r/step", {**STEP, **spread})
    s.put(_key("P1", "M1", "complementary"), "static", "run-sweep", "r/sweep",
          {**STATIC, "k_q_nm_s2": 2e-8, "k_f_std_n_s2": 3e-8, "k_q_std_nm_s2": 1e-9})
    # written before the spreads were kept (tau stds only), or with ones a fit left open
    s.put(_key("P2", "M1", "complementary"), "step", "run-old", "r/old",
          {**STEP, "tau_up_std_s": None, "tau_down_std_s": -1.0})
    got = {o.propeller_id: o for o in load_measured(s.root)}
    new, old = got["P1"], got["P2"]
    assert (new.tau_up_std_s, new.tau_down_std_s, new.latency_std_s) == (0.002, 0.004, 0.0)
    assert (new.k_f_std_n_s2, new.k_m_nm_s2, new.k_m_std_nm_s2) == (3e-8, 2e-8, 1e-9)
    assert (old.tau_up_std_s, old.tau_down_std_s, old.latency_std_s) == (None, None, None)
    assert old.tau_up_s == STEP["tau_up_s"] and old.k_f_std_n_s2 is None
