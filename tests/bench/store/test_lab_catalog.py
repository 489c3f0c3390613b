"""The lab catalog on a real PostgreSQL: schema, runs, constants history, roles."""

from __future__ import annotations

import threading

import psycopg
import pytest

from bench.errors import RigError
from bench.store.lab_catalog import CatalogUnavailable, LabCatalog, StoredConstants, run_from_meta
from bench.store.pg_schema import SCHEMA_VERSION
from bench.store.run_summary import RunFilter


def _meta(i: int, status: str = "ok") -> dict:
    return {"id": f"20261127T0800{i:02d}_000000Z-step1-{i:04x}", "rig": {"name": "sim"},
            "sequence": {"name": "step1"}, "components": {"motor": "M3", "propeller": "P4"},
            "status": status, "reason": "", "started_utc": f"2026-11-27T08:00:{i % 60:02d}Z",
            "ended_utc": None, "host": "bench-a", "software_version": "0.1.0"}


def test_init_twice_is_harmless(pg_url: str) -> None:
    cat = LabCatalog(pg_url)
    assert cat.init() == (0, SCHEMA_VERSION)
    assert cat.init() == (SCHEMA_VERSION, SCHEMA_VERSION)
    assert cat.list_runs() == []


def test_uninitialised_database_says_how_to_init(pg_url: str) -> None:
    with pytest.raises(RigError, match="store init"):
        LabCatalog(pg_url).list_runs()


def test_runs_upsert_by_id_and_filter(pg_url: str) -> None:
    cat = LabCatalog(pg_url)
    cat.init()
    for i in range(5):
        cat.upsert_run(run_from_meta(_meta(i, "running"), data=f"s3://lab/runs/{i}",
                                     samples=0, bench="A" if i % 2 else "B", operator="ana"))
    cat.upsert_run(run_from_meta(_meta(3, "trip"), data="s3://lab/runs/3", samples=1234,
                                 bench="A", operator="ana"))  # the end of run 3
    runs = cat.list_runs()
    assert len(runs) == 5
    assert [r.run_id for r in runs] == sorted((r.run_id for r in runs), reverse=True)
    three = cat.get_run(_meta(3)["id"])
    assert three is not None and three.status == "trip" and three.samples == 1234
    assert three.meta["host"] == "bench-a"
    assert {r.bench for r in cat.list_runs(RunFilter(bench="A"))} == {"A"}
    assert cat.count_runs(RunFilter(status="running")) == 4
    assert len(cat.list_runs(limit=2, offset=4)) == 1
    # a hostile value is a bound parameter, not SQL
    assert cat.list_runs(RunFilter(bench="x' OR '1'='1")) == []


def test_concurrent_benches_lose_and_duplicate_nothing(pg_url: str) -> None:
    cat = LabCatalog(pg_url)
    cat.init()
    errors: list[BaseException] = []

    def bench(name: str) -> None:
        try:
            for i in range(40):
                meta = _meta(i) | {"id": f"{name}-{i:03d}"}
                cat.upsert_run(run_from_meta(meta, data="", samples=i, bench=name,
                                             operator=name))
                cat.upsert_run(run_from_meta(meta, data="", samples=i, bench=name,
                                             operator=name))  # a retried upload
        except BaseException as exc:  # reported below
            errors.append(exc)

    threads = [threading.Thread(target=bench, args=(n,)) for n in ("A", "B", "C")]
    for t in threads:
        t.start()
    for t in threads:
        t.join(60)
    assert not errors
    assert cat.count_runs() == 120
    assert {cat.count_runs(RunFilter(bench=n)) for n in "ABC"} == {40}


