"""``--samples`` that cannot fit in memory (``bench.jobs.sweep_memory``): refused in one
line naming the limit, before anything flies; what fits is not."""

from __future__ import annotations

import math
import os
import re
import tracemalloc
from collections.abc import Iterator

import pytest
from rotorbench_tests_services import DaskCluster

from bench.errors import RigError
from bench.jobs.sweep_memory import (
    BYTES_PER_PERCENTILE_SAMPLE,
    check_fits,
    chunk_bytes,
    most_samples,
)
from optimizer.flight.maneuvers import MANEUVERS, Maneuver
from optimizer.sweep.designs import plan_designs
from optimizer.sweep.flight_params import STD_PREFIX
from optimizer.sweep.fly_rows import Chunk, fly_chunk
from tests.bench.jobs.conftest import SWEEP, run_cli, unprofiled_cluster

pytestmark = pytest.mark.slow(wall_s=15)  # CLI runs in subprocesses, a Dask cluster

TOO_MANY = 10**12  # 25 TB of percentiles alone: more than any machine here has


@pytest.fixture(scope="module")
def spread_plan(thesis_e):
    """Six thesis-e designs, every other one with a measured-like spread."""
    plan = plan_designs(thesis_e, [4]).iloc[:6].reset_index(drop=True)
    plan.loc[::2, STD_PREFIX + "tau_up_s"] = 0.1 * plan.loc[::2, "actuator_tau_up_s"]
    return plan


def test_samples_that_cannot_fit_are_one_line_exit_2(tmp_path) -> None:
    """The command as typed: exit 2, one line naming the memory after the warning that
    no design spreads, no traceback, nothing written (was a MemoryError traceback from
    deep in the flight)."""
    done = run_cli([*SWEEP, "--samples", str(TOO_MANY), "--out", str(tmp_path / "s.parquet")])
    assert done.returncode == 2, done.stderr
    warning, line = done.stderr.strip().splitlines()
    assert warning.startswith("warning: --samples: no design has a measured spread")
    assert line.startswith(f"rotorbench: error: --samples {TOO_MANY}: a chunk of 44 designs "
                           "(0 with measured spreads) needs about 22.7 TiB of memory, ")
    assert " is available on this machine; " in line
    fits = int(re.search(r"at most --samples (\d+) fits$", line)[1])
    total = os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    assert 0 < fits * BYTES_PER_PERCENTILE_SAMPLE < total
    assert list(tmp_path.iterdir()) == []


@pytest.fixture(scope="module")
def one_worker() -> Iterator[DaskCluster]:
    """A scheduler and one worker: the limit is the smallest worker's, and one worker has
    it as well as two on this machine (nothing flies: the check comes first)."""
    with unprofiled_cluster(workers=1) as cluster:
        yield cluster


def test_on_a_cluster_the_limit_is_a_workers(tmp_path, one_worker) -> None:
    done = run_cli([*SWEEP, "--samples", str(TOO_MANY), "--scheduler", one_worker.address,
                    "--out", str(tmp_path / "s.parquet")])
    assert done.returncode == 2, done.stderr
    assert " is available per worker thread of the cluster; " in \
        done.stderr.strip().splitlines()[-1]
    assert list(tmp_path.iterdir()) == []


def test_the_limit_is_the_largest_count_that_fits(spread_plan) -> None:
    """At the memory a chunk of 4 (2 drawn) needs for M samples, M passes and M + 1 is
    refused naming M; without spreads only the percentiles grow with M."""
    need = chunk_bytes(4, 2, 1000)
    check_fits(spread_plan, 4, 1000, need, "here")
    with pytest.raises(RigError, match=r"--samples 1001: a chunk of 4 designs \(2 with "
                       r"measured spreads\).* is available here; at most --samples 1000 fits "
                       r"\(or a smaller --chunk-size\)"):
        check_fits(spread_plan, 4, 1001, need, "here")
    assert most_samples(4, 2, need) == 1000
    assert chunk_bytes(6, 0, 10**6) - chunk_bytes(6, 0, 10**3) < 10**6 * 25


def test_the_estimate_is_below_what_a_chunk_takes(spread_plan, monkeypatch) -> None:
    """The bytes counted are no more than a chunk's real peak (tracemalloc sees numpy's
    buffers too), so what is refused truly would not fit."""
    monkeypatch.setitem(MANEUVERS, "roll_step",
                        Maneuver("roll_step", "roll", math.radians(10.0), 0.3))
    plan, m = spread_plan.iloc[:2], 2000  # one drawn design, one not
    tracemalloc.start()
    try:
        fly_chunk(Chunk(plan, ("roll_step",), samples=m))
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert chunk_bytes(2, 1, m) <= peak
