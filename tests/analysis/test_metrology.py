"""The metrology core: reference forces, the fit of a calibration series, GUM budgets."""

from __future__ import annotations

import math

import numpy as np
import pytest

from analysis.errors import CalibrationError
from analysis.metrology.force_calibration import CalibrationPoint, fit_force_calibration
from analysis.metrology.gum import Budget, Term, normalised_error, rectangular
from analysis.metrology.reference_force import (
    G_STANDARD,
    conventional_weight_force,
    local_gravity,
    mass_uncertainty_kg,
)

MASSES_KG = (0.0, 0.1, 0.2, 0.5, 1.0)


def _series(rng, *, scale=2.0e-4, offset=0.013, bow=0.0, hyst=0.0, creep=0.0, noise=2e-6,
            g=G_STANDARD, hold_s=2.0, rate_hz=80.0, zero_drift=0.0):
    """A simulated cell under an up/down series: reading = offset + F/scale, plus a bow
    (quadratic, ``bow`` of FSO at mid-range), hysteresis (down branch higher by ``hyst`` of
    FSO at mid-range, 0 at the ends), creep (``creep`` of FSO over the top hold) and noise."""
    f_max = MASSES_KG[-1] * g
    fso = f_max / scale
    order = [(m, "up") for m in MASSES_KG] + [(m, "down") for m in MASSES_KG[-2::-1]]
    points = []
    t = np.arange(0.0, hold_s, 1.0 / rate_hz)
    for i, (m, d) in enumerate(order):
        u_mass = mass_uncertainty_kg(m, "F1")  # the stated class; the weight itself is off
        f = (m + rng.uniform(-1, 1) * u_mass * 3 ** 0.5) * g  # by up to its MPE
        f_nominal = m * g
        x = f / f_max
        y = offset + f / scale + 4 * bow * fso * x * (1 - x)
        if d == "down":
            y += 4 * hyst * fso * x * (1 - x)
            if m == 0:
                y += zero_drift * fso
        if m == MASSES_KG[-1]:
            y = y + creep * fso * t / hold_s
        else:
            y = y + 0 * t
        y = y + rng.normal(0.0, noise, t.size)
        points.append(CalibrationPoint(f_nominal, u_mass * g, d, t + 10 * i, y))
    return points


def test_local_gravity_buoyancy_and_weight_classes():
    assert local_gravity(45.0).g == pytest.approx(9.8062, abs=2e-4)  # the reference's figures
    assert local_gravity(0.0).g == pytest.approx(9.7803, abs=1e-4)
    assert local_gravity(90.0).g == pytest.approx(9.8322, abs=1e-4)
    assert local_gravity(45.0, 1000.0).g == pytest.approx(9.8062 - 0.003085, abs=2e-4)
    unknown = local_gravity()
    assert unknown.g == G_STANDARD and unknown.u / unknown.g == pytest.approx(0.0027 / 3 ** 0.5)
    # at rho_air = 1.2 the force is m_c g (1 - 1.5e-4) whatever the material
    for rho in (2700.0, 8000.0, 21450.0):
        f = conventional_weight_force(1.0, 9.81, 1.2, rho)
        assert f == pytest.approx(9.81 * (1 - 1.5e-4), rel=1e-12)
    assert conventional_weight_force(1.0, 9.81, 1.1, 2700.0) != pytest.approx(
        conventional_weight_force(1.0, 9.81, 1.1, 8000.0), rel=1e-6)
    assert mass_uncertainty_kg(1.0, "M1") == pytest.approx(50e-6 / 3 ** 0.5)
    assert mass_uncertainty_kg(0.3, "F1") == mass_uncertainty_kg(0.5, "F1")  # next larger
    assert mass_uncertainty_kg(0.0, "F1") == 0.0


