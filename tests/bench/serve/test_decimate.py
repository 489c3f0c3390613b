"""Min/max decimation: every bin keeps its exact minimum and maximum (a spike survives),
a signal fed in chunks gives the same points as the whole signal, and a run's plots are
the decimation of the columns ``read_run`` reads."""

from __future__ import annotations

import itertools
import shutil
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from analysis.run_record import read_run
from bench.serve.decimate import Bins, MinMaxEnvelope, minmax_decimate
from bench.serve.run_views import _efficiency_of, series_of


def _signal(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    t = np.cumsum(rng.uniform(0.0, 2e-4, n))  # uneven, with repeated stamps
    y = np.sin(t * 40) + 0.05 * rng.standard_normal(n)
    y[rng.integers(0, n, n // 50)] = np.nan
    return t, y


def test_each_bin_keeps_its_exact_min_and_max() -> None:
    t, y = _signal(50_000, 1)
    y[31_337] = 25.0  # one sample spike, as a trip
    columns = 300
    tt, yy = minmax_decimate(t, y, columns)
    edges = np.linspace(t[0], t[-1], columns + 1)
    which = np.clip(np.searchsorted(edges, t, side="right") - 1, 0, columns - 1)
    bins = [b for b in range(columns) if (which == b).any()]
    assert tt.size == yy.size == 2 * len(bins)
    for k, b in enumerate(bins):
        inside = y[which == b]
        lo, hi = np.nanmin(inside), np.nanmax(inside)
        assert sorted(yy[2 * k:2 * k + 2]) == [lo, hi]
        assert tt[2 * k] == t[which == b][0] and tt[2 * k + 1] == t[which == b][-1]
    assert np.nanmax(yy) == 25.0


def test_falling_bins_draw_the_max_first() -> None:
    t = np.linspace(0.0, 1.0, 1000)
    falling = minmax_decimate(t, 1.0 - t, 10)[1]
    assert np.all(falling[0::2] > falling[1::2])
    rising = minmax_decimate(t, t, 10)[1]
    assert np.all(rising[0::2] < rising[1::2])


def test_short_signals_come_back_whole() -> None:
    t, y = _signal(400, 2)
    tt, yy = minmax_decimate(t, y, 200)
    np.testing.assert_array_equal(tt, t)
    np.testing.assert_array_equal(yy, y)


@settings(max_examples=60, deadline=None)
@given(n=st.integers(1, 3000), columns=st.integers(1, 400), seed=st.integers(0, 2**16),
       cuts=st.lists(st.integers(0, 3000), max_size=12))
def test_chunks_give_the_points_of_the_whole_signal(n: int, columns: int, seed: int,
                                                     cuts: list[int]) -> None:
    t, y = _signal(n, seed)
    envelope = MinMaxEnvelope(Bins(t, columns))
    bounds = [0, *sorted(c for c in cuts if c <= n), n]
    for a, b in itertools.pairwise(bounds):
        envelope.add(y[a:b])  # empty chunks too
    whole = minmax_decimate(t, y, columns)
    for got, want in zip(envelope.points(), whole, strict=True):
        np.testing.assert_array_equal(got, want)


def test_an_envelope_wants_all_rows_and_no_more() -> None:
    t, y = _signal(5000, 3)
    envelope = MinMaxEnvelope(Bins(t, 100))
    envelope.add(y[:4000])
    with pytest.raises(ValueError, match="4000 rows given of 5000"):
        envelope.points()
    with pytest.raises(ValueError, match="more rows"):
        envelope.add(y)
    with pytest.raises(ValueError, match="columns"):
        Bins(t, 0)


def test_a_runs_plots_are_the_decimation_of_its_columns(recorded: Path,
                                                        tmp_path: Path) -> None:
    """The page's plots, read a chunk at a time from a run of many parts, are the
    decimation of the whole columns (``read_run``), efficiency included."""
    run = tmp_path / "run"
    shutil.copytree(next(p.parent for p in sorted(recorded.glob("*-step1/run.json"))), run)
    parts = sorted((run / "samples.parquet").glob("*.parquet"))
    if len(parts) < 3:  # a flat-out simulated run writes 10 s parts: cut it in three
        table = pa.concat_tables([pq.read_table(q) for q in parts])
        for q in parts:
            q.unlink()
        third = -(-table.num_rows // 3)
        for i in range(3):
            pq.write_table(table.slice(i * third, third),
                           run / "samples.parquet" / f"part-{i:06d}.parquet")
    assert len(sorted((run / "samples.parquet").glob("*.parquet"))) >= 3  # chunks cross parts
    record = read_run(run)
    t = record.column("t_s")
    want = {k: record.column(k) for k in ("throttle_us", "thrust_n", "current_a",
                                          "voltage_v", "rpm")}
    want["efficiency_g_w"] = _efficiency_of(want["thrust_n"], want["current_a"],
                                            want["voltage_v"])
    got = series_of(run, columns=300)
    assert got["rows"] == t.size > 2 * 300
    assert {p["key"] for p in got["plots"]} == set(want)
    for plot in got["plots"]:
        tt, yy = minmax_decimate(t, want[plot["key"]], 300)
        assert plot["t"] == _as_json(tt) and plot["y"] == _as_json(yy)


def _as_json(a: np.ndarray) -> list[float | None]:
    return [v if np.isfinite(v) else None for v in np.round(a, 6).tolist()]
