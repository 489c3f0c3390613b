"""Runs recorded into a local spool reach the lab (PostgreSQL + S3 on moto) behind the run,
and wait in the spool while a server is away."""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd
import pytest
from rotorbench_tests_services import s3_server

from bench.cli import main
from bench.store.lab_catalog import CatalogUnavailable, LabCatalog
from bench.store.lab_publish import Publisher, pending_runs
from bench.store.run_data import DataLocation, DataUnavailable


@pytest.fixture(scope="module")
def spool_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """One short simulated Step 1 run recorded into a spool folder."""
    spool = tmp_path_factory.mktemp("spool")
    assert main(["step", "--repeats", "2", "--out", str(spool)]) == 0
    (run,) = [p.parent for p in spool.glob("*/run.json")]
    return run


def _waiting(spool: Path) -> list[Path]:
    return [p.run_dir for p in pending_runs(spool)]


def _fresh_spool(run: Path, tmp_path: Path) -> Path:
    import shutil

    spool = tmp_path / "spool"
    shutil.copytree(run, spool / run.name)
    return spool


def test_publish_to_s3_and_postgres(spool_run: Path, tmp_path: Path, pg_url: str,
                                    s3_env: object) -> None:
    cat = LabCatalog(pg_url)
    cat.init()
    data = DataLocation(f"s3://{s3_env.bucket}/runs")
    pub = Publisher(cat, data, cat.identity().catalog_id)
    spool = _fresh_spool(spool_run, tmp_path)
    assert _waiting(spool) == [spool / spool_run.name]
    uri = pub.publish(spool / spool_run.name)
    assert _waiting(spool) == []
    run_id = json.loads((spool_run / "run.json").read_text())["id"]
    assert uri == f"s3://{s3_env.bucket}/runs/{run_id}" and data.has_run(run_id)
    (row,) = cat.list_runs()
    local = pd.read_parquet(spool_run / "samples.parquet")
    assert row.run_id == run_id and row.samples == len(local) and row.data == uri
    assert row.bench == "sim" and row.sequence == "step1" and row.status == "success"
    back = data.download(run_id, tmp_path / "cache")
    pd.testing.assert_frame_equal(pd.read_parquet(back / "samples.parquet"), local)
    assert (back / "events.csv").read_bytes() == (spool_run / "events.csv").read_bytes()
    pub.publish(spool / spool_run.name)  # again: nothing duplicated
    assert cat.count_runs() == 1


def test_object_store_outage_then_sync(spool_run: Path, tmp_path: Path, pg_url: str,
                                       s3_env: object, monkeypatch: pytest.MonkeyPatch) -> None:
    cat = LabCatalog(pg_url)
    cat.init()
    spool = _fresh_spool(spool_run, tmp_path)
    with s3_server() as own:
        monkeypatch.setenv("AWS_ENDPOINT_URL", own.endpoint)
        own.create_bucket("lab")
        port = own.port
    # the server is gone now
    pub = Publisher(cat, DataLocation("s3://lab/runs"), cat.identity().catalog_id)
    with pytest.raises(DataUnavailable, match=r"upload of .* failed"):
        pub.publish(spool / spool_run.name)
    assert _waiting(spool) == [spool / spool_run.name]
    assert cat.count_runs() == 0
    with s3_server(port) as back:
        back.create_bucket("lab")
        assert [pub.publish(p) for p in _waiting(spool)]
        assert _waiting(spool) == []
        assert cat.count_runs() == 1


def test_database_outage_then_sync(spool_run: Path, tmp_path: Path, pg_cluster: object,
                                   pg_url: str, s3_env: object) -> None:
    cat = LabCatalog(pg_url, connect_timeout_s=2)
    cat.init()
    spool = _fresh_spool(spool_run, tmp_path)
    pub = Publisher(cat, DataLocation(f"s3://{s3_env.bucket}/runs"), cat.identity().catalog_id)
    pg_cluster.stop()
    try:
        with pytest.raises(CatalogUnavailable):
            pub.publish(spool / spool_run.name)
        assert _waiting(spool) == [spool / spool_run.name]
    finally:
        pg_cluster.start()
    for p in _waiting(spool):
        pub.publish(p)
    assert _waiting(spool) == [] and cat.count_runs() == 1


def test_each_file_goes_up_in_one_put(spool_run: Path, s3_env: object) -> None:
    """A run's files are PUT whole, not as multipart uploads (three requests each: most
    of the object store's work for a run of many parts): the ETag the server gives each
    object is then the MD5 of its bytes, where a multipart upload's ends in ``-1``."""
    import hashlib

    import boto3  # moto's own client library, here to read what the server keeps

    data = DataLocation(f"s3://{s3_env.bucket}/runs")
    data.upload(spool_run, "one-put")
    s3 = boto3.client("s3", endpoint_url=s3_env.endpoint)
    files = sorted(p for p in spool_run.rglob("*") if p.is_file())
    assert len(files) >= 3
    for path in files:
        rel = path.relative_to(spool_run).as_posix()
        head = s3.head_object(Bucket=s3_env.bucket, Key=f"runs/one-put/{rel}")
        assert head["ETag"].strip('"') == hashlib.md5(path.read_bytes()).hexdigest(), rel


