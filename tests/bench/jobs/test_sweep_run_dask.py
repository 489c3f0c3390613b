"""The sweep on real Dask processes: a LocalCluster and a ``dask scheduler`` with
``dask worker`` processes give the in-process rows in any chunking; a worker killed in
the middle costs nothing."""

from __future__ import annotations

import json
import os
import signal
import time

import pyarrow.parquet as pq
import pytest
from pandas.testing import assert_frame_equal

from bench.cli import main
from bench.jobs.sweep_run import Executor, run_sweep
from optimizer.sweep.designs import plan_designs
from optimizer.sweep.spec import sweep_spec
from tests.bench.jobs.conftest import SWEEP

pytestmark = pytest.mark.slow(wall_s=25)  # real Dask schedulers and workers: started first

#: a series/parallel sweep of a small subset: 12 flyable 2S2P designs, N = 4 and 6
PACKS = ["fly", "--sweep", "--actuators", "4", "6", "--series", "2", "--parallel", "2",
         "--flyable", "--maneuver", "roll_step"]


def assert_same_rows(a, b) -> None:
    """The same designs in the same order with the same numbers (1e-9)."""
    assert_frame_equal(a.to_pandas(), b.to_pandas(), check_exact=False, rtol=1e-9, atol=0.0)


def test_every_executor_gives_the_in_process_rows(capsys, tmp_path, dask, reference) -> None:
    # chunkings of the 44 designs other than the in-process one chunk (2 chunks of 22, one
    # per worker; 3 of 15, the last of 14), finished in any order; each chunk flies the
    # maneuver's whole tick loop, a second whatever its size, so more chunks would only
    # cost time
    runs = {"local": ["--workers", "2", "--chunk-size", "22"],
            "remote": ["--scheduler", dask.address, "--chunk-size", "15"]}
    for name, options in runs.items():
        out = tmp_path / f"{name}.parquet"
        assert main([*SWEEP, *options, "--out", str(out)]) == 0
        table = pq.read_table(out)
        assert_same_rows(table, reference)
        assert table.schema.metadata == reference.schema.metadata  # the same spec
    err = capsys.readouterr().err
    assert "Dask LocalCluster of 2 worker processes: 2 worker threads" in err
    assert f"Dask scheduler {dask.address}: 2 worker threads" in err
    assert "dashboard" not in err  # no bokeh here: no dashboard to name


def test_a_series_sweep_is_the_same_on_the_cluster(capsys, tmp_path, dask) -> None:
    here, there = tmp_path / "here.parquet", tmp_path / "there.parquet"
    assert main([*PACKS, "--out", str(here), "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["designs"] == 12 and doc["errors"] == 0
    assert main([*PACKS, "--out", str(there), "--scheduler", dask.address,
                 "--chunk-size", "5"]) == 0
    a, b = pq.read_table(here), pq.read_table(there)
    assert_same_rows(a, b)
    assert set(a["series"].to_pylist()) == {2} and set(a["parallel"].to_pylist()) == {2}
    assert set(a["actuators"].to_pylist()) == {4, 6}
    options = json.loads(a.schema.metadata[b"rotorbench_sweep"])["options"]
    assert (options["series"], options["parallel"], options["rules"]["tip_speed_m_s"]) == \
        ([2], [2], 140.0)


def test_a_worker_killed_mid_sweep_costs_nothing(tmp_path, dask, reference, thesis_e) -> None:
    """SIGKILL a worker while it flies a chunk: the scheduler runs its tasks again on the
    others, and the file has every design once, with the in-process numbers."""
    from distributed import Client

    doomed = dask.add_worker("doomed")
    plan = plan_designs(thesis_e, [4])
    spec = sweep_spec(thesis_e, plan, ["roll_step"], {})
    killed: list[int] = []

    def kill_while_busy(done: int, total: int) -> None:
        if killed:
            return
        with Client(dask.address, timeout="10s", set_as_default=False) as client:
            [address] = [a for a, w in client.scheduler_info(n_workers=-1)["workers"].items()
                         if w["name"] == "doomed"]
            deadline = time.monotonic() + 30
            while not client.processing(workers=[address])[address]:
                assert time.monotonic() < deadline, "the doomed worker never got a chunk"
                time.sleep(0.005)
            os.kill(doomed.pid, signal.SIGKILL)
            killed.append(done)

    out = tmp_path / "killed.parquet"
    result = run_sweep(plan, ["roll_step"], spec, out=out, chunk=4, progress=False,
                       executor=Executor(scheduler=dask.address), on_rows=kill_while_busy)
    assert killed and killed[0] < 44
    assert doomed.wait(10) == -signal.SIGKILL
    assert result.table.num_rows == 44 and result.table["design_id"].to_pylist() == \
        reference["design_id"].to_pylist()
    assert_same_rows(pq.read_table(out), reference)
    assert dask.wait_workers(2, 30)  # the scheduler let the dead one go