def test_constants_keep_their_history(pg_url: str) -> None:
    cat = LabCatalog(pg_url)
    cat.init()

    def row(tau: float, run: str) -> StoredConstants:
        return StoredConstants("M3", "P4", "F30A", "plain", "3S", "step", "thesis-e", run,
                               f"s3://lab/runs/{run}", "", {"tau_up_s": tau,
                                                             "nan": float("nan")})

    cat.add_constants([row(0.150, "r1")])
    cat.add_constants([row(0.140, "r2")])
    current = cat.constants()
    assert len(current) == 1 and current[0].data["tau_up_s"] == 0.140
    assert current[0].run_id == "r2" and current[0].data["nan"] is None
    assert [r.run_id for r in cat.constants(history=True)] == ["r1", "r2"]
    # one transaction: a bad row leaves none of its batch behind
    bad = StoredConstants("M3", "P4", "F30A", "plain", "3S", "nonsense", "", "r3", "", "", {})
    with pytest.raises(RigError):
        cat.add_constants([row(0.1, "r3"), bad])
    assert len(cat.constants(history=True)) == 2


def _login(pg_url: str, name: str, role: str) -> str:
    with psycopg.connect(pg_url, autocommit=True) as con:
        con.execute(f"CREATE ROLE {name} LOGIN PASSWORD 'pw-{name}' IN ROLE {role}")
    return pg_url.replace("postgres:s3cret-superuser-pw@", f"{name}:pw-{name}@")


def test_roles_reader_reads_writer_writes_its_own(pg_url: str) -> None:
    admin = LabCatalog(pg_url)
    admin.init()
    admin.upsert_run(run_from_meta(_meta(1), data="", samples=1, bench="A", operator="x"))
    reader = LabCatalog(_login(pg_url, "rosa", "rotorbench_reader"))
    writer = LabCatalog(_login(pg_url, "wim", "rotorbench_writer"))
    other = LabCatalog(_login(pg_url, "olga", "rotorbench_writer"))
    assert len(reader.list_runs()) == 1
    with pytest.raises(RigError, match=r"user rosa may not record runs.*rotorbench_writer"):
        reader.check_can_record()
    with pytest.raises(RigError, match="permission denied") as err:
        reader.upsert_run(run_from_meta(_meta(2), data="", samples=1, bench="A", operator="r"))
    assert "pw-rosa" not in str(err.value)
    writer.check_can_record()
    writer.upsert_run(run_from_meta(_meta(2), data="", samples=1, bench="A", operator="w"))
    writer.upsert_run(run_from_meta(_meta(2, "trip"), data="", samples=2, bench="A",
                                    operator="w"))  # its own run: may update
    assert writer.get_run(_meta(2)["id"]).status == "trip"
    with pytest.raises(RigError):  # someone else's run: may not overwrite it
        other.upsert_run(run_from_meta(_meta(2, "ok"), data="", samples=9, bench="A",
                                       operator="o"))
    assert admin.get_run(_meta(2)["id"]).status == "trip"
    with psycopg.connect(writer.dsn, autocommit=True) as con, pytest.raises(
            psycopg.errors.InsufficientPrivilege):
        con.execute("DELETE FROM runs")
    writer.add_constants([StoredConstants("M", "P", "E", "m", "B", "static", "", "r", "", "",
                                          {})])
    with pytest.raises(RigError, match="permission denied"):
        reader.add_constants([StoredConstants("M", "P", "E", "m", "B", "static", "", "r", "",
                                              "", {})])


def test_wrong_password_and_server_away_never_show_the_secret(pg_url: str) -> None:
    bad = LabCatalog(pg_url.replace("s3cret-superuser-pw", "wrong-secret-pw"))
    with pytest.raises(CatalogUnavailable) as err:
        bad.list_runs()
    assert "wrong-secret-pw" not in str(err.value) and "***" in str(err.value)
    assert "wrong-secret-pw" not in repr(bad)
    from rotorbench_tests_services import free_port

    away = LabCatalog(f"postgresql://u:topsecret@127.0.0.1:{free_port()}/db",
                      connect_timeout_s=2)
    with pytest.raises(CatalogUnavailable, match="cannot connect") as err:
        away.list_runs()
    assert "topsecret" not in str(err.value)
