"""Every bench's stored constants of one actuator, read from a real lab catalog: the bench of
each fit from its run, the newest fit per bench, the uncertainty in either stored form
(a budget stored with the constant, else the fit's spread), and bad requests refused in
one line with nothing written."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from analysis.metrology.gum import Budget, Term
from bench.store.bench_comparison import compare_benches
from bench.store.lab_catalog import LabCatalog, StoredConstants, run_from_meta
from bench.store.stored_uncertainty import stored_budget
from bench.store.stores import open_store
from tests.conftest import run_bad

M, P = "m-2212", "p-8x45"


def _run(cat: LabCatalog, i: int, bench: str, motor: str = M) -> str:
    run_id = f"20261127T0800{i:02d}_000000Z-step1-{i:04x}"
    meta = {"id": run_id, "rig": {"name": "sim"}, "status": "success",
            "components": {"motor": motor, "propeller": P},
            "started_utc": f"2026-11-27T08:00:{i:02d}Z"}
    cat.upsert_run(run_from_meta(meta, data=f"s3://lab/runs/{run_id}", samples=10,
                                 bench=bench, operator="ana"))
    return run_id


def _row(run_id: str, kind: str, data: dict, esc_mode: str = "complementary",
         motor: str = M) -> StoredConstants:
    return StoredConstants(motor, P, "f30a", esc_mode, "3s", kind, "", run_id, "", "", data)


def _step(tau_up: float) -> dict:
    return {"tau_up_s": tau_up, "tau_down_s": 0.05, "latency_s": 0.012, "repeats": 4,
            "tau_up_std_s": 0.002, "tau_down_std_s": 0.002, "latency_std_s": 0.001}


@pytest.fixture
def lab(pg_url: str, tmp_path: Path) -> str:
    """Benches A and B with step and static fits, A refitted since; B's sweep carries a
    stored budget; C only measured another motor."""
    cat = LabCatalog(pg_url)
    cat.init()
    a1, a2, b, c = (_run(cat, 1, "A"), _run(cat, 2, "A"), _run(cat, 3, "B"),
                    _run(cat, 4, "C", motor="other"))
    budget = Budget.of(6.5e-6, "N s^2", [Term("fit", 1e-9, "A", 40), Term("cal", 2e-9, "B")])
    cat.add_constants([
        _row(a1, "step", _step(0.090)),  # superseded by a2's
        _row(a2, "step", _step(0.030)),
        _row(b, "step", _step(0.031)),
        _row(a2, "static", {"k_f_n_s2": 6.4e-6, "k_f_std_n_s2": 4e-9, "points": 64,
                            "thrust_poly_w": [0.01, 1e-5, 6.4e-6]}),
        _row(b, "static", {"k_f_n_s2": 6.5e-6, "thrust_poly_w": [0.02, 2e-5, 6.5e-6],
                           "uncertainty": {"k_f_n_s2": {**budget.as_dict(), "run": b,
                                                        "calibrations": ["cal-1"]}}}),
        _row(c, "step", _step(0.03), motor="other"),
    ])
    return pg_url


def test_each_bench_newest_fit_with_the_uncertainty_its_row_carries(lab: str, tmp_path: Path
                                                                   ) -> None:
    result = compare_benches(open_store(lab, spool=tmp_path / "spool"), M, P)
    assert [b.bench for b in result.benches] == ["A", "B"]
    assert [b.calibrations for b in result.benches] == [(), ("cal-1",)]  # B's stored budget
    by = {c.name: {p.bench: p for p in c.participants} for c in result.constants}
    assert by["tau_up_s"]["A"].value == 0.030  # the newer of A's two step fits
    # the spread of one edge over sqrt(repeats); the latency is the mean of both edges
    assert by["tau_up_s"]["A"].u == pytest.approx(0.002 / 2)
    assert by["latency_s"]["A"].u == pytest.approx(0.001 / math.sqrt(8))
    assert by["k_f_n_s2"]["A"].u == pytest.approx(4e-9 / 8)
    assert by["k_f_n_s2"]["B"].u == pytest.approx(math.hypot(1e-9, 2e-9))  # stored budget
    assert [t.name for t in by["k_f_n_s2"]["B"].budget.terms] == ["fit", "cal"]
    assert by["thrust_poly_w_2"]["A"].u is None  # no uncertainty stored: never judged
    assert "k_q_nm_s2" not in by  # no bench measured it
    (k_f,) = [c for c in result.constants if c.name == "k_f_n_s2"]
    (pair,) = k_f.pairs
    assert pair.e_n == pytest.approx((6.4e-6 - 6.5e-6) / (2 * math.hypot(5e-10, 2.236e-9)),
                                     rel=1e-3)
    assert ("k_f_n_s2", "A", "B", pair.e_n) in result.flagged


def test_stored_budget_reads_either_form_and_nothing_else() -> None:
    assert stored_budget("tau_up_s", 0.03, "s", {"tau_up_std_s": 0.002}) is None  # no count
    assert stored_budget("gain", 1.0, "", {"gain_std": 0.1, "repeats": 4}) is None
    damaged = {"uncertainty": {"k_f_n_s2": {"budget": [{"name": "x"}]}},
               "k_f_std_n_s2": 4e-9, "points": 16}
    budget = stored_budget("k_f_n_s2", 6.4e-6, "N s^2", damaged)
    assert budget is not None and budget.u == pytest.approx(1e-9)  # the spread instead


def test_bad_requests_are_one_line_exit_2_and_write_nothing(
        lab: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    plot = tmp_path / "out" / "benches.png"
    empty = tmp_path / "empty"
    empty.mkdir()
    base = ["compare-benches", "--plot", str(plot), "--store"]
    cases = [
        ([*base, str(empty), "--motor", M, "--propeller", P], "no constants stored"),
        ([*base, lab, "--motor", "nope", "--propeller", P],
         "--motor nope: no constants of it in postgresql://postgres:***@"),
        ([*base, lab, "--motor", M, "--propeller", "nope"], f"(stored: {P})"),
        ([*base, lab, "--motor", "other", "--propeller", P],
         "nothing to compare: only bench C measured other / p-8x45"),
    ]
    for argv, message in cases:
        assert message in run_bad(capsys, *argv)
    assert not plot.exists() and not any(empty.iterdir())


def test_benches_measured_in_several_esc_modes_are_compared_like_with_like(
        lab: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    cat = LabCatalog(lab)
    cat.add_constants([_row(_run(cat, 5, "B"), "step", _step(0.02), esc_mode="diode")])
    err = run_bad(capsys, "compare-benches", "--store", lab, "--motor", M, "--propeller", P)
    assert "several ESCs, modes or batteries" in err and "--esc-mode" in err
    capsys.readouterr()
    from bench.cli import main

    assert main(["compare-benches", "--store", lab, "--motor", M, "--propeller", P,
                 "--esc-mode", "complementary"]) == 1  # A and B disagree on k_f
    out = capsys.readouterr().out
    assert "FLAGGED" in out and "k_f A vs B" in out
