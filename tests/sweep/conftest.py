"""Fixtures of the sweep tests: a real Dask cluster (``dask scheduler`` and two
``dask worker`` processes on loopback) and the thesis-e catalog with the hover margin."""

from __future__ import annotations

from collections.abc import Iterator

import pytest
from rotorbench_tests_services import DaskCluster, dask_cluster

from bench.store.catalogs import with_min_thrust_to_weight
from optimizer.catalog import load_catalog
from tests.conftest import CATALOGS


@pytest.fixture(scope="module")
def dask() -> Iterator[DaskCluster]:
    """One scheduler with two single-thread workers for the module that asks for it. Not
    for the session: idle, the three processes still cost 2 s of CPU per 30 s (heartbeats),
    about 14 s of a suite that runs on saturated cores after the file has ended."""
    with dask_cluster(workers=2) as cluster:
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
