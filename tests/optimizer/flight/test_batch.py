"""The batch flight (optimizer.flight.batch) against the scalar loop it repeats: every
figure of every design equal to ``fly``'s within 1e-9, None where ``fly`` gives None."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from optimizer.catalogs.catalog import load_catalog
from optimizer.errors import RequestError
from optimizer.flight.actuators import ActuatorModel
from optimizer.flight.batch import DesignBatch, fly_batch
from optimizer.flight.batch_loop import simulate
from optimizer.flight.design import feasible_indices, gains_for, setup
from optimizer.flight.maneuvers import HOVER, MANEUVERS, Maneuver, fly
from optimizer.flight.ranking import _row, roll_step
from optimizer.model.design_model import evaluate_grid
from optimizer.sweep.ranking import rank
from tests.conftest import CATALOGS

CATALOG = CATALOGS / "thesis-e"
#: Short runs keep the file fast: the step at 0.1 s, 0.5 s of response; the gust's 0.5 s
#: pulse from 0.1 s and 0.2 s after it.
SHORT_S = 0.6
GUST_SHORT_S = 0.8


def _short(man: Maneuver) -> Maneuver:
    return dataclasses.replace(man, duration_s=GUST_SHORT_S if man.axis == "gust" else SHORT_S)


ALL_SHORT = [_short(m) for m in (*MANEUVERS.values(), HOVER)]


@pytest.fixture(scope="module")
def catalog():
    return load_catalog(CATALOG)


@pytest.fixture(scope="module")
def grids(catalog):
    return {n: evaluate_grid(catalog, n) for n in (4, 6, 8)}


def _models(catalog, grid, indices, **kwargs):
    return [setup(catalog, grid, idx, **kwargs) for idx in indices]


def _scalar(models, man: Maneuver) -> list[dict]:
    return [fly(v, a, man, gains=gains_for(a), record=False).figures for v, a in models]


def _batch(models, man: Maneuver, **kwargs) -> list[dict]:
    batch = DesignBatch.from_models([v for v, _ in models], [a for _, a in models])
    return fly_batch(batch, man, **kwargs)


def _assert_same(got: list[dict], want: list[dict]) -> None:
    assert len(got) == len(want)
    for i, (g, w) in enumerate(zip(got, want, strict=True)):
        assert "error" not in g, (i, g)
        assert list(g) == list(w), i
        for key, value in w.items():
            if isinstance(value, float):
                assert g[key] == pytest.approx(value, rel=1e-9, abs=1e-9), (i, key)
            else:  # None where the scalar loop gives None; labels, notes
                assert g[key] == value, (i, key, g[key])


@pytest.fixture(scope="module")
def thesis_n4(catalog, grids):
    """Every feasible N = 4 design of thesis-e (the thesis' rules: two cannot hover)."""
    return _models(catalog, grids[4], feasible_indices(grids[4]))


@pytest.fixture(scope="module")
def n4_roll_step(thesis_n4) -> list[dict]:
    """The scalar loop's full 4 s roll_step of every feasible N = 4 design, flown once: the
    figures (a) holds the batch to, and those ``roll_step`` makes the ranking's rows of."""
    return _scalar(thesis_n4, MANEUVERS["roll_step"])


def test_every_feasible_n4_design_flies_the_full_roll_step_as_the_scalar_loop(
        thesis_n4, n4_roll_step) -> None:
    """(a) the full 4 s roll_step of all 48 designs in one batch."""
    man = MANEUVERS["roll_step"]
    assert len(thesis_n4) == 48
    _assert_same(_batch(thesis_n4, man), n4_roll_step)


def test_the_ranking_flies_its_designs_in_a_batch_with_the_same_rows(
        catalog, grids, thesis_n4, n4_roll_step) -> None:
    """``rank`` flies the designs through the sweep engine (batch flights): its rows are
    ``roll_step``'s, one design at a time, also for those that cannot hover. ``roll_step``
    is ``fly`` of the design's ``setup`` made a row: the rows are made of the flights (a)
    checked, and ``roll_step`` itself gives them for a design that hovers and one that
    cannot (its every design would fly all 48 full roll steps a second time)."""
    grid = grids[4]
    indices = feasible_indices(grid)
    assert any(setup(catalog, grid, i)[0].hover_shortfall() for i in indices)
    got = rank(catalog, grid).rows
    want = [_row(grid, idx, v, a, fig)
            for idx, (v, a), fig in zip(indices, thesis_n4, n4_roll_step, strict=True)]
    spot = [next(k for k, r in enumerate(want) if r.note),
            next(k for k, r in enumerate(want) if not r.note)]
    assert [roll_step(catalog, grid, indices[k]) for k in spot] == [want[k] for k in spot]
    assert [r.note for r in got] == [r.note for r in want]
    _assert_same([dataclasses.asdict(r) for r in got], [dataclasses.asdict(r) for r in want])


@pytest.mark.parametrize("n", [6, 8])
def test_a_subset_of_n6_and_n8_designs_fly_the_roll_step_as_the_scalar_loop(
        catalog, grids, n) -> None:
    indices = feasible_indices(grids[n])[::4]
    assert len(indices) >= 8
    models = _models(catalog, grids[n], indices)
    man = _short(MANEUVERS["roll_step"])
    _assert_same(_batch(models, man), _scalar(models, man))


def test_designs_that_cannot_hover_saturate_as_in_the_scalar_loop(catalog, grids) -> None:
    """(b) the thesis' rules accept designs whose rotors cannot hold the weight: the mixer
    saturates nearly every tick; with a hovering design in the batch, every maneuver."""
    models = []
    for idx in feasible_indices(grids[4]):
        vehicle, actuator = setup(catalog, grids[4], idx)
        if vehicle.hover_shortfall() or len(models) == 2:
            models.append((vehicle, actuator))
    falling = [bool(v.hover_shortfall()) for v, _ in models]
    assert falling == [True, True, False]
    for man in ALL_SHORT:
        got, want = _batch(models, man), _scalar(models, man)
        _assert_same(got, want)
        if man.axis != "hover":
            assert [g["saturation_pct"] == 100.0 for g in got][:2] == [True, True]


def _measured_like(models) -> list[tuple]:
    """Measured-like actuators (Paper C: rising slower than falling, latency, ESC frames
    of several rates, other resolutions) and linear drag on some: every design differs in
    frame ticks, delay ticks, or both."""
    latencies = (0.0, 0.013, 0.0045, 0.0005, 0.004, 0.02, 0.013, 0.0)
    frames = (1 / 400, 0.0, 1 / 50, 1 / 490, 0.002, 1 / 400, 0.001, 0.0125)
    out = []
    for i, (v, a) in enumerate(models):
        tau = a.tau_up_s
        act = ActuatorModel(tau * 1.07, tau * 0.93, latencies[i % 8], frames[i % 8],
                            levels=(1000, 2048, 200)[i % 3], idle_fraction=(0.05, 0.1)[i % 2],
                            source="measured-like")
        out.append((dataclasses.replace(v, drag_n_s_m=0.3 * (i % 3)), act))
    return out


@pytest.mark.parametrize("man", ALL_SHORT, ids=lambda m: m.name)
def test_mixed_latency_frames_and_lags_fly_every_maneuver_as_the_scalar_loop(
        thesis_n4, man) -> None:
    """(c) per-design latency, ESC frame, tau up != tau down, levels, idle, drag."""
    models = _measured_like(thesis_n4[::6])
    assert len({round(a.latency_s / 1e-3) for _, a in models}) > 3
    assert len({max(1, round(a.frame_s / 1e-3)) for _, a in models}) > 3
    _assert_same(_batch(models, man), _scalar(models, man))


@pytest.mark.parametrize("n", [4, 8])
def test_plus_layout_flies_as_the_scalar_loop(catalog, grids, n) -> None:
    """(d) the plus layout, with one latency and frame for the whole batch (the batch's
    shared-delay path)."""
    models = [(v, dataclasses.replace(a, latency_s=0.004))
              for v, a in _models(catalog, grids[n], feasible_indices(grids[n])[::6],
                                  layout="plus")]
    for man in (_short(MANEUVERS["roll_step"]), _short(MANEUVERS["yaw_step"])):
        _assert_same(_batch(models, man), _scalar(models, man))


def test_a_batch_of_one_and_chunks_fly_as_the_scalar_loop(thesis_n4) -> None:
    """(e) one design alone; and a batch flown in chunks of 5 (each chunk its own loop)."""
    man = _short(MANEUVERS["pitch_step"])
    _assert_same(_batch(thesis_n4[7:8], man), _scalar(thesis_n4[7:8], man))
    models = _measured_like(thesis_n4[:12])
    _assert_same(_batch(models, man, chunk=5), _scalar(models, man))


def test_the_trajectory_is_the_scalar_loops_to_the_last_bit(thesis_n4) -> None:
    """Stricter than the rounded figures: the flown roll angle of each tick and the
    saturation flags equal ``fly``'s exactly (same floating-point operations)."""
    models = _measured_like(thesis_n4[::5])
    man = _short(MANEUVERS["roll_step"])
    batch = DesignBatch.from_models([v for v, _ in models], [a for _, a in models])
    trace = simulate(batch, man, 1e-3)
    for j, (v, a) in enumerate(models):
        flight = fly(v, a, man, gains=gains_for(a))
        assert np.array_equal(trace.signal[:, j], flight.euler[:, 0])
        assert np.array_equal(trace.saturated[:, j], flight.saturated)


def test_broken_designs_get_their_error_and_the_others_fly(thesis_n4) -> None:
    """(f) a design with NaN numbers is not flown, one whose flight diverges (an inertia
    so small that its rates overflow: the scalar loop raises a math domain error) is
    reported from the tick it diverged; the others' figures are the scalar ones."""
    (v0, a0), (v1, a1) = thesis_n4[3], thesis_n4[20]
    man = _short(MANEUVERS["roll_step"])
    tiny = dataclasses.replace(v1, inertia_kgm2=(1e-300, 1e-300, 2e-300))
    with pytest.raises(ValueError, match="math domain error"):
        fly(tiny, a1, man, gains=gains_for(a1))
    rows = [(v0, a0), (v1, a1), (tiny, a1), (v1, a0), (v0, a0)]

    def column(get):
        return [get(v, a) for v, a in rows]

    batch = DesignBatch.from_arrays(
        4, mass_kg=[math.nan, *column(lambda v, a: v.mass_kg)[1:]],
        ixx=column(lambda v, a: v.inertia_kgm2[0]), iyy=column(lambda v, a: v.inertia_kgm2[1]),
        izz=column(lambda v, a: v.inertia_kgm2[2]), arm_m=column(lambda v, a: v.arm_m),
        k_f=column(lambda v, a: v.k_f), k_m=column(lambda v, a: v.k_m),
        omega_max_rad_s=column(lambda v, a: v.omega_max_rad_s),
        tau_up_s=column(lambda v, a: a.tau_up_s),
        tau_down_s=[*column(lambda v, a: a.tau_down_s)[:4], -0.01],
        labels=["nan-mass", "good", "tiny-inertia", "good-2", "bad-tau"])
    got = fly_batch(batch, man)
    assert got[0] == {"error": "vehicle nan-mass: mass_kg must be > 0, got nan"}
    assert got[2] == {"error": "flight diverged: the state is not finite from t = 0.001 s"}
    assert got[4] == {"error": "actuator (design bad-tau): tau_down_s must be > 0 s, got "
                               "-0.01"}
    _assert_same([got[1], got[3]], _scalar([rows[1], rows[3]], man))


def test_from_arrays_is_from_models(thesis_n4) -> None:
    """The array constructor (no Vehicle objects) builds the same batch, gains included."""
    models = _measured_like(thesis_n4[::7])
    by_models = DesignBatch.from_models([v for v, _ in models], [a for _, a in models])
    by_arrays = DesignBatch.from_arrays(
        4, "x", **{name: getattr(by_models, name) for name in (
            "mass_kg", "ixx", "iyy", "izz", "arm_m", "k_f", "k_m", "omega_max_rad_s",
            "gravity_m_s2", "drag_n_s_m", "tau_up_s", "tau_down_s", "latency_s", "frame_s",
            "levels", "idle_fraction")}, labels=by_models.labels)
    for f in dataclasses.fields(DesignBatch):
        a, b = getattr(by_models, f.name), getattr(by_arrays, f.name)
        assert np.array_equal(a, b) if isinstance(a, np.ndarray) else a == b, f.name


def test_bad_batches_are_request_errors(thesis_n4, catalog, grids) -> None:
    v6, a6 = setup(catalog, grids[6], feasible_indices(grids[6])[0])
    with pytest.raises(RequestError, match="one rotor count and layout per batch"):
        DesignBatch.from_models([thesis_n4[0][0], v6], [thesis_n4[0][1], a6])
    with pytest.raises(RequestError, match="do not broadcast"):
        DesignBatch.from_arrays(4, mass_kg=[1.0, 1.0], ixx=[0.1, 0.1, 0.1], iyy=0.1,
                                izz=0.2, arm_m=0.2, k_f=1e-5, k_m=1e-7, omega_max_rad_s=900,
                                tau_up_s=0.05, tau_down_s=0.05)
    with pytest.raises(RequestError, match="N = 4, 6 or 8"):
        DesignBatch.from_arrays(5, mass_kg=1.0, ixx=0.1, iyy=0.1, izz=0.2, arm_m=0.2,
                                k_f=1e-5, k_m=1e-7, omega_max_rad_s=900, tau_up_s=0.05,
                                tau_down_s=0.05)