def test_budget_combines_in_quadrature_with_welch_satterthwaite():
    b = Budget.of(4.43e-6, "N s^2", [Term("a", 3.0, "A", dof=4), Term("b", 4.0, "B")])
    assert b.u == pytest.approx(5.0) and b.expanded == pytest.approx(10.0)
    assert b.dof_eff == pytest.approx(5.0 ** 4 / (3.0 ** 4 / 4))
    assert Budget.from_dict(b.as_dict()) == b
    assert rectangular(-3 ** 0.5) == pytest.approx(1.0)
    assert normalised_error(10.0, 3.0, 6.0, 4.0) == pytest.approx(0.8)
    assert normalised_error(1.0, 0.0, 1.0, 0.0) == 0.0


def test_a_linear_cell_gives_its_scale_and_offset_within_the_stated_uncertainty():
    """Coverage: over 200 seeded series the true scale lies within +-U (k = 2) of the fit
    in 90-99 % of them (the budget is neither optimistic nor padded)."""
    inside = 0
    n = 200
    for seed in range(n):
        rng = np.random.default_rng(seed)
        cal = fit_force_calibration(_series(rng, noise=5e-6), u_rel_systematic=0.0)
        assert cal.offset == pytest.approx(0.013, abs=1e-6 * 49033)  # 1 ppm of FSO
        inside += abs(cal.scale - 2.0e-4) <= cal.scale_budget.expanded * cal.scale
    assert 0.90 * n <= inside <= 0.99 * n, inside


def test_hysteresis_bow_creep_and_zero_return_are_recovered():
    rng = np.random.default_rng(3)
    truth = {"bow": 0.004, "hyst": 0.006, "creep": 0.002, "zero_drift": 0.001}
    cal = fit_force_calibration(_series(rng, noise=1e-7, **truth), u_rel_systematic=1e-4)
    assert cal.hysteresis == pytest.approx(truth["hyst"], rel=0.05)
    assert cal.creep == pytest.approx(truth["creep"], rel=0.05)
    assert cal.zero_return == pytest.approx(truth["zero_drift"], rel=0.05)
    # the bow against the best line: largest deviation between half and all of it
    assert 0.5 * truth["bow"] < cal.nonlinearity < 1.2 * truth["bow"] + truth["hyst"] / 2
    assert cal.birge_ratio > 10  # residuals far beyond the noise: the covariance widened
    assert cal.failed({"hysteresis": 0.005, "nonlinearity": 0.05}) == [
        "hysteresis 0.599 % of full scale > limit 0.5 %"]
    names = [t.name for t in cal.scale_budget.terms]
    assert names[0].startswith("reference forces") and cal.scale_budget.terms[0].u == 1e-4
    # the in-use terms dominate a cell this bad
    assert cal.scale_budget.u > rectangular(truth["hyst"] / 2)


def test_a_clean_cell_passes_and_its_characteristics_are_near_zero():
    cal = fit_force_calibration(_series(np.random.default_rng(5), noise=1e-7),
                                u_rel_systematic=1e-4)
    assert max(abs(v) for v in cal.characteristics().values()) < 1e-4
    assert cal.failed({"hysteresis": 0.001, "nonlinearity": 0.001}) == []
    assert cal.force(cal.offset + 1.0 / cal.scale) == pytest.approx(1.0)
    assert math.isclose(cal.as_dict()["scale"], cal.scale)


def test_too_few_points_and_a_dead_cell_are_refused():
    rng = np.random.default_rng(0)
    pts = _series(rng)
    with pytest.raises(CalibrationError, match="at least 3"):
        fit_force_calibration(pts[:2], u_rel_systematic=0.0)
    dead = [CalibrationPoint(p.force, p.u_force, p.direction, p.t_s, np.zeros_like(p.readings))
            for p in pts]
    with pytest.raises(CalibrationError, match="do not change with the force"):
        fit_force_calibration(dead, u_rel_systematic=0.0)
    same = [CalibrationPoint(1.0, 0.0, "up", p.t_s, p.readings) for p in pts]
    with pytest.raises(CalibrationError, match="same force"):
        fit_force_calibration(same, u_rel_systematic=0.0)
