"""Battery model (optimizer.model.battery) against hand-computed discharges."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import quad

from optimizer.model import battery as bat


def test_curve_passes_through_its_datasheet_points() -> None:
    curve = bat.CellCurve()
    assert curve.open_circuit_v(0.0) == pytest.approx(curve.full_v)
    # Tremblay's K makes E(x_nom) = V_nom exactly
    assert curve.open_circuit_v(curve.nom_frac) == pytest.approx(curve.nom_v)
    e = curve.open_circuit_v(np.linspace(0, 0.95, 50))
    assert np.all(np.diff(e) < 0)  # discharging lowers the voltage


def test_constant_power_current_solves_v_times_i() -> None:
    # hand: E = 12 V, R = 0.1 ohm, P = 100 W: I = (12 - sqrt(144 - 40)) / 0.2 = 9.0098 A
    i = bat.load_current_a(100.0, 12.0, 0.1)
    assert i == pytest.approx((12 - math.sqrt(104)) / 0.2)
    assert i * (12 - 0.1 * i) == pytest.approx(100.0)
    assert bat.load_current_a(100.0, 12.0, 0.0) == pytest.approx(100 / 12)
    assert np.isnan(bat.load_current_a(400.0, 12.0, 0.1))  # beyond E^2 / 4R = 360 W


def test_flat_curve_with_resistance_hand_computed() -> None:
    # A = K = 0 (all points 4.0 V): E = 3 x 4.0 V everywhere, I = 9.0098 A from start to
    # the last node (x = X_MAX): t = X_MAX Q / I
    curve = bat.CellCurve(full_v=4.0, exp_v=4.0, nom_v=4.0, cutoff_v=3.0)
    d = bat.discharge(100.0, 3, 2.0, 0.1, curve)
    i = (12 - math.sqrt(104)) / 0.2
    assert float(d.time_min) == pytest.approx(60 * bat.X_MAX * 2.0 / i, rel=1e-9)
    assert float(d.start_voltage_v) == pytest.approx(12 - 0.1 * i)


def test_cutoff_without_resistance_closed_form() -> None:
    # A = 0, R = 0: E(x) = E0 - K / (1 - x) with K = (4.2 - 3.7) (1 - 0.8) / 0.8 = 0.125,
    # E0 = 4.325. Cut-off 3.3 V at 1 - x = K / (E0 - 3.3): x_end = 0.87805.
    # Constant power: t = Q S / P [E0 x + K ln(1 - x)] = 0.35345 h = 21.21 min (Q 1 Ah, 4S,
    # 40 W).
    curve = bat.CellCurve(full_v=4.2, exp_v=4.2, nom_v=3.7, cutoff_v=3.3)
    k, e0 = 0.125, 4.325
    x_end = 1 - k / (e0 - 3.3)
    hours = 1.0 * 4 / 40.0 * (e0 * x_end + k * math.log(1 - x_end))
    d = bat.discharge(40.0, 4, 1.0, 0.0, curve)
    assert float(d.used_fraction) == pytest.approx(x_end, rel=1e-3)
    assert float(d.time_min) == pytest.approx(60 * hours, rel=1e-3)
    assert float(d.end_voltage_v) == pytest.approx(4 * 3.3)


def test_sagging_voltage_raises_the_current_and_matches_quadrature() -> None:
    curve = bat.CellCurve()
    s, q, r, p = 3, 4.0, 0.03, 150.0
    d = bat.discharge(p, s, q, r, curve)
    assert float(d.end_current_a) > float(d.start_current_a)

    def current(x: float) -> float:
        return float(bat.load_current_a(p, s * curve.open_circuit_v(x), r))

    def margin(x: float) -> float:
        return s * float(curve.open_circuit_v(x)) - r * current(x) - s * curve.cutoff_v

    from scipy.optimize import brentq

    x_end = brentq(margin, 0.5, 0.95)
    hours, _ = quad(lambda x: q / current(x), 0, x_end, limit=200)
    assert float(d.used_fraction) == pytest.approx(x_end, rel=1e-3)
    assert float(d.time_min) == pytest.approx(60 * hours, rel=2e-3)


def test_discharge_broadcasts_over_a_grid() -> None:
    p = np.array([50.0, 100.0, 200.0])[:, None]
    d = bat.discharge(p, np.array([3, 4]), 2.0, 0.05)
    assert d.time_min.shape == (3, 2)
    assert np.all(np.diff(d.time_min, axis=0) < 0)  # more power, shorter flight
    single = bat.discharge(100.0, 4, 2.0, 0.05)
    assert d.time_min[1, 1] == pytest.approx(float(single.time_min))


def test_pack_resistance_series_parallel() -> None:
    # 4S2P of 2 Ah cells with r = 15 mOhm Ah: R_cell = 7.5 mOhm, pack 4 x 7.5 / 2 = 15 mOhm
    assert bat.pack_resistance_ohm(4, 4.0) == pytest.approx(4 * 0.0075 / 2)
    given = bat.pack_resistance_ohm(np.array([4, 4]), 4.0, given_ohm=np.array([0.02, np.nan]))
    assert given.tolist() == pytest.approx([0.02, 0.015])


def test_bad_curve_is_refused() -> None:
    with pytest.raises(ValueError, match="cut"):
        bat.CellCurve(cutoff_v=4.5)
