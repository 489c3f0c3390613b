"""A sweep's parts (``bench.jobs.sweep_parts``) when the files or the folder fail it: a
damaged part flies again on resume, a folder that turns read-only mid-sweep ends the
command in one line with what was kept."""

from __future__ import annotations

import json

import pyarrow.parquet as pq
import pytest

from bench.jobs.sweep_parts import Parts, parts_folder
from tests.bench.jobs.conftest import SWEEP, run_cli, start_sweep, stop, wait_for_parts
from tests.bench.paths.test_outputs import unwritable

pytestmark = pytest.mark.slow(wall_s=15)  # sweeps in subprocesses


def test_a_truncated_part_flies_again_on_resume(tmp_path, reference) -> None:
    """Parts of the reference sweep as an interrupted run leaves them, one cut to half its
    bytes: the same command says so in one line, flies that chunk again and writes the
    reference file."""
    out = tmp_path / "sweep.parquet"
    spec = json.loads(reference.schema.metadata[b"rotorbench_sweep"])
    parts = Parts(parts_folder(out), spec)
    rows = reference.to_pylist()
    written = [parts.write(rows[start:start + 4]) for start in (0, 4, 8)]
    cut = written[1]
    cut.write_bytes(cut.read_bytes()[: cut.stat().st_size // 2])
    done = run_cli([*SWEEP, "--out", str(out)])
    assert done.returncode == 0, done.stderr
    assert "Traceback" not in done.stderr
    lines = done.stderr.strip().splitlines()
    [said] = [line for line in lines if "damaged" in line]
    assert said.startswith(f"damaged part {cut} (") and \
        said.endswith("): its chunk flies again")
    assert "resumed: 8 of 44 done" in done.stderr
    assert pq.read_table(out).equals(reference)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["sweep.parquet"]


def test_a_folder_read_only_mid_sweep_ends_in_one_line_with_what_was_kept(
        tmp_path, reference) -> None:
    """The parts folder and the folder of --out turn read-only while the sweep flies: the
    command keeps what it wrote, says so, ends with one line naming the folder (exit 2);
    once writable again the same command finishes it."""
    out = tmp_path / "sweep.parquet"
    argv = [*SWEEP, "--out", str(out)]
    child = start_sweep([*argv, "--chunk-size", "3"])
    try:
        wait_for_parts(out, child)
        folder = parts_folder(out)
        with unwritable(folder, tmp_path):
            kept = len(list(folder.glob("part-*.parquet")))
            _, err = child.communicate(timeout=120)
            assert len(list(folder.glob("part-*.parquet"))) == kept  # no half part
    finally:
        stop(child)
    assert child.returncode == 2, err
    assert "Traceback" not in err
    designs = sum(pq.read_metadata(p).num_rows for p in folder.glob("part-*.parquet"))
    assert err.strip().splitlines()[-2:] == [
        f"kept {designs} of 44 designs in {folder}; run the same command again to fly the "
        "rest",
        f"rotorbench: error: cannot write in {folder} (Operation not permitted); the "
        "finished chunks stay, run the same command again once it is writable"]
    done = run_cli(argv)
    assert done.returncode == 0, done.stderr
    assert f"resumed: {designs} of 44 done" in done.stderr
    assert pq.read_table(out).equals(reference)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["sweep.parquet"]