def test_publishing_a_recorded_run_leaves_pandas_unimported(spool_run: Path, tmp_path: Path,
                                                             pg_url: str) -> None:
    """The publish at the end of a recording command takes the row count from run.json:
    the run reader, and pandas with it (0.2 s of the command), stay unimported."""
    import subprocess
    import sys

    LabCatalog(pg_url).init()
    spool = _fresh_spool(spool_run, tmp_path)
    code = ("import sys\nfrom pathlib import Path\n"
            "from bench.store.lab_catalog import LabCatalog\n"
            "from bench.store.lab_publish import Publisher\n"
            "from bench.store.run_data import DataLocation\n"
            "Publisher(LabCatalog(sys.argv[1]), DataLocation(sys.argv[2]), 'id').publish("
            "Path(sys.argv[3]))\n"
            "print([m for m in ('pandas', 'analysis.run_record') if m in sys.modules])\n")
    out = subprocess.run([sys.executable, "-c", code, pg_url, str(tmp_path / "share"),
                          str(spool / spool_run.name)], capture_output=True, text=True,
                         check=True, timeout=120)
    assert out.stdout.strip() == "[]"
    assert LabCatalog(pg_url).count_runs() == 1


def test_folder_data_location(spool_run: Path, tmp_path: Path) -> None:
    data = DataLocation(str(tmp_path / "share"))
    uri = data.upload(spool_run, "r1")
    assert data.has_run("r1") and uri.endswith("/r1")
    assert (tmp_path / "share" / "r1" / "samples.parquet").is_dir()


def test_parts_trail_the_run_and_run_json_seals_it(spool_run: Path, tmp_path: Path,
                                                   s3_env: object) -> None:
    """While a run records (this process, status running) its whole parts go up; run.json
    and events.csv wait for the publish at the end, which skips what was sent."""
    import os

    from bench.store.trailing_upload import TrailingUpload

    spool = _fresh_spool(spool_run, tmp_path)
    run = spool / spool_run.name
    meta = json.loads((run / "run.json").read_text())
    meta.update(status="running", pid=os.getpid())
    (run / "run.json").write_text(json.dumps(meta))
    (run / "samples.parquet" / ".part-99999.parquet.tmp").write_bytes(b"half a part")
    data = DataLocation(f"s3://{s3_env.bucket}/runs")
    trailing = TrailingUpload(spool, data)
    trailing.send_new()
    parts = sorted(p.name for p in (run / "samples.parquet").glob("part-*.parquet"))
    assert sorted(r.split("/")[-1] for r in trailing.done[run.name]) == parts
    assert not data.has_run(meta["id"])  # no run.json up there yet: not a whole run
    (run / "samples.parquet" / ".part-99999.parquet.tmp").unlink()
    meta["status"] = "success"
    (run / "run.json").write_text(json.dumps(meta))
    trailing.send_new()  # an ended run is not trailed any more
    data.upload(run, meta["id"], done=trailing.done[run.name])
    assert data.has_run(meta["id"])
    back = data.download(meta["id"], tmp_path / "cache")
    pd.testing.assert_frame_equal(pd.read_parquet(back / "samples.parquet"),
                                  pd.read_parquet(run / "samples.parquet"))


class _CountingJson:
    """``json`` as a module uses it, counting the documents it parses."""

    def __init__(self) -> None:
        self.loads_calls = 0

    def loads(self, text: str) -> object:
        self.loads_calls += 1
        return json.loads(text)

    def __getattr__(self, name: str) -> object:
        return getattr(json, name)


def test_a_spool_full_of_runs_is_not_read_again(spool_run: Path, tmp_path: Path,
                                                monkeypatch: pytest.MonkeyPatch) -> None:
    """A bench's spool keeps every run it recorded: the trailing upload reads the run.json
    only of runs recorded after it started, again only when it was replaced, and no more
    once they end; the publish at the end looks at the marker of a published run, not
    its run.json (0.25 MB for a 200-repeat Step 1: reading them all every pass would slow the
    bench the more runs it kept)."""
    import os
    import shutil

    import analysis.run_paths as run_paths
    import bench.store.lab_publish as lab_publish
    from bench.store.trailing_upload import TrailingUpload

    spool = tmp_path / "spool"
    for i in range(3):
        shutil.copytree(spool_run, spool / f"old-{i}")
        (spool / f"old-{i}" / lab_publish.MARKER).write_text(json.dumps({"store": "lab"}))
    data = DataLocation(str(tmp_path / "share"))
    counted = _CountingJson()
    monkeypatch.setattr(run_paths, "json", counted)  # every run.json is read there
    monkeypatch.setattr(lab_publish, "json", counted)
    trailing = TrailingUpload(spool, data, period_s=60.0).start()
    trailing.stop()
    trailing.send_new()
    assert counted.loads_calls == 0 and trailing.done == {}
    new = spool / "new"
    shutil.copytree(spool_run, new)
    meta = json.loads((new / "run.json").read_text())
    (new / "run.json").write_text(json.dumps({**meta, "status": "running", "pid": os.getpid()}))
    trailing.send_new()
    trailing.send_new()  # its run.json unchanged: not parsed again
    assert counted.loads_calls == 1 and len(trailing.done["new"]) == meta["parts"]
    (new / "run.json").write_text(json.dumps(meta))  # the run ended
    trailing.send_new()
    trailing.send_new()
    assert counted.loads_calls == 2  # read once more, seen ended, passed
    counted.loads_calls = 0
    assert _waiting(spool) == [new]
    assert counted.loads_calls == 1  # one run.json; the three markers are only there
