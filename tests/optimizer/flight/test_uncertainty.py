"""Robust designs (optimizer.flight.uncertainty): per-design seeds that no chunking or order
changes, draws with the measured mean and spread that keep the constants physical, the
nominal as sample 0, and percentiles that count a step that never rose as +inf.

The statistical checks use a fixed seed (so they cannot flake) and bounds of 5 standard
errors of the estimate (so they would still hold for any other seed but a 1 in 10^6)."""

from __future__ import annotations

import math
import random

import numpy as np
import pandas as pd
import pytest
from scipy import stats
from scipy.special import ndtr

from optimizer.catalogs.catalog import load_catalog
from optimizer.errors import RequestError
from optimizer.flight.actuators import ActuatorModel
from optimizer.flight.design import StepConstants, design_index, design_std, setup
from optimizer.flight.uncertainty import (
    QUANTITIES,
    _truncated_normal,
    design_seed,
    design_seeds,
    draw,
    draw_many,
    nominal_of,
    percentile_columns,
    std_of,
    varies,
    with_sample,
)
from optimizer.model.design_model import evaluate_grid
from optimizer.model.measured import MeasuredActuator
from tests.conftest import CATALOGS

DESIGN = {"actuators": 4, "propeller": "P1", "motor": "M1", "battery": "B3", "series": 3,
          "parallel": 1}
NOMINAL = {"tau_up_s": 0.040, "tau_down_s": 0.060, "latency_s": 0.012, "k_f_n_s2": 1.2e-6,
           "k_m_nm_s2": 2.0e-8}
STD = {"tau_up_s": 0.004, "tau_down_s": 0.009, "latency_s": 0.002, "k_f_n_s2": 3e-8,
       "k_m_nm_s2": 1e-9}


def _designs(n: int) -> list[dict]:
    return [{**DESIGN, "propeller": f"P{i % 7}", "motor": f"M{i // 7}", "series": 2 + i % 3}
            for i in range(n)]


# --- seeds ----------------------------------------------------------------------------------


def test_a_designs_draws_do_not_depend_on_order_or_chunking() -> None:
    designs = _designs(30)
    nominal = {q: np.full(30, v) for q, v in NOMINAL.items()}
    std = {q: np.full(30, v) for q, v in STD.items()}
    whole = draw_many(nominal, std, 8, design_seeds(designs, seed=7))
    order = list(range(30))
    random.Random(3).shuffle(order)
    for chunk in (order[:11], order[11:12], order[12:]):  # another worker, another order
        part = draw_many({q: v[chunk] for q, v in nominal.items()},
                         {q: v[chunk] for q, v in std.items()}, 8,
                         design_seeds([designs[i] for i in chunk], seed=7))
        for q in QUANTITIES:
            np.testing.assert_array_equal(part[q], whole[q][chunk])
    # one design alone draws the same too
    alone = draw(NOMINAL, STD, 8, design_seed(designs[5], seed=7))
    assert all(np.array_equal(alone[q], whole[q][5]) for q in QUANTITIES)
    # different designs and different user seeds draw differently
    assert len({whole["tau_up_s"][i, 1] for i in range(30)}) == 30
    other = draw(NOMINAL, STD, 8, design_seed(designs[5], seed=8))
    assert not np.array_equal(other["tau_up_s"], alone["tau_up_s"])


def test_the_seed_is_the_designs_keys_not_their_spelling() -> None:
    base = design_seed(DESIGN, 1).generate_state(4)
    same = {"parallel": 1, "series": np.int64(3), "battery": "B3", "motor": "M1",
            "propeller": "P1", "actuators": np.int32(4), "note": "ignored"}
    assert np.array_equal(design_seed(same, 1).generate_state(4), base)
    assert not np.array_equal(design_seed({**DESIGN, "series": 4}, 1).generate_state(4), base)
    # a catalog battery without a pack: series and parallel absent = null
    plain = {k: DESIGN[k] for k in ("actuators", "propeller", "motor", "battery")}
    for empty in (None, math.nan, pd.NA):  # a design table's empty cell
        assert np.array_equal(design_seed(plain).generate_state(4),
                              design_seed({**plain, "series": empty}).generate_state(4))
    with pytest.raises(RequestError, match="no battery"):
        design_seed({"actuators": 4, "propeller": "P", "motor": "M"})
    for bad in (2.5, "3", True):
        with pytest.raises(RequestError, match="series must be a whole number"):
            design_seed({**DESIGN, "series": bad})
    with pytest.raises(RequestError, match="seed must be"):
        design_seed(DESIGN, -1)


