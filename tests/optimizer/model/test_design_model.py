"""Model behaviour: grid shape and contract, physics identities, overrides, evaluate_design."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from optimizer.catalogs.catalog import load_catalog
from optimizer.errors import RequestError
from optimizer.model.design_model import evaluate_design, evaluate_grid
from optimizer.model.grid import METRIC_KEYS

ROOT = Path(__file__).resolve().parents[3]


@pytest.fixture(scope="module")
def cat():
    return load_catalog(ROOT / "optimizer" / "data" / "catalogs" / "thesis-e")


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


def _with(cat, **changes):
    from dataclasses import replace

    return replace(cat, constants=cat.constants.with_updates(**changes))


def test_hover_identities(cat):
    """Thrust balances weight (E.19)-(E.20); power, current, flight time are consistent."""
    n = 6
    g = evaluate_grid(cat, n, 0.7)
    props = cat.propellers
    rho, grav = cat.constants.air_density_kg_m3, cat.constants.gravity_m_s2
    rev_s = g.metrics["hover_rpm"] / 60
    d = props["diameter_m"].to_numpy()[:, None, None]
    thrust = props["ct"].to_numpy()[:, None, None] * rho * rev_s**2 * d**4  # (E.1)
    np.testing.assert_allclose(n * thrust, g.metrics["total_mass_kg"] * grav, rtol=1e-12)
    np.testing.assert_allclose(g.metrics["power_w"], n * g.metrics["propeller_power_w"])
    volts = cat.batteries["cells"].to_numpy() * 4.0
    np.testing.assert_allclose(g.metrics["current_a"] * volts, g.metrics["power_w"])
    cap = cat.batteries["capacity_ah"].to_numpy()
    np.testing.assert_allclose(g.metrics["flight_time_min"], 60 * cap / g.metrics["current_a"])
    np.testing.assert_allclose(g.metrics["roll_inertia_kgm2"], g.metrics["pitch_inertia_kgm2"])


def test_payload_adds_mass_and_lowers_flight_time(cat):
    a, b = evaluate_grid(cat, 4, 0.0), evaluate_grid(cat, 4, 1.0)
    np.testing.assert_allclose(b.metrics["total_mass_kg"] - a.metrics["total_mass_kg"], 1.0)
    assert np.all(b.metrics["flight_time_min"] < a.metrics["flight_time_min"])
    np.testing.assert_allclose(b.metrics["roll_inertia_kgm2"], a.metrics["roll_inertia_kgm2"])


def test_price_with_and_without_propellers(cat):
    without = evaluate_design(cat, 4, "P4", "M3", "B3")["price"]
    with_props = evaluate_design(_with(cat, price_includes_propellers=True), 4, "P4", "M3", "B3")
    assert without == pytest.approx(4 * 31.36 + 102.0)  # (E.18) without N x P_p
    assert with_props["price"] == pytest.approx(4 * (7.8 + 31.36) + 102.0)  # (E.18)


def test_time_constant_formula(cat):
    """(E.35) by hand for one design: J R_a / (K_t^2 + D_omega R_a)."""
    d = evaluate_design(cat, 4, "P1", "M1", "B1")
    n = d["hover_rpm"] / 60
    rho = 1.225
    damping = 0.0797 * rho * n**3 * 0.254**5 / (2 * np.pi * n) ** 2
    kt = 60 / (2 * np.pi * 380)
    r_o, r_i = 0.0235, 0.0195
    j_motor = 0.5 * 6800 * np.pi * (r_o**2 - r_i**2) * 0.012 * (r_o**2 + r_i**2)
    j_prop = 0.012 * 0.254**2 / 8
    tau = 0.222 * (j_motor + j_prop) / (kt**2 + damping * 0.222)
    assert d["time_constant_ms"] == pytest.approx(tau * 1e3, rel=1e-12)


def test_evaluate_design_is_the_grid_cell(cat):
    g = evaluate_grid(cat, 8, 0.3)
    for i, pid in enumerate(cat.propeller_ids):
        for j, mid in enumerate(cat.motor_ids):
            for k, bid in enumerate(cat.battery_ids):
                d = evaluate_design(cat, 8, pid, mid, bid, 0.3)
                for key in METRIC_KEYS:
                    assert d[key] == pytest.approx(g.metrics[key][i, j, k], rel=1e-12), key
                assert d["feasible"] == bool(g.feasible()[i, j, k])


def test_design_record_keys(cat):
    d = evaluate_design(cat, 4, "P1", "M1", "B1")
    assert {
        "actuators",
        "propeller",
        "motor",
        "battery",
        "flight_time_min",
        "time_constant_ms",
        "price",
        "total_mass_kg",
        "hover_rpm",
        "propeller_power_w",
        "current_a",
        "roll_inertia_kgm2",
        "pitch_inertia_kgm2",
        "feasible",
        "reason",
    } <= set(d)
    assert (d["propeller"], d["motor"], d["battery"], d["actuators"]) == ("P1", "M1", "B1", 4)
    import json

    json.dumps(d)


def test_violated_limits_are_named(cat):
    from dataclasses import replace

    motors = cat.motors.copy()
    motors["max_power_w"] = 10.0
    batteries = cat.batteries.copy()
    batteries["max_current_a"] = 1.0
    small = replace(cat, motors=motors, batteries=batteries)
    d = evaluate_design(small, 4, "P1", "M1", "B1")
    assert not d["feasible"]
    assert d["reason"].startswith("motor power 19.39 W > limit 10 W")
    assert "battery current 6.463 A > limit 1 A" in d["reason"]
    assert "motor current" not in d["reason"]


def test_thrust_to_weight_check(cat):
    from optimizer.model import physics

    strict = _with(cat, min_thrust_to_weight=1.0)
    g = evaluate_grid(strict, 4, 1.5)
    ratio = g.extras["thrust_to_weight"]
    check = next(c for c in g.checks if c.label == "thrust to weight")
    assert check.sense == ">="
    assert g.feasible()[3, 0, 2] == bool(ratio[3, 0, 2] >= 1.0)
    assert ratio[3, 0, 2] < 1.0 < ratio[3, 2, 2]  # 380 Kv cannot lift 3.3 kg on 4 x 14 in
    # The full-throttle speed satisfies the steady state of (E.4)-(E.7).
    kt = 60 / (2 * np.pi * 600)
    w = physics.full_throttle_speed_rad_s(12.0, kt, 0.123, 0.0630, 1.225, 0.3556)
    torque = 0.0630 * 1.225 * (w / (2 * np.pi)) ** 3 * 0.3556**5 / w  # (E.2)-(E.3)
    assert kt * w + 0.123 * torque / kt == pytest.approx(12.0)
    assert "thrust to weight" not in {c.label for c in evaluate_grid(cat, 4).checks}


def test_request_errors(cat):
    with pytest.raises(RequestError, match="actuators: expected a whole number >= 3, got 2"):
        evaluate_grid(cat, 2)
    with pytest.raises(RequestError, match="payload: expected a number of kg from 0 to 10000, "
                                           "got -1"):
        evaluate_grid(cat, 4, -1)
    with pytest.raises(RequestError, match="got 1e"):
        evaluate_grid(cat, 4, 1e308)
    with pytest.raises(RequestError, match="unknown propeller id 'P0'"):
        evaluate_design(cat, 4, "P0", "M1", "B1")
    with pytest.raises(RequestError, match="unknown battery id 'B7'"):
        evaluate_design(cat, 4, "P1", "M1", "B7")


def test_motor_without_inertia_data_notes_it():
    cat = load_catalog(ROOT / "optimizer" / "data" / "catalogs" / "thesis-d")
    assert "motor_inertia" in evaluate_grid(cat, 4).notes


def test_measured_time_constant_and_current_replace_the_model(cat):
    from optimizer.model.measured import MeasuredActuator

    base = evaluate_grid(cat, 4)
    hover = base.extras["hover_thrust_n"][3, 2, :]  # P4 on M3, every battery
    lo, hi = float(hover.min()), float(hover.max())
    measured = MeasuredActuator(
        "P4",
        "M3",
        time_constant_s=0.2,
        hover_thrust_n=(lo, (lo + hi) / 2 + 1e-9),
        hover_current_a=(3.0, 5.0),
    )
    g = evaluate_grid(cat, 4, overrides=[measured])
    assert np.all(g.metrics["time_constant_ms"][3, 2, :] == pytest.approx(200.0))
    mask = g.measured["time_constant_ms"]
    assert mask.sum() == len(cat.battery_ids) and mask[3, 2].all()
    # Current: measured where the hover thrust lies in the measured range, else modelled.
    inside = (hover >= lo) & (hover <= (lo + hi) / 2 + 1e-9)
    assert inside.any() and not inside.all()
    np.testing.assert_array_equal(g.measured["current_a"][3, 2, :], inside)
    expected = 4 * np.interp(hover, (lo, (lo + hi) / 2), (3.0, 5.0))
    np.testing.assert_allclose(g.metrics["current_a"][3, 2, inside], expected[inside], rtol=1e-6)
    np.testing.assert_allclose(
        g.metrics["current_a"][3, 2, ~inside], base.metrics["current_a"][3, 2, ~inside]
    )
    untouched = np.ones(g.shape, bool)
    untouched[3, 2, :] = False
    for key in METRIC_KEYS:
        np.testing.assert_array_equal(g.metrics[key][untouched], base.metrics[key][untouched])
    d = evaluate_design(cat, 4, "P4", "M3", "B1", overrides=[measured])
    assert "time_constant_ms" in d["measured"]


def test_esc_mode_selects_overrides(cat):
    from optimizer.model.measured import MeasuredActuator

    generic = MeasuredActuator("P1", "M1", time_constant_s=0.05)
    damped = MeasuredActuator("P1", "M1", esc_mode="complementary", time_constant_s=0.03)
    tau = lambda mode: evaluate_grid(  # noqa: E731
        cat, 4, overrides=[generic, damped], esc_mode=mode
    ).metrics["time_constant_ms"][0, 0, 0]
    assert tau(None) == pytest.approx(50.0)
    assert tau("complementary") == pytest.approx(30.0)
    assert tau("standard") == pytest.approx(50.0)


def test_bad_overrides(cat):
    from optimizer.model.measured import MeasuredActuator

    with pytest.raises(RequestError, match="unknown motor id 'M7'"):
        evaluate_grid(cat, 4, overrides=[MeasuredActuator("P1", "M7", time_constant_s=0.1)])
    with pytest.raises(RequestError, match="time_constant_s must be > 0"):
        MeasuredActuator("P1", "M1", time_constant_s=-1.0)
    with pytest.raises(RequestError, match="strictly ascending"):
        MeasuredActuator("P1", "M1", hover_thrust_n=(2.0, 1.0), hover_current_a=(1.0, 2.0))
    with pytest.raises(RequestError, match="two entries"):
        item = MeasuredActuator("P1", "M1", time_constant_s=0.1)
        evaluate_grid(cat, 4, overrides=[item, item])


def test_random_catalogs_obey_the_model_invariants():
    """Any valid catalog: finite positive metrics, and more payload never flies longer."""
    import pandas as pd
    from hypothesis import given, settings
    from hypothesis import strategies as st

    from optimizer.catalogs.catalog import Catalog

    @settings(max_examples=25, deadline=None)
    @given(
        seed=st.integers(0, 2**32 - 1), n=st.sampled_from([4, 6, 8]), payload=st.floats(0.0, 3.0)
    )
    def check(seed, n, payload):
        rng = np.random.default_rng(seed)
        P, M, B = (int(v) for v in rng.integers(1, 5, 3))
        props = pd.DataFrame(
            {
                "id": [f"p{i}" for i in range(P)],
                "name": "p",
                "mass_g": rng.uniform(0, 40, P),
                "diameter_m": rng.uniform(0.1, 0.5, P),
                "ct": rng.uniform(0.05, 0.15, P),
                "cp": rng.uniform(0.03, 0.1, P),
                "price": rng.uniform(0, 9, P),
            }
        )
        mots = pd.DataFrame(
            {
                "id": [f"m{i}" for i in range(M)],
                "name": "m",
                "kv_rpm_per_v": rng.uniform(200, 4000, M),
                "resistance_ohm": rng.uniform(0, 0.3, M),
                "mass_g": rng.uniform(20, 200, M),
                "max_current_a": rng.uniform(5, 60, M),
                "max_power_w": rng.uniform(50, 900, M),
                "price": rng.uniform(0, 80, M),
            }
        )
        bats = pd.DataFrame(
            {
                "id": [f"b{i}" for i in range(B)],
                "name": "b",
                "mass_g": rng.uniform(50, 2000, B),
                "capacity_mah": rng.uniform(500, 20000, B),
                "cells": rng.integers(1, 7, B),
                "price": rng.uniform(0, 120, B),
                "c_rating": rng.uniform(5, 60, B),
            }
        )
        cat = Catalog.from_frames(props, mots, bats)
        light, heavy = evaluate_grid(cat, n, payload), evaluate_grid(cat, n, payload + 0.5)
        for key in METRIC_KEYS:
            values = light.metrics[key]
            assert np.all(np.isfinite(values)) and np.all(values >= 0), key
        assert np.all(heavy.metrics["flight_time_min"] < light.metrics["flight_time_min"])
        assert np.all(heavy.metrics["current_a"] > light.metrics["current_a"])
        i, j, k = (int(rng.integers(0, s)) for s in light.shape)
        d = evaluate_design(cat, n, f"p{i}", f"m{j}", f"b{k}", payload)
        assert d["flight_time_min"] == light.metrics["flight_time_min"][i, j, k]
        assert d["feasible"] == bool(light.feasible()[i, j, k])

    check()


def test_actuator_at_thrust_is_the_grid_chain(cat):
    """The demo's model column (one propeller and motor at a given thrust) is the grid's
    own chain: at a design's hover thrust it gives that design's time constant, current
    per actuator and hover speed, bit for bit."""
    from optimizer.model.design_model import actuator_at_thrust, battery_voltage_v

    g = evaluate_grid(_with(cat, min_thrust_to_weight=1.0), 6, 0.5)
    k = 2
    volt = float(battery_voltage_v(cat)[k])
    for i, j in ((0, 0), (3, 2), (1, 1)):
        thrust = float(g.extras["hover_thrust_n"][i, j, k])
        point = actuator_at_thrust(cat, i, j, thrust, volt)
        assert point.hover.time_constant_s * 1e3 == g.metrics["time_constant_ms"][i, j, k]
        assert point.hover.current_a * 6 == pytest.approx(g.metrics["current_a"][i, j, k],
                                                          rel=1e-15)
        assert point.hover.n_rev_s * 60.0 == g.metrics["hover_rpm"][i, j, k]
        assert point.hover.winding_current_a == g.extras["motor_current_a"][i, j, k]
        ratio = g.extras["thrust_to_weight"][i, j, k]
        assert point.top_thrust_n == pytest.approx(ratio * thrust, rel=1e-14)


def test_top_thrust_is_the_drive_at_full_throttle(cat):
    """``top_thrust_n`` (E.1 at the full-throttle speed) agrees with the eCalc-style drive
    model at 100 % throttle, an independent path through ``optimizer.model.operating_points``."""
    from optimizer.model import operating_points as ops
    from optimizer.model.design_model import actuator_at_thrust

    point = actuator_at_thrust(cat, 3, 0, 2.0, 11.1)
    prop, mot = cat.propellers.iloc[3], cat.motors.iloc[0]
    drive = ops.Drive(ct=prop["ct"], cp=prop["cp"], diameter_m=prop["diameter_m"],
                       kt=1.0 / mot["kv_rad_s_per_v"], resistance_ohm=mot["resistance_ohm"],
                       no_load_current_a=0.0, rho=cat.constants.air_density_kg_m3)
    full = ops.at_throttle(drive, 1.0, 11.1)
    assert point.top_thrust_n == pytest.approx(float(full.thrust_n), rel=1e-12)
    assert point.voltage_v == 11.1 and point.thrust_n == 2.0
