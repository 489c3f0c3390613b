"""Fixtures of the sweep tests: a real Dask cluster (``dask scheduler`` and two
``dask worker`` processes on loopback) and the thesis-e catalog with the hover margin."""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from rotorbench_tests_services import DaskCluster, dask_cluster

from bench.store.catalogs import with_min_thrust_to_weight
from optimizer.catalogs.catalog import load_catalog
from tests.conftest import CATALOGS


@contextlib.contextmanager
def unprofiled_cluster(workers: int) -> Iterator[DaskCluster]:
    """``dask_cluster(workers)`` whose workers, the ones a test adds later too, run without
    Dask's statistical profiler: it samples the flying thread's stack every 10 ms for a
    dashboard that no test reads (about a tenth of a worker's CPU), and it costs CPU idle.
    Scheduling, heartbeats and a lost worker are Dask's defaults."""
    import dask.config  # noqa: F401 (this process's own configuration read first)

    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("DASK_DISTRIBUTED__WORKER__PROFILE__ENABLED", "False")
        with dask_cluster(workers=workers) as cluster:
            yield cluster


@pytest.fixture(scope="module")
def dask() -> Iterator[DaskCluster]:
    """One scheduler with two single-thread workers for the module that asks for it. Not
    for the session: idle, the three processes still cost 2 s of CPU per 30 s (heartbeats),
    about 14 s of a suite that runs on saturated cores after the file has ended."""
    with unprofiled_cluster(workers=2) as cluster:
        yield cluster


@pytest.fixture(scope="session")
def thesis_e():
    """thesis-e with the default hover margin (1.2): the 44 N = 4 designs that hover."""
    return with_min_thrust_to_weight(load_catalog(CATALOGS / "thesis-e"), 1.2)


#: the sweep every executor test flies: thesis-e, N = 4, 44 designs, roll_step
SWEEP = ["fly", "--sweep", "--actuators", "4", "--maneuver", "roll_step"]


@pytest.fixture(scope="session")
def reference(tmp_path_factory: pytest.TempPathFactory):
    """The in-process sweep (``--workers 1``, the default): what every executor must give."""
    import pyarrow.parquet as pq

    from bench.cli import main

    out = tmp_path_factory.mktemp("reference") / "sweep.parquet"
    assert main([*SWEEP, "--out", str(out)]) == 0
    return pq.read_table(out)


#: the ``rotorbench`` command of this venv: the CLI as a user types it
ROTORBENCH = str(Path(sys.executable).with_name("rotorbench"))


def start_sweep(argv: list[str]) -> subprocess.Popen[str]:
    """``rotorbench fly --sweep ...`` in its own process group, stderr captured."""
    return subprocess.Popen([ROTORBENCH, *argv], stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, text=True, start_new_session=True)


def wait_for_parts(out: Path, child: subprocess.Popen[str], count: int = 1,
                   timeout_s: float = 60.0) -> None:
    """Until the sweep writing ``out`` has ``count`` parts; it must still be running."""
    from bench.jobs.sweep_parts import parts_folder

    deadline = time.monotonic() + timeout_s
    while len(list(parts_folder(out).glob("part-*.parquet"))) < count:
        assert child.poll() is None, f"the sweep ended first: {child.communicate()[1]}"
        assert time.monotonic() < deadline, "no part within the time"
        time.sleep(0.01)


def run_cli(argv: list[str], timeout_s: float = 120.0) -> subprocess.CompletedProcess[str]:
    """``rotorbench ARGV`` run to its end, as a user types it."""
    return subprocess.run([ROTORBENCH, *argv], capture_output=True, text=True,
                          timeout=timeout_s)


def stop(child: subprocess.Popen[str]) -> None:
    """SIGKILL a sweep's process group if it still runs, and reap it."""
    if child.poll() is None:
        os.killpg(child.pid, signal.SIGKILL)
    child.communicate()