def test_raising_m_keeps_the_first_samples_and_sample_0_is_the_nominal() -> None:
    key = design_seed(DESIGN)
    short, long = draw(NOMINAL, STD, 5, key), draw(NOMINAL, STD, 50, key)
    for q in QUANTITIES:
        np.testing.assert_array_equal(long[q][:5], short[q])
        assert long[q][0] == NOMINAL[q]
        assert np.all(long[q][1:] != NOMINAL[q])


# --- distributions ---------------------------------------------------------------------------


def test_positive_constants_are_log_normal_with_the_measured_mean_and_std() -> None:
    n = 20_000
    got = draw(NOMINAL, STD, n + 1, design_seed(DESIGN, 11))
    for q in ("tau_up_s", "tau_down_s", "k_f_n_s2", "k_m_nm_s2"):
        x = got[q][1:]
        mean, std = NOMINAL[q], STD[q]
        assert np.all(x > 0)
        assert abs(x.mean() - mean) < 5 * std / math.sqrt(n)
        cv2 = (std / mean) ** 2
        w = 1 + cv2
        kurt = w**4 + 2 * w**3 + 3 * w**2 - 3  # the log-normal's (non-excess) kurtosis
        assert abs(x.std(ddof=1) / std - 1) < 5 * math.sqrt((kurt - 1) / (4 * n))
        # log-normal: the log is normal with sigma^2 = ln(1 + cv^2)
        sigma = math.sqrt(math.log1p(cv2))
        assert abs(np.log(x).std(ddof=1) / sigma - 1) < 5 / math.sqrt(2 * n)
    # a spread larger than the value still gives positive constants
    wide = draw({"tau_up_s": 0.01}, {"tau_up_s": 0.03}, 2000, design_seed(DESIGN))["tau_up_s"]
    assert np.all(wide > 0) and wide.max() > 0.05


@pytest.mark.parametrize("nominal", [0.012, 0.002, 0.0])
def test_the_latency_is_a_normal_truncated_at_zero(nominal: float) -> None:
    n, std = 20_000, 0.002
    x = draw({"latency_s": nominal}, {"latency_s": std}, n + 1,
             design_seed(DESIGN, 5))["latency_s"][1:]
    assert np.all(x >= 0)
    truth = stats.truncnorm(-nominal / std, np.inf, loc=nominal, scale=std)
    t_mean, t_var = (float(v) for v in truth.stats("mv"))
    assert abs(x.mean() - t_mean) < 5 * math.sqrt(t_var / n)
    assert abs(x.std(ddof=1) / math.sqrt(t_var) - 1) < 0.03  # 5 se of a std (kurtosis < 3.9)
    # far from zero (6 std) the truncation changes nothing: the mean is the nominal
    if nominal / std > 5:
        assert abs(t_mean - nominal) < 1e-6 * std


def test_the_truncated_inverse_cdf_is_exact_and_safe_in_both_tails() -> None:
    z = np.linspace(-6, 6, 121)
    for a in (-8.0, -1.0, 0.0, 2.0):  # truncation point in std units
        mean, std = -a * 0.001, 0.001
        got = _truncated_normal(np.full_like(z, mean), np.full_like(z, std), z)
        want = stats.truncnorm(a, np.inf, loc=mean, scale=std).ppf(ndtr(z))
        np.testing.assert_allclose(got, want, rtol=1e-7, atol=1e-12)
    z = np.array([-40, -9, 9, 40.0])
    far = _truncated_normal(np.full(4, 0.05), np.full(4, 0.001), z)  # 50 std above 0
    np.testing.assert_allclose(far, [0.013, 0.041, 0.059, 0.087], rtol=1e-9)  # +-40: at 37
    at_zero = _truncated_normal(np.zeros(4), np.full(4, 0.001), z)  # a half-normal
    assert np.all(np.isfinite(at_zero)) and np.all(at_zero >= 0)


