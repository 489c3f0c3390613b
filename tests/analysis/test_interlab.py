"""Benches compared as an interlaboratory comparison: E_n of every pair, the flag at
|E_n| > 1, values without an uncertainty listed but never judged, and the figure."""

from __future__ import annotations

import json

import pytest

from analysis.metrology.gum import Budget, Term
from analysis.metrology.interlab import Participant, compare_constant, flagged_benches
from analysis.metrology.interlab_figure import plot_comparison


def _p(bench: str, value: float, u: float | None) -> Participant:
    budget = None if u is None else Budget.of(value, "N s^2", [Term("fit", u, "A", 59)])
    return Participant(bench, value, budget, run_id=f"run-{bench}")


def test_every_pair_gets_its_normalised_error_and_only_the_outlier_is_flagged():
    # two benches agree; the third reads 10 % high with the same uncertainty
    c = compare_constant("k_f", "N s^2", [_p("a", 6.43e-6, 5e-10), _p("b", 6.4305e-6, 5e-10),
                                          _p("c", 7.07e-6, 5e-10)])
    en = {(p.bench_a, p.bench_b): p.e_n for p in c.pairs}
    assert set(en) == {("a", "b"), ("a", "c"), ("b", "c")}
    big_u = 2 * 5e-10  # U = k u, k = 2, the same for every bench
    assert en["a", "b"] == pytest.approx((6.43e-6 - 6.4305e-6) / (2 ** 0.5 * big_u))
    assert abs(en["a", "b"]) < 1 < abs(en["a", "c"])
    assert [(p.bench_a, p.bench_b) for p in c.flagged] == [("a", "c"), ("b", "c")]
    assert flagged_benches(c) == {"a": 1, "b": 1, "c": 2}  # c: against every other bench
    row = json.loads(json.dumps(c.as_dict()))  # plain JSON
    assert row["benches"][0]["U"] == pytest.approx(big_u) and row["benches"][0]["k"] == 2


def test_a_value_without_an_uncertainty_is_listed_never_judged():
    c = compare_constant("thrust_poly_w_2", "N s^2", [_p("a", 1.0, None), _p("b", 9.0, 0.1)])
    (pair,) = c.pairs
    assert pair.e_n is None and not pair.flagged and c.flagged == ()
    assert c.participants[0].expanded is None


def test_the_figure_has_a_panel_per_constant(tmp_path):
    cs = [compare_constant(name, "u", [_p("a", 1.0, 0.01), _p("b", 1.5, 0.01),
                                       _p("c", 1.0, None)])
          for name in ("k_f", "tau_up", "tau_down", "latency")]
    out = plot_comparison(cs, tmp_path / "benches.png")
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and out.stat().st_size > 10_000
    assert not list(tmp_path.glob(".*tmp*"))
