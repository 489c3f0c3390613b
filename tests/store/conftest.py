"""Fixtures for the lab-store tests: one PostgreSQL cluster and one S3 server per session,
a fresh database and bucket per test."""

from __future__ import annotations

import importlib.util
import itertools
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

_NAME = "rotorbench_tests_services"
if _NAME not in sys.modules:
    _spec = importlib.util.spec_from_file_location(
        _NAME, Path(__file__).parents[1] / "services.py")
    assert _spec and _spec.loader
    sys.modules[_NAME] = importlib.util.module_from_spec(_spec)
    _spec.loader.exec_module(sys.modules[_NAME])
services = sys.modules[_NAME]
_count = itertools.count()


@pytest.fixture(scope="session")
def pg_cluster() -> Iterator[object]:
    with services.postgres_cluster() as pg:
        yield pg


@pytest.fixture
def pg_url(pg_cluster: object) -> str:
    """A superuser URL of a new empty database."""
    import psycopg

    name = f"lab_{next(_count)}"
    with psycopg.connect(pg_cluster.url(), autocommit=True) as con:
        con.execute(f"DROP DATABASE IF EXISTS {name}")
        con.execute(f"CREATE DATABASE {name}")
    return pg_cluster.url(db=name)


@pytest.fixture(scope="session")
def s3() -> Iterator[object]:
    with services.s3_server() as server:
        yield server


@pytest.fixture
def s3_env(s3: object, monkeypatch: pytest.MonkeyPatch) -> object:
    """The AWS_* variables of the S3 server set for this test, and a fresh bucket."""
    for k, v in s3.env.items():
        monkeypatch.setenv(k, v)
    bucket = f"lab{next(_count)}"
    s3.create_bucket(bucket)
    s3.bucket = bucket
    return s3