def test_no_spread_flies_the_nominal() -> None:
    got = draw(NOMINAL, {"tau_up_s": 0.0}, 6, design_seed(DESIGN))
    assert all(np.all(got[q] == NOMINAL[q]) for q in QUANTITIES)
    # a design whose constant was not measured passes it through (NaN: "the model's")
    nan = draw({"k_f_n_s2": math.nan}, {}, 3, design_seed(DESIGN))["k_f_n_s2"]
    assert np.all(np.isnan(nan))
    std = {q: np.array([0.0, v, 0.0]) for q, v in STD.items()}
    assert varies(std).tolist() == [False, True, False]
    assert varies(std_of(None)).tolist() == [False]


def test_bad_draw_requests_are_refused_in_one_line() -> None:
    key = design_seed(DESIGN)
    bad = [
        (dict(std={"tau_up_s": -0.001}), "std of tau_up_s: must be finite and >= 0"),
        (dict(std={"tau_up_s": math.nan}), "must be finite and >= 0"),
        (dict(nominal={**NOMINAL, "tau_up_s": 0.0}), "a std needs a finite nominal > 0"),
        (dict(nominal={**NOMINAL, "latency_s": -0.001}), "a std needs a finite nominal >= 0"),
        (dict(nominal={**NOMINAL, "gain": 1.0}), "gain: not one of"),
        (dict(m=0), "samples must be a whole number >= 1"),
    ]
    for change, message in bad:
        args = {"nominal": NOMINAL, "std": STD, "m": 4, **change}
        with pytest.raises(RequestError, match=message):
            draw(args["nominal"], args["std"], args["m"], key)
    with pytest.raises(RequestError, match="3 values for 2 designs"):
        draw_many({"tau_up_s": [0.04, 0.05, 0.06]}, {}, 3, design_seeds(_designs(2)))


# --- percentiles -----------------------------------------------------------------------------


def test_percentiles_are_flown_samples_and_never_rose_is_infinite() -> None:
    rise = np.arange(1.0, 21.0)  # 20 samples, 1 .. 20 ms
    cols = percentile_columns("roll_rise_time_ms", rise)
    assert cols == {"roll_rise_time_ms_p05": 1.0, "roll_rise_time_ms_p50": 10.0,
                    "roll_rise_time_ms_p95": 19.0}
    one = [*rise[:19], None]  # 5 % never rose: the 95th percentile is still a flight's
    assert percentile_columns("r", one)["r_p95"] == 19.0
    two = [*rise[:18], None, math.nan]  # 10 % never rose: it is +inf
    assert percentile_columns("r", two)["r_p95"] == math.inf
    half = [*rise[:10], *[None] * 10]
    most = [*rise[:9], *[None] * 11]
    assert percentile_columns("r", half)["r_p50"] == 10.0
    assert percentile_columns("r", most)["r_p50"] == math.inf
    # designs x samples: one column per design; NaN instead of inf when asked
    many = percentile_columns("r", [rise, two], never=math.nan)
    np.testing.assert_array_equal(many["r_p05"], [1.0, math.nan])
    with pytest.raises(RequestError, match="no samples"):
        percentile_columns("r", [])


# --- the measured actuator and the flown design --------------------------------------------


def test_a_measured_actuator_checks_its_spreads() -> None:
    ok = MeasuredActuator("P1", "M1", tau_up_s=0.04, tau_up_std_s=0.0, latency_s=0.0,
                          latency_std_s=0.001, k_f_n_s2=1e-6, k_f_std_n_s2=2e-8)
    assert std_of(ok)["latency_s"] == 0.001 and std_of(ok)["tau_down_s"] == 0.0
    for kwargs, message in (
        ({"tau_up_s": 0.04, "tau_up_std_s": -1e-3}, "tau_up_std_s must be finite and >= 0"),
        ({"k_f_n_s2": 1e-6, "k_f_std_n_s2": math.inf}, "k_f_std_n_s2 must be finite"),
        ({"latency_std_s": 0.001}, "latency_std_s is given without latency_s"),
    ):
        with pytest.raises(RequestError, match=message):
            MeasuredActuator("P1", "M1", **kwargs)


