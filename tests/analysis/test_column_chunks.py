"""A run's columns a chunk at a time (``ColumnChunks``, what the web view's plots read):
the parts in order, a part lacking a column, a clock that stepped back, damaged files."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from analysis.errors import LogError
from analysis.run_record import ColumnChunks, read_columns, read_run


def _run(root: Path, parts: list[dict[str, np.ndarray]]) -> Path:
    """A run folder with one Parquet part per dict (as the recorder names them)."""
    run = root / "run"
    (run / "samples.parquet").mkdir(parents=True)
    (run / "run.json").write_text(json.dumps({"id": "r1", "samples": "samples.parquet"}))
    for k, cols in enumerate(parts):
        pq.write_table(pa.table(cols), run / "samples.parquet" / f"part-{k:06d}.parquet")
    return run


def _joined(chunks: ColumnChunks) -> dict[str, np.ndarray]:
    got = list(chunks)
    return {c: np.concatenate([g[c] for g in got]) for c in chunks.names}


def test_parts_come_in_order_in_chunks_of_at_most_rows(tmp_path: Path) -> None:
    t = np.arange(2500) * 1e-3
    y = np.sin(t)
    run = _run(tmp_path, [{"t_s": t[a:a + 1000], "y": y[a:a + 1000],
                           "n": np.arange(a, min(a + 1000, 2500))} for a in (0, 1000, 2000)])
    (run / "samples.parquet" / ".part-000003.parquet.tmp").write_bytes(b"half a part")
    chunks = ColumnChunks(run, ["y", "n", "t_s", "missing", "y"], rows=300)
    assert chunks.names == ["y", "n"]
    np.testing.assert_array_equal(chunks.t, t)
    sizes = [len(c["y"]) for c in chunks]
    assert max(sizes) == 300 and sum(sizes) == 2500
    got = _joined(chunks)
    np.testing.assert_array_equal(got["y"], y)
    assert got["n"].dtype == float and np.array_equal(got["n"], np.arange(2500))
    assert set(read_columns(run, ["y"])) == {"t_s", "y"}


def test_a_part_without_a_column_gives_nan(tmp_path: Path) -> None:
    run = _run(tmp_path, [{"t_s": [0.0, 1.0], "y": [5.0, 6.0]}, {"t_s": [2.0, 3.0]},
                          {"t_s": [4.0], "y": [None]}])
    got = _joined(ColumnChunks(run, ["y"]))
    np.testing.assert_array_equal(got["y"], [5.0, 6.0, np.nan, np.nan, np.nan])


def test_a_clock_that_stepped_back_is_sorted_as_read_run_sorts_it(tmp_path: Path) -> None:
    run = _run(tmp_path, [{"t_s": [0.0, 1.0, 2.0], "y": [0.0, 1.0, 2.0]},
                          {"t_s": [1.5, 3.0], "y": [1.5, 3.0]}])
    chunks = ColumnChunks(run, ["y"], rows=1)
    record = read_run(run)
    np.testing.assert_array_equal(chunks.t, record.column("t_s"))
    (only,) = list(chunks)
    np.testing.assert_array_equal(only["y"], record.column("y"))


@pytest.mark.parametrize(("parts", "damage", "says"), [
    ([{"t_s": [0.0]}], "part-000000.parquet", "not readable as Parquet"),
    ([{"t_s": [0.0]}, {"t_s": [1.0]}], "part-000001.parquet", "not readable as Parquet"),
    ([{"y": [0.0]}], None, "no 't_s' column"),
    ([{"t_s": np.array([], float)}], None, "no samples"),
    ([{"t_s": [0.0, np.nan]}], None, "row 1: t_s is not a finite number"),
    ([], None, "no sample parts"),
])
def test_bad_samples_raise_one_line_naming_the_file(tmp_path: Path, parts: list[dict],
                                                    damage: str | None, says: str) -> None:
    run = _run(tmp_path, parts)
    if damage:
        (run / "samples.parquet" / damage).write_bytes(b"PAR1 not really")
    with pytest.raises(LogError, match=says) as err:
        list(ColumnChunks(run, ["y"]))
    assert str(run / "samples.parquet") in str(err.value)