def test_the_flown_design_gives_its_nominal_spread_and_samples(fixtures_dir) -> None:
    cat = load_catalog(CATALOGS / "thesis-e")
    measured = MeasuredActuator("P1", "M1", time_constant_s=0.05, tau_up_s=0.04,
                                tau_down_s=0.06, latency_s=0.01, tau_up_std_s=0.004,
                                tau_down_std_s=0.006, latency_std_s=0.001)
    grid = evaluate_grid(cat, 4, 0.0, overrides=[measured])
    index = design_index(grid, "P1", "M1", "B3")
    vehicle, actuator = setup(cat, grid, index)
    nominal = nominal_of(vehicle, actuator)
    assert (nominal["tau_up_s"], nominal["latency_s"]) == (0.04, 0.01)
    assert nominal["k_f_n_s2"] == vehicle.k_f  # the model's: not measured here
    std = design_std(grid, index)
    assert std == {"tau_up_s": 0.004, "tau_down_s": 0.006, "latency_s": 0.001,
                   "k_f_n_s2": 0.0, "k_m_nm_s2": 0.0}
    # a step run given to setup replaces the measured time constants: no spread left
    step = StepConstants(0.03, 0.05, 0.008)
    assert set(design_std(grid, index, step).values()) == {0.0}
    # an unmeasured pair has none
    assert set(design_std(grid, design_index(grid, "P2", "M1", "B3")).values()) == {0.0}
    got = draw(nominal, std, 3, design_seed({"actuators": 4, "propeller": "P1",
                                             "motor": "M1", "battery": "B3"}))
    v2, a2 = with_sample(vehicle, actuator, {q: got[q][2] for q in got})
    assert isinstance(a2, ActuatorModel) and a2.frame_s == actuator.frame_s
    assert a2.tau_up_s == got["tau_up_s"][2] != actuator.tau_up_s
    assert a2.latency_s == got["latency_s"][2] and v2.k_f == vehicle.k_f
    v3, _ = with_sample(vehicle, actuator, {"k_f_n_s2": 2e-6})
    assert v3.k_f == 2e-6 and v3.mass_kg == vehicle.mass_kg


def test_twenty_flown_samples_of_a_measured_design_spread_about_the_nominal(fixtures_dir
                                                                             ) -> None:
    """The docs' example (docs/flight.md, "Uncertainty of measured constants")."""
    from optimizer.flight.design import gains_for
    from optimizer.flight.maneuvers import MANEUVERS, fly

    cat = load_catalog(CATALOGS / "thesis-e")
    measured = MeasuredActuator("P4", "M1", time_constant_s=0.12, tau_up_s=0.10,
                                tau_down_s=0.14, latency_s=0.012, tau_up_std_s=0.010,
                                tau_down_std_s=0.014, latency_std_s=0.002)
    grid = evaluate_grid(cat, 4, overrides=[measured])
    index = design_index(grid, "P4", "M1", "B3")
    vehicle, actuator = setup(cat, grid, index)
    gains = gains_for(actuator)
    key = design_seed({"actuators": 4, "propeller": "P4", "motor": "M1", "battery": "B3"}, 1)
    samples = draw(nominal_of(vehicle, actuator), design_std(grid, index), 20, key)
    rise = []
    for k in range(20):
        v, a = with_sample(vehicle, actuator, {q: x[k] for q, x in samples.items()})
        rise.append(fly(v, a, MANEUVERS["roll_step"], gains=gains, record=False)
                    .figures["rise_time_ms"])
    nominal = fly(vehicle, actuator, MANEUVERS["roll_step"], gains=gains, record=False)
    assert rise[0] == nominal.figures["rise_time_ms"]  # sample 0 is the nominal flight
    cols = percentile_columns("roll_rise_time_ms", rise)
    p05, p50, p95 = cols.values()
    assert {p05, p50, p95} <= set(rise)  # each one a flown sample's figure
    assert p05 < rise[0] < p95 and p95 - p05 > 0.02 * p50  # 10 % slower lags: a spread
